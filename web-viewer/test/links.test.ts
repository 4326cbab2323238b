// Share links carry the page's frame encoding (issue 11) and nothing else of its query.
import assert from "node:assert/strict";
import { describe, it } from "node:test";
import { linkQuery } from "../src/links";

describe("linkQuery", () => {
  it("names the session, and watch=1 for a watch link", () => {
    assert.equal(linkQuery("sessions/abc", false, "").toString(), "session=sessions%2Fabc");
    assert.equal(linkQuery("sessions/abc", true, "?x=1").toString(),
      "session=sessions%2Fabc&watch=1");
  });
  it("keeps the encoding this page chose", () => {
    assert.equal(linkQuery("sessions/abc", true, "?session=sessions/old&encoding=float32&watch=1")
      .get("encoding"), "float32");
    assert.equal(linkQuery("sessions/abc", false, "?encoding=quantized").toString(),
      "session=sessions%2Fabc&encoding=quantized");
  });
  it("drops everything else of the page's query (tokens never travel in it)", () => {
    const q = linkQuery("sessions/abc", false, "?edit=secret&view=v&session=sessions/old");
    assert.equal(q.get("edit"), null);
    assert.equal(q.get("view"), null);
    assert.equal(q.get("session"), "sessions/abc");
  });
});

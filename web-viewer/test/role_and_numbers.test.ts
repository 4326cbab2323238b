// Issue 37: what a link's token may do (the role probe), the presence model across a switch of
// session, the lease naming the session of its answers, and number boxes that show values whole.
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import { describe, it } from "node:test";
import { PresenceSchema } from "../src/gen/hdeform/v1/deform_pb";
import { HandleLease } from "../src/multi/handle_lease";
import { CommandLayer } from "../src/commands/command_layer";
import type { DeformationClient } from "../src/api";
import { PresenceModel } from "../src/multi/presence_model";
import { faithful } from "../src/panels/number_box";
import { tokenRole } from "../src/token_role";

const answering = (answer: () => Promise<unknown>, seen: Record<string, unknown>[] = []) =>
  new CommandLayer({
    client: {
      releaseHandles: async (request: Record<string, unknown>) => {
        seen.push(request);
        return answer();
      },
    } as unknown as DeformationClient,
  });

describe("token role", () => {
  it("an edit token: the edit-only probe succeeds; it names a throwaway client and no handle", async () => {
    const seen: Record<string, unknown>[] = [];
    assert.equal(await tokenRole(answering(async () => ({}), seen), "sessions/s"), "edit");
    assert.equal(seen[0].name, "sessions/s");
    assert.match(String(seen[0].clientId), /^role-probe-[0-9a-f]{12}$/);
    assert.deepEqual(seen[0].handles, []);
  });
  it("a view token: PERMISSION_DENIED", async () => {
    const denied = answering(async () => {
      throw new ConnectError("needs the edit token", Code.PermissionDenied);
    });
    assert.equal(await tokenRole(denied, "sessions/s"), "view");
  });
  it("anything else says nothing (an older server, a lost connection)", async () => {
    for (const code of [Code.Unimplemented, Code.Unavailable, Code.ResourceExhausted]) {
      const c = answering(async () => {
        throw new ConnectError("x", code);
      });
      assert.equal(await tokenRole(c, "sessions/s"), "unknown");
    }
    assert.equal(await tokenRole(answering(async () => Promise.reject(new TypeError("fetch failed"))), "s"), "unknown");
  });
});

describe("presence across sessions", () => {
  const presence = (version: bigint, ids: string[]) =>
    create(PresenceSchema, { version, participants: ids.map((clientId) => ({ clientId, displayName: clientId })) });
  it("after clear() a new session's presence is listed even at a lower version", () => {
    const p = new PresenceModel("me");
    p.update(presence(7n, ["me", "quinn"]));
    assert.equal(p.update(presence(1n, ["me"])), false); // what kept the old session's people
    p.clear();
    assert.ok(p.update(presence(1n, ["me"])));
    assert.deepEqual(p.people.map((x) => x.clientId), ["me"]);
  });
  it("the lease names the session each answer is of", async () => {
    const got: string[] = [];
    const client = {
      grabHandles: async () => ({ presence: presence(2n, ["me"]) }),
      releaseHandles: async () => ({ presence: presence(3n, ["me"]) }),
    } as unknown as DeformationClient;
    const lease = new HandleLease(new CommandLayer({ client }), () => ({ clientId: "me" }), (_p, name) => got.push(name));
    await lease.grab("sessions/a", [0]);
    await lease.release();
    assert.deepEqual(got, ["sessions/a", "sessions/a"]);
  });
});

describe("number boxes", () => {
  it("show values whole: enough digits, the exponent intact, no float noise", () => {
    assert.equal(faithful(0.99), "0.99");
    assert.equal(faithful(0.9875), "0.9875");
    assert.equal(faithful(3.57e-25), "3.57e-25");
    assert.equal(faithful(0.1 + 0.2), "0.3");
    assert.equal(faithful(0), "0");
    assert.equal(faithful(1e-7), "1e-7");
  });
});

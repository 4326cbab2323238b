// The viewer offers "Repair and open" only for the refusals the server's repair fixes.
import assert from "node:assert/strict";
import { describe, it } from "node:test";
import { repairFixes, repairNotice } from "../src/mesh_repair";

describe("repairFixes", () => {
  it("offers repair for zero-area triangles, duplicate triangles and non-manifold vertices", () => {
    assert.ok(repairFixes(400, 3, "zero-area triangles: 1 triangle has area ≤ 1e-14·(bbox diagonal)² = 5e-14 (first: triangles 0)"));
    assert.ok(repairFixes(400, 3, "non-manifold vertex: 1 vertex has triangles forming more than one fan (first: vertex 0 (2 fans))"));
    assert.ok(repairFixes(400, 3, "duplicate triangles: 1 triangle has the same three vertices as an earlier one (first: triangle 4 repeats triangle 1)"));
    assert.ok(repairFixes(400, null, "non-manifold vertex: 1 vertex …"), "a reply without grpc-status");
  });
  it("not for non-manifold edges, inconsistent orientation, other refusals or other statuses", () => {
    assert.ok(!repairFixes(400, 3, "non-manifold edge: 1 edge has more than two triangles (first: vertices 0–1, triangles 0, 1, 2)"));
    assert.ok(!repairFixes(400, 3, "inconsistent orientation (non-manifold edge): 1 edge is used twice in the same direction"));
    assert.ok(!repairFixes(400, 3, "obj: line 1: unknown keyword"));
    assert.ok(!repairFixes(400, 3, "the mesh is not non-manifold"));
    assert.ok(!repairFixes(413, null, "non-manifold vertex: …"));
    assert.ok(!repairFixes(400, 8, "non-manifold vertex: …"));
  });
});

describe("repairNotice", () => {
  it("lists the report's lines, nothing when nothing changed", () => {
    assert.equal(repairNotice([]), "");
    assert.equal(repairNotice(["split 1 non-manifold vertex", "dropped 1 unreferenced vertex"]),
      "Repaired: split 1 non-manifold vertex; dropped 1 unreferenced vertex");
  });
});

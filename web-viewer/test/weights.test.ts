// The handle-weight preview's pure parts: the ramp, decoding GetHandleWeights' bytes, dropping
// stale answers; and the held-handle outline's region boundary.
import assert from "node:assert/strict";
import { describe, it } from "node:test";
import { ramp } from "../src/colormap";
import { keyAction, SHORTCUTS } from "../src/keymap";
import { regionBoundaryEdges, weldByPosition } from "../src/viewport/region_boundary";
import { decodeWeights, WEIGHT_STOPS, weightRamp } from "../src/weights/weight_ramp";
import { WeightsRequests } from "../src/weights/weights_requests";

const at = (f: (t: number, out: Float32Array, at: number) => void, t: number) => {
  const c = new Float32Array(3);
  f(t, c, 0);
  return Array.from(c);
};
const close = (a: number[], b: readonly number[]) => a.every((x, i) => Math.abs(x - b[i]) < 1e-6);

describe("weight ramp", () => {
  it("runs from the first stop at 0 to the last at 1, clamped outside", () => {
    assert.ok(close(at(weightRamp, 0), WEIGHT_STOPS[0]));
    assert.ok(close(at(weightRamp, 1), WEIGHT_STOPS[WEIGHT_STOPS.length - 1]));
    assert.deepEqual(at(weightRamp, -0.5), at(weightRamp, 0));
    assert.deepEqual(at(weightRamp, 7), at(weightRamp, 1));
  });
  it("interpolates between stops", () => {
    const mid = at(weightRamp, 0.125); // half-way between stops 0 and 1 of 5
    const want = WEIGHT_STOPS[0].map((a, k) => (a + WEIGHT_STOPS[1][k]) / 2);
    assert.ok(close(mid, want), `${mid} vs ${want}`);
  });
  it("gets lighter from 0 to 1 (luminance rises), so the order reads without the legend", () => {
    const lum = (c: number[]) => 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let prev = -1;
    for (let i = 0; i <= 20; i++) {
      const l = lum(at(weightRamp, i / 20));
      assert.ok(l > prev, `luminance at ${i / 20}`);
      prev = l;
    }
  });
  it("is not the energy ramp (one look tells which map is on)", () => {
    for (const t of [0, 0.25, 0.5, 0.75]) {
      const d = at(weightRamp, t).reduce((s, x, k) => s + Math.abs(x - at(ramp, t)[k]), 0);
      assert.ok(d > 0.3, `ramps too alike at ${t} (${d})`);
    }
  });
});

describe("decodeWeights", () => {
  it("reads float32 little-endian, also from an unaligned offset", () => {
    const values = [0, 1, 0.25, 0.7];
    const buf = new Uint8Array(1 + 4 * values.length);
    const view = new DataView(buf.buffer);
    values.forEach((v, i) => view.setFloat32(1 + 4 * i, v, true));
    const out = decodeWeights(buf.subarray(1), values.length);
    assert.deepEqual(Array.from(out), Array.from(new Float32Array(values)));
  });
  it("refuses a length that is not 4 per vertex", () => {
    assert.throws(() => decodeWeights(new Uint8Array(12), 4), /12 bytes for 4 vertices/);
  });
});

describe("WeightsRequests (stale answers are dropped)", () => {
  it("shows only the newest request's answer", () => {
    const r = new WeightsRequests();
    const first = r.begin({ handle: 0, minVersion: 5n });
    const second = r.begin({ handle: 1, minVersion: 5n });
    // The answer for handle 0 arrives after the switch to handle 1: dropped.
    assert.equal(r.accept(first, { handle: 0, version: 6n }), false);
    assert.equal(r.isLatest(first), false);
    assert.equal(r.accept(second, { handle: 1, version: 6n }), true);
  });
  it("drops an answer for another handle or read before the state the page asked from", () => {
    const r = new WeightsRequests();
    const t = r.begin({ handle: 2, minVersion: 10n });
    assert.equal(r.accept(t, { handle: 1, version: 10n }), false);
    assert.equal(r.accept(t, { handle: 2, version: 9n }), false);
    assert.equal(r.accept(t, { handle: 2, version: 10n }), true);
  });
  it("drops everything in flight once the preview is turned off", () => {
    const r = new WeightsRequests();
    const t = r.begin({ handle: 0, minVersion: 0n });
    r.cancel();
    assert.equal(r.accept(t, { handle: 0, version: 1n }), false);
    assert.equal(r.isLatest(t), false);
  });
});

describe("V toggles the weights", () => {
  it("is a shortcut, listed in the ? overlay, and not with Ctrl (paste)", () => {
    assert.equal(keyAction({ key: "v" }), "toggleWeights");
    assert.equal(keyAction({ key: "V", shiftKey: true }), "toggleWeights");
    assert.equal(keyAction({ key: "v", ctrlKey: true }), null);
    assert.ok(SHORTCUTS.some(([k, what]) => k === "V" && /weights/.test(what)));
  });
});

describe("region boundary (held-handle outline)", () => {
  // A 3×3 grid of vertices (ids 3 j + i), two triangles per cell.
  const grid = () => {
    const idx: number[] = [];
    for (let j = 0; j < 2; j++)
      for (let i = 0; i < 2; i++) {
        const v = 3 * j + i;
        idx.push(v, v + 1, v + 4, v, v + 4, v + 3);
      }
    const rest = new Float32Array(27);
    for (let v = 0; v < 9; v++) rest.set([v % 3, Math.floor(v / 3), 0], 3 * v);
    return { index: new Uint32Array(idx), rest };
  };
  const asSet = (pairs: number[]) => new Set(Array.from({ length: pairs.length / 2 }, (_, k) => [pairs[2 * k], pairs[2 * k + 1]].sort((a, b) => a - b).join("-")));

  it("is the ring of edges around the region's triangles", () => {
    const { index, rest } = grid();
    const labels = new Int16Array(9).fill(1); // the whole grid
    const edges = asSet(regionBoundaryEdges(index, labels, 1, weldByPosition(rest)));
    assert.deepEqual(edges, new Set(["0-1", "1-2", "2-5", "5-8", "7-8", "6-7", "3-6", "0-3"]));
  });
  it("leaves out triangles with a corner outside the region, and other labels", () => {
    const { index, rest } = grid();
    const labels = new Int16Array(9).fill(-1);
    for (const v of [0, 1, 3, 4]) labels[v] = 2; // the first cell only
    assert.deepEqual(asSet(regionBoundaryEdges(index, labels, 2, weldByPosition(rest))), new Set(["0-1", "1-4", "3-4", "0-3"]));
    assert.deepEqual(regionBoundaryEdges(index, labels, 1, weldByPosition(rest)), []);
  });
  it("draws no line along a seam (vertices at one position count as one)", () => {
    // Two triangles that share an edge only through duplicated vertices (a UV seam).
    const rest = new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0, /* copies of 1 and 2: */ 1, 0, 0, 0, 1, 0, 1, 1, 0]);
    const index = new Uint32Array([0, 1, 2, 3, 5, 4]);
    const labels = new Int16Array(6).fill(1);
    const weld = weldByPosition(rest);
    assert.deepEqual(Array.from(weld), [0, 1, 2, 1, 2, 5]);
    const edges = asSet(regionBoundaryEdges(index, labels, 1, weld));
    assert.equal(edges.size, 4);
    assert.ok(!edges.has("1-2") && !edges.has("3-4"));
  });
});

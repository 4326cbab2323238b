// Issue 39 item 1 (Export rig's report as shown), issue 37's perf overlay numbers and its selection
// commands (all / none / invert / grow / shrink by one ring of neighbours) and their keys.
import assert from "node:assert/strict";
import { describe, it } from "node:test";
import { keyAction, SHORTCUTS } from "../src/keymap";
import { PerfStats, perfLines, quantile } from "../src/perf/perf_stats";
import { percentOfDiagonal, poseName, reportCells, reportSummary } from "../src/rig/rig_report";
import { adjacency, selectionChange } from "../src/selection/commands";

describe("rig report", () => {
  it("shows max and rms as % of the diagonal, 3 significant digits, the current pose then key times", () => {
    assert.equal(percentOfDiagonal(0.11512), "11.5");
    assert.equal(percentOfDiagonal(0.069), "6.9");
    assert.equal(percentOfDiagonal(1.234e-4), "0.0123");
    assert.equal(percentOfDiagonal(1e-14), "1.00e-12");
    assert.equal(percentOfDiagonal(0), "0");
    assert.equal(poseName({ current: true, timeS: 0 }), "current");
    assert.equal(poseName({ current: false, timeS: 1 }), "1.000 s");
    const rows = [
      { current: true, timeS: 0, max: 0.115, rms: 0.069 },
      { current: false, timeS: 0, max: 1e-14, rms: 3e-15 },
      { current: false, timeS: 1.5, max: 0.0321, rms: 0.00456 },
    ];
    assert.deepEqual(reportCells(rows), [
      ["current", "11.5", "6.9"],
      ["0.000 s", "1.00e-12", "3.00e-13"],
      ["1.500 s", "3.21", "0.456"],
    ]);
    assert.match(reportSummary(rows), /current max 11.5 rms 6.9 · 0.000 s max 1.00e-12 rms 3.00e-13 · 1.500 s max 3.21 rms 0.456/);
  });
});

describe("perf stats", () => {
  it("frames/s, median latency and cost, mean bytes over the window", () => {
    const s = new PerfStats(1000);
    for (let i = 0; i < 20; i++) s.record({ at: 1000 + 50 * i, bytes: 1000, costMs: i < 10 ? 1 : 3, latencyMs: i % 2 ? 40 : null });
    const sum = s.summary(1999);
    assert.equal(sum.frames, 20);
    assert.equal(sum.framesPerS, 20);
    assert.equal(sum.bytesPerFrame, 1000);
    assert.equal(sum.latencyMedianMs, 40);
    assert.equal(sum.costMedianMs, 1);
    assert.equal(sum.costP90Ms, 3);
    assert.equal(s.summary(5000).frames, 0); // the window moved on
    assert.equal(s.costs.length, 20);
    s.reset();
    assert.equal(s.costs.length, 0);
    assert.equal(quantile([5, 1, 3], 0.5), 3);
    assert.equal(quantile([], 0.5), null);
    const lines = perfLines(sum, 100000).join("\n");
    assert.match(lines, /frames applied\/s\s+20\.0/);
    assert.match(lines, /update→frame\s+40\.0 ms/);
    assert.match(lines, /bytes\/frame\s+1000 B/);
    assert.match(lines, /page cost\/frame\s+1\.00 ms median/);
  });
});

describe("selection commands", () => {
  // A strip of 6 vertices in a row, triangles (0,1,2), (1,3,2), (2,3,4), (3,5,4): neighbours by edges.
  const index = new Uint32Array([0, 1, 2, 1, 3, 2, 2, 3, 4, 3, 5, 4]);
  const adj = adjacency(6, index);
  const neighbours = (v: number) => [...adj.ids.subarray(adj.start[v], adj.start[v + 1])].sort().filter((x, i, a) => a.indexOf(x) === i);
  it("builds each vertex's edge neighbours", () => {
    assert.deepEqual(neighbours(0), [1, 2]);
    assert.deepEqual(neighbours(3), [1, 2, 4, 5]);
  });
  const run = (labels: number[], command: Parameters<typeof selectionChange>[0], label = 0) => {
    const l = Int16Array.from(labels);
    const { add, remove } = selectionChange(command, l, label, () => adj);
    for (const v of add) l[v] = label;
    for (const v of remove) l[v] = -1;
    return [...l];
  };
  it("all, none and invert leave the other regions alone", () => {
    assert.deepEqual(run([0, -1, -1, 1, -1, -1], "all"), [0, 0, 0, 1, 0, 0]);
    assert.deepEqual(run([0, 0, -1, 1, -1, -1], "none"), [-1, -1, -1, 1, -1, -1]);
    assert.deepEqual(run([0, 0, -1, 1, -1, -1], "invert"), [-1, -1, 0, 1, 0, 0]);
  });
  it("grow adds one ring of neighbours, shrink takes the boundary ring off", () => {
    assert.deepEqual(run([0, -1, -1, -1, -1, -1], "grow"), [0, 0, 0, -1, -1, -1]);
    assert.deepEqual(run([0, 0, 0, -1, -1, -1], "grow"), [0, 0, 0, 0, 0, -1]);
    assert.deepEqual(run([0, 0, 0, 1, -1, -1], "grow"), [0, 0, 0, 1, 0, -1]); // not into handle 0's vertex
    assert.deepEqual(run([0, 0, 0, 0, 0, -1], "shrink"), [0, 0, 0, -1, -1, -1]); // 3 and 4 touch vertex 5
    assert.deepEqual(run([0, 0, 0, 0, 0, 0], "shrink"), [0, 0, 0, 0, 0, 0]); // no boundary: nothing to take
  });
  it("grows and shrinks across a glTF seam (coincident copies count as one vertex)", () => {
    // Two triangles sharing the edge (1,2), split along it as a UV seam splits a glTF: 3 and 4
    // are copies of 1 and 2 (same positions), 5 is the far corner.
    const seamIndex = new Uint32Array([0, 1, 2, 3, 5, 4]);
    const rest = new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0]);
    const split = adjacency(6, seamIndex);
    const welded = adjacency(6, seamIndex, rest);
    const grow = (a: typeof split, labels: number[], command: "grow" | "shrink" = "grow") => {
      const l = Int16Array.from(labels);
      const { add, remove } = selectionChange(command, l, 0, () => a);
      for (const v of add) l[v] = 0;
      for (const v of remove) l[v] = -1;
      return [...l];
    };
    assert.deepEqual(grow(split, [0, -1, -1, -1, -1, -1]), [0, 0, 0, -1, -1, -1]); // stops at the seam
    assert.deepEqual(grow(welded, [0, -1, -1, -1, -1, -1]), [0, 0, 0, 0, 0, -1]); // the copies come along
    assert.deepEqual(grow(welded, [0, 0, 0, 0, 0, -1]), [0, 0, 0, 0, 0, 0]); // and the far side next
    assert.deepEqual(grow(welded, [-1, -1, -1, -1, -1, 0]), [-1, 0, 0, 0, 0, 0]); // from the other side too
    // Shrink with the far corner unselected: the seam's copies on both sides touch it.
    assert.deepEqual(grow(split, [0, 0, 0, 0, 0, -1], "shrink"), [0, 0, 0, -1, -1, -1]);
    assert.deepEqual(grow(welded, [0, 0, 0, 0, 0, -1], "shrink"), [0, -1, -1, -1, -1, -1]);
  });
  it("has keys, listed in the shortcuts", () => {
    assert.equal(keyAction({ key: "a" }), "selectAll");
    assert.equal(keyAction({ key: "a", altKey: true, code: "KeyA" }), "selectNone");
    assert.equal(keyAction({ key: "å", altKey: true, code: "KeyA" }), "selectNone"); // macOS Alt+A
    assert.equal(keyAction({ key: "a", ctrlKey: true }), null); // the browser's select-all
    assert.equal(keyAction({ key: "i" }), "selectInvert");
    assert.equal(keyAction({ key: "+" }), "selectGrow");
    assert.equal(keyAction({ key: "=" }), "selectGrow");
    assert.equal(keyAction({ key: "-" }), "selectShrink");
    assert.equal(keyAction({ key: "p" }), "togglePerf");
    const text = SHORTCUTS.map((r) => r.join(" ")).join("\n");
    for (const want of [/Alt\+A/, /invert/, /grow \/ shrink/, /Shift\+drag/, /Ctrl\+drag/, /perf overlay/]) assert.match(text, want);
  });
});

// The history's pure logic: the undo / redo keys (Ctrl, ⌘ on macOS), the History panel's list
// (pages and live steps merged, undone flags kept current by later UNDO / REDO steps), and the
// relative times.
import assert from "node:assert/strict";
import { create, type MessageInitShape } from "@bufbuild/protobuf";
import { describe, it } from "node:test";
import { HistoryStepSchema, StepKind, type HistoryStep } from "../src/gen/hdeform/v1/deform_pb";
import { HistoryList } from "../src/history/history_list";
import { relativeTime } from "../src/history/relative_time";
import { historyKey, isMacPlatform, keyAction } from "../src/keymap";

describe("undo / redo keys", () => {
  it("Ctrl+Z undo, Ctrl+Shift+Z and Ctrl+Y redo elsewhere than macOS", () => {
    assert.equal(historyKey({ key: "z", ctrlKey: true }, false), "undo");
    assert.equal(historyKey({ key: "Z", ctrlKey: true, shiftKey: true }, false), "redo");
    assert.equal(historyKey({ key: "y", ctrlKey: true }, false), "redo");
    assert.equal(historyKey({ key: "z", metaKey: true }, false), null); // the Windows / Super key
    assert.equal(historyKey({ key: "z" }, false), null); // plain Z: the axis key
    assert.equal(historyKey({ key: "z", ctrlKey: true, altKey: true }, false), null);
    assert.equal(historyKey({ key: "y", ctrlKey: true, shiftKey: true }, false), null);
    assert.equal(historyKey({ key: "c", ctrlKey: true }, false), null);
  });
  it("⌘ instead of Ctrl on macOS", () => {
    assert.equal(historyKey({ key: "z", metaKey: true }, true), "undo");
    assert.equal(historyKey({ key: "z", metaKey: true, shiftKey: true }, true), "redo");
    assert.equal(historyKey({ key: "y", metaKey: true }, true), "redo");
    assert.equal(historyKey({ key: "z", ctrlKey: true }, true), null);
    assert.equal(historyKey({ key: "z", ctrlKey: true, metaKey: true }, true), null);
  });
  it("knows macOS by navigator.platform", () => {
    for (const p of ["MacIntel", "Macintosh", "iPad", "iPhone"]) assert.equal(isMacPlatform(p), true, p);
    for (const p of ["Win32", "Linux x86_64", "", undefined]) assert.equal(isMacPlatform(p), false, String(p));
  });
  it("Ctrl+Z is not also the Z axis key", () => {
    assert.equal(keyAction({ key: "z", ctrlKey: true }), null);
  });
});

const step = (id: number, kind: StepKind, more: Omit<MessageInitShape<typeof HistoryStepSchema>, "$typeName"> = {}): HistoryStep =>
  create(HistoryStepSchema, { id: BigInt(id), kind, author: "Alice", summary: `step ${id}`, ...more });
const ids = (l: HistoryList) => l.shown().map((s) => Number(s.step.id));
const undone = (l: HistoryList) => l.shown().filter((s) => s.undone).map((s) => Number(s.step.id));

describe("history list", () => {
  it("pages newest first, older pages appended, until no token", () => {
    const l = new HistoryList();
    assert.equal(l.hasOlder, false);
    l.addFirstPage({ steps: [step(5, StepKind.MOVE), step(4, StepKind.BETA)], nextPageToken: "t1" });
    assert.deepEqual(ids(l), [5, 4]);
    assert.equal(l.hasOlder, true);
    assert.equal(l.olderToken, "t1");
    l.addOlderPage({ steps: [step(3, StepKind.MOVE), step(2, StepKind.CONSTRAINTS)], nextPageToken: "" });
    assert.deepEqual(ids(l), [5, 4, 3, 2]);
    assert.equal(l.hasOlder, false);
  });
  it("live steps before and after the first page: merged by id, no duplicates", () => {
    const l = new HistoryList();
    l.addLive(step(6, StepKind.MOVE)); // came on the stream while ListHistory was on its way
    l.addFirstPage({ steps: [step(6, StepKind.MOVE), step(5, StepKind.MOVE)], nextPageToken: "" });
    l.addLive(step(7, StepKind.BETA));
    assert.deepEqual(ids(l), [7, 6, 5]);
    assert.equal(l.size, 3);
  });
  it("a live UNDO greys its target, a REDO ungreys it; the newest one decides", () => {
    const l = new HistoryList();
    l.addFirstPage({ steps: [step(2, StepKind.MOVE), step(1, StepKind.CONSTRAINTS)], nextPageToken: "" });
    l.addLive(step(3, StepKind.UNDO, { target: 2n }));
    assert.deepEqual(undone(l), [2]);
    l.addLive(step(4, StepKind.REDO, { target: 2n }));
    assert.deepEqual(undone(l), []);
    l.addLive(step(5, StepKind.UNDO, { target: 2n }));
    assert.deepEqual(undone(l), [2]);
  });
  it("a page listed before a live UNDO (but answered after it) does not ungrey the target", () => {
    const l = new HistoryList();
    l.addLive(step(3, StepKind.UNDO, { target: 2n }));
    l.addFirstPage({ steps: [step(2, StepKind.MOVE, { undone: false }), step(1, StepKind.CONSTRAINTS)], nextPageToken: "" });
    assert.deepEqual(undone(l), [2]);
  });
  it("the server's flag stands for steps whose undo is not held", () => {
    const l = new HistoryList();
    l.addFirstPage({ steps: [step(9, StepKind.BETA), step(8, StepKind.MOVE, { undone: true })], nextPageToken: "t" });
    assert.deepEqual(undone(l), [8]);
    l.clear();
    assert.equal(l.size, 0);
    assert.equal(l.hasOlder, false);
  });
});

describe("relative time", () => {
  it("says how long ago, for people", () => {
    const now = 1_000_000_000;
    assert.equal(relativeTime(now - 1000, now), "just now");
    assert.equal(relativeTime(now + 3000, now), "just now"); // a clock a little ahead
    assert.equal(relativeTime(now - 42_000, now), "42 s ago");
    assert.equal(relativeTime(now - 3 * 60_000, now), "3 min ago");
    assert.equal(relativeTime(now - 5 * 3_600_000, now), "5 h ago");
    assert.equal(relativeTime(now - 3 * 86_400_000, now), "3 d ago");
  });
});

// Issue 37's timeline edits without the DOM: moving a key (kept sorted, never onto another key's
// time), the Ctrl+C / Ctrl+V keys (⌘ on macOS), and their rows in the shortcuts list.
import assert from "node:assert/strict";
import { describe, it, test } from "node:test";
import { clipboardKey, keyAction, SHORTCUTS } from "../src/keymap";
import { moveKey, SAME_TIME_S, withKeyEasing } from "../src/timeline/key_list";

const keys = [
  { timeS: 0, tag: "a" },
  { timeS: 1, tag: "b" },
  { timeS: 2, tag: "c" },
];

describe("moving a key", () => {
  it("moves it to the new time and keeps the list sorted", () => {
    const r = moveKey(keys, 0, 1.5);
    assert.ok("keys" in r);
    assert.deepEqual(r.keys.map((k) => [k.timeS, k.tag]), [[1, "b"], [1.5, "a"], [2, "c"]]);
    assert.equal(r.index, 1, "the moved key's new index (it stays selected)");
  });
  it("past the last key and back to 0", () => {
    const r = moveKey(keys, 1, 7.25);
    assert.ok("keys" in r);
    assert.deepEqual(r.keys.map((k) => k.tag), ["a", "c", "b"]);
    assert.equal(r.index, 2);
    const back = moveKey(r.keys, 2, 0.5);
    assert.ok("keys" in back);
    assert.deepEqual(back.keys.map((k) => k.tag), ["a", "b", "c"]);
  });
  it("keeps the key's pose (everything but the time)", () => {
    const r = moveKey([{ timeS: 0, pose: [1, 2, 3] }], 0, 4);
    assert.ok("keys" in r);
    assert.deepEqual(r.keys, [{ timeS: 4, pose: [1, 2, 3] }]);
  });
  it("refuses a drop on another key's time (within SAME_TIME_S), naming that key", () => {
    assert.deepEqual(moveKey(keys, 0, 2), { onto: 2 });
    assert.deepEqual(moveKey(keys, 2, 1 + SAME_TIME_S / 2), { onto: 1 });
    const near = moveKey(keys, 2, 1 + 2 * SAME_TIME_S); // 2 ms beside it: a key of its own
    assert.ok("keys" in near);
    assert.equal(near.keys.length, 3);
  });
  it("a move by less than SAME_TIME_S is not a drop on itself", () => {
    const r = moveKey(keys, 1, 1 + SAME_TIME_S / 2);
    assert.ok("keys" in r);
    assert.equal(r.keys[1].timeS, 1 + SAME_TIME_S / 2);
  });
  it("does not change the list it was given", () => {
    const before = JSON.stringify(keys);
    moveKey(keys, 0, 3);
    moveKey(keys, 0, 1);
    assert.equal(JSON.stringify(keys), before);
  });
});

describe("copy / paste keys", () => {
  it("Ctrl+C / Ctrl+V, ⌘C / ⌘V on macOS", () => {
    assert.equal(clipboardKey({ key: "c", ctrlKey: true }, false), "copy");
    assert.equal(clipboardKey({ key: "V", ctrlKey: true }, false), "paste");
    assert.equal(clipboardKey({ key: "c", metaKey: true }, true), "copy");
    assert.equal(clipboardKey({ key: "v", metaKey: true }, true), "paste");
  });
  it("not the other platform's modifier, nor with Shift / Alt, nor plain keys", () => {
    assert.equal(clipboardKey({ key: "c", metaKey: true }, false), null);
    assert.equal(clipboardKey({ key: "c", ctrlKey: true }, true), null);
    assert.equal(clipboardKey({ key: "v", ctrlKey: true, shiftKey: true }, false), null);
    assert.equal(clipboardKey({ key: "c", ctrlKey: true, altKey: true }, false), null);
    assert.equal(clipboardKey({ key: "c" }, false), null);
    assert.equal(clipboardKey({ key: "x", ctrlKey: true }, false), null);
  });
  it("Ctrl+C / Ctrl+V are no other shortcut (V alone still toggles the weights)", () => {
    assert.equal(keyAction({ key: "c", ctrlKey: true }), null);
    assert.equal(keyAction({ key: "v", ctrlKey: true }), null);
    assert.equal(keyAction({ key: "v" }), "toggleWeights");
  });
  it("the shortcuts list has them and the key drag", () => {
    assert.ok(SHORTCUTS.some(([k, what]) => /Ctrl\+C/.test(k) && /paste/.test(what)));
    assert.ok(SHORTCUTS.some(([k, what]) => /drag/.test(k) && /Esc/.test(what)));
  });
});

test("withKeyEasing sets and clears one key's easing, the others the same objects", () => {
  const keys: { timeS: number; easing?: number }[] = [
    { timeS: 0, easing: 1 },
    { timeS: 1 },
    { timeS: 2, easing: 0 },
  ];
  const set = withKeyEasing(keys, 1, 1);
  assert.deepEqual(set.map((k) => k.easing), [1, 1, 0]);
  assert.equal(set[0], keys[0]);
  assert.equal(set[2], keys[2]);
  const cleared = withKeyEasing(set, 0, undefined);
  assert.equal("easing" in cleared[0], false);
  assert.equal(cleared[0].timeS, 0);
  assert.deepEqual(keys.map((k) => k.easing), [1, undefined, 0]); // the input is not changed
});

// The timeline strip's pure parts: editing the key list, the ruler's time ⇄ pixel mapping and
// snapping, and dropping stale PoseAt answers; K in the keymap.
import assert from "node:assert/strict";
import { describe, it } from "node:test";
import { keyAction, SHORTCUTS } from "../src/keymap";
import { AnswerOrder } from "../src/timeline/answer_order";
import { deleteKey, keyAt, SAME_TIME_S, setKey } from "../src/timeline/key_list";
import { rulerEnd, TimeScale } from "../src/timeline/time_scale";

const times = (keys: { timeS: number }[]) => keys.map((k) => k.timeS);

describe("key list", () => {
  it("inserts keys in time order whatever order they are set in", () => {
    let keys: { timeS: number; tag: string }[] = [];
    keys = setKey(keys, { timeS: 2, tag: "c" });
    keys = setKey(keys, { timeS: 0, tag: "a" });
    keys = setKey(keys, { timeS: 1, tag: "b" });
    assert.deepEqual(times(keys), [0, 1, 2]);
    assert.deepEqual(keys.map((k) => k.tag), ["a", "b", "c"]);
  });
  it("replaces a key at the same time (within 1 ms), keeping one key there", () => {
    let keys = [{ timeS: 0, tag: "a" }, { timeS: 1, tag: "b" }];
    keys = setKey(keys, { timeS: 1 + SAME_TIME_S / 2, tag: "B" });
    assert.equal(keys.length, 2);
    assert.equal(keys[1].tag, "B");
    keys = setKey(keys, { timeS: 1 + 2 * SAME_TIME_S, tag: "x" }); // 2 ms later: a new key
    assert.equal(keys.length, 3);
  });
  it("does not change the list it was given", () => {
    const keys = [{ timeS: 0 }];
    setKey(keys, { timeS: 0.5 });
    deleteKey(keys, 0);
    assert.deepEqual(keys, [{ timeS: 0 }]);
  });
  it("deletes by index; out of range changes nothing", () => {
    const keys = [{ timeS: 0 }, { timeS: 1 }, { timeS: 2 }];
    assert.deepEqual(times(deleteKey(keys, 1)), [0, 2]);
    assert.deepEqual(times(deleteKey(keys, 7)), [0, 1, 2]);
    assert.deepEqual(times(deleteKey(keys, -1)), [0, 1, 2]);
  });
  it("finds the key at a time within 1 ms", () => {
    const keys = [{ timeS: 0 }, { timeS: 1.25 }];
    assert.equal(keyAt(keys, 1.2504), 1);
    assert.equal(keyAt(keys, 1.26), -1);
  });
});

describe("time scale", () => {
  const s = new TimeScale(10, 520, 10); // 500 px for 10 s: 50 px per second
  it("maps seconds to pixels and back (padding at both ends)", () => {
    assert.equal(s.toPx(0), 10);
    assert.equal(s.toPx(10), 510);
    assert.equal(s.toPx(2.5), 135);
    assert.equal(s.toTime(135), 2.5);
    for (const t of [0, 0.123, 3.5, 9.999]) assert.equal(s.toTime(s.toPx(t)), t);
  });
  it("clamps to [0, end] and rounds to the millisecond", () => {
    assert.equal(s.toTime(-40), 0);
    assert.equal(s.toTime(900), 10);
    assert.equal(s.toTime(10 + 50 * 1.23456), 1.235);
  });
  it("snaps to a key within a few pixels, the nearest one", () => {
    const keys = [1, 1.2, 4];
    assert.equal(s.snap(1.05, keys), 1); // 2.5 px away
    assert.equal(s.snap(1.15, keys), 1.2); // nearer 1.2 than 1
    assert.equal(s.snap(1.5, keys), 1.5); // 15 px from any key: free
    assert.equal(s.snap(3.9, keys, 4), 3.9); // 5 px > 4 px
    assert.equal(s.snap(3.9, keys, 6), 4);
  });
  it("labels ticks at least minPx apart with 1-2-5 steps", () => {
    assert.equal(s.tickStep(48), 1); // 50 px per second
    assert.equal(s.tickStep(60), 2);
    assert.equal(new TimeScale(100, 520).tickStep(48), 10);
    assert.equal(new TimeScale(1, 1010).tickStep(48), 0.05);
  });
  it("ends the ruler a little past the last key, at least 5 s", () => {
    assert.equal(rulerEnd([]), 5);
    assert.equal(rulerEnd([0, 2]), 5);
    assert.equal(rulerEnd([0, 8]), 11);
    assert.equal(rulerEnd([1], 7), 9);
  });
});

describe("stale answers", () => {
  it("applies answers in request order only: an older one after a newer is dropped", () => {
    const o = new AnswerOrder();
    const a = o.begin(), b = o.begin(), c = o.begin();
    assert.equal(o.accept(b), true);
    assert.equal(o.accept(a), false); // older than b, which is on screen
    assert.equal(o.accept(c), true);
    assert.equal(o.accept(c), false); // once
  });
  it("drops everything issued before a cancel, not what comes after", () => {
    const o = new AnswerOrder();
    const a = o.begin();
    o.cancel();
    const b = o.begin();
    assert.equal(o.accept(a), false);
    assert.equal(o.accept(b), true);
  });
});

describe("keymap", () => {
  it("K sets a key, listed in the shortcuts overlay", () => {
    assert.equal(keyAction({ key: "k" }), "setKey");
    assert.equal(keyAction({ key: "K" }), "setKey");
    assert.equal(keyAction({ key: "k", ctrlKey: true }), null);
    assert.ok(SHORTCUTS.some(([k]) => k === "K"));
  });
});

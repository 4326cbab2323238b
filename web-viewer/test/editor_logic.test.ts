// The editor's pure logic: the keyboard map, snapping steps, this tab's identity, the presence
// model, latest-wins sending and the onboarding steps.
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { describe, it } from "node:test";
import { PresenceSchema } from "../src/gen/hdeform/v1/deform_pb";
import { isTyping, keyAction } from "../src/keymap";
import { colorFor, defaultName, Identity } from "../src/multi/identity";
import { heldMessage, holderFromMessage, PresenceModel } from "../src/multi/presence_model";
import { LatestWins } from "../src/latest_wins";
import { stepsDone } from "../src/panels/onboarding";
import { snapSteps } from "../src/viewport/snap";
import { parseSel } from "../src/sel_file";
import { Code, ConnectError } from "@connectrpc/connect";
import { HandleLease } from "../src/multi/handle_lease";
import { CommandLayer } from "../src/commands/command_layer";
import type { DeformationClient } from "../src/api";

class MemoryStore {
  private m = new Map<string, string>();
  getItem(k: string): string | null {
    return this.m.get(k) ?? null;
  }
  setItem(k: string, v: string): void {
    this.m.set(k, v);
  }
}

describe("keymap", () => {
  it("maps Blender / three.js editor keys", () => {
    assert.equal(keyAction({ key: "w" }), "translate");
    assert.equal(keyAction({ key: "E" }), "rotate");
    assert.equal(keyAction({ key: "r" }), "scale");
    assert.equal(keyAction({ key: "Escape" }), "cancel");
    assert.equal(keyAction({ key: "x" }), "axisX");
    assert.equal(keyAction({ key: "Z" }), "axisZ");
    assert.equal(keyAction({ key: "f" }), "frameSelection");
    assert.equal(keyAction({ key: "Home" }), "frameAll");
    assert.equal(keyAction({ key: "Delete" }), "clearSelection");
    assert.equal(keyAction({ key: "?" }), "help");
    assert.equal(keyAction({ key: "j" }), null); // K is taken by the timeline (set key)
  });
  it("leaves the browser's own Ctrl / Alt / ⌘ keys alone", () => {
    assert.equal(keyAction({ key: "r", ctrlKey: true }), null);
    assert.equal(keyAction({ key: "w", metaKey: true }), null);
    assert.equal(keyAction({ key: "f", altKey: true }), null);
  });
  it("knows when keys are typed into a field", () => {
    assert.equal(isTyping({ tagName: "INPUT", type: "text" }), true);
    assert.equal(isTyping({ tagName: "INPUT", type: "number" }), true);
    assert.equal(isTyping({ tagName: "INPUT", type: "range" }), false);
    assert.equal(isTyping({ tagName: "INPUT", type: "checkbox" }), false);
    assert.equal(isTyping({ tagName: "TEXTAREA" }), true);
    assert.equal(isTyping({ tagName: "SELECT" }), true);
    assert.equal(isTyping({ tagName: "DIV", isContentEditable: true }), true);
    assert.equal(isTyping({ tagName: "CANVAS" }), false);
    assert.equal(isTyping(null), false);
  });
});

describe("snapping", () => {
  it("is off without Ctrl or the Snap box", () => {
    assert.deepEqual(snapSteps({ ctrl: false, shift: false, enabled: false, grid: 0.1 }), { translation: null, rotation: null, scale: null });
  });
  it("Ctrl: 15° steps and the grid; Ctrl+Shift: 5°", () => {
    const s = snapSteps({ ctrl: true, shift: false, enabled: false, grid: 0.1 });
    assert.equal(s.translation, 0.1);
    assert.ok(Math.abs(s.rotation! - Math.PI / 12) < 1e-15);
    assert.ok(Math.abs(snapSteps({ ctrl: true, shift: true, enabled: false, grid: 0.1 }).rotation! - Math.PI / 36) < 1e-15);
  });
  it("the Snap box snaps without Ctrl; no grid step, no translation snap", () => {
    const s = snapSteps({ ctrl: false, shift: false, enabled: true, grid: 0 });
    assert.equal(s.translation, null);
    assert.ok(s.rotation! > 0);
    assert.equal(snapSteps({ ctrl: true, shift: false, enabled: false, grid: NaN }).translation, null);
  });
});

describe("identity", () => {
  it("keeps its client id per tab and its name per user", () => {
    const tab = new MemoryStore(), user = new MemoryStore();
    const a = new Identity(tab, user);
    assert.match(a.clientId, /^[0-9a-f]{16}$/);
    assert.equal(a.displayName, defaultName(a.clientId));
    a.setDisplayName("  Alice\u0007 ");
    assert.equal(a.displayName, "Alice");
    const again = new Identity(tab, user);
    assert.equal(again.clientId, a.clientId);
    assert.equal(again.displayName, "Alice");
    const otherTab = new Identity(new MemoryStore(), user);
    assert.notEqual(otherTab.clientId, a.clientId);
    assert.equal(otherTab.displayName, "Alice");
    otherTab.setDisplayName("");
    assert.equal(otherTab.displayName, defaultName(otherTab.clientId));
  });
  it("gives an id the same colour everywhere", () => {
    assert.equal(colorFor("abc"), colorFor("abc"));
    assert.match(colorFor("abc"), /^#[0-9a-f]{6}$/);
    assert.equal(new Identity(new MemoryStore(), new MemoryStore()).participant().color.length, 7);
  });
});

describe("presence", () => {
  const presence = (version: bigint, people: [string, string, number[]][]) =>
    create(PresenceSchema, { version, participants: people.map(([clientId, displayName, heldHandles]) => ({ clientId, displayName, heldHandles, editor: true })) });
  it("knows who holds a handle, never this page itself", () => {
    const p = new PresenceModel("me");
    assert.ok(p.update(presence(3n, [["me", "Me", [0]], ["a", "Alice", [1]]])));
    assert.equal(p.holderOf(0), null);
    assert.equal(p.holderOf(1)?.name, "Alice");
    assert.equal(p.people.find((x) => x.me)?.name, "Me");
  });
  it("ignores an older presence (a late GrabHandles answer)", () => {
    const p = new PresenceModel("me");
    p.update(presence(5n, [["a", "Alice", [1]]]));
    assert.equal(p.update(presence(4n, [["a", "Alice", []]])), false);
    assert.equal(p.holderOf(1)?.name, "Alice");
  });
  it("says who holds a handle", () => {
    assert.equal(heldMessage(2, "Alice"), "Handle 2 is being moved by Alice");
    assert.equal(holderFromMessage("handle 1 is held by Alice (client a1b2)"), "Alice");
    assert.equal(holderFromMessage("something else"), "something else");
  });
});

describe("latest wins", () => {
  it("keeps one call in flight and sends only the newest value after it", async () => {
    const sent: number[] = [];
    let release: () => void = () => {};
    const lw = new LatestWins<number>(async (v) => {
      sent.push(v);
      await new Promise<void>((r) => (release = r));
    });
    lw.send(1);
    lw.send(2);
    lw.send(3);
    assert.deepEqual(sent, [1]);
    release();
    await new Promise((r) => setTimeout(r, 0));
    assert.deepEqual(sent, [1, 3]);
    release();
    await lw.idle;
    assert.equal(lw.busy, false);
    assert.equal(lw.calls, 2);
  });
});

describe("onboarding", () => {
  it("ticks off fixed, handle, moved", () => {
    assert.deepEqual(stepsDone(new Int16Array([-1, -1]), false, false), { fixed: false, handle: false, applied: false, moved: false });
    assert.deepEqual(stepsDone(new Int16Array([0, -1]), false, false), { fixed: true, handle: false, applied: false, moved: false });
    // Both regions marked but not applied: Apply is not ticked (issue 37).
    assert.deepEqual(stepsDone(new Int16Array([0, 2]), false, false), { fixed: true, handle: true, applied: false, moved: false });
    assert.deepEqual(stepsDone(new Int16Array([0, 2]), true, true), { fixed: true, handle: true, applied: true, moved: true });
    assert.deepEqual(stepsDone(null, true, false), { fixed: true, handle: true, applied: true, moved: false });
  });
});

describe(".sel files", () => {
  it("reads fixed (0) and handle (2) vertices after the # lines", () => {
    assert.deepEqual(parseSel("# status\n# 4 vertices\n0\n1\n2\n0\n", 4), { fixed: [0, 3], handle: [2] });
  });
  it("refuses a file for another mesh", () => {
    assert.throws(() => parseSel("0\n2\n", 3), /2 vertices, the mesh 3/);
  });
});

describe("handle lease", () => {
  const me = () => ({ clientId: "tab1", displayName: "Alice" });
  function fakeGrab(answer: () => Promise<unknown>) {
    const calls: { method: string; request: Record<string, unknown> }[] = [];
    const client = {
      grabHandles: async (request: Record<string, unknown>) => {
        calls.push({ method: "grab", request });
        return answer();
      },
      releaseHandles: async (request: Record<string, unknown>) => {
        calls.push({ method: "release", request });
        return {};
      },
    } as unknown as DeformationClient;
    return { client: new CommandLayer({ client }), calls };
  }
  it("grabs, then releases what it holds", async () => {
    const { client, calls } = fakeGrab(async () => ({}));
    const lease = new HandleLease(client, me, () => {});
    assert.deepEqual(await lease.grab("sessions/s", [1]), { ok: true });
    assert.equal(lease.supported, true);
    assert.deepEqual(lease.holding, [1]);
    await lease.release();
    assert.deepEqual(calls.map((c) => c.method), ["grab", "release"]);
    assert.deepEqual(calls[1].request.handles, [1]);
    assert.equal(calls[1].request.clientId, "tab1");
    assert.deepEqual(lease.holding, []);
  });
  it("a refusal names the holder's message", async () => {
    const { client } = fakeGrab(async () => {
      throw new ConnectError("GrabHandles: handle 0 is held by Bob (client b2)", Code.Aborted);
    });
    const r = await new HandleLease(client, me, () => {}).grab("sessions/s", [0]);
    assert.equal(r.ok, false);
    if (!r.ok) {
      assert.equal(r.code, Code.Aborted);
      assert.equal(holderFromMessage(r.message), "Bob");
    }
  });
  it("a server without GrabHandles: every grab succeeds, nothing more is asked", async () => {
    const { client, calls } = fakeGrab(async () => {
      throw new ConnectError("unknown method", Code.Unimplemented);
    });
    const lease = new HandleLease(client, me, () => {});
    assert.deepEqual(await lease.grab("sessions/s", [0]), { ok: true });
    assert.equal(lease.supported, false);
    assert.deepEqual(await lease.grab("sessions/s", [0]), { ok: true });
    await lease.release();
    assert.equal(calls.length, 1);
  });
});

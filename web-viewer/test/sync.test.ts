// sync against a fake client: the update window, newest-wins coalescing, the drag's final
// update, errors, reconnects and frame ordering.
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import { afterEach, describe, it } from "node:test";
import { FrameEncoding, SessionEventSchema, SessionSchema, StepKind } from "../src/gen/hdeform/v1/deform_pb";
import { Sync, type SyncEvents, type SyncOptions } from "../src/sync/sync";
import { CommandLayer } from "../src/commands/command_layer";
import { deletedEvent, FakeClient, frame, frameEvent, settle, stateEvent, until } from "./fake_client";

const FAST = { reconnectFirstMs: 1, reconnectMaxMs: 4, lostBannerAfterMs: 60_000, editRetryWaitMs: 1000 };
const opened: Sync[] = [];

/** A Sync on session "sessions/s" whose pose is `x` (the first handle's translation). */
function setup(window = 1, format?: SyncOptions["format"]) {
  const fake = new FakeClient();
  const pose = { x: 0 };
  const sync = new Sync({
    client: fake.client,
    pose: () => ({ transforms: [{ translation: { x: pose.x, y: 0, z: 0 } }], energies: false }),
    window,
    format,
    timing: FAST,
  });
  const events: { [K in keyof SyncEvents]: SyncEvents[K][] } = { link: [], frame: [], skippedFrame: [], state: [], error: [], clearError: [], revert: [], presence: [], step: [], timeline: [], opened: [] };
  for (const k of Object.keys(events) as (keyof SyncEvents)[]) sync.on(k, (p) => (events[k] as unknown[]).push(p));
  sync.open("sessions/s");
  opened.push(sync);
  const sentX = (i: number) => fake.updates[i].request.transforms[0].translation?.x;
  return { fake, pose, sync, events, sentX };
}

/** The page's command layer for SetBeta / SetConstraints: retried through `sync` (as main.ts wires it). */
function commandsOf(fake: FakeClient, sync: Sync, clientId?: () => string) {
  return new CommandLayer<"setBeta" | "setConstraints">({ client: fake.client, retry: (call) => sync.edit(call), clientId });
}
const setBeta = (commands: ReturnType<typeof commandsOf>, request: { name: string; beta?: { value: number }; clientId?: string }) =>
  commands.execute({ method: "setBeta", what: "β", request: () => request });

afterEach(() => {
  for (const s of opened.splice(0)) s.open(""); // stops every watch loop
});

describe("sync, one update in flight (window 1)", () => {
  it("sends nothing until the pose changes, then one update per tick", () => {
    const { fake, sync } = setup();
    sync.tick();
    assert.equal(fake.updates.length, 0);
    sync.request();
    assert.equal(sync.busy, true);
    sync.tick();
    sync.tick();
    assert.equal(fake.updates.length, 1);
    assert.equal(fake.updates[0].request.name, "sessions/s");
    assert.equal(fake.updates[0].request.coalesce, false);
    assert.equal(fake.updates[0].request.omitBuffers, false);
  });

  it("asks for its frame format on UpdateHandles and WatchSession", async () => {
    const { fake, sync } = setup(1, { encoding: FrameEncoding.MESHOPT, exactAsFloat32: true });
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    sync.request();
    sync.tick();
    for (const format of [fake.updates[0].request.format, fake.watchRequests[0].format]) {
      assert.equal(format?.encoding, FrameEncoding.MESHOPT);
      assert.equal(format?.exactAsFloat32, true);
    }
  });

  it("keeps at most one update in flight and sends the newest pose next", async () => {
    const { fake, pose, sync, events, sentX } = setup();
    pose.x = 1;
    sync.request();
    sync.tick();
    for (const x of [2, 3, 4]) {
      pose.x = x;
      sync.request();
      sync.tick();
    }
    assert.equal(fake.updates.length, 1);
    fake.updates[0].resolve(frame({ version: 1, sequence: 1, positions: [1, 0, 0] }));
    await settle();
    sync.tick();
    assert.equal(fake.updates.length, 2);
    assert.equal(sentX(0), 1);
    assert.equal(sentX(1), 4); // 2 and 3 were coalesced away
    assert.equal(fake.updates[1].request.sequence, 2n);
    fake.updates[1].resolve(frame({ version: 2, sequence: 2, positions: [4, 0, 0] }));
    await settle();
    assert.equal(sync.busy, false);
    assert.deepEqual(events.frame.map((e) => [e.frame.version, e.source]), [[1n, "reply"], [2n, "reply"]]);
    assert.equal(sync.framesApplied, 2);
  });

  it("marks drag updates and sends a final non-dragging update on release", async () => {
    const { fake, sync } = setup();
    sync.setDragging(true);
    sync.request();
    sync.tick();
    assert.equal(fake.updates[0].request.dragging, true);
    sync.setDragging(false); // released while the drag update is in flight, no further move
    assert.equal(sync.busy, true);
    fake.updates[0].resolve(frame({ version: 1, sequence: 1, positions: [0, 0, 0] }));
    await settle();
    sync.tick();
    assert.equal(fake.updates.length, 2);
    assert.equal(fake.updates[1].request.dragging, false);
  });

  it("reports a rejected update and keeps pumping; a later answer clears the report", async () => {
    const { fake, sync, events } = setup();
    sync.request();
    sync.tick();
    fake.updates[0].reject(new ConnectError("bad transform", Code.InvalidArgument));
    await settle();
    assert.equal(events.error.length, 1);
    assert.equal(events.error[0].kind, "rejected");
    assert.match(events.error[0].message, /^Handle update rejected: bad transform \[InvalidArgument\]/);
    assert.equal(sync.busy, false);
    sync.request();
    sync.tick();
    assert.equal(fake.updates.length, 2);
    fake.updates[1].resolve(frame({ version: 1, sequence: 2, positions: [0, 0, 0] }));
    await settle();
    assert.deepEqual(events.clearError, ["rejected"]);
    assert.equal(events.frame.length, 1);
  });

  it("MESHOPT_DELTA: the watch stream asks for it, UpdateHandles for MESHOPT (a reply is no stream)", async () => {
    const { fake, sync } = setup(1, { encoding: FrameEncoding.MESHOPT_DELTA, exactAsFloat32: true });
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    sync.request();
    sync.tick();
    assert.equal(fake.watchRequests[0].format?.encoding, FrameEncoding.MESHOPT_DELTA);
    assert.equal(fake.updates[0].request.format?.encoding, FrameEncoding.MESHOPT);
    assert.equal(fake.updates[0].request.format?.exactAsFloat32, true);
  });

  it("ignores WatchSession frames while its own update is pending, and duplicates", async () => {
    const { fake, sync, events } = setup();
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    sync.request();
    sync.tick();
    fake.stream.push(frameEvent(frame({ version: 1, sequence: 9, positions: [0, 0, 0] }))); // older than ours
    await settle();
    assert.equal(events.frame.length, 0);
    const reply = frame({ version: 2, sequence: 1, positions: [1, 0, 0] });
    fake.updates[0].resolve(reply);
    await settle();
    fake.stream.push(frameEvent(reply)); // our own frame, seen again on the stream
    fake.stream.push(frameEvent(frame({ version: 3, sequence: 4, positions: [2, 0, 0] }))); // another editor
    await until(() => sync.watchEvents === 3, "three watch events");
    assert.deepEqual(events.frame.map((e) => [e.frame.version, e.source]), [[2n, "reply"], [3n, "watch"]]);
    // Every watch frame not shown is handed on (MESHOPT_DELTA's decoder must still see it).
    assert.deepEqual(events.skippedFrame.map((e) => e.frame.version), [1n, 2n]);
  });

  it("never applies a frame older than the newest applied", async () => {
    const { fake, sync, events } = setup();
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    fake.stream.push(frameEvent(frame({ version: 5, sequence: 1, positions: [0, 0, 0] })));
    fake.stream.push(frameEvent(frame({ version: 4, sequence: 2, positions: [0, 0, 0] })));
    fake.stream.push(frameEvent(frame({ version: 5, sequence: 3, positions: [0, 0, 0] }))); // same version: new frame
    await until(() => sync.watchEvents === 3, "three watch events");
    assert.deepEqual(events.frame.map((e) => [e.frame.version, e.frame.sequence]), [[5n, 1n], [5n, 3n]]);
    assert.equal(sync.version, 5n);
  });
});

describe("sync, connection", () => {
  it("reconnects after a failed stream: re-reads the session, refreshes, watches again", async () => {
    const { fake, sync, events } = setup();
    fake.session = () => create(SessionSchema, { name: "sessions/s", version: 7n });
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    fake.stream.push(new ConnectError("server restarting", Code.Unavailable));
    await until(() => sync.reconnects === 1 && fake.streams.length === 2, "the reconnect");
    assert.equal(sync.link.state, "connected");
    assert.deepEqual(events.link.map((l) => l.link), ["connected", "reconnecting", "connected"]);
    assert.equal(events.state.length, 1);
    assert.equal(events.state[0].source, "resync");
    assert.equal(events.state[0].session.version, 7n);
    assert.deepEqual(events.clearError, ["lost"]);
    assert.equal(events.error.length, 0); // an outage shorter than lostBannerAfterMs
  });

  it("rewatch: a broken delta stream is dropped and watched anew (a new stream starts with a key frame)", async () => {
    const { fake, sync, events } = setup();
    fake.session = () => create(SessionSchema, { name: "sessions/s", version: 3n });
    sync.watch();
    await until(() => fake.streams.length === 1 && sync.link.state === "connected", "the watch stream");
    sync.rewatch("a frame did not decode");
    await until(() => fake.streams.length === 2 && sync.link.state === "connected", "the second stream");
    assert.deepEqual(events.link.map((l) => [l.link, l.why]).slice(1, 2), [["reconnecting", "a frame did not decode"]]);
    assert.equal(events.state.at(-1)?.source, "resync");
  });

  it("retries an edit that failed for a transient reason once, after the reconnect", async () => {
    const { fake, pose, sync, events, sentX } = setup();
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    pose.x = 1;
    sync.request();
    sync.tick();
    pose.x = 2; // moved again while the first try was out
    fake.updates[0].reject(new ConnectError("unavailable", Code.Unavailable));
    await until(() => fake.updates.length === 2, "the retry");
    assert.equal(sync.reconnects, 1);
    assert.equal(sentX(1), 2); // built anew: the newest pose
    fake.updates[1].resolve(frame({ version: 3, sequence: 2, positions: [2, 0, 0] }));
    await settle();
    assert.equal(events.error.length, 0);
    assert.equal(events.frame.length, 1);
  });

  it("reports an edit that fails again after the reconnect", async () => {
    const { fake, sync } = setup();
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    const unavailable = () => {
      throw new ConnectError("unavailable", Code.Unavailable);
    };
    fake.betaAnswers = [unavailable, unavailable, () => create(SessionSchema, {})];
    const commands = commandsOf(fake, sync);
    await assert.rejects(setBeta(commands, { name: "sessions/s", beta: { value: 0.4 } }), /unavailable/);
    assert.equal(fake.setBetaCalls, 2);
    // The retry is the same request to the server (its request_id): applied at most once.
    const [first, retry] = fake.requests.map((r) => r.requestId);
    assert.match(first ?? "", /^[0-9a-f]{32}$/);
    assert.equal(retry, first);
    await setBeta(commands, { name: "sessions/s", beta: { value: 0.4 } });
    assert.notEqual(fake.requests[2].requestId, first); // a new change: a new id
    assert.equal(sync.link.state, "connected");
  });

  it("holds updates while reconnecting and sends them once connected", async () => {
    const { fake, sync } = setup();
    let failReads = 2;
    fake.session = () => {
      if (failReads-- > 0) throw new ConnectError("still down", Code.Unavailable);
      return create(SessionSchema, { name: "sessions/s" });
    };
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    fake.stream.push(new ConnectError("gone away", Code.Unavailable));
    await until(() => sync.link.state === "reconnecting", "reconnecting");
    sync.request();
    sync.tick();
    assert.equal(fake.updates.length, 0);
    await until(() => sync.link.state === "connected", "the reconnect", 3000);
    assert.equal(fake.getSessionCalls, 3);
    sync.tick();
    assert.equal(fake.updates.length, 1);
  });

  it("a deleted session is gone: no more tries, edits fail at once", async () => {
    const { fake, sync, events } = setup();
    fake.session = () => {
      throw new ConnectError("no such session", Code.NotFound);
    };
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    fake.stream.push(deletedEvent("sessions/s"));
    await until(() => sync.link.state === "gone", "gone");
    assert.deepEqual(events.error.map((e) => [e.kind, e.message]), [["lost", "Session sessions/s was deleted"]]);
    await settle(20);
    assert.equal(fake.getSessionCalls, 1);
    sync.request();
    sync.tick();
    assert.equal(fake.updates.length, 0);
  });

  it("a deleted session whose token now opens nothing (PermissionDenied) is gone too", async () => {
    const { fake, sync, events } = setup();
    // Without the operator token the server answers a gone id like a wrong token.
    fake.session = () => {
      throw new ConnectError("the token presented opens no session of that name", Code.PermissionDenied);
    };
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    fake.stream.push(deletedEvent("sessions/s"));
    await until(() => sync.link.state === "gone", "gone");
    assert.deepEqual(events.error.map((e) => [e.kind, e.message]), [["lost", "Session sessions/s was deleted"]]);
  });

  it("drops the answer of an update sent for a session no longer open", async () => {
    const { fake, sync, events } = setup();
    sync.request();
    sync.tick();
    sync.open("sessions/other");
    fake.updates[0].resolve(frame({ version: 1, sequence: 1, positions: [0, 0, 0] }));
    await settle();
    assert.equal(events.frame.length, 0);
    assert.equal(sync.busy, false);
  });
  it("announces each switch of session (the page forgets the old one's people)", () => {
    const { sync, events } = setup();
    sync.open("sessions/other");
    assert.deepEqual(events.opened, ["sessions/s", "sessions/other"]);
  });
});

/** Starts the watch stream and lets it bring its first event (the server's initial state). */
async function goLive(fake: FakeClient, sync: Sync): Promise<void> {
  sync.watch();
  await until(() => fake.streams.length === 1, "the watch stream");
  fake.stream.push(stateEvent());
  await until(() => sync.watchEvents === 1, "the stream's first event");
}

describe("sync, pipelined (window > 1)", () => {
  it("asks for omit_buffers only once the stream is live (a connecting one could miss the frame)", async () => {
    const { fake, sync } = setup(2);
    sync.watch();
    await until(() => fake.streams.length === 1, "the watch stream");
    sync.request();
    sync.tick();
    assert.equal(fake.updates[0].request.omitBuffers, false);
    fake.updates[0].resolve(frame({ version: 1, sequence: 1, positions: [1, 0, 0] }));
    await settle();
    assert.equal(sync.busy, false);
    fake.stream.push(stateEvent());
    await until(() => sync.watchEvents === 1, "the stream's first event");
    sync.request();
    sync.tick();
    assert.equal(fake.updates[1].request.omitBuffers, true);
  });

  it("sends one update per tick without waiting, up to the window", async () => {
    const { fake, pose, sync, sentX } = setup(3);
    await goLive(fake, sync);
    sync.setDragging(true);
    for (let x = 1; x <= 5; x++) {
      pose.x = x;
      sync.request();
      sync.tick();
    }
    assert.equal(fake.updates.length, 3);
    assert.deepEqual([0, 1, 2].map(sentX), [1, 2, 3]);
    // The first update after a non-dragging one does not coalesce, so that one is solved.
    assert.deepEqual(fake.updates.map((u) => u.request.coalesce), [false, true, true]);
    assert.ok(fake.updates.every((u) => u.request.omitBuffers && u.request.dragging));
  });

  it("treats a superseded answer as an acknowledgement that frees the window", async () => {
    const { fake, pose, sync, events, sentX } = setup(2);
    sync.setDragging(true);
    for (let x = 1; x <= 3; x++) {
      pose.x = x;
      sync.request();
      sync.tick();
    }
    assert.equal(fake.updates.length, 2);
    fake.updates[0].resolve(frame({ version: 0, sequence: 1, superseded: true }));
    await settle();
    assert.equal(events.frame.length, 0);
    sync.tick();
    assert.equal(fake.updates.length, 3);
    assert.equal(sentX(2), 3);
  });

  it("counts its updates up and lets an overtaken answer confirm nothing", async () => {
    const { fake, pose, sync } = setup(2);
    sync.setDragging(true);
    for (let x = 1; x <= 2; x++) {
      pose.x = x;
      sync.request();
      sync.tick();
    }
    assert.deepEqual(fake.updates.map((u) => u.request.sequence), [1n, 2n]);
    assert.ok(fake.updates.every((u) => u.request.clientId !== undefined));
    // Update 2 is answered first, then the older update 1 (its answer overtaken on the way).
    fake.updates[1].resolve(frame({ version: 2, sequence: 2, superseded: true }));
    await settle();
    assert.equal(sync.confirmedTransforms?.[0].translation?.x, 2);
    fake.updates[0].resolve(frame({ version: 2, sequence: 1, superseded: true }));
    await settle();
    assert.equal(sync.confirmedTransforms?.[0].translation?.x, 2, "the older answer did not win");
  });

  it("applies frames in version order, buffers from the stream, and stays busy until they come", async () => {
    const { fake, sync, events } = setup(4);
    await goLive(fake, sync);
    sync.setDragging(true);
    sync.request();
    sync.tick();
    sync.request();
    sync.tick();
    sync.setDragging(false);
    sync.tick(); // the release's final update
    assert.equal(fake.updates.length, 3);
    assert.equal(fake.updates[2].request.dragging, false);
    assert.equal(fake.updates[2].request.coalesce, true);
    // Answers without buffers (omit_buffers); the stream brings the shapes, one out of order.
    fake.updates[0].resolve(frame({ version: 1, sequence: 1 }));
    fake.updates[1].resolve(frame({ version: 0, sequence: 2, superseded: true }));
    fake.updates[2].resolve(frame({ version: 3, sequence: 3 }));
    await settle();
    assert.equal(sync.busy, true); // the final pose's shape has not arrived
    fake.stream.push(frameEvent(frame({ version: 3, sequence: 3, positions: [3, 0, 0] })));
    fake.stream.push(frameEvent(frame({ version: 1, sequence: 1, positions: [1, 0, 0] }))); // late: older
    await until(() => sync.watchEvents === 3, "two more watch events");
    assert.equal(sync.busy, false);
    const shown = events.frame.map((e) => [e.frame.version, e.source, e.frame.positions.byteLength > 0]);
    assert.deepEqual(shown, [
      [1n, "reply", false],
      [3n, "reply", false],
      [3n, "watch", true],
    ]);
  });

  it("a stream frame that arrives before its answer is not waited for", async () => {
    const { fake, sync } = setup(2);
    await goLive(fake, sync);
    sync.request();
    sync.tick();
    fake.stream.push(frameEvent(frame({ version: 1, sequence: 1, positions: [1, 0, 0] })));
    await until(() => sync.watchEvents === 2, "the watch event");
    fake.updates[0].resolve(frame({ version: 1, sequence: 1 }));
    await settle();
    assert.equal(sync.busy, false);
  });
});

describe("sync, the confirmed pose", () => {
  it("a refused update reverts to the last pose the server confirmed", async () => {
    const { fake, sync, events, pose } = setup();
    pose.x = 1;
    sync.request();
    sync.tick();
    fake.updates[0].resolve(frame({ version: 1, sequence: 1, positions: [0, 0, 0] }));
    await settle();
    assert.equal(sync.confirmedTransforms?.[0].translation?.x, 1);
    pose.x = 5;
    sync.request();
    sync.tick();
    fake.updates[1].reject(new ConnectError("session gone", Code.NotFound));
    await settle();
    assert.equal(events.revert.length, 1);
    assert.equal(events.revert[0].transforms[0].translation?.x, 1);
  });

  it("does not revert when a newer update is still to be sent", async () => {
    const { fake, sync, events, pose } = setup();
    sync.request();
    sync.tick();
    fake.updates[0].resolve(frame({ version: 1, sequence: 1, positions: [0, 0, 0] }));
    await settle();
    pose.x = 2;
    sync.request();
    sync.tick();
    sync.request(); // a newer pose, sent after this one
    fake.updates[1].reject(new ConnectError("held by Alice", Code.Aborted));
    await settle();
    assert.equal(events.revert.length, 0);
  });

  it("several editors: sends only the named handles, with the client id", async () => {
    const fake = new FakeClient();
    const sync = new Sync({
      client: fake.client,
      pose: () => ({ transforms: [{ translation: { x: 1, y: 0, z: 0 } }, { translation: { x: 2, y: 0, z: 0 } }], handles: [1], energies: false }),
      participant: () => ({ clientId: "tab1", displayName: "Alice" }),
      timing: FAST,
    });
    opened.push(sync);
    sync.open("sessions/s");
    sync.request();
    sync.tick();
    const req = fake.updates[0].request;
    assert.deepEqual(req.handles, [1]);
    assert.equal(req.transforms.length, 1);
    assert.equal(req.transforms[0].translation?.x, 2);
    assert.equal(req.clientId, "tab1");
    sync.watch();
    await until(() => fake.watchRequests.length > 0, "a watch request");
    assert.equal(fake.watchRequests[0].client?.displayName, "Alice");
  });

  it("history: SetBeta and SetConstraints carry the client id; steps on the stream come out as events", async () => {
    const fake = new FakeClient();
    const sync = new Sync({
      client: fake.client,
      pose: () => ({ transforms: [], energies: false }),
      participant: () => ({ clientId: "tab1", displayName: "Alice" }),
      timing: FAST,
    });
    opened.push(sync);
    const steps: SyncEvents["step"][] = [];
    sync.on("step", (st) => steps.push(st));
    sync.open("sessions/s");
    const commands = commandsOf(fake, sync, () => "tab1");
    await setBeta(commands, { name: "sessions/s", beta: { value: 0.3 } });
    await commands.execute({ method: "setConstraints", what: "Constraints", request: () => ({ name: "sessions/s" }) });
    await setBeta(commands, { name: "sessions/s", clientId: "explicit" });
    assert.deepEqual(
      fake.requests.map((r) => r.clientId),
      ["tab1", "tab1", "explicit"],
    );
    sync.watch();
    await until(() => fake.streams.length > 0, "a watch stream");
    fake.streams[0].push(create(SessionEventSchema, { event: { case: "step", value: { id: 7n, kind: StepKind.MOVE, author: "Bob", summary: "moved handle 1" } } }));
    await until(() => steps.length > 0, "a step event");
    assert.equal(steps[0].id, 7n);
    assert.equal(steps[0].summary, "moved handle 1");
    // Timeline events (set or cleared) come out as events too.
    const timelines: SyncEvents["timeline"][] = [];
    sync.on("timeline", (t) => timelines.push(t));
    fake.streams[0].push(create(SessionEventSchema, { event: { case: "timeline", value: { keys: [{ timeS: 0 }, { timeS: 1.5 }], author: "Bob" } } }));
    await until(() => timelines.length > 0, "a timeline event");
    assert.deepEqual(timelines[0].keys.map((k) => k.timeS), [0, 1.5]);
  });

  it("whenSent: resolves once the last pose is sent and answered (a drag's release waits for it)", async () => {
    const { fake, sync } = setup(2);
    sync.open("sessions/s");
    let done = false;
    await sync.whenSent(); // nothing to send: at once
    sync.setDragging(true);
    sync.setDragging(false); // the release: its pose is still to be sent
    void sync.whenSent().then(() => (done = true));
    await settle();
    assert.equal(done, false);
    sync.tick();
    await settle();
    assert.equal(done, false, "sent but not answered");
    fake.updates[0].resolve(frame({ version: 2 }));
    await until(() => done, "whenSent after the answer");
  });
});

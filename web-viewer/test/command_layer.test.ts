// The one command layer (issue 37): request_id and client_id attached and kept on a retry, the
// gesture (a drag's `dragging`, a keyed gesture's merge of stale updates), and one refusal
// handler: the text naming what was refused, conflicts re-read, the timeline-keys question.
import assert from "node:assert/strict";
import { Code, ConnectError } from "@connectrpc/connect";
import { describe, it } from "node:test";
import type { DeformationClient } from "../src/api";
import { CommandLayer, refusalText, type CommandLayerOptions } from "../src/commands/command_layer";
import { GestureLane } from "../src/commands/gesture_lane";
import type { CommandMethod } from "../src/commands/methods";

type Sent = { method: string; request: Record<string, unknown> };

/** A client whose every method records its request and answers with `answer` (or throws it). */
function recording(answer: (s: Sent, n: number) => unknown = () => ({})) {
  const sent: Sent[] = [];
  const client = new Proxy(
    {},
    {
      get: (_t, method: string) => async (request: Record<string, unknown>) => {
        const s = { method, request };
        sent.push(s);
        const a = answer(s, sent.length);
        if (a instanceof Error) throw a;
        return a;
      },
    },
  ) as DeformationClient;
  return { client, sent };
}

function layer(client: DeformationClient, options: Partial<CommandLayerOptions<CommandMethod>> = {}) {
  const shown: string[] = [];
  let accepted = 0;
  const commands = new CommandLayer<CommandMethod>({
    client,
    clientId: () => "tab1",
    refused: (t) => shown.push(t),
    accepted: () => accepted++,
    ...options,
  });
  return { commands, shown, accepted: () => accepted };
}

/** Once more after the first transient failure, as Sync.edit does after a reconnect. */
const retryOnce = async <T>(call: () => Promise<T>): Promise<T> => {
  try {
    return await call();
  } catch (err) {
    if (err instanceof ConnectError && err.code === Code.Unavailable) return await call();
    throw err;
  }
};

describe("command layer: request id and client id", () => {
  it("attaches this tab's client id and a request id; the retry sends the same id; a new command a new one", async () => {
    const { client, sent } = recording((_s, n) => (n === 1 ? new ConnectError("lost", Code.Unavailable) : {}));
    const { commands } = layer(client, { retry: retryOnce });
    await commands.execute({ method: "undo", what: "Undo", request: () => ({ name: "sessions/s" }) });
    assert.equal(sent.length, 2);
    const [first, retry] = sent.map((s) => s.request);
    assert.match(String(first.requestId), /^[0-9a-f]{32}$/);
    assert.equal(retry.requestId, first.requestId);
    assert.equal(first.clientId, "tab1");
    await commands.execute({ method: "undo", what: "Undo", request: () => ({ name: "sessions/s" }) });
    assert.notEqual(sent[2].request.requestId, first.requestId);
  });
  it("keeps a client id the request names; retries only what is safe to repeat", async () => {
    const { client, sent } = recording(() => new ConnectError("lost", Code.Unavailable));
    const { commands } = layer(client, { retry: retryOnce });
    await assert.rejects(commands.execute({ method: "setBeta", what: "β", request: () => ({ name: "s", clientId: "explicit" }) }));
    assert.equal(sent.length, 2); // request_id: retried
    assert.equal(sent[0].request.clientId, "explicit");
    await assert.rejects(commands.execute({ method: "grabHandles", what: "Grab", quiet: true, request: () => ({ name: "s" }) }));
    assert.equal(sent.length, 3); // no request_id: once
    assert.equal(sent[2].request.requestId, undefined);
  });
  it("builds the request anew for each attempt (a retry sends the newest state)", async () => {
    const { client, sent } = recording((_s, n) => (n === 1 ? new ConnectError("lost", Code.Unavailable) : {}));
    const { commands } = layer(client, { retry: retryOnce });
    let x = 1;
    await commands.execute({ method: "updateHandles", what: "Handle update", request: () => ({ name: "s", sequence: BigInt(x++) }) });
    assert.deepEqual(sent.map((s) => s.request.sequence), [1n, 2n]);
  });
});

describe("command layer: gestures", () => {
  it("a drag's updates carry dragging; its end and a lone update do not", async () => {
    const { client, sent } = recording();
    const { commands } = layer(client);
    await commands.execute({ method: "updateHandles", what: "Handle update", gesture: { phase: "update" }, request: () => ({ name: "s" }) });
    await commands.execute({ method: "updateHandles", what: "Handle update", gesture: { phase: "end" }, request: () => ({ name: "s" }) });
    await commands.execute({ method: "updateHandles", what: "Handle update", request: () => ({ name: "s" }) });
    assert.deepEqual(sent.map((s) => s.request.dragging), [true, false, false]);
  });
  it("a keyed gesture goes one at a time; waiting updates merge into the newest, its end is always sent", async () => {
    const release: (() => void)[] = [];
    const sent: number[] = [];
    const client = {
      setBeta: (r: { beta?: { value: number } }) =>
        new Promise((resolve) => {
          sent.push(r.beta?.value ?? -1);
          release.push(() => resolve({ beta: r.beta }));
        }),
    } as unknown as DeformationClient;
    const { commands } = layer(client);
    const beta = (value: number, phase: "update" | "end") =>
      commands.execute({ method: "setBeta", what: "β", gesture: { key: "beta", phase }, request: () => ({ name: "s", beta: { value } }) });
    const answers = [beta(0.1, "update"), beta(0.2, "update"), beta(0.3, "update"), beta(0.4, "end"), beta(0.5, "update")];
    assert.ok(commands.lane("beta").busy);
    assert.deepEqual(sent, [0.1]); // one in flight
    for (let i = 0; i < 3; i++) {
      release.shift()!();
      await new Promise((r) => setTimeout(r, 0));
    }
    await commands.lane("beta").idle;
    assert.deepEqual(sent, [0.1, 0.4, 0.5]); // 0.2 and 0.3 merged away; the end kept
    const got = await Promise.all(answers);
    assert.deepEqual(
      got.map((a) => (a as { beta?: { value: number } } | undefined)?.beta?.value),
      [0.1, undefined, undefined, 0.4, 0.5],
    );
    assert.equal(commands.lane("beta").merged, 2);
    assert.equal(commands.lane("beta").busy, false);
  });
  it("the lane never drops a begin or an end", async () => {
    const lane = new GestureLane();
    const ran: string[] = [];
    const run = (s: string) => async () => {
      ran.push(s);
      return s;
    };
    const all = [lane.add("begin", run("b")), lane.add("update", run("u1")), lane.add("end", run("e")), lane.add("update", run("u2"))];
    assert.deepEqual(await Promise.all(all), ["b", "u1", "e", "u2"].map((s) => (s === "u1" ? undefined : s)));
    assert.deepEqual(ran, ["b", "e", "u2"]);
  });
});

describe("command layer: refusals", () => {
  it("one handler shows what was refused, and the refusal is still thrown; an accepted command clears it", async () => {
    const { client } = recording((s) => (s.method === "setBeta" ? new ConnectError("beta out of range", Code.InvalidArgument) : {}));
    const { commands, shown, accepted } = layer(client);
    await assert.rejects(commands.execute({ method: "setBeta", what: "β", request: () => ({ name: "s" }) }), /out of range/);
    assert.deepEqual(shown, ["β rejected: beta out of range [InvalidArgument]"]);
    await commands.execute({ method: "saveSnapshot", what: "Snapshot save", request: () => ({ name: "s", snapshot: "A" }) });
    assert.equal(accepted(), 1);
  });
  it("the server's own words when they name the change already", () => {
    const err = new ConnectError("Undo of step 4 (Alice: moved handle 1) refused: handle 1 changed since", Code.Aborted);
    assert.equal(refusalText("Undo", err), "Undo of step 4 (Alice: moved handle 1) refused: handle 1 changed since [Aborted]");
    assert.equal(refusalText("Redo", new ConnectError("nothing to redo", Code.FailedPrecondition)), "Redo rejected: nothing to redo [FailedPrecondition]");
  });
  it("quiet commands, cancelled calls and a place of the caller's own", async () => {
    const { client } = recording((s) => (s.method === "setTimeline" ? new ConnectError("bad easing", Code.InvalidArgument) : new ConnectError("gone", Code.Canceled)));
    const { commands, shown } = layer(client);
    await assert.rejects(commands.execute({ method: "releaseHandles", what: "Role probe", quiet: true, request: () => ({ name: "s" }) }));
    await assert.rejects(commands.execute({ method: "deleteSnapshot", what: "Snapshot delete", request: () => ({ name: "s" }) }));
    const note: string[] = [];
    await assert.rejects(commands.execute({ method: "setTimeline", what: "Timeline", showIn: (t) => note.push(t), request: () => ({ name: "s" }) }));
    assert.deepEqual(shown, []);
    assert.deepEqual(note, ["Timeline rejected: bad easing [InvalidArgument]"]);
  });
  it("a conflict on expected_config_version goes to the re-read, naming the change", async () => {
    const { client } = recording(() => new ConnectError("config version 3, expected 2", Code.Aborted));
    const conflicts: string[] = [];
    const { commands, shown } = layer(client, { conflict: (what) => void conflicts.push(what) });
    await assert.rejects(commands.execute({ method: "setConstraints", what: "Constraints", request: () => ({ name: "s" }) }));
    await assert.rejects(commands.execute({ method: "undo", what: "Undo", request: () => ({ name: "s" }) })); // no config version: shown
    assert.deepEqual(conflicts, ["Constraints"]);
    assert.deepEqual(shown, ["Undo rejected: config version 3, expected 2 [Aborted]"]);
  });
  it("asks before dropping another editor's timeline keys: yes sends it again (same request id), no keeps them", async () => {
    const keys = () => new ConnectError("would drop 3 keys Tia set; send discard_timeline", Code.Aborted);
    const { client, sent } = recording((s) => (s.request.discardTimeline ? {} : keys()));
    let answer = true;
    const asked: string[] = [];
    const { commands, shown } = layer(client, { confirm: (m) => (asked.push(m), answer) });
    await commands.execute({ method: "restoreSnapshot", what: "Snapshot restore", dropsKeys: true, request: () => ({ name: "s", snapshot: "A" }) });
    assert.deepEqual(sent.map((s) => s.request.discardTimeline), [false, true]);
    assert.equal(sent[1].request.requestId, sent[0].request.requestId);
    assert.match(asked[0], /Drop those keys\?/);
    answer = false;
    await assert.rejects(commands.execute({ method: "setConstraints", what: "Constraints", dropsKeys: true, request: () => ({ name: "s" }) }));
    assert.equal(sent.length, 3);
    assert.deepEqual(shown, ["Constraints not applied, the timeline kept: would drop 3 keys Tia set; send discard_timeline [Aborted]"]);
  });
});

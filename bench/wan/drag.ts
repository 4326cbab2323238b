// Headless WAN drag client (issue 11): what the viewer does during a drag, over the viewer's
// own gRPC-Web transport (web-viewer/src/api.ts) and frame decoders (decodeFrame), timed.
// Run by bench/wan/run.sh inside a shaped network namespace; also usable alone:
//
//   web-viewer/node_modules/.bin/tsx bench/wan/drag.ts --url http://127.0.0.1:8080 \
//     [--vertices 100000] [--seconds 10] [--hz 60] [--encoding float32|quantized|meshopt|meshopt-delta] [--rate LABEL]
//
// Flow: POST /upload a procedural capsule (CreateSession is client-streaming, which
// connect-web cannot call over fetch, so we use the gateway's upload door like the viewer);
// SetConstraints (base fixed, cap = one handle, by vertex ids); two warm-up moves (the first
// drag frame builds the float32 factor copy); WatchSession in the chosen format with
// exact_as_float32; then H ticks a second for S seconds, each sending one pipelined
// UpdateHandles (dragging, coalesce, omit_buffers) unless 2 are already unanswered, and a
// last update without `dragging` whose exact float32 frame must arrive on the watch stream.
// Prints one JSON line and one human-readable line.
import { performance } from "node:perf_hooks";
import { parseArgs } from "node:util";
// The viewer's own modules; @bufbuild/protobuf by path so that it is the very module
// instance the generated code uses (bench/wan has no node_modules of its own).
import { fromBinary } from "../../web-viewer/node_modules/@bufbuild/protobuf/dist/esm/index.js";
import { describeError, makeClient, newSessionId, setRoutingSession, setTokens } from "../../web-viewer/src/api";
import { decodeFrame, FrameDecodeError, MeshoptDeltaStream } from "../../web-viewer/src/decode/frame_decode";
import { FrameEncoding, SessionSchema, type Frame } from "../../web-viewer/src/gen/hdeform/v1/deform_pb";
import { capsule, toOff } from "./capsule";

const { values: opt } = parseArgs({
  options: {
    url: { type: "string", default: "http://127.0.0.1:8080" },
    vertices: { type: "string", default: "100000" },
    seconds: { type: "string", default: "10" },
    hz: { type: "string", default: "60" },
    encoding: { type: "string", default: "float32" },
    rate: { type: "string", default: "unknown" }, // label only: run.sh shapes the link
    window: { type: "string", default: "2" },
  },
});
const url = opt.url!;
const N = Number(opt.vertices);
const seconds = Number(opt.seconds);
const hz = Number(opt.hz);
const windowSize = Number(opt.window);
const encodings: Record<string, FrameEncoding> = {
  float32: FrameEncoding.FLOAT32,
  quantized: FrameEncoding.QUANTIZED,
  meshopt: FrameEncoding.MESHOPT,
  "meshopt-delta": FrameEncoding.MESHOPT_DELTA,
};
if (!(opt.encoding! in encodings)) throw new Error(`--encoding: one of ${Object.keys(encodings).join(", ")}`);
const format = { encoding: encodings[opt.encoding!], exactAsFloat32: true };
// As the viewer's sync does: MESHOPT_DELTA is the watch stream's; replies (buffers omitted
// anyway) ask MESHOPT, which UpdateHandles can carry.
const replyFormat = format.encoding === FrameEncoding.MESHOPT_DELTA ? { ...format, encoding: FrameEncoding.MESHOPT } : format;
const adminToken = process.env.HDEFORM_ADMIN_TOKEN ?? "";

// Count the bytes of the WatchSession response as they come off the socket (gRPC-Web
// envelopes included): the wire cost per frame, without re-serializing frames in JS.
// connect-web reads globalThis.fetch at every call, so wrapping it here is enough.
let watchBytes = 0;
const realFetch = globalThis.fetch;
globalThis.fetch = async (input: RequestInfo | URL, init?: RequestInit) => {
  const res = await realFetch(input, init);
  if (!String(input instanceof Request ? input.url : input).endsWith("/WatchSession") || !res.body) return res;
  const counted = res.body.pipeThrough(
    new TransformStream<Uint8Array, Uint8Array>({
      transform(chunk, out) {
        watchBytes += chunk.byteLength;
        out.enqueue(chunk);
      },
    }),
  );
  return new Response(counted, { status: res.status, statusText: res.statusText, headers: res.headers });
};

const now = () => performance.now();
/** Nearest-rank percentile; NaN for no samples. */
function pct(xs: number[], p: number): number {
  if (xs.length === 0) return NaN;
  const s = [...xs].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.max(0, Math.ceil(p * s.length) - 1))];
}
const r1 = (x: number) => Math.round(x * 10) / 10;
const sleep = (ms: number) => new Promise((r) => setTimeout(r, Math.max(0, ms)));

// Move k at t seconds into the drag: the cap swings about x (±29°) and wanders sideways,
// smooth and different at every tick (a hand on a gizmo, not a constant pose).
function move(t: number) {
  const angle = 0.5 * Math.sin(2 * Math.PI * 0.25 * t);
  return {
    rotation: { w: Math.cos(angle / 2), x: Math.sin(angle / 2), y: 0, z: 0 },
    translation: { x: 1.5 * Math.sin(2 * Math.PI * 0.2 * t), y: 0.75 * (1 - Math.cos(2 * Math.PI * 0.15 * t)), z: 0 },
  };
}

// Where the run is, for the watchdog's message: a hang must end the run with a reason, not
// stall the whole table (the first factorization at 100K takes seconds, hence the margin).
let phase = "start";
const watchdog = setTimeout(() => {
  console.error(`drag: stuck in phase "${phase}" after ${seconds + 600} s; giving up`);
  process.exit(1);
}, (seconds + 600) * 1000);

async function main() {
  phase = "upload";
  // --- session: upload, constrain -------------------------------------------------------
  const mesh = capsule(N);
  const id = newSessionId();
  const up = await fetch(`${url}/upload?filename=capsule${N}.off&session_id=${id}`, {
    method: "POST",
    headers: {
      "x-session-id": id,
      "content-type": "application/octet-stream",
      ...(adminToken ? { authorization: `Bearer ${adminToken}` } : {}),
    },
    body: toOff(mesh),
  });
  const upBody = new Uint8Array(await up.arrayBuffer());
  if (up.status !== 200) throw new Error(`upload: HTTP ${up.status}: ${new TextDecoder().decode(upBody)}`);
  const session = fromBinary(SessionSchema, upBody);
  setRoutingSession(session.name);
  setTokens(session.editToken, session.viewToken); // the viewer's interceptor sends Bearer EDIT
  const client = makeClient(url);
  const name = session.name;
  const vc = session.vertexCount;
  const tc = session.triangleCount;
  phase = "SetConstraints";
  const ids = (v: number[]) => ({ selectors: [{ kind: { case: "ids" as const, value: { ids: v } } }] });
  await client.setConstraints({ name, constraints: { fixed: ids(mesh.base), handles: [ids(mesh.cap)] } }, { timeoutMs: 600_000 });

  let seq = 0;
  const update = (t: number, dragging: boolean) =>
    client.updateHandles(
      { name, sequence: BigInt(++seq), transforms: [move(t)], dragging, coalesce: true, omitBuffers: true, format: replyFormat },
      { timeoutMs: 120_000 },
    );
  phase = "warm-up";
  await update(0, false); // warm-up: first exact frame
  await update(0, true); // warm-up: first drag frame (float32 copy of the factor)

  // --- watch stream ----------------------------------------------------------------------
  const sentAt = new Map<bigint, number>();
  const latency: number[] = [];
  const bufferBytes: number[] = [];
  const decodeMs: number[] = [];
  const solveMs: number[] = [];
  let t0 = Infinity;
  let tEnd = Infinity;
  let framesInDrag = 0;
  let decodedInDrag = 0;
  let framesTotal = 0;
  let events = 0;
  let decoder = "ok";
  let finalSeq = -1n;
  let resolveFinal!: (f: { frame: Frame; decodedOk: boolean }) => void;
  const finalFrame = new Promise<{ frame: Frame; decodedOk: boolean }>((r) => (resolveFinal = r));
  let resolveOpen!: () => void;
  const opened = new Promise<void>((r) => (resolveOpen = r));
  const abort = new AbortController();
  const deltaStream = new MeshoptDeltaStream(); // MESHOPT_DELTA: this watch stream's state
  let keyFrames = 0;
  const reuse = { positions: new Float32Array(3 * vc), normals: new Float32Array(3 * vc) };
  const watching = (async () => {
    for await (const ev of client.watchSession({ name, format }, { signal: abort.signal })) {
      ++events;
      if (ev.event.case === "state") resolveOpen(); // sent first: the stream is live
      if (ev.event.case !== "frame") continue;
      const t = now();
      const frame = ev.event.value;
      ++framesTotal;
      const inDrag = t >= t0 && t <= tEnd;
      if (inDrag) ++framesInDrag;
      const sent = sentAt.get(frame.sequence);
      if (sent !== undefined) latency.push(t - sent);
      bufferBytes.push(frame.positions.length + frame.normals.length + frame.energies.length + frame.vertices.length);
      solveMs.push(frame.solveMs);
      let decodedOk = false;
      try {
        const t1 = now();
        // `await`: a decoder moved off the main thread may return a promise. Into the same
        // arrays every frame, as the viewer's decode worker does (frame_decoder.ts).
        const d = await decodeFrame(frame, vc, tc, deltaStream, reuse);
        if (frame.encoding === FrameEncoding.MESHOPT_DELTA && !frame.delta) ++keyFrames;
        decodedOk = d.positions?.length === 3 * vc;
        if (inDrag) {
          decodeMs.push(now() - t1); // drag frames only: the final exact one is FLOAT32
          ++decodedInDrag;
        }
      } catch (e) {
        if (!(e instanceof FrameDecodeError)) throw e;
        decoder = `decoder missing (${e.message})`;
      }
      if (frame.sequence === finalSeq) resolveFinal({ frame, decodedOk });
    }
  })().catch((e) => {
    if (!abort.signal.aborted) console.error(`watch: ${describeError(e)}`);
  });
  phase = "WatchSession open";
  await opened;

  // --- the drag --------------------------------------------------------------------------
  let inflight = 0;
  let sent = 0;
  let skipped = 0;
  let replies = 0;
  let superseded = 0;
  const errors: string[] = [];
  const replyMs: number[] = [];
  const bytesBefore = watchBytes;
  const eventsBefore = events;
  const ticks = Math.round(seconds * hz);
  phase = "drag";
  t0 = now();
  for (let k = 0; k < ticks; ++k) {
    await sleep(t0 + (k * 1000) / hz - now());
    if (inflight >= windowSize) {
      ++skipped; // the viewer's rule: never more than `window` unanswered updates
      continue;
    }
    const t = now();
    ++inflight;
    ++sent;
    const p = update((t - t0) / 1000, true);
    sentAt.set(BigInt(seq), t);
    p.then(
      (reply) => {
        ++replies;
        if (reply.superseded) ++superseded;
        replyMs.push(now() - t);
      },
      (e) => errors.push(describeError(e)),
    ).finally(() => --inflight);
  }
  await sleep(t0 + seconds * 1000 - now());
  tEnd = now();
  const watchBytesDrag = watchBytes - bytesBefore;
  const watchEventsDrag = events - eventsBefore;

  // The last update ends the drag: without `dragging`, so exact, and (exact_as_float32)
  // FLOAT32 whatever the stream's encoding. Wait for room in the window like any tick.
  phase = "final update";
  while (inflight >= windowSize) await sleep(1);
  const tFinal = now();
  finalSeq = BigInt(seq + 1);
  const finalReply = await update(seconds, false);
  let timer: NodeJS.Timeout | undefined;
  const final = await Promise.race([finalFrame, new Promise<null>((r) => (timer = setTimeout(() => r(null), 60_000)))]);
  clearTimeout(timer); // or the pending timer alone keeps node alive for a minute
  const finalMs = now() - tFinal;
  phase = "closing";
  abort.abort();
  // Bounded: the report must not depend on how fast an aborted stream unwinds.
  await Promise.race([watching, sleep(2000)]);
  await client.deleteSession({ name }, { timeoutMs: 10_000 }).catch(() => {});
  clearTimeout(watchdog);

  const result = {
    encoding: opt.encoding,
    rate: opt.rate,
    vertices: vc,
    triangles: tc,
    hz,
    seconds,
    ticks,
    sent,
    skipped_full_window: skipped,
    replies,
    superseded,
    errors: errors.length,
    first_error: errors[0] ?? null,
    frames: framesInDrag,
    fps_delivered: r1(framesInDrag / seconds),
    fps_decoded: r1(decodedInDrag / seconds),
    latency_n: latency.length,
    latency_p50_ms: r1(pct(latency, 0.5)),
    latency_p99_ms: r1(pct(latency, 0.99)),
    reply_p50_ms: r1(pct(replyMs, 0.5)),
    solve_p50_ms: r1(pct(solveMs, 0.5)),
    frame_buffer_bytes_p50: pct(bufferBytes, 0.5),
    // Watch stream bytes during the drag per event (almost all frames; a state event is tiny).
    wire_bytes_per_frame: watchEventsDrag ? Math.round(watchBytesDrag / watchEventsDrag) : null,
    watch_mbit_s: r1((watchBytesDrag * 8) / seconds / 1e6),
    decode_p50_ms: Math.round(pct(decodeMs, 0.5) * 1000) / 1000,
    decoder,
    final_ok: !!final && final.decodedOk && final.frame.exact && final.frame.encoding === FrameEncoding.FLOAT32,
    final_exact: final?.frame.exact ?? null,
    final_encoding: final ? FrameEncoding[final.frame.encoding] : null,
    final_reply_superseded: finalReply.superseded,
    final_ms: r1(finalMs),
    frames_total: framesTotal,
    key_frames: keyFrames, // MESHOPT_DELTA: frames sent whole (the first of the drag, grid exits)
  };
  console.log(JSON.stringify(result));
  console.log(
    `${result.encoding}@${result.rate} N=${vc}: ${result.fps_delivered} fps delivered, ${result.fps_decoded} decoded; ` +
      `latency p50 ${result.latency_p50_ms} / p99 ${result.latency_p99_ms} ms (${latency.length} updates); ` +
      `${(result.frame_buffer_bytes_p50 / 1e6).toFixed(3)} MB buffers, ${((result.wire_bytes_per_frame ?? 0) / 1e6).toFixed(3)} MB on the wire per frame; ` +
      `decode p50 ${result.decode_p50_ms} ms; solve p50 ${result.solve_p50_ms} ms; ${superseded} superseded, ${skipped} skipped ticks; ` +
      `final ${result.final_ok ? "ok" : "MISSING/BAD"} (${result.final_encoding}, ${result.final_ms} ms); ${decoder}`,
  );
}

main().then(
  // Exit explicitly: a stream that has not unwound yet must not keep node alive.
  () => process.exit(0),
  (e) => {
    console.error(`drag: ${describeError(e)} (phase "${phase}")`);
    process.exit(1);
  },
);

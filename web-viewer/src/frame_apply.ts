// Shows the frames sync lets through: shape, energies, measures, β, version. Decoding may be
// asynchronous (QUANTIZED / MESHOPT in the decode worker), so frames are applied through a
// promise chain in the order sync gave them: an older drag frame never lands after the exact
// one. Frames carry no transforms, so after another editor's frames the session is re-read
// once the stream goes quiet, to bring the gizmo (transforms) and regions up to date.
import type { App } from "./app";
import { FrameDecoder } from "./decode/frame_decoder";
import { FrameEncoding, type Frame } from "./gen/hdeform/v1/deform_pb";
import type { Sync } from "./sync/sync";
import type { PerfStats } from "./perf/perf_stats";

const RESYNC_QUIET_MS = 250;

/** Bytes of a frame's buffers (what the encoding changes); 0 for a frame without them. */
function bufferBytes(f: Frame): number {
  return f.positions.byteLength + f.normals.byteLength + f.vertices.byteLength + f.energies.byteLength;
}

export interface FrameApply {
  /** Frames given by sync and not yet shown (decoding). */
  readonly pending: number;
  /** The decode worker's time per frame for the newest frames it decoded (ms). */
  readonly workerDecodeMs: readonly number[];
}

export function setupFrameApply({ state, client, banner, status }: App, sync: Sync, perf?: PerfStats, myClientId?: () => string): FrameApply {
  const decoder = new FrameDecoder();
  let chain: Promise<void> = Promise.resolve();
  let pending = 0;
  // Newest buffer size per encoding, for the status line (drag frames vs exact float32 ones).
  const sizes = new Map<FrameEncoding, number>();
  let resyncTimer: ReturnType<typeof setTimeout> | undefined;
  const scheduleResync = () => {
    if (state.watchOnly) return;
    clearTimeout(resyncTimer);
    resyncTimer = setTimeout(async () => {
      if (sync.busy) return;
      try {
        const s = await client.getSession({ name: state.sessionName });
        if (!sync.busy) state.adoptSession(s);
      } catch {
        /* the watch loop reports connection problems */
      }
    }, RESYNC_QUIET_MS);
  };

  // Another mesh: the status line's frame sizes were the previous session's.
  state.on("mesh", () => {
    sizes.clear();
    status.setFrameSizes("");
  });

  sync.on("skippedFrame", ({ frame }) => {
    const mesh = state.mesh;
    // Not shown, but a MESHOPT_DELTA frame moves the decoder's state on; its errors show on
    // the next frame that is shown.
    if (mesh) decoder.skip(frame, mesh.n, mesh.m).catch(() => {});
  });

  sync.on("frame", ({ frame, source }) => {
    const mesh = state.mesh;
    if (!mesh) return;
    // The page's cost of this frame (perf overlay): decode (on the main thread for FLOAT32, else
    // the worker's time), then the copy into the state and the display's buffers, and normals.
    const t0 = performance.now();
    const decoding = decoder.decode(frame, mesh.n, mesh.m); // starts now, shown in turn
    const mainDecodeMs = performance.now() - t0;
    pending++;
    chain = chain.then(async () => {
      try {
        const decoded = await decoding;
        if (state.mesh !== mesh) return; // another session opened meanwhile
        const t1 = performance.now();
        const decodeMs = mainDecodeMs + (decoded.workerMs ?? 0);
        if (decoded.positions) {
          state.setShape(decoded.positions, decoded.normals); // copies: the arrays go round
          decoder.recycle(decoded);
          if (source === "watch") scheduleResync();
        }
        if (decoded.energies) state.setEnergies(decoded.energies);
        const applied = performance.now();
        if (perf && decoded.positions) {
          const sent = myClientId && frame.clientId === myClientId() && frame.sequence > 0n ? sync.sentTime(Number(frame.sequence)) : undefined;
          perf.record({ at: applied, bytes: bufferBytes(frame), costMs: decodeMs + (applied - t1), decodeMs, latencyMs: sent === undefined ? null : applied - sent });
        }
        showFrameInfo(frame);
        showFrameSize(frame);
      } catch (err) {
        banner.show((err as Error).message);
        // A delta stream is broken from here on: a new stream starts with a key frame.
        if (frame.encoding === FrameEncoding.MESHOPT_DELTA) sync.rewatch("a frame did not decode");
      } finally {
        pending--;
      }
    });
  });

  function showFrameSize(frame: Frame): void {
    const bytes = bufferBytes(frame);
    if (bytes === 0) return;
    sizes.set(frame.encoding, bytes);
    const parts = [...sizes].map(([enc, b]) => `${FrameEncoding[enc].toLowerCase().replace("_", "-")} ${(b / 1024).toFixed(1)} KiB`);
    status.setFrameSizes(`frames: ${parts.join(", ")}`);
  }

  function showFrameInfo(frame: Frame): void {
    if (frame.version > state.frameVersion) {
      state.frameVersion = frame.version;
      state.emit("session", undefined);
    }
    if (frame.measures) state.setMeasures(frame.measures, frame.solveMs);
    if (frame.beta && (frame.beta.value !== state.beta.value || frame.beta.units !== state.beta.units)) {
      state.setBeta(frame.beta.value, frame.beta.units);
    }
  }

  return {
    get pending() {
      return pending;
    },
    workerDecodeMs: decoder.workerMs,
  };
}

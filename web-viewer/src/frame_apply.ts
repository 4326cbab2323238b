// Shows the frames sync lets through: shape, energies, measures, β, version. Frames carry no
// transforms, so after another editor's frames the session is re-read once the stream goes
// quiet, to bring the gizmo (transforms) and regions up to date.
import type { App } from "./app";
import { decodeFrame } from "./decode/frame_decode";
import type { Frame } from "./gen/hdeform/v1/deform_pb";
import type { Sync } from "./sync/sync";

const RESYNC_QUIET_MS = 250;

export function setupFrameApply({ state, client, banner }: App, sync: Sync): void {
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

  sync.on("frame", ({ frame, source }) => {
    const mesh = state.mesh;
    if (!mesh) return;
    let decoded;
    try {
      decoded = decodeFrame(frame, mesh.n, mesh.m);
    } catch (err) {
      banner.show((err as Error).message);
      return;
    }
    if (decoded.positions) {
      state.setShape(decoded.positions, decoded.normals);
      if (source === "watch") scheduleResync();
    }
    if (decoded.energies) state.setEnergies(decoded.energies);
    showFrameInfo(frame);
  });

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
}

// The up axis of downloaded GLBs (the top bar's "z-up / y-up"): by default the one the viewer
// shows the model with (viewport.ts: a z-up model gets camera up = +z), chosen again for every
// mesh that opens; the user may pick the other. The GLB download and the timeline's Export use
// it (glb_up_axis.ts wraps a z-up model for glTF's y-up); Play does not (the viewer shows the
// model in its own frame).
import { $ } from "../dom";
import type { UpAxis } from "../glb_up_axis";
import type { SessionState } from "../state";

export interface ExportUp {
  readonly value: UpAxis;
}

export function setupExportUp(state: SessionState, viewerUp: () => UpAxis): ExportUp {
  const select = $<HTMLSelectElement>("export-up");
  state.on("opened", () => (select.value = viewerUp()));
  return {
    get value() {
      return select.value === "z" ? "z" : "y";
    },
  };
}

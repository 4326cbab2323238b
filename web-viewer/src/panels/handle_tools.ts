// The mode buttons (Orbit / Vertex / Brush / Box) and the Handle panel: the active handle, the
// gizmo's Move / Rotate / Scale (one control: choosing one enters Move mode), world / local
// axes, snapping, Reset transforms.
import type { App } from "../app";
import { $ } from "../dom";
import { openMeshFirst } from "./banner";
import type { Mode } from "../state";
import type { GizmoMode, GizmoSpace, HandleGizmo } from "../viewport/handle_gizmo";

export function setupHandleTools({ state, edits, banner }: App, gizmo: HandleGizmo, multi: () => boolean): void {
  const modeButtons = document.querySelectorAll<HTMLButtonElement>("button.mode");
  modeButtons.forEach((b) => b.addEventListener("click", () => state.setMode(b.dataset.mode as Mode)));
  const gizmoButtons = document.querySelectorAll<HTMLButtonElement>("button.gizmo-mode");
  const showActive = () => {
    modeButtons.forEach((b) => b.classList.toggle("active", b.dataset.mode === state.mode));
    gizmoButtons.forEach((b) => b.classList.toggle("active", state.mode === "move" && b.dataset.gizmo === gizmo.mode));
  };
  state.on("mode", showActive);
  gizmoButtons.forEach((b) =>
    b.addEventListener("click", () => {
      gizmo.setMode(b.dataset.gizmo as GizmoMode);
      state.setMode("move");
    }),
  );
  const space = $<HTMLSelectElement>("gizmo-space");
  space.addEventListener("change", () => gizmo.setSpace(space.value as GizmoSpace));
  gizmo.onChange((_, s) => {
    space.value = s;
    showActive();
  });
  const snap = $<HTMLInputElement>("snap");
  const grid = $<HTMLInputElement>("snap-grid");
  const readSnap = () => {
    gizmo.snap = { enabled: snap.checked, grid: Number(grid.value) };
    gizmo.applySnap(false, false);
  };
  snap.addEventListener("change", readSnap);
  grid.addEventListener("input", readSnap);
  state.on("mesh", (mesh) => {
    // A round grid step about 1 % of the model's size.
    if (!grid.value) grid.value = String(Number((10 ** Math.round(Math.log10(mesh.diag / 100))).toPrecision(1)));
    readSnap();
  });

  $<HTMLSelectElement>("active-handle").addEventListener("change", (e) => {
    state.activeHandle = Number((e.target as HTMLSelectElement).value);
    state.emit("handles", undefined);
  });
  $("reset-handles").addEventListener("click", () => {
    if (!state.mesh || !state.sessionName) return openMeshFirst(banner);
    // Several editors: updates carry only the active handle (the others may be someone else's).
    if (multi()) {
      const h = state.activeHandle - 1;
      if (!state.pivots[h]) return;
      void gizmo.setPose({ position: state.pivots[h].clone(), quaternion: state.handles[h].quaternion.clone().identity(), scale: state.handles[h].scale.clone().setScalar(1) });
      return;
    }
    state.resetHandles();
    edits.requestFrame();
  });
}

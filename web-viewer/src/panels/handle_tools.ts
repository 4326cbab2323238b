// The Handle panel and the mode buttons: the active handle, Move / Rotate / Scale, Reset
// transforms; Orbit / Vertex / Brush / Box / Move.
import type { App } from "../app";
import { $ } from "../dom";
import type { Mode } from "../state";
import type { HandleGizmo } from "../viewport/handle_gizmo";

export function setupHandleTools({ state, edits }: App, gizmo: HandleGizmo): void {
  const modeButtons = document.querySelectorAll<HTMLButtonElement>("button.mode");
  modeButtons.forEach((b) => b.addEventListener("click", () => state.setMode(b.dataset.mode as Mode)));
  state.on("mode", (mode) => modeButtons.forEach((b) => b.classList.toggle("active", b.dataset.mode === mode)));

  const gizmoButtons = document.querySelectorAll<HTMLButtonElement>("button.gizmo-mode");
  gizmoButtons.forEach((b) =>
    b.addEventListener("click", () => {
      gizmo.setMode(b.dataset.gizmo as "translate" | "rotate" | "scale");
      gizmoButtons.forEach((x) => x.classList.toggle("active", x === b));
    }),
  );
  document.querySelector<HTMLButtonElement>('button[data-gizmo="translate"]')!.classList.add("active");

  $<HTMLSelectElement>("active-handle").addEventListener("change", (e) => {
    state.activeHandle = Number((e.target as HTMLSelectElement).value);
    state.emit("handles", undefined);
  });
  $("reset-handles").addEventListener("click", () => {
    state.resetHandles();
    edits.requestFrame();
  });
}

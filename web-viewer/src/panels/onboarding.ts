// The first steps, said where the eye is: after a mesh opens, "1 fixed region → 2 handle →
// 3 Apply → 4 move", each ticked off as it is done (Apply only once it happened); gone once a handle has moved. Before any mesh, the
// placeholder says what to do.
import type { App } from "../app";
import { $ } from "../dom";
import { handleName } from "../handle_names";

export interface Steps {
  fixed: boolean;
  handle: boolean;
  /** Apply constraints happened (and nothing was changed since): its own tick, never with marking. */
  applied: boolean;
  moved: boolean;
}

/** Which of the four steps are done. */
export function stepsDone(labels: Int16Array | null, constraintsApplied: boolean, moved: boolean): Steps {
  let fixed = false;
  let handle = false;
  if (labels) for (let v = 0; v < labels.length && !(fixed && handle); v++) (labels[v] === 0 ? (fixed = true) : labels[v] > 0 && (handle = true));
  return { fixed: fixed || constraintsApplied, handle: handle || constraintsApplied, applied: constraintsApplied, moved };
}

export function setupOnboarding({ state }: App): void {
  const hint = $("hint");
  let moved = false;
  const render = () => {
    if (!state.mesh || state.watchOnly) {
      hint.classList.add("hidden");
      return;
    }
    const s = stepsDone(state.mesh.labels, state.constraintsApplied && !state.labelsDirty, moved);
    hint.classList.toggle("hidden", s.moved);
    const step = (done: boolean, n: number, text: string) => `<span class="step${done ? " done" : ""}">${done ? "✓" : n} ${text}</span>`;
    hint.innerHTML = [
      step(s.fixed, 1, "mark a <b>fixed</b> region (Box / Brush, Assign to Fixed)"),
      step(s.handle, 2, `mark a <b>handle</b> (Assign to ${handleName(0)})`),
      step(s.applied, 3, "<b>Apply</b>"),
      step(s.moved, 4, "<b>move</b> it (W / E / R, the gizmo)"),
    ].join(' <span class="arrow">→</span> '); // spaces: a narrow canvas wraps the hint between steps
  };
  state.on("mesh", () => {
    moved = false;
    render();
  });
  state.on("labels", render);
  state.on("session", () => {
    // A session that is already deformed needs no introduction.
    if (state.handles.some((h, i) => !state.pivots[i] || h.position.distanceToSquared(state.pivots[i]) > 0 || h.quaternion.w < 1 || h.scale.x !== 1)) moved = true;
    render();
  });
  state.on("pose", () => {
    moved = true;
    render();
  });
}

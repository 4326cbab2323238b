// The keyboard shortcuts (keymap.ts) carried out, and the "?" overlay listing them. Keys typed
// into a field are left alone.
import * as THREE from "three";
import type { App } from "../app";
import { $ } from "../dom";
import { isTyping, keyAction, SHORTCUTS } from "../keymap";
import type { HandleGizmo } from "../viewport/handle_gizmo";
import type { Viewport } from "../viewport/viewport";
import type { SelectionCommand } from "../selection/commands";
import type { ViewName } from "../viewport/view_axes";

/** The box of the vertices labelled `label` (current positions), or null when there are none. */
export function regionBox(app: App, label: number): THREE.Box3 | null {
  const mesh = app.state.mesh;
  if (!mesh) return null;
  const box = new THREE.Box3();
  const p = new THREE.Vector3();
  for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] === label) box.expandByPoint(p.fromArray(mesh.cur, 3 * v));
  return box.isEmpty() ? null : box;
}

/** F: the active handle in Move mode, else the region being assigned; nothing selected: all. */
export function frameSelection(app: App, viewport: Viewport): void {
  const { state } = app;
  const label = state.mode === "move" || state.mode === "orbit" ? state.activeHandle : state.currentLabel;
  const box = regionBox(app, label);
  if (box) viewport.frameBox(box);
  else viewport.frameAll();
}

export interface ShortcutActions {
  toggleWeights: () => void;
  setKey: () => void;
  togglePerf: () => void;
  select: (command: SelectionCommand) => number;
  /** Numpad 1 / 3 / 7 (Ctrl: the opposite side): the camera to that side of the orbit target. */
  lookFrom: (view: ViewName) => void;
  toggleXray: () => void;
}

export function setupShortcuts(app: App, gizmo: HandleGizmo, viewport: Viewport, { toggleWeights, setKey, togglePerf, select, lookFrom, toggleXray }: ShortcutActions): void {
  const { state } = app;
  const overlay = $("shortcuts");
  $("shortcuts-list").innerHTML = SHORTCUTS.map(([k, what]) => `<tr><th><kbd>${k}</kbd></th><td>${what}</td></tr>`).join("");
  const toggleHelp = (show = overlay.classList.contains("hidden")) => overlay.classList.toggle("hidden", !show);
  $("shortcuts-close").addEventListener("click", () => toggleHelp(false));
  $("show-shortcuts").addEventListener("click", () => toggleHelp());
  window.addEventListener("keydown", (ev) => {
    if (isTyping(ev.target as HTMLElement)) return;
    const action = keyAction(ev);
    if (!action) return;
    const editor = !state.watchOnly;
    let handled = true;
    switch (action) {
      case "translate":
      case "rotate":
      case "scale":
        if (!editor) return;
        gizmo.setMode(action);
        state.setMode("move");
        break;
      case "toggleSpace":
        gizmo.setSpace(gizmo.space === "world" ? "local" : "world");
        break;
      case "cancel":
        if (!gizmo.cancel()) toggleHelp(false);
        break;
      case "axisX":
      case "axisY":
      case "axisZ":
        handled = gizmo.constrain(action.slice(4) as "X" | "Y" | "Z");
        break;
      case "frameSelection":
        frameSelection(app, viewport);
        break;
      case "frameAll":
        viewport.frameAll();
        break;
      case "clearSelection": {
        const mesh = state.mesh;
        if (!editor || !mesh || state.mode === "move") return;
        const ids: number[] = [];
        for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] === state.currentLabel) ids.push(v);
        state.assign(ids, -1);
        break;
      }
      case "toggleWeights":
        toggleWeights();
        break;
      case "setKey":
        if (!editor) return;
        setKey();
        break;
      case "togglePerf":
        togglePerf();
        break;
      case "selectAll":
      case "selectNone":
      case "selectInvert":
      case "selectGrow":
      case "selectShrink":
        if (!editor || !state.mesh || state.mode === "move") return;
        select(action.slice(6).toLowerCase() as SelectionCommand);
        break;
      case "viewFront":
      case "viewBack":
      case "viewRight":
      case "viewLeft":
      case "viewTop":
      case "viewBottom":
        lookFrom(action.slice(4).toLowerCase() as ViewName);
        break;
      case "toggleOrthographic":
        viewport.toggleOrthographic();
        break;
      case "toggleXray":
        toggleXray();
        break;
      case "help":
        toggleHelp();
        break;
    }
    if (handled) ev.preventDefault();
  });
}

// Keyboard shortcuts, as people know them from Blender and the three.js editor: which key does
// what, without the DOM (unit-tested); panels/shortcuts.ts carries the actions out.

export type KeyAction =
  | "translate" // W: move gizmo
  | "rotate" // E
  | "scale" // R
  | "toggleSpace" // Q: world / local axes (the three.js editor's key)
  | "cancel" // Esc: cancel the drag (or close the shortcuts overlay)
  | "axisX" // X / Y / Z while dragging: keep to that axis
  | "axisY"
  | "axisZ"
  | "frameSelection" // F
  | "frameAll" // Home
  | "clearSelection" // Delete / Backspace: clear the region being assigned
  | "toggleWeights" // V: the active handle's weights on the mesh (soft-selection preview)
  | "setKey" // K: a timeline key at the playhead (Blender's "insert keyframe" is I; K is free here)
  | "togglePerf" // P: the perf overlay
  | "selectAll" // A (Blender)
  | "selectNone" // Alt+A (Blender)
  | "selectInvert" // I (Blender: Ctrl+I)
  | "selectGrow" // + (Blender: Ctrl+numpad +)
  | "selectShrink" // - (Blender: Ctrl+numpad -)
  | "viewFront" // Numpad 1 (Blender's numeric keypad; Ctrl: the opposite side)
  | "viewBack" // Ctrl+Numpad 1
  | "viewRight" // Numpad 3
  | "viewLeft" // Ctrl+Numpad 3
  | "viewTop" // Numpad 7
  | "viewBottom" // Ctrl+Numpad 7
  | "toggleOrthographic" // Numpad 5 (Blender): perspective / orthographic
  | "toggleXray" // Alt+Z (Blender): Box and Lasso select through the mesh
  | "help"; // ?

/** Blender's keypad views: the key's physical code → [view, view with Ctrl]. */
const NUMPAD_VIEWS: Record<string, [KeyAction, KeyAction]> = {
  Numpad1: ["viewFront", "viewBack"],
  Numpad3: ["viewRight", "viewLeft"],
  Numpad7: ["viewTop", "viewBottom"],
};

export interface KeyInput {
  key: string;
  ctrlKey?: boolean;
  metaKey?: boolean;
  altKey?: boolean;
  shiftKey?: boolean;
  /** The physical key ("KeyA"): Alt+A types "å" on macOS. */
  code?: string;
}

/** The action of a key press; null for keys that are not shortcuts (or with Ctrl / Alt / ⌘). */
export function keyAction(ev: KeyInput): KeyAction | null {
  // The keypad by its physical key: with Num Lock off Numpad 7 types "Home" (frame all otherwise).
  const numpad = ev.code ? NUMPAD_VIEWS[ev.code] : undefined;
  if (numpad && !ev.altKey) return numpad[ev.ctrlKey || ev.metaKey ? 1 : 0];
  if (ev.code === "NumpadDecimal" && !ev.altKey && !ev.ctrlKey && !ev.metaKey) return "frameSelection"; // Blender's "view selected"
  // With Num Lock off Numpad 5 types "Clear" (or nothing): the physical key decides.
  if (ev.code === "Numpad5" && !ev.altKey && !ev.ctrlKey && !ev.metaKey) return "toggleOrthographic";
  if (ev.altKey && !ev.ctrlKey && !ev.metaKey && (ev.code === "KeyZ" || ev.key === "z" || ev.key === "Z")) return "toggleXray";
  // Alt+A: select none, as in Blender (Alt alone with A is not the browser's).
  if (ev.altKey && !ev.ctrlKey && !ev.metaKey && (ev.code === "KeyA" || ev.key === "a" || ev.key === "A")) return "selectNone";
  if (ev.ctrlKey || ev.metaKey || ev.altKey) return null; // the browser's own (copy, reload, …)
  switch (ev.key) {
    case "w":
    case "W":
      return "translate";
    case "e":
    case "E":
      return "rotate";
    case "r":
    case "R":
      return "scale";
    case "q":
    case "Q":
      return "toggleSpace";
    case "Escape":
      return "cancel";
    case "x":
    case "X":
      return "axisX";
    case "y":
    case "Y":
      return "axisY";
    case "z":
    case "Z":
      return "axisZ";
    case "f":
    case "F":
      return "frameSelection";
    case "Home":
      return "frameAll";
    case "Delete":
    case "Backspace":
      return "clearSelection";
    case "v":
    case "V":
      return "toggleWeights";
    case "k":
    case "K":
      return "setKey";
    case "p":
    case "P":
      return "togglePerf";
    case "a":
    case "A":
      return "selectAll";
    case "i":
    case "I":
      return "selectInvert";
    case "+":
    case "=":
      return "selectGrow";
    case "-":
    case "_":
      return "selectShrink";
    case "?":
      return "help";
    default:
      return null;
  }
}

export type HistoryKey = "undo" | "redo";

/** macOS (and iOS) use ⌘ where other systems use Ctrl (navigator.platform: "MacIntel", "iPad", …). */
export function isMacPlatform(platform: string | undefined): boolean {
  return /^(mac|iphone|ipad|ipod)/i.test(platform ?? "");
}

/**
 * Undo / redo, as in every editor: Ctrl+Z undo, Ctrl+Shift+Z or Ctrl+Y redo; ⌘ instead of Ctrl
 * on macOS (where Ctrl+Z is not undo, so it is left alone). With Alt: not ours.
 */
export function historyKey(ev: KeyInput, mac: boolean): HistoryKey | null {
  const command = mac ? ev.metaKey && !ev.ctrlKey : ev.ctrlKey && !ev.metaKey;
  if (!command || ev.altKey) return null;
  switch (ev.key) {
    case "z":
    case "Z":
      return ev.shiftKey ? "redo" : "undo";
    case "y":
    case "Y":
      return ev.shiftKey ? null : "redo";
    default:
      return null;
  }
}

export type ClipboardKey = "copy" | "paste";

/**
 * Ctrl+C / Ctrl+V (⌘C / ⌘V on macOS, as historyKey): the timeline's copy and paste of a key.
 * Shift or Alt with them is something else (the browser's paste-as-plain-text, …).
 */
export function clipboardKey(ev: KeyInput, mac: boolean): ClipboardKey | null {
  const command = mac ? ev.metaKey && !ev.ctrlKey : ev.ctrlKey && !ev.metaKey;
  if (!command || ev.altKey || ev.shiftKey) return null;
  switch (ev.key) {
    case "c":
    case "C":
      return "copy";
    case "v":
    case "V":
      return "paste";
    default:
      return null;
  }
}

/** What an element is, as far as typing goes (a DOM element or a plain description in tests). */
export interface TargetInfo {
  tagName?: string;
  type?: string;
  isContentEditable?: boolean;
}

const NOT_TEXT = new Set(["range", "checkbox", "radio", "button", "submit", "reset", "file", "color"]);

/** Keys typed into a text field, a select or an editable element are not shortcuts. */
export function isTyping(target: TargetInfo | null | undefined): boolean {
  if (!target) return false;
  if (target.isContentEditable) return true;
  const tag = (target.tagName ?? "").toUpperCase();
  if (tag === "TEXTAREA" || tag === "SELECT") return true;
  if (tag === "INPUT") return !NOT_TEXT.has((target.type ?? "text").toLowerCase());
  return false;
}

/** The shortcuts overlay's rows: keys, what they do. */
export const SHORTCUTS: [string, string][] = [
  ["W / E / R", "move / rotate / scale gizmo"],
  ["Q", "world / local axes"],
  ["Esc · right click", "cancel the drag (back to where it began)"],
  ["X / Y / Z (dragging)", "keep the drag to one axis"],
  ["Ctrl (Shift) while dragging", "snap: 15° (5°) steps, grid moves"],
  ["F · Numpad .", "frame the active handle / selected region"],
  ["Numpad 1 / 3 / 7", "front / right / top view (Blender's keypad; the model's up axis stays up)"],
  ["Ctrl+Numpad 1 / 3 / 7", "back / left / bottom view"],
  ["Numpad 5", "perspective / orthographic view"],
  ["Home", "frame everything"],
  ["Delete", "clear the region being assigned"],
  ["V", "show / hide the active handle's weights (0 = fixed, 1 = moves with it)"],
  ["K", "timeline: set a key (every handle's pose) at the playhead"],
  ["Delete (timeline focused)", "delete the selected key"],
  ["Ctrl+C / Ctrl+V (⌘C / ⌘V)", "timeline: copy the selected key's pose / paste it as a key at the playhead"],
  ["drag the selected key", "timeline: move it to another time (Esc: cancel)"],
  ["Ctrl+Z (⌘Z)", "undo your last change"],
  ["Ctrl+Shift+Z · Ctrl+Y", "redo it"],
  ["A / Alt+A", "select all / none (of the region Assign to names)"],
  ["I", "invert the selection"],
  ["+ / −", "grow / shrink the selection by one ring of neighbours"],
  ["Shift+drag · Ctrl+drag", "Brush, Box, Lasso, Vertex: add to / remove from the selection"],
  ["Alt+Z", "X-ray: Box and Lasso select through the mesh (off: only what the camera sees)"],
  ["P", "perf overlay (frames/s, latency, bytes, page cost per frame)"],
  ["?", "this list"],
];

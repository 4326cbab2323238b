// Ctrl+Z / Ctrl+Shift+Z / Ctrl+Y (⌘ on macOS) carried out (keymap.ts's historyKey). Keys typed
// into a field are the field's own (its text's undo).
import { historyKey, isMacPlatform, isTyping } from "../keymap";
import type { UndoRedo } from "./undo_redo";

export function setupUndoShortcuts(undo: UndoRedo): void {
  const mac = isMacPlatform(navigator.platform);
  window.addEventListener("keydown", (ev) => {
    if (isTyping(ev.target as HTMLElement)) return;
    const kind = historyKey(ev, mac);
    if (!kind) return;
    ev.preventDefault(); // not the browser's (nothing of the page is text to undo)
    if (!ev.repeat) void undo.run(kind);
  });
}

// Ctrl+C / Ctrl+V (⌘ on macOS; keymap.ts's clipboardKey) for timeline keys: when the strip has
// the focus (a press on the ruler gives it), or when nothing has it (the canvas takes no focus,
// so after posing the handles the focus is on the page itself). Text the user selected, and
// keys typed into a field, stay the browser's: copying a share link must keep working.
import { clipboardKey, isMacPlatform, isTyping, type ClipboardKey } from "../keymap";

export function setupKeyClipboardKeys(strip: HTMLElement, run: (what: ClipboardKey) => void): void {
  const mac = isMacPlatform(navigator.platform);
  window.addEventListener("keydown", (ev) => {
    const what = clipboardKey(ev, mac);
    if (!what || isTyping(ev.target as HTMLElement)) return;
    const focus = document.activeElement;
    const inStrip = !!focus && strip.contains(focus);
    const onPage = !focus || focus === document.body;
    if (!inStrip && !onPage) return;
    const selection = window.getSelection();
    if (!inStrip && what === "copy" && selection && !selection.isCollapsed) return;
    ev.preventDefault();
    if (!ev.repeat) run(what);
  });
}

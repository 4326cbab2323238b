// Narrow windows (style.css has the breakpoints): below 1180 px the top bar folds its downloads
// into a "Files" menu, below 960 px the side panel becomes a drawer over the canvas's right side
// that "Panels" opens and closes, so the canvas keeps the window's width. The state is a class
// on <body>; a wide window ignores it.
import { $ } from "../dom";

export function setupLayout(): void {
  const filesToggle = $<HTMLButtonElement>("files-toggle");
  const panelToggle = $<HTMLButtonElement>("panel-toggle");
  const setFiles = (open: boolean) => {
    document.body.classList.toggle("files-open", open);
    filesToggle.setAttribute("aria-expanded", String(open));
  };
  filesToggle.addEventListener("click", (ev) => {
    ev.stopPropagation();
    setFiles(!document.body.classList.contains("files-open"));
  });
  // The menu closes on a choice or a click elsewhere (a file input's dialog opens first).
  document.addEventListener("click", (ev) => {
    if (!document.body.classList.contains("files-open")) return;
    const inMenu = (ev.target as HTMLElement).closest("#files-group");
    if (!inMenu || (ev.target as HTMLElement).closest("button, label.button")) setFiles(false);
  });
  window.addEventListener("keydown", (ev) => {
    if (ev.key === "Escape") setFiles(false);
  });
  panelToggle.addEventListener("click", () => {
    const open = !document.body.classList.contains("panel-open");
    document.body.classList.toggle("panel-open", open);
    panelToggle.setAttribute("aria-expanded", String(open));
    panelToggle.classList.toggle("active", open);
  });
}

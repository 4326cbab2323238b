// The viewport's camera buttons: frame the selection (F), frame all (Home), the default view.
import type { App } from "../app";
import { $ } from "../dom";
import type { Viewport } from "../viewport/viewport";
import { frameSelection } from "./shortcuts";

export function setupViewButtons(app: App, viewport: Viewport): void {
  $("view-frame").addEventListener("click", () => frameSelection(app, viewport));
  $("view-all").addEventListener("click", () => viewport.frameAll());
  $("view-reset").addEventListener("click", () => viewport.resetView());
}

// What a Box or Lasso drag shows while it lasts: the dashed rectangle (#boxsel) or the lasso's
// path, closed back to its start (#lassosel, an SVG over the canvas).
import { $ } from "../dom";
import type { Point } from "./screen_rect";

export function drawBox(from: Point, to: Point): void {
  const el = $("boxsel");
  el.classList.remove("hidden");
  el.style.left = `${Math.min(from.x, to.x)}px`;
  el.style.top = `${Math.min(from.y, to.y)}px`;
  el.style.width = `${Math.abs(to.x - from.x)}px`;
  el.style.height = `${Math.abs(to.y - from.y)}px`;
}

export function drawLasso(points: readonly Point[]): void {
  const svg = $("lassosel");
  svg.classList.remove("hidden");
  svg.querySelector("polygon")?.setAttribute("points", points.map((p) => `${p.x},${p.y}`).join(" "));
}

export function hideGesture(): void {
  $("boxsel").classList.add("hidden");
  $("lassosel").classList.add("hidden");
}

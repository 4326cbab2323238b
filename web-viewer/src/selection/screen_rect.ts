// Box select: every vertex whose projection falls in a screen rectangle (all of them, or only
// those not hidden behind the mesh: visibility.ts decides).
import type { MeshData } from "../state";
import type { Viewport } from "../viewport/viewport";
import { forEachOnScreen } from "./screen_projection";

export type Point = { x: number; y: number };

/** Keeps a vertex at pixel (x, y) with window depth `depth` (true: select it). */
export type VertexFilter = (x: number, y: number, depth: number) => boolean;

/** Vertices in the rectangle a–b (viewport pixels) that `keep` accepts; none for a rectangle under 2 px. */
export function verticesInScreenRect(viewport: Viewport, mesh: MeshData, a: Point, b: Point, keep: VertexFilter = () => true): number[] {
  const x0 = Math.min(a.x, b.x), x1 = Math.max(a.x, b.x), y0 = Math.min(a.y, b.y), y1 = Math.max(a.y, b.y);
  if (x1 - x0 < 2 || y1 - y0 < 2) return [];
  const ids: number[] = [];
  forEachOnScreen(viewport, mesh, (v, sx, sy, depth) => {
    if (sx >= x0 && sx <= x1 && sy >= y0 && sy <= y1 && keep(sx, sy, depth)) ids.push(v);
  });
  return ids;
}

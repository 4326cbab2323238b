// Lasso select: every vertex whose projection falls inside the polygon the pointer drew
// (closed by its last-to-first edge, as in Blender), filtered like the box (visibility.ts).
import type { MeshData } from "../state";
import type { Viewport } from "../viewport/viewport";
import { forEachOnScreen } from "./screen_projection";
import type { Point, VertexFilter } from "./screen_rect";

/** A lasso point closer than this (px) to the previous one is not recorded. */
export const LASSO_STEP_PX = 2;

/**
 * (x, y) inside the closed polygon, by the even–odd rule (a ray to +x crosses its edges an odd
 * number of times). Self-crossing lassos: the parts enclosed an odd number of times are inside.
 */
export function insidePolygon(x: number, y: number, poly: readonly Point[]): boolean {
  let inside = false;
  for (let i = 0, j = poly.length - 1; i < poly.length; j = i++) {
    const a = poly[i], b = poly[j];
    if (a.y > y !== b.y > y && x < ((b.x - a.x) * (y - a.y)) / (b.y - a.y) + a.x) inside = !inside;
  }
  return inside;
}

/** The polygon's area (px², shoelace); a lasso under 4 px² selects nothing (a click). */
export function polygonArea(poly: readonly Point[]): number {
  let s = 0;
  for (let i = 0, j = poly.length - 1; i < poly.length; j = i++) s += (poly[j].x - poly[i].x) * (poly[j].y + poly[i].y);
  return Math.abs(s) / 2;
}

export function verticesInPolygon(viewport: Viewport, mesh: MeshData, poly: readonly Point[], keep: VertexFilter = () => true): number[] {
  if (poly.length < 3 || polygonArea(poly) < 4) return [];
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (const p of poly) {
    x0 = Math.min(x0, p.x);
    x1 = Math.max(x1, p.x);
    y0 = Math.min(y0, p.y);
    y1 = Math.max(y1, p.y);
  }
  const ids: number[] = [];
  forEachOnScreen(viewport, mesh, (v, sx, sy, depth) => {
    // The bounding box first: most vertices of a 100K mesh are outside it, and the edge walk costs.
    if (sx >= x0 && sx <= x1 && sy >= y0 && sy <= y1 && insidePolygon(sx, sy, poly) && keep(sx, sy, depth)) ids.push(v);
  });
  return ids;
}

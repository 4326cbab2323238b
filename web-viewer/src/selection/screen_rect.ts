// Box select: every vertex whose projection falls in a screen rectangle (through the mesh).
import * as THREE from "three";
import type { MeshData } from "../state";
import type { Viewport } from "../viewport/viewport";

export type Point = { x: number; y: number };

/** Vertices in the rectangle a–b (viewport pixels); none for a rectangle under 2 px. */
export function verticesInScreenRect(viewport: Viewport, mesh: MeshData, a: Point, b: Point): number[] {
  const w = viewport.element.clientWidth;
  const h = viewport.element.clientHeight;
  const x0 = Math.min(a.x, b.x), x1 = Math.max(a.x, b.x), y0 = Math.min(a.y, b.y), y1 = Math.max(a.y, b.y);
  if (x1 - x0 < 2 || y1 - y0 < 2) return [];
  const { camera, root } = viewport;
  root.updateMatrixWorld(true);
  const M = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse).multiply(root.matrixWorld);
  const p = new THREE.Vector3();
  const ids: number[] = [];
  for (let v = 0; v < mesh.n; v++) {
    p.set(mesh.cur[3 * v], mesh.cur[3 * v + 1], mesh.cur[3 * v + 2]).applyMatrix4(M);
    if (p.z < -1 || p.z > 1) continue;
    const sx = ((p.x + 1) / 2) * w;
    const sy = ((1 - p.y) / 2) * h;
    if (sx >= x0 && sx <= x1 && sy >= y0 && sy <= y1) ids.push(v);
  }
  return ids;
}

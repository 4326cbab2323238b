// Vertices projected to the canvas (viewport pixels from its top left), the way the box and
// lasso tools see them: the current (deformed) positions, through the camera as it is now.
import * as THREE from "three";
import type { MeshData } from "../state";
import type { Viewport } from "../viewport/viewport";

/** The canvas size and model → clip matrix (column-major) the tools project with. */
export interface Projection {
  width: number;
  height: number;
  matrix: number[];
}

export function currentProjection(viewport: Viewport): Projection {
  const { viewCamera: camera, root } = viewport;
  root.updateMatrixWorld(true);
  camera.updateMatrixWorld();
  const M = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse).multiply(root.matrixWorld);
  return { width: viewport.element.clientWidth, height: viewport.element.clientHeight, matrix: M.toArray() };
}

/**
 * Calls `visit(v, x, y, depth)` for each vertex in front of the camera (NDC z in [−1, 1]):
 * its pixel position and window depth (0 near … 1 far). Same arithmetic as three's
 * Vector3.applyMatrix4 (the browser tests redo it to check the tools).
 */
export function forEachProjected(projection: Projection, positions: Float32Array, n: number, visit: (v: number, x: number, y: number, depth: number) => void): void {
  const e = projection.matrix;
  const { width: w, height: h } = projection;
  for (let v = 0; v < n; v++) {
    const x = positions[3 * v], y = positions[3 * v + 1], z = positions[3 * v + 2];
    const iw = 1 / (e[3] * x + e[7] * y + e[11] * z + e[15]);
    const px = (e[0] * x + e[4] * y + e[8] * z + e[12]) * iw;
    const py = (e[1] * x + e[5] * y + e[9] * z + e[13]) * iw;
    const pz = (e[2] * x + e[6] * y + e[10] * z + e[14]) * iw;
    if (pz < -1 || pz > 1) continue;
    visit(v, ((px + 1) / 2) * w, ((1 - py) / 2) * h, (pz + 1) / 2);
  }
}

/** The same for the state's mesh. */
export function forEachOnScreen(viewport: Viewport, mesh: MeshData, visit: (v: number, x: number, y: number, depth: number) => void): void {
  forEachProjected(currentProjection(viewport), mesh.cur, mesh.n, visit);
}

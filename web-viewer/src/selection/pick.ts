// Vertices under the pointer or near a point, for the Vertex and Brush tools.
import * as THREE from "three";
import type { MeshData } from "../state";
import type { Viewport } from "../viewport/viewport";

const raycaster = new THREE.Raycaster();

/** The surface point under the pointer in model coordinates, with its triangle. */
export function pick(viewport: Viewport, object: THREE.Object3D | null, ev: PointerEvent): { point: THREE.Vector3; triangle: number } | null {
  if (!object) return null;
  const r = viewport.canvas.getBoundingClientRect();
  const ndc = new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, viewport.viewCamera);
  const hit = raycaster.intersectObject(object, false)[0];
  if (!hit || hit.faceIndex === undefined || hit.faceIndex === null) return null;
  return { point: viewport.root.worldToLocal(hit.point.clone()), triangle: hit.faceIndex };
}

/**
 * `v` and every other base vertex at exactly its rest position: the copies of a glTF vertex
 * split at a UV seam, which the server welds into one (so they must share a label). Brush
 * and box selections pick all copies by themselves; a vertex click picks one corner.
 */
export function withTwins(mesh: MeshData, v: number): number[] {
  const { rest, n } = mesh;
  const x = rest[3 * v], y = rest[3 * v + 1], z = rest[3 * v + 2];
  const out: number[] = [];
  for (let u = 0; u < n; u++) {
    if (rest[3 * u] === x && rest[3 * u + 1] === y && rest[3 * u + 2] === z) out.push(u);
  }
  return out;
}

export function nearestCorner(mesh: MeshData, point: THREE.Vector3, triangle: number): number {
  const { index, cur } = mesh;
  let best = index[3 * triangle];
  let bestD = Infinity;
  for (let k = 0; k < 3; k++) {
    const v = index[3 * triangle + k];
    const d = (cur[3 * v] - point.x) ** 2 + (cur[3 * v + 1] - point.y) ** 2 + (cur[3 * v + 2] - point.z) ** 2;
    if (d < bestD) {
      bestD = d;
      best = v;
    }
  }
  return best;
}

export function verticesWithin(mesh: MeshData, center: THREE.Vector3, radius: number): number[] {
  const out: number[] = [];
  const { cur, n } = mesh;
  const r2 = radius * radius;
  for (let v = 0; v < n; v++) {
    const d = (cur[3 * v] - center.x) ** 2 + (cur[3 * v + 1] - center.y) ** 2 + (cur[3 * v + 2] - center.z) ** 2;
    if (d <= r2) out.push(v);
  }
  return out;
}

/** Vertices whose rest position lies in the model-space box [min, max]. */
export function verticesInBox(mesh: MeshData, min: number[], max: number[]): number[] {
  const ids: number[] = [];
  for (let v = 0; v < mesh.n; v++) {
    const x = mesh.rest[3 * v], y = mesh.rest[3 * v + 1], z = mesh.rest[3 * v + 2];
    if (x >= min[0] && x <= max[0] && y >= min[1] && y <= max[1] && z >= min[2] && z <= max[2]) ids.push(v);
  }
  return ids;
}

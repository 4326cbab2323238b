// What "everything" is for the camera (Home, Frame all, the default view, a session opening):
// the mesh as it is now — a shared session may already be deformed, its moved part far from the
// rest shape — and the handles' gizmos, which stand at the handles' current poses.
import * as THREE from "three";
import type { SessionState } from "../state";

/**
 * The gizmo's arrows reach about half the framed radius from its centre (TransformControls
 * keeps them a fixed share of the view, which the framing makes ≈ 2.3 radii tall): a cube of
 * that half-size around the active handle keeps its tips on screen too.
 */
const GIZMO_REACH = 0.6;

/** The box of the current positions, every handle's pose and the active gizmo; null: no mesh. */
export function contentBox(state: SessionState): THREE.Box3 | null {
  const mesh = state.mesh;
  if (!mesh) return null;
  const box = new THREE.Box3().setFromArray(mesh.cur);
  for (const h of state.handles) box.expandByPoint(h.position);
  const active = state.handles[state.activeHandle - 1];
  if (active) {
    const reach = (box.getSize(new THREE.Vector3()).length() / 2) * GIZMO_REACH;
    box.union(new THREE.Box3().setFromCenterAndSize(active.position, new THREE.Vector3(2 * reach, 2 * reach, 2 * reach)));
  }
  return box;
}

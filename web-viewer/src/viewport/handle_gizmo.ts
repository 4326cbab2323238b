// The TransformControls gizmo on the active handle: shown in Move mode once constraints are
// applied; its drags become the handle's pose.
import * as THREE from "three";
import type { SessionState } from "../state";
import type { ScreenPoint, Viewport } from "./viewport";

export interface GizmoCallbacks {
  /** The gizmo was grabbed (true) or released (false). */
  dragging(held: boolean): void;
  /** The active handle's pose changed. */
  moved(): void;
}

export class HandleGizmo {
  constructor(private readonly viewport: Viewport, private readonly state: SessionState, callbacks: GizmoCallbacks) {
    const { gizmo, orbit, pivotObject } = viewport;
    state.on("handles", () => this.place());
    gizmo.addEventListener("dragging-changed", (e) => {
      const held = (e as unknown as { value: boolean }).value;
      orbit.enabled = !held;
      callbacks.dragging(held);
    });
    gizmo.addEventListener("objectChange", () => {
      const h = state.activeHandle - 1;
      if (h >= state.handles.length) return;
      state.setHandle(h, {
        position: pivotObject.position.clone(),
        quaternion: pivotObject.quaternion.clone(),
        scale: pivotObject.scale.clone(),
      });
      callbacks.moved();
    });
  }

  setMode(mode: "translate" | "rotate" | "scale"): void {
    this.viewport.gizmo.setMode(mode);
  }

  private place(): void {
    const { gizmo, pivotObject } = this.viewport;
    if (!this.state.canMoveHandle) {
      gizmo.detach();
      this.viewport.requestRender();
      return;
    }
    const s = this.state.handles[this.state.activeHandle - 1];
    pivotObject.position.copy(s.position);
    pivotObject.quaternion.copy(s.quaternion);
    pivotObject.scale.copy(s.scale);
    pivotObject.updateMatrixWorld(true);
    gizmo.attach(pivotObject);
    this.viewport.requestRender();
  }

  /**
   * Client coordinates of the gizmo's centre (the active handle's pivot), or of a point on
   * one of its translate arrows (world axis, 0.6 of the arrow's length, as TransformControls
   * sizes it); null when the gizmo is not shown.
   */
  screenPoint(axis?: "x" | "y" | "z"): ScreenPoint | null {
    const { gizmo, pivotObject, camera } = this.viewport;
    if (!gizmo.object) return null;
    const world = pivotObject.getWorldPosition(new THREE.Vector3());
    if (axis) {
      const factor =
        world.distanceTo(camera.position) * Math.min((1.9 * Math.tan((Math.PI * camera.fov) / 360)) / camera.zoom, 7);
      const length = (factor * gizmo.size) / 4;
      world.add(new THREE.Vector3(axis === "x" ? 1 : 0, axis === "y" ? 1 : 0, axis === "z" ? 1 : 0).multiplyScalar(0.6 * length));
    }
    return this.viewport.toClient(world);
  }
}

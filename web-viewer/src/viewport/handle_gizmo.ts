// The TransformControls gizmo on the active handle: shown in Move mode once constraints are
// applied; its drags become the handle's pose. A drag first takes the handle (GrabHandles,
// through `grab`): refused, it goes back and nothing is sent. Esc or a right click cancels a
// drag: the handle goes back to where the drag began, and that pose is sent, so the server
// agrees. X / Y / Z while dragging keep the drag to that axis.
import * as THREE from "three";
import type { SessionState } from "../state";
import type { HandleState } from "../transforms";
import { snapSteps, type SnapInput } from "./snap";
import type { ScreenPoint, Viewport } from "./viewport";

export type GizmoMode = "translate" | "rotate" | "scale";
export type GizmoSpace = "world" | "local";

export interface GizmoCallbacks {
  /** The gizmo was grabbed (true) or released (false), after the grab was granted. */
  dragging(held: boolean): void;
  /** The active handle's pose changed. */
  moved(): void;
  /** A drag of handle h (0-based) begins: resolves false when it may not (held by someone). */
  grab(h: number): Promise<boolean>;
  /** The drag ended (or was cancelled): give the handle back. */
  release(): void;
}

function copyPose(s: HandleState): HandleState {
  return { position: s.position.clone(), quaternion: s.quaternion.clone(), scale: s.scale.clone() };
}

export class HandleGizmo {
  mode: GizmoMode = "translate";
  space: GizmoSpace = "world";
  /** Snap settings from the panel (the modifier keys come from the pointer events). */
  snap: Omit<SnapInput, "ctrl" | "shift"> = { enabled: false, grid: 0 };
  private start: HandleState | null = null;
  private granted = false;
  private dragHandle = -1;
  private changedWhileWaiting = false;
  private listeners: ((mode: GizmoMode, space: GizmoSpace) => void)[] = [];

  constructor(private readonly viewport: Viewport, private readonly state: SessionState, private readonly callbacks: GizmoCallbacks) {
    const { gizmo, orbit, pivotObject } = viewport;
    state.on("handles", () => this.place());
    gizmo.addEventListener("dragging-changed", (e) => {
      const held = (e as unknown as { value: boolean }).value;
      orbit.enabled = !held;
      if (held) this.begin();
      else this.end();
    });
    gizmo.addEventListener("objectChange", () => {
      const h = state.activeHandle - 1;
      if (h >= state.handles.length) return;
      state.setHandle(h, { position: pivotObject.position.clone(), quaternion: pivotObject.quaternion.clone(), scale: pivotObject.scale.clone() });
      if (this.granted) callbacks.moved();
      else this.changedWhileWaiting = true;
      state.emit("pose", h);
    });
    const canvas = viewport.canvas;
    // A right click cancels a drag (the context menu would otherwise open over the canvas).
    // mousedown, not pointerdown: a second button pressed during a drag is no new pointerdown.
    canvas.addEventListener("mousedown", (ev) => {
      if (ev.button === 2 && gizmo.dragging) this.cancel();
    });
    canvas.addEventListener("contextmenu", (ev) => {
      if (gizmo.dragging || this.start) ev.preventDefault();
    });
    // Ctrl (Shift) snaps while held: read from every pointer event, as the keys may change mid-drag.
    const modifiers = (ev: PointerEvent | KeyboardEvent) => this.applySnap(ev.ctrlKey || ev.metaKey, ev.shiftKey);
    canvas.addEventListener("pointerdown", modifiers, { capture: true });
    canvas.addEventListener("pointermove", modifiers, { capture: true });
    window.addEventListener("keydown", modifiers);
    window.addEventListener("keyup", modifiers);
  }

  get dragging(): boolean {
    return this.viewport.gizmo.dragging;
  }

  onChange(listener: (mode: GizmoMode, space: GizmoSpace) => void): void {
    this.listeners.push(listener);
  }

  setMode(mode: GizmoMode): void {
    this.mode = mode;
    this.viewport.gizmo.setMode(mode);
    this.viewport.requestRender();
    for (const l of this.listeners) l(this.mode, this.space);
  }

  /** World: the model's axes; local: the handle's own (rotated) axes. Scale is always local. */
  setSpace(space: GizmoSpace): void {
    this.space = space;
    this.viewport.gizmo.setSpace(space);
    this.viewport.requestRender();
    for (const l of this.listeners) l(this.mode, this.space);
  }

  applySnap(ctrl: boolean, shift: boolean): void {
    const s = snapSteps({ ctrl, shift, ...this.snap });
    const g = this.viewport.gizmo;
    g.setTranslationSnap(s.translation);
    g.setRotationSnap(s.rotation);
    g.setScaleSnap(s.scale);
  }

  /** While dragging: keep the drag to one axis (X / Y / Z keys). */
  constrain(axis: "X" | "Y" | "Z"): boolean {
    const g = this.viewport.gizmo;
    if (!g.dragging) return false;
    g.axis = axis;
    this.viewport.requestRender();
    return true;
  }

  /** Esc / right click: back to where the drag began, and the drag ends there. */
  cancel(): boolean {
    const g = this.viewport.gizmo;
    if (!g.dragging) return false;
    g.reset(); // the object back to its pose at the drag's start (objectChange: sent)
    g.pointerUp({ button: 0 } as unknown as PointerEvent); // ends the drag: dragging-changed
    return true;
  }

  /** Sets the active handle's pose (typed-in values): grabbed, sent, released. */
  async setPose(pose: HandleState): Promise<boolean> {
    const h = this.state.activeHandle - 1;
    if (h >= this.state.handles.length || !this.state.canMoveHandle) return false;
    if (!(await this.callbacks.grab(h))) return false;
    this.state.setHandle(h, copyPose(pose));
    this.place();
    this.callbacks.moved();
    this.callbacks.release();
    this.state.emit("pose", h);
    return true;
  }

  private begin(): void {
    const h = this.state.activeHandle - 1;
    this.dragHandle = h;
    this.start = this.state.handles[h] ? copyPose(this.state.handles[h]) : null;
    this.granted = false;
    this.changedWhileWaiting = false;
    void this.callbacks.grab(h).then((ok) => {
      if (this.dragHandle !== h || !this.start) return; // this drag already ended
      if (!ok) {
        this.refuse(h);
        return;
      }
      this.granted = true;
      this.callbacks.dragging(true);
      if (this.changedWhileWaiting) this.callbacks.moved();
      if (!this.viewport.gizmo.dragging) this.end(); // released while the grab was asked
    });
  }

  private end(): void {
    if (this.viewport.gizmo.dragging) return;
    const wasGranted = this.granted;
    this.granted = false;
    if (wasGranted) {
      this.callbacks.dragging(false);
      this.callbacks.release();
    }
    if (!wasGranted && this.start && this.dragHandle >= 0) {
      // Released before the grab came back: the grab's answer finishes this drag.
      return;
    }
    this.start = null;
    this.dragHandle = -1;
  }

  /** The grab was refused: the handle goes back, nothing was sent. */
  private refuse(h: number): void {
    const start = this.start;
    this.start = null;
    this.dragHandle = -1;
    const g = this.viewport.gizmo;
    if (g.dragging) g.pointerUp({ button: 0 } as unknown as PointerEvent);
    if (start) this.state.setHandle(h, start);
    this.place();
  }

  /** Puts the gizmo on the active handle (or hides it). */
  place(): void {
    const { gizmo, pivotObject } = this.viewport;
    if (!this.state.canMoveHandle) {
      gizmo.detach();
      this.viewport.requestRender();
      return;
    }
    if (gizmo.dragging) return; // the drag owns the pose
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
   * one of its translate arrows (0.6 of the arrow's length, as TransformControls sizes it;
   * along the handle's own axes in local space); null when the gizmo is not shown.
   */
  screenPoint(axis?: "x" | "y" | "z"): ScreenPoint | null {
    const { gizmo, pivotObject, viewCamera: camera } = this.viewport;
    if (!gizmo.object) return null;
    const world = pivotObject.getWorldPosition(new THREE.Vector3());
    if (axis) {
      const factor = gizmoFactor(camera, world);
      const length = (factor * gizmo.size) / 4;
      const dir = new THREE.Vector3(axis === "x" ? 1 : 0, axis === "y" ? 1 : 0, axis === "z" ? 1 : 0);
      if (this.space === "local" || this.mode === "scale") dir.applyQuaternion(pivotObject.getWorldQuaternion(new THREE.Quaternion()));
      world.add(dir.multiplyScalar(0.6 * length));
    }
    return this.viewport.toClient(world);
  }
}

/** TransformControls' size factor of a gizmo at `world` (three's TransformControlsGizmo). */
export function gizmoFactor(camera: THREE.PerspectiveCamera | THREE.OrthographicCamera, world: THREE.Vector3): number {
  if (camera instanceof THREE.OrthographicCamera) return (camera.top - camera.bottom) / camera.zoom;
  return world.distanceTo(camera.position) * Math.min((1.9 * Math.tan((Math.PI * camera.fov) / 360)) / camera.zoom, 7);
}

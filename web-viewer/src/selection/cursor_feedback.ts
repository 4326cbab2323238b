// What the pointer would select, before it does: in Brush mode a ring of the brush's radius
// lying on the surface under the cursor; in Vertex mode a dot on the vertex a click would take.
// One raycast per animation frame at most (the pointer can move faster than that).
import * as THREE from "three";
import type { SessionState } from "../state";
import type { MeshDisplay } from "../viewport/mesh_display";
import type { Viewport } from "../viewport/viewport";
import { nearestCorner, pick } from "./pick";

export class CursorFeedback {
  readonly ring: THREE.Mesh;
  readonly dot: THREE.Mesh;
  /** The vertex the dot marks (-1: none). */
  hoverVertex = -1;
  private pending: PointerEvent | null = null;

  constructor(private readonly viewport: Viewport, private readonly display: MeshDisplay, private readonly state: SessionState, private readonly brushRadius: () => number) {
    const overlay = (color: number) => new THREE.MeshBasicMaterial({ color, side: THREE.DoubleSide, depthTest: false, transparent: true, opacity: 0.9 });
    this.ring = new THREE.Mesh(new THREE.RingGeometry(0.9, 1, 64), overlay(0x4fc3f7));
    this.dot = new THREE.Mesh(new THREE.SphereGeometry(1, 12, 8), overlay(0xffffff));
    for (const m of [this.ring, this.dot]) {
      m.visible = false;
      m.renderOrder = 10; // drawn over the mesh
      viewport.root.add(m);
    }
    const canvas = viewport.canvas;
    canvas.addEventListener("pointermove", (ev) => {
      if (!this.pending) requestAnimationFrame(() => this.update());
      this.pending = ev;
    });
    canvas.addEventListener("pointerleave", () => this.hide());
    state.on("mode", () => this.hide());
  }

  private hide(): void {
    this.pending = null;
    this.hoverVertex = -1;
    if (this.ring.visible || this.dot.visible) this.viewport.requestRender();
    this.ring.visible = false;
    this.dot.visible = false;
  }

  private update(): void {
    const ev = this.pending;
    this.pending = null;
    const { state } = this;
    const mesh = state.mesh;
    if (!ev || !mesh || state.watchOnly || (state.mode !== "brush" && state.mode !== "vertex")) return this.hide();
    const hit = pick(this.viewport, this.display.object, ev);
    if (!hit) return this.hide();
    if (state.mode === "brush") {
      // Lie on the triangle under the cursor.
      const { index, cur } = mesh;
      const a = new THREE.Vector3().fromArray(cur, 3 * index[3 * hit.triangle]);
      const b = new THREE.Vector3().fromArray(cur, 3 * index[3 * hit.triangle + 1]);
      const c = new THREE.Vector3().fromArray(cur, 3 * index[3 * hit.triangle + 2]);
      const n = b.sub(a).cross(c.sub(a)).normalize();
      this.ring.position.copy(hit.point);
      this.ring.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), n);
      this.ring.scale.setScalar(this.brushRadius());
      this.ring.visible = true;
      this.dot.visible = false;
      this.hoverVertex = -1;
    } else {
      const v = nearestCorner(mesh, hit.point, hit.triangle);
      this.hoverVertex = v;
      this.dot.position.fromArray(mesh.cur, 3 * v);
      this.dot.scale.setScalar(mesh.diag * 0.006);
      this.dot.visible = true;
      this.ring.visible = false;
    }
    this.viewport.requestRender();
  }
}

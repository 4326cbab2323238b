// The axes view helper in the top right corner of the canvas (three's ViewHelper, as in the
// three.js editor; Blender's navigation gizmo): it turns with the camera, and a click on an
// axis end moves the camera to that end, looking at the orbit target (view_snap.ts).
//
// ViewHelper's own click handling is not used: it animates the camera's quaternion for a
// y-up camera, which rolls a z-up model (camera.up = +z) on its side and leaves OrbitControls'
// state behind. Only its drawing is; the click is hit-tested here against its sprites, with
// the same orthographic camera it draws them with.
import * as THREE from "three";
import { ViewHelper } from "three/examples/jsm/helpers/ViewHelper.js";
import type { AxisEnd } from "./view_axes";
import { axisEndDirection } from "./view_axes";
import type { ViewSnap } from "./view_snap";
import type { Viewport } from "./viewport";

/** ViewHelper's square (px) and its camera's half-size (fixed in three's code). */
const DIM = 128;
const HALF = 2;
/** Distance from the canvas's top right corner (px): clear of the top bar's banner edge. */
const MARGIN = 8;

export class AxesViewHelper {
  readonly helper: ViewHelper;
  private readonly ortho = new THREE.OrthographicCamera(-HALF, HALF, HALF, -HALF, 0, 4);
  private readonly raycaster = new THREE.Raycaster();

  constructor(private readonly viewport: Viewport, private readonly snap: ViewSnap) {
    this.helper = new ViewHelper(viewport.camera, viewport.canvas);
    this.helper.location = { top: MARGIN, right: MARGIN, bottom: 0, left: null };
    this.helper.setLabels("X", "Y", "Z");
    this.ortho.position.set(0, 0, 2);
    this.ortho.updateMatrixWorld();
    viewport.overlays.push((renderer) => {
      // Over the scene: the helper clears only the depth buffer, not the picture under it.
      renderer.autoClear = false;
      this.helper.render(renderer);
      renderer.autoClear = true;
    });
    // Capture phase: ahead of OrbitControls and the selection tools, so a click on an axis end
    // neither orbits nor starts a box.
    viewport.canvas.addEventListener(
      "pointerdown",
      (ev) => {
        if (ev.button !== 0) return;
        const end = this.endAt(ev.clientX, ev.clientY);
        if (!end) return;
        ev.stopImmediatePropagation();
        ev.preventDefault();
        this.snap.lookFrom(axisEndDirection(end));
      },
      { capture: true },
    );
  }

  /** The helper's square in client coordinates. */
  private square(): DOMRect {
    const r = this.viewport.canvas.getBoundingClientRect();
    return new DOMRect(r.left + this.viewport.canvas.offsetWidth - DIM - MARGIN, r.top + MARGIN, DIM, DIM);
  }

  /** The helper turned as the camera is now (render does the same). */
  private orient(): void {
    this.helper.quaternion.copy(this.viewport.camera.quaternion).invert();
    this.helper.updateMatrixWorld();
  }

  /** The axis end under client (x, y), or null. */
  endAt(x: number, y: number): AxisEnd | null {
    const sq = this.square();
    if (x < sq.left || x > sq.right || y < sq.top || y > sq.bottom) return null;
    this.orient();
    const ndc = new THREE.Vector2(((x - sq.left) / DIM) * 2 - 1, -((y - sq.top) / DIM) * 2 + 1);
    this.raycaster.setFromCamera(ndc, this.ortho);
    const ends = this.helper.children.filter((c) => c instanceof THREE.Sprite && typeof c.userData.type === "string");
    const hit = this.raycaster.intersectObjects(ends, false)[0];
    return hit ? (hit.object.userData.type as AxisEnd) : null;
  }

  /** Client coordinates of an axis end's centre (for the browser tests). */
  endPoint(end: AxisEnd): { x: number; y: number } {
    this.orient();
    const sprite = this.helper.children.find((c) => c.userData.type === end);
    const p = (sprite ? sprite.getWorldPosition(new THREE.Vector3()) : new THREE.Vector3()).project(this.ortho);
    const sq = this.square();
    return { x: sq.left + ((p.x + 1) / 2) * DIM, y: sq.top + ((1 - p.y) / 2) * DIM };
  }
}

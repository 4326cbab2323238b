// The region tools on the canvas: Vertex (click), Brush (drag with a radius), Box (screen
// rectangle), Lasso (a drawn outline). In selection modes the left button selects; the right
// orbits, the middle pans. As in Blender: a drag (or Shift+drag) adds to the region "Assign to"
// names, Ctrl+drag (⌘ on macOS) removes from it — only that region's vertices, the other
// regions are left alone. Box and Lasso take only the vertices the camera sees unless X-ray is
// on (visibility.ts: one depth pass per gesture).
import * as THREE from "three";
import { $ } from "../dom";
import type { Mode, SessionState } from "../state";
import type { MeshDisplay } from "../viewport/mesh_display";
import type { Viewport } from "../viewport/viewport";
import { drawBox, drawLasso, hideGesture } from "./gesture_overlay";
import { LASSO_STEP_PX, verticesInPolygon } from "./lasso";
import { nearestCorner, pick, verticesWithin, withTwins } from "./pick";
import { verticesInScreenRect, type Point, type VertexFilter } from "./screen_rect";
import { DepthProbe, visibleFilter } from "./visibility";
import { XrayToggle } from "./xray";

/** Visible-only: how far (× the model's diagonal) behind the surface a vertex still counts as on it. */
const VISIBLE_TOLERANCE = 0.005;

export const SELECTING_MODES: readonly Mode[] = ["vertex", "brush", "box", "lasso"];

export class SelectionTools {
  private brushing = false;
  private boxStart: Point | null = null;
  private lasso: Point[] | null = null;
  /** The gesture removes from the region (Ctrl / ⌘ held when it began) rather than adding. */
  private subtract = false;
  readonly xray = new XrayToggle();
  private readonly depth: DepthProbe;
  /** The last Lasso gesture's outline (viewport pixels), for the browser tests. */
  lastLasso: Point[] = [];

  constructor(private readonly viewport: Viewport, private readonly display: MeshDisplay, private readonly state: SessionState) {
    this.depth = new DepthProbe(viewport, display);
    state.on("mode", (mode) => this.modeChanged(mode));
    const canvas = viewport.canvas;
    canvas.addEventListener("pointerdown", (ev) => this.down(ev));
    canvas.addEventListener("pointermove", (ev) => this.move(ev));
    canvas.addEventListener("pointerup", (ev) => this.up(ev));
  }

  /** The depth pass's time (ms) of the last visible-only gesture. */
  get depthMs(): number {
    return this.depth.lastMs;
  }

  /**
   * Which projected vertices a Box or Lasso gesture may take: all (X-ray) or the visible ones.
   * The depth pass runs at the first candidate vertex, so a click or an empty outline costs none.
   */
  private filter(): VertexFilter | undefined {
    const mesh = this.state.mesh;
    if (this.xray.enabled || !mesh) return undefined;
    let visible: VertexFilter | null = null;
    return (x, y, depth) => {
      if (!visible) {
        const img = this.depth.capture();
        visible = img ? visibleFilter(img, VISIBLE_TOLERANCE * mesh.diag) : () => true;
      }
      return visible(x, y, depth);
    };
  }

  /** Assigns the vertices in the screen rectangle a–b (viewport pixels) to `label` (subtract: takes them out of it). */
  selectScreenRect(a: Point, b: Point, label: number, subtract = false): number {
    const mesh = this.state.mesh;
    return mesh ? this.apply(verticesInScreenRect(this.viewport, mesh, a, b, this.filter()), label, subtract) : 0;
  }

  /** The same for the closed polygon `poly` (viewport pixels). */
  selectPolygon(poly: Point[], label: number, subtract = false): number {
    const mesh = this.state.mesh;
    this.lastLasso = poly.map((p) => ({ ...p }));
    return mesh ? this.apply(verticesInPolygon(this.viewport, mesh, poly, this.filter()), label, subtract) : 0;
  }

  /** `ids` into region `label`, or (subtract) those of them in it out of it; how many changed. */
  private apply(ids: Iterable<number>, label: number, subtract: boolean): number {
    const mesh = this.state.mesh;
    if (!mesh) return 0;
    if (!subtract) return this.state.assign(ids, label);
    const out: number[] = [];
    for (const id of ids) if (mesh.labels[id] === label && label >= 0) out.push(id);
    return this.state.assign(out, -1);
  }

  private modeChanged(mode: Mode): void {
    const selecting = SELECTING_MODES.includes(mode);
    this.viewport.orbit.mouseButtons = selecting
      ? { LEFT: null as unknown as THREE.MOUSE, MIDDLE: THREE.MOUSE.PAN, RIGHT: THREE.MOUSE.ROTATE }
      : { LEFT: THREE.MOUSE.ROTATE, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: THREE.MOUSE.PAN };
    this.viewport.canvas.style.cursor = selecting ? "crosshair" : "";
    document.body.classList.toggle("selecting", selecting); // the Select row shows (style.css)
  }

  brushRadius(): number {
    return (Number($<HTMLInputElement>("brush-radius").value) / 100) * (this.state.mesh?.diag ?? 1);
  }

  private brush(ev: PointerEvent): void {
    const mesh = this.state.mesh;
    if (!mesh) return;
    const hit = pick(this.viewport, this.display.object, ev);
    if (hit) this.apply(verticesWithin(mesh, hit.point, this.brushRadius()), this.state.currentLabel, this.subtract);
  }

  private local(ev: PointerEvent): Point {
    const r = this.viewport.element.getBoundingClientRect();
    return { x: ev.clientX - r.left, y: ev.clientY - r.top };
  }

  private down(ev: PointerEvent): void {
    const { state } = this;
    const mesh = state.mesh;
    if (ev.button !== 0 || !mesh || state.watchOnly) return;
    const canvas = this.viewport.canvas;
    this.subtract = ev.ctrlKey || ev.metaKey;
    if (state.mode === "vertex") {
      const hit = pick(this.viewport, this.display.object, ev);
      if (hit) this.apply(withTwins(mesh, nearestCorner(mesh, hit.point, hit.triangle)), state.currentLabel, this.subtract);
    } else if (state.mode === "brush") {
      this.brushing = true;
      canvas.setPointerCapture(ev.pointerId);
      this.brush(ev);
    } else if (state.mode === "box") {
      this.boxStart = this.local(ev);
      canvas.setPointerCapture(ev.pointerId);
      drawBox(this.boxStart, this.boxStart);
    } else if (state.mode === "lasso") {
      this.lasso = [this.local(ev)];
      canvas.setPointerCapture(ev.pointerId);
      drawLasso(this.lasso);
    }
  }

  private move(ev: PointerEvent): void {
    if (this.brushing && this.state.mode === "brush") this.brush(ev);
    else if (this.boxStart) drawBox(this.boxStart, this.local(ev));
    else if (this.lasso) {
      const p = this.local(ev);
      const last = this.lasso[this.lasso.length - 1];
      if (Math.hypot(p.x - last.x, p.y - last.y) < LASSO_STEP_PX) return;
      this.lasso.push(p);
      drawLasso(this.lasso);
    }
  }

  private up(ev: PointerEvent): void {
    this.brushing = false;
    if (this.boxStart) {
      this.selectScreenRect(this.boxStart, this.local(ev), this.state.currentLabel, this.subtract);
      this.boxStart = null;
    } else if (this.lasso) {
      const poly = this.lasso;
      this.lasso = null;
      const p = this.local(ev);
      const last = poly[poly.length - 1];
      if (p.x !== last.x || p.y !== last.y) poly.push(p);
      this.selectPolygon(poly, this.state.currentLabel, this.subtract);
    }
    hideGesture();
  }
}

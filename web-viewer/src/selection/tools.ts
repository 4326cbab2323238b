// The region tools on the canvas: Vertex (click), Brush (drag with a radius), Box (screen
// rectangle). In selection modes the left button selects; the right orbits, the middle pans.
// As in Blender: a drag (or Shift+drag) adds to the region "Assign to" names, Ctrl+drag (⌘ on
// macOS) removes from it — only that region's vertices, the other regions are left alone.
import * as THREE from "three";
import { $ } from "../dom";
import type { Mode, SessionState } from "../state";
import type { MeshDisplay } from "../viewport/mesh_display";
import type { Viewport } from "../viewport/viewport";
import { nearestCorner, pick, verticesWithin, withTwins } from "./pick";
import { verticesInScreenRect, type Point } from "./screen_rect";

export class SelectionTools {
  private brushing = false;
  private boxStart: Point | null = null;
  /** The gesture removes from the region (Ctrl / ⌘ held when it began) rather than adding. */
  private subtract = false;

  constructor(private readonly viewport: Viewport, private readonly display: MeshDisplay, private readonly state: SessionState) {
    state.on("mode", (mode) => this.modeChanged(mode));
    const canvas = viewport.canvas;
    canvas.addEventListener("pointerdown", (ev) => this.down(ev));
    canvas.addEventListener("pointermove", (ev) => this.move(ev));
    canvas.addEventListener("pointerup", (ev) => this.up(ev));
  }

  /** Assigns the vertices in the screen rectangle a–b (viewport pixels) to `label` (subtract: takes them out of it). */
  selectScreenRect(a: Point, b: Point, label: number, subtract = false): number {
    const mesh = this.state.mesh;
    return mesh ? this.apply(verticesInScreenRect(this.viewport, mesh, a, b), label, subtract) : 0;
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
    const selecting = mode === "vertex" || mode === "brush" || mode === "box";
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
      this.drawBox(this.boxStart);
    }
  }

  private move(ev: PointerEvent): void {
    if (this.brushing && this.state.mode === "brush") this.brush(ev);
    else if (this.boxStart) this.drawBox(this.local(ev));
  }

  private up(ev: PointerEvent): void {
    this.brushing = false;
    if (this.boxStart) {
      this.selectScreenRect(this.boxStart, this.local(ev), this.state.currentLabel, this.subtract);
      this.boxStart = null;
      $("boxsel").classList.add("hidden");
    }
  }

  private drawBox(to: Point): void {
    const from = this.boxStart;
    if (!from) return;
    const el = $("boxsel");
    el.classList.remove("hidden");
    el.style.left = `${Math.min(from.x, to.x)}px`;
    el.style.top = `${Math.min(from.y, to.y)}px`;
    el.style.width = `${Math.abs(to.x - from.x)}px`;
    el.style.height = `${Math.abs(to.y - from.y)}px`;
  }
}

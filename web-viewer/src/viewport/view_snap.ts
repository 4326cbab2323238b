// Turns the camera to look along a given direction around the orbit target, keeping its
// distance: the keypad views and the axes view helper's clicks. Animated (a short turn shows
// where the view came from, as in Blender), ending exactly on the direction.
import * as THREE from "three";
import { orbitSafeDirection, type Vec3 } from "./view_axes";
import type { Viewport } from "./viewport";

const DURATION_MS = 220;

export class ViewSnap {
  private from = new THREE.Vector3();
  private to = new THREE.Vector3();
  private start = 0;
  private frame = 0;

  constructor(private readonly viewport: Viewport) {}

  /** A turn is under way. */
  get animating(): boolean {
    return this.frame !== 0;
  }

  /** Turns to `dir` (target → camera, model = world coordinates). */
  lookFrom(dir: Vec3): void {
    const { camera, orbit } = this.viewport;
    this.from.copy(camera.position).sub(orbit.target).normalize();
    this.to.fromArray(orbitSafeDirection(dir, this.viewport.upAxis));
    this.start = performance.now();
    if (!this.frame) this.frame = requestAnimationFrame((t) => this.step(t));
  }

  private step(now: number): void {
    const t = Math.min(1, (now - this.start) / DURATION_MS);
    const s = t * t * (3 - 2 * t); // smoothstep: no jolt at either end
    // Slerp of the unit directions (about their common normal; opposite ones turn about any axis).
    const q = new THREE.Quaternion().setFromUnitVectors(this.from, this.to);
    const dir = this.from.clone().applyQuaternion(new THREE.Quaternion().slerp(q, s));
    if (t >= 1) dir.copy(this.to);
    this.place(dir);
    this.frame = t < 1 ? requestAnimationFrame((n) => this.step(n)) : 0;
  }

  private place(dir: THREE.Vector3): void {
    const { camera, orbit } = this.viewport;
    const dist = camera.position.distanceTo(orbit.target);
    camera.position.copy(orbit.target).addScaledVector(dir, dist);
    orbit.update(); // looks at the target with the model's up (and tells the viewport to render)
    this.viewport.requestRender();
  }
}

// The ground grid (Blender's floor, the three.js editor's grid): lines in the plane under the
// model's rest shape, across its up axis (+z or +y, as viewport.ts shows it), centred below it.
// The step is a round number (1, 2 or 5 × 10^k) near a tenth of the model's footprint, so the
// squares say something about its size. On by default; the Grid button (Display heading) hides it.
import * as THREE from "three";
import type { SessionState } from "../state";
import type { Viewport } from "./viewport";

/** A round step (1, 2 or 5 × 10^k) at most `x`. */
export function roundStep(x: number): number {
  if (!(x > 0) || !Number.isFinite(x)) return 1;
  const p = 10 ** Math.floor(Math.log10(x));
  const m = x / p;
  return (m >= 5 ? 5 : m >= 2 ? 2 : 1) * p;
}

export class GroundGrid {
  private grid: THREE.GridHelper | null = null;
  private shown = true;

  constructor(private readonly viewport: Viewport, state: SessionState) {
    // After MeshDisplay's "mesh" listener (main.ts builds it first), which sets the up axis.
    state.on("mesh", (mesh) => this.build(new THREE.Box3().setFromArray(mesh.rest)));
  }

  get visible(): boolean {
    return this.shown;
  }

  /** The plane's normal (the model's up), or null before a mesh. */
  get normal(): number[] | null {
    return this.grid ? new THREE.Vector3(0, 1, 0).applyQuaternion(this.grid.quaternion).toArray().map((v) => Math.round(v * 1e6) / 1e6) : null;
  }

  setVisible(on: boolean): void {
    this.shown = on;
    if (this.grid) this.grid.visible = on;
    this.viewport.requestRender();
  }

  private build(box: THREE.Box3): void {
    if (this.grid) {
      this.viewport.root.remove(this.grid);
      this.grid.dispose();
    }
    const zUp = this.viewport.upAxis === "z";
    const size = box.getSize(new THREE.Vector3());
    const footprint = Math.max(size.x, zUp ? size.y : size.z, 1e-9);
    const step = roundStep(footprint / 5);
    const divisions = 2 * Math.ceil((0.75 * footprint) / step); // even (a line through the centre), 1.5× the footprint or more
    const grid = new THREE.GridHelper(divisions * step, divisions, 0x5a606a, 0x3c4048);
    const material = grid.material as THREE.LineBasicMaterial;
    material.transparent = true;
    material.opacity = 0.8;
    const centre = box.getCenter(new THREE.Vector3());
    const below = 1e-3 * size.length(); // a flat bottom's faces and the lines would z-fight
    if (zUp) {
      grid.rotation.x = Math.PI / 2; // GridHelper lies in xz (normal +y): stand it in xy
      grid.position.set(centre.x, centre.y, box.min.z - below);
    } else grid.position.set(centre.x, box.min.y - below, centre.z);
    grid.visible = this.shown;
    grid.renderOrder = -1; // under the mesh's transparent overlays
    this.grid = grid;
    this.viewport.root.add(grid);
    this.viewport.requestRender();
  }
}

// Regions of a few vertices (a single-vertex handle, the benchmark's usual kind) are all but
// invisible as vertex colours: each of their vertices also gets a sphere in the region's
// colour, drawn over the mesh, following the shape.
import * as THREE from "three";
import { regionColour } from "../region_colours";
import type { SessionState } from "../state";
import type { Viewport } from "./viewport";

/** Regions with at most this many vertices get markers. */
export const MARKED_REGION_MAX = 4;

export class RegionMarkers {
  private readonly group = new THREE.Group();
  private readonly geometry = new THREE.SphereGeometry(1, 16, 12);
  private marked: { v: number; mesh: THREE.Mesh }[] = [];

  constructor(private readonly viewport: Viewport, private readonly state: SessionState) {
    viewport.root.add(this.group);
    state.on("colours", () => this.rebuild());
    state.on("labels", () => this.rebuild());
    state.on("shape", () => this.follow());
  }

  /** How many vertices are drawn as markers. */
  get count(): number {
    return this.marked.length;
  }

  private rebuild(): void {
    for (const { mesh } of this.marked) (mesh.material as THREE.Material).dispose();
    this.group.clear();
    this.marked = [];
    const mesh = this.state.mesh;
    if (!mesh) return;
    const members = new Map<number, number[]>();
    for (let v = 0; v < mesh.n; v++) {
      const l = mesh.labels[v];
      if (l < 0) continue;
      const list = members.get(l) ?? [];
      if (list.length <= MARKED_REGION_MAX) list.push(v);
      members.set(l, list);
    }
    for (const [label, vs] of members) {
      if (vs.length > MARKED_REGION_MAX) continue;
      const held = label > 0 ? this.state.heldColours.get(label) : undefined;
      const material = new THREE.MeshBasicMaterial({ color: held ? new THREE.Color(held) : regionColour(label), depthTest: false });
      for (const v of vs) {
        const m = new THREE.Mesh(this.geometry, material);
        m.renderOrder = 9;
        m.scale.setScalar(mesh.diag * 0.008);
        this.group.add(m);
        this.marked.push({ v, mesh: m });
      }
    }
    this.follow();
  }

  private follow(): void {
    const mesh = this.state.mesh;
    if (!mesh) return;
    for (const { v, mesh: m } of this.marked) m.position.fromArray(mesh.cur, 3 * v);
    this.viewport.requestRender();
  }
}

// The mesh on screen. Indexed (the base GLB's triangles over its vertices: each vertex once)
// while the energy map is off; while it is on, split into three corners per triangle so that
// per-triangle energy colours are exact (a shared vertex cannot carry its triangles' different
// colours), and back to indexed when it goes off. The state's per-vertex arrays are copied
// (indexed) or expanded through the index (split) on every change. The handle-weight preview
// (per vertex, exclusive with the energy map) colours every vertex, regions included.
import * as THREE from "three";
import { ramp, rampPosition } from "../colormap";
import { regionColour } from "../region_colours";
import { energyTop } from "../energy_scale";
import { weightRamp } from "../weights/weight_ramp";
import type { MeshData, SessionState } from "../state";
import type { Viewport } from "./viewport";

const BASE_COLOUR = new THREE.Color(0xc9c4ba);

export class MeshDisplay {
  object: THREE.Mesh | null = null;
  private wire: THREE.Mesh | null = null;
  private geometry: THREE.BufferGeometry | null = null;
  /** Three corners per triangle (energy map on) rather than indexed. */
  private split = false;
  private wireframe = false;
  /** Play shows the animation in its place (timeline/animation_player.ts). */
  private hidden = false;
  private readonly material = new THREE.MeshStandardMaterial({
    vertexColors: true,
    side: THREE.DoubleSide,
    roughness: 0.75,
    metalness: 0.0,
    polygonOffset: true,
    polygonOffsetFactor: 1,
    polygonOffsetUnits: 1,
  });
  private readonly wireMaterial = new THREE.MeshBasicMaterial({ color: 0x000000, wireframe: true, transparent: true, opacity: 0.25 });

  constructor(private readonly viewport: Viewport, private readonly state: SessionState) {
    state.on("mesh", (mesh) => {
      this.build(mesh);
      this.viewport.fitCamera(new THREE.Box3().setFromArray(mesh.rest));
    });
    state.on("shape", () => this.updatePositions());
    state.on("colours", () => {
      const mesh = this.state.mesh;
      if (mesh && this.split !== (energyTop(this.state) !== null)) this.build(mesh);
      else this.updateColours();
    });
  }

  /** The colours drawn (per vertex when indexed, per corner when split), for the test hook. */
  colours(): Float32Array {
    return (this.geometry?.getAttribute("color").array as Float32Array | undefined) ?? new Float32Array(0);
  }

  /** Vertices the GPU is given per draw (split: 3 per triangle; indexed: the mesh's). */
  get vertexCount(): number {
    return this.geometry?.getAttribute("position").count ?? 0;
  }

  setWireframe(on: boolean): void {
    this.wireframe = on;
    if (this.wire) this.wire.visible = on && !this.hidden;
    this.viewport.requestRender();
  }

  setHidden(hidden: boolean): void {
    this.hidden = hidden;
    if (this.object) this.object.visible = !hidden;
    if (this.wire) this.wire.visible = this.wireframe && !hidden;
    this.viewport.requestRender();
  }

  private build(mesh: MeshData): void {
    const root = this.viewport.root;
    if (this.object && this.wire && this.geometry) {
      root.remove(this.object, this.wire);
      this.geometry.dispose();
    }
    this.split = energyTop(this.state) !== null;
    const count = this.split ? 3 * mesh.m : mesh.n;
    const geometry = new THREE.BufferGeometry();
    // Indexed, the display draws the state's own arrays (no copy per frame: a 100K frame is 2.4 MB
    // of positions and normals); split, its own per-corner ones.
    geometry.setAttribute("position", new THREE.BufferAttribute(this.split ? new Float32Array(3 * count) : mesh.cur, 3));
    geometry.setAttribute("normal", new THREE.BufferAttribute(this.split ? new Float32Array(3 * count) : mesh.normals, 3));
    geometry.setAttribute("color", new THREE.BufferAttribute(new Float32Array(3 * count), 3));
    if (!this.split) geometry.setIndex(new THREE.BufferAttribute(mesh.index, 1));
    this.geometry = geometry;
    this.object = new THREE.Mesh(geometry, this.material);
    this.wire = new THREE.Mesh(geometry, this.wireMaterial);
    this.wire.visible = this.wireframe && !this.hidden;
    this.object.visible = !this.hidden;
    root.add(this.object, this.wire);
    this.updatePositions();
    this.updateColours();
  }

  private updatePositions(): void {
    const mesh = this.state.mesh;
    if (!mesh || !this.geometry) return;
    const pos = this.geometry.getAttribute("position") as THREE.BufferAttribute;
    const nor = this.geometry.getAttribute("normal") as THREE.BufferAttribute;
    const P = pos.array as Float32Array;
    const N = nor.array as Float32Array;
    const { index, cur, normals } = mesh;
    if (!this.split) {
      if (P !== cur) P.set(cur);
      if (N !== normals) N.set(normals);
    } else {
      for (let c = 0; c < index.length; c++) {
        const v = index[c] * 3;
        const o = c * 3;
        P[o] = cur[v];
        P[o + 1] = cur[v + 1];
        P[o + 2] = cur[v + 2];
        N[o] = normals[v];
        N[o + 1] = normals[v + 1];
        N[o + 2] = normals[v + 2];
      }
    }
    pos.needsUpdate = true;
    nor.needsUpdate = true;
    // Bounds for culling and picking in one pass (three's computeBoundingSphere makes two more):
    // the box, and the sphere around it (a little larger than the tightest; that is all culling needs).
    let x0 = Infinity, y0 = Infinity, z0 = Infinity, x1 = -Infinity, y1 = -Infinity, z1 = -Infinity;
    for (let i = 0; i < P.length; i += 3) {
      const x = P[i], y = P[i + 1], z = P[i + 2];
      if (x < x0) x0 = x;
      if (x > x1) x1 = x;
      if (y < y0) y0 = y;
      if (y > y1) y1 = y;
      if (z < z0) z0 = z;
      if (z > z1) z1 = z;
    }
    const box = (this.geometry.boundingBox ??= new THREE.Box3());
    box.min.set(x0, y0, z0);
    box.max.set(x1, y1, z1);
    const sphere = (this.geometry.boundingSphere ??= new THREE.Sphere());
    box.getCenter(sphere.center);
    sphere.radius = 0.5 * Math.hypot(x1 - x0, y1 - y0, z1 - z0);
    this.viewport.requestRender();
  }

  private updateColours(): void {
    const mesh = this.state.mesh;
    if (!mesh || !this.geometry) return;
    const col = this.geometry.getAttribute("color") as THREE.BufferAttribute;
    const C = col.array as Float32Array;
    const { index, labels, energies } = mesh;
    const top = energyTop(this.state);
    const weights = this.split ? null : this.state.shownWeights;
    if (weights) {
      for (let v = 0; v < mesh.n; v++) weightRamp(weights[v], C, 3 * v);
      col.needsUpdate = true;
      this.viewport.requestRender();
      return;
    }
    // Indexed: one colour per vertex; split: one per corner (vertex index[c], triangle c / 3).
    const corners = this.split ? index.length : mesh.n;
    for (let c = 0; c < corners; c++) {
      const o = c * 3;
      const label = labels[this.split ? index[c] : c];
      if (label >= 0) {
        // A handle another editor is moving shows in that editor's colour.
        const held = label > 0 ? this.state.heldColours.get(label) : undefined;
        const k = held ? new THREE.Color(held) : regionColour(label);
        C[o] = k.r;
        C[o + 1] = k.g;
        C[o + 2] = k.b;
      } else if (this.split && top !== null) {
        ramp(rampPosition(energies![(c / 3) | 0], top), C, o);
      } else {
        C[o] = BASE_COLOUR.r;
        C[o + 1] = BASE_COLOUR.g;
        C[o + 2] = BASE_COLOUR.b;
      }
    }
    col.needsUpdate = true;
    this.viewport.requestRender();
  }
}

// A coloured outline around each handle another editor holds, in that editor's colour, drawn
// over the region colours (and over the weight preview, which hides them). Fat lines
// (LineSegments2: WebGL draws plain lines 1 px wide) along the region's boundary edges,
// rebuilt only when who holds what or the regions change, and moved with the shape.
import * as THREE from "three";
import { LineMaterial } from "three/examples/jsm/lines/LineMaterial.js";
import { LineSegments2 } from "three/examples/jsm/lines/LineSegments2.js";
import { LineSegmentsGeometry } from "three/examples/jsm/lines/LineSegmentsGeometry.js";
import type { MeshData, SessionState } from "../state";
import { regionBoundaryEdges, weldByPosition } from "./region_boundary";
import type { Viewport } from "./viewport";

const WIDTH_PX = 3;

interface Outline {
  label: number;
  colour: string;
  edges: number[]; // vertex pairs
  line: LineSegments2;
  points: Float32Array; // 6 per edge
}

export class HeldOutline {
  private readonly group = new THREE.Group();
  private outlines: Outline[] = [];
  private signature = "";
  private weld: { mesh: MeshData; ids: Uint32Array } | null = null;

  constructor(private readonly viewport: Viewport, private readonly state: SessionState) {
    viewport.root.add(this.group);
    state.on("colours", () => this.rebuild(false)); // presence changes come as colours
    state.on("labels", () => this.rebuild(true));
    state.on("mesh", () => this.rebuild(true));
    state.on("shape", () => this.follow());
  }

  /** What is outlined: handle label, colour, boundary edge count (for the test hook). */
  summary(): { label: number; colour: string; edges: number }[] {
    return this.outlines.map((o) => ({ label: o.label, colour: o.colour, edges: o.edges.length / 2 }));
  }

  private rebuild(regionsChanged: boolean): void {
    const mesh = this.state.mesh;
    const held = [...this.state.heldColours].sort(([a], [b]) => a - b);
    const signature = JSON.stringify(held);
    // "colours" comes with every energy frame: rebuild only when the holders changed.
    if (!regionsChanged && signature === this.signature) return;
    this.signature = signature;
    for (const o of this.outlines) {
      o.line.geometry.dispose();
      o.line.material.dispose();
    }
    this.group.clear();
    this.outlines = [];
    if (!mesh || held.length === 0) {
      this.viewport.requestRender();
      return;
    }
    if (this.weld?.mesh !== mesh) this.weld = { mesh, ids: weldByPosition(mesh.rest) };
    for (const [label, colour] of held) {
      const edges = regionBoundaryEdges(mesh.index, mesh.labels, label, this.weld.ids);
      if (edges.length === 0) continue; // a region of lone vertices: its markers show the colour
      const points = new Float32Array(3 * edges.length);
      const geometry = new LineSegmentsGeometry();
      geometry.setPositions(points);
      const material = new LineMaterial({ color: new THREE.Color(colour).getHex(), linewidth: WIDTH_PX });
      const line = new LineSegments2(geometry, material);
      line.frustumCulled = false; // its bounds are not kept up to date while the shape moves
      line.renderOrder = 5;
      this.group.add(line);
      this.outlines.push({ label, colour, edges, line, points });
    }
    this.follow();
  }

  private follow(): void {
    const mesh = this.state.mesh;
    if (!mesh || this.outlines.length === 0) return;
    for (const o of this.outlines) {
      const { edges, points } = o;
      for (let i = 0; i < edges.length; i++) {
        const v = 3 * edges[i];
        points[3 * i] = mesh.cur[v];
        points[3 * i + 1] = mesh.cur[v + 1];
        points[3 * i + 2] = mesh.cur[v + 2];
      }
      // In place: setPositions would allocate new buffers on every frame of a drag.
      const start = o.line.geometry.getAttribute("instanceStart") as THREE.InterleavedBufferAttribute;
      (start.data.array as Float32Array).set(points);
      start.data.needsUpdate = true;
    }
    this.viewport.requestRender();
  }
}

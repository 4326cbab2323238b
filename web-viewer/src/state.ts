// The page's session state: one object that the panels, the viewport and the selection
// tools read, changed through its methods, which announce every change as a typed event.
import type * as THREE from "three";
import { Emitter } from "./events";
import { BetaUnits, type Measures, type Session } from "./gen/hdeform/v1/deform_pb";
import type { EnergyMapping } from "./colormap";
import { computeNormals } from "./mesh_normals";
import { fromProtoTransform, identityHandle, vec, type HandleState } from "./transforms";

/**
 * The mesh in base-GLB vertex order (frames arrive in that order). Plain arrays: the
 * viewport derives its display geometry from them.
 */
export interface MeshData {
  n: number;
  m: number;
  index: Uint32Array;
  rest: Float32Array;
  cur: Float32Array;
  normals: Float32Array;
  energies: Float32Array | null;
  labels: Int16Array; // -1 none, 0 fixed, h ≥ 1 handle h
  diag: number;
}

export type Mode = "orbit" | "vertex" | "brush" | "box" | "lasso" | "move";

/** A handle's harmonic weight field Φ_j as GetHandleWeights answered it (weights/). */
export interface HandleWeightField {
  handle: number; // 0-based
  values: Float32Array; // one per base-GLB vertex, in [0, 1]
  version: bigint; // the session version the server read the constraints at
}

export interface StateEvents {
  mesh: MeshData; // a new mesh
  shape: void; // cur / normals changed
  energies: { first: boolean };
  colours: void; // labels, energies or their mapping changed
  labels: void; // labels or the handle labels offered changed
  handles: void; // handle poses, the active handle, or whether they can be moved
  beta: void;
  measures: { measures: Measures; solveMs: number };
  session: void; // the session, its version or its tokens
  mode: Mode;
  /** The gizmo changed handle h's (0-based) pose (a drag, a cancel, typed-in values). */
  pose: number;
  /** The handle-weight preview was turned on or off. */
  weightsToggle: boolean;
  /** The page became watch-only (its link's token turned out to be the view token). */
  access: void;
  /** A session finished opening: its current shape (deformed or not) and poses are in. */
  opened: void;
}

export class SessionState extends Emitter<StateEvents> {
  session: Session | null = null;
  sessionName = "";
  loaded = false; // the session's mesh is on screen
  mesh: MeshData | null = null;
  constraintsApplied = false; // the server holds constraints matching our labels
  labelsDirty = false; // local edits not yet sent
  handleCount = 1; // handle labels offered in the UI
  activeHandle = 1;
  currentLabel = 0; // what the selection tools assign; -1 erases
  pivots: THREE.Vector3[] = [];
  handles: HandleState[] = [];
  beta = { value: 0, units: BetaUnits.AREA };
  measures: Measures | null = null;
  frameVersion = 0n; // version of the newest frame shown
  energyMapping: EnergyMapping = "off";
  truncation = 1; // top of the "truncated" energy mapping
  mode: Mode = "orbit";
  /** Handle labels (1-based) another editor holds → that editor's colour (drawn so). */
  heldColours = new Map<number, string>();
  /** The handle-weight preview is on (it replaces the region and energy colours while shown). */
  weightsOn = false;
  /** The field shown while the preview is on (null: not yet answered, or none). */
  weights: HandleWeightField | null = null;

  private watching: boolean;

  constructor(watchOnly: boolean) {
    super();
    this.watching = watchOnly;
  }

  /** No editing: the page holds no edit token (or was asked to watch). */
  get watchOnly(): boolean {
    return this.watching;
  }

  /** From now on watch-only (never back: a page gets no new token). */
  becomeWatcher(): void {
    if (this.watching) return;
    this.watching = true;
    this.emit("access", undefined);
    this.setMode("orbit");
  }

  /** The newest version seen: of the session, or of a frame (handle moves bump it too). */
  get version(): number {
    const v = this.session ? this.session.version : 0n;
    return Number(this.frameVersion > v ? this.frameVersion : v);
  }

  /** The gizmo may move the active handle. */
  get canMoveHandle(): boolean {
    return this.mode === "move" && !this.watchOnly && this.constraintsApplied && !this.labelsDirty && this.activeHandle - 1 < this.handles.length;
  }

  setMesh(positions: Float32Array, normals: Float32Array | null, index: Uint32Array, diag: number): void {
    const n = positions.length / 3;
    this.mesh = {
      n,
      m: index.length / 3,
      index,
      rest: positions.slice(),
      cur: positions.slice(),
      normals: normals ? normals.slice() : new Float32Array(3 * n),
      energies: null,
      labels: new Int16Array(n).fill(-1),
      diag,
    };
    if (!normals) computeNormals(this.mesh.cur, index, this.mesh.normals);
    // Nothing of the previous mesh's carries over: what the tools assign, the handles offered
    // and the active one start afresh (the session's constraints set them again when it has
    // some); the panels reset their own settings (energy map, threshold) on "mesh".
    this.currentLabel = 0;
    this.handleCount = 1;
    this.activeHandle = 1;
    this.emit("mesh", this.mesh);
  }

  /** New vertex positions (and normals; computed when null). */
  setShape(positions: Float32Array, normals: Float32Array | null): void {
    if (!this.mesh) return;
    this.mesh.cur.set(positions);
    if (normals) this.mesh.normals.set(normals);
    else computeNormals(this.mesh.cur, this.mesh.index, this.mesh.normals);
    this.emit("shape", undefined);
  }

  setEnergies(energies: Float32Array): void {
    if (!this.mesh) return;
    const first = this.mesh.energies === null;
    this.mesh.energies = energies.slice();
    this.emit("energies", { first });
    this.emit("colours", undefined);
  }

  /** Labels `ids` with `label`; returns how many changed. */
  assign(ids: Iterable<number>, label: number): number {
    const mesh = this.mesh;
    if (!mesh) return 0;
    let count = 0;
    for (const id of ids) {
      if (mesh.labels[id] !== label) {
        mesh.labels[id] = label;
        count++;
      }
    }
    if (count > 0) {
      this.labelsDirty = true;
      if (label > this.handleCount) this.handleCount = label;
      this.emit("handles", undefined);
      this.emit("colours", undefined);
      this.emit("labels", undefined);
    }
    return count;
  }

  /**
   * Adopts a Session message: β, constraints (as labels, unless local edits are unsent),
   * pivots, and with `transforms` the handles' poses.
   */
  adoptSession(s: Session, { labels = true, transforms = true } = {}): void {
    this.session = s;
    this.setBeta(s.beta?.value ?? 0, s.beta?.units ?? BetaUnits.AREA);
    this.pivots = s.pivots.map(vec);
    this.constraintsApplied = s.constrained;
    const mesh = this.mesh;
    if (labels && mesh && !this.labelsDirty) {
      mesh.labels.fill(-1);
      // base-GLB ids (set when they differ from the engine ids in `constraints`: glTF uploads)
      const c = s.baseConstraints ?? s.constraints;
      if (c) {
        for (const id of c.fixed?.ids ?? []) if (id >= 0 && id < mesh.n) mesh.labels[id] = 0;
        c.handles.forEach((h, k) => {
          for (const id of h.ids) if (id >= 0 && id < mesh.n) mesh.labels[id] = k + 1;
        });
        this.handleCount = Math.max(1, c.handles.length);
      }
      this.emit("colours", undefined);
      this.emit("labels", undefined);
    }
    if (transforms) {
      const count = Math.max(this.pivots.length, s.transforms.length);
      this.handles = [];
      for (let h = 0; h < count; h++) {
        this.handles.push(s.transforms[h] ? fromProtoTransform(s.transforms[h], this.pivots[h]) : identityHandle(this.pivots[h]));
      }
      this.emit("handles", undefined);
    }
    this.emit("session", undefined);
  }

  /** Every handle back to identity. */
  resetHandles(): void {
    this.handles = this.pivots.map((p) => identityHandle(p));
    this.emit("handles", undefined);
  }

  setHandle(h: number, pose: HandleState): void {
    if (h < this.handles.length) this.handles[h] = pose;
  }

  setBeta(value: number, units: BetaUnits): void {
    this.beta = { value, units };
    this.emit("beta", undefined);
  }

  setMeasures(measures: Measures, solveMs: number): void {
    this.measures = measures;
    this.emit("measures", { measures, solveMs });
  }

  setWeightsOn(on: boolean): void {
    if (this.weightsOn === on) return;
    this.weightsOn = on;
    if (!on) this.weights = null;
    this.emit("weightsToggle", on);
    this.emit("colours", undefined);
  }

  setWeights(field: HandleWeightField | null): void {
    this.weights = field;
    this.emit("colours", undefined);
  }

  /** The weight field to colour the mesh with, or null (preview off, not answered, stale mesh). */
  get shownWeights(): Float32Array | null {
    const w = this.weights;
    return this.weightsOn && w && this.mesh && w.values.length === this.mesh.n ? w.values : null;
  }

  setMode(mode: Mode): void {
    this.mode = this.watchOnly ? "orbit" : mode;
    this.emit("mode", this.mode);
    this.emit("handles", undefined);
  }
}

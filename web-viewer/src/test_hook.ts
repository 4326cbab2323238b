// The page's test hook (tests/browser/e2e.mjs): state, and the same code paths the UI uses.
import * as THREE from "three";
import { Code, ConnectError } from "@connectrpc/connect";
import { fetchMesh, tokens } from "./api";
import type { App } from "./app";
import { MeshFormat } from "./gen/hdeform/v1/deform_pb";
import type { FrameApply } from "./frame_apply";
import { shareLink } from "./links";
import type { SelectionTools } from "./selection/tools";
import { verticesInBox } from "./selection/pick";
import type { Mode } from "./state";
import type { Sync } from "./sync/sync";
import { toProtoTransforms } from "./transforms";
import { parseGlb } from "./viewport/glb";
import type { HandleGizmo } from "./viewport/handle_gizmo";
import type { MeshDisplay } from "./viewport/mesh_display";
import type { Viewport } from "./viewport/viewport";
import type { Editors } from "./multi/editors";
import type { CursorFeedback } from "./selection/cursor_feedback";
import type { RegionMarkers } from "./viewport/region_markers";
import type { HistoryList } from "./history/history_list";
import type { SnapshotsPanel } from "./panels/snapshots_panel";
import { StepKind } from "./gen/hdeform/v1/deform_pb";

declare global {
  interface Window {
    hdeform: unknown;
  }
}

export interface HookParts {
  sync: Sync;
  frameApply: FrameApply;
  display: MeshDisplay;
  viewport: Viewport;
  gizmo: HandleGizmo;
  tools: SelectionTools;
  applyConstraints: () => Promise<void>;
  openLibrary: (name: string) => Promise<void>;
  sweepRows: () => number;
  editors: Editors;
  feedback: CursorFeedback;
  markers: RegionMarkers;
  history: HistoryList;
  snapshots: SnapshotsPanel;
}

export function installTestHook({ state, client, banner, status }: App, parts: HookParts): void {
  const { sync, viewport, gizmo, tools } = parts;
  window.hdeform = {
    get loaded() {
      return state.loaded && !!state.mesh;
    },
    get sessionName() {
      return state.sessionName;
    },
    /** The newest version seen: of the session, or of a frame (handle moves bump it too). */
    get version() {
      return state.version;
    },
    /** Vertices the mesh display draws (indexed: the mesh's; energy map on: 3 per triangle). */
    get displayVertices() {
      return parts.display.vertexCount;
    },
    get framesApplied() {
      return sync.framesApplied;
    },
    get watchEvents() {
      return sync.watchEvents;
    },
    get constraintsApplied() {
      return state.constraintsApplied && !state.labelsDirty;
    },
    get lastError() {
      return banner.shown;
    },
    /** This page's own edit is not yet shown, or a frame is still being decoded. */
    get busy() {
      return sync.busy || parts.frameApply.pending > 0;
    },
    bbox(): number[][] {
      const b = new THREE.Box3().setFromArray(state.mesh!.rest);
      return [b.min.toArray(), b.max.toArray()];
    },
    /** Assigns every vertex whose rest position lies in the model-space box; returns the count. */
    selectBox(min: number[], max: number[], label: number): number {
      if (!state.mesh) return 0;
      const ids = verticesInBox(state.mesh, min, max);
      state.assign(ids, label);
      return ids.length;
    },
    selectScreenRect: (a: { x: number; y: number }, b: { x: number; y: number }, label: number) => tools.selectScreenRect(a, b, label),
    applyConstraints: parts.applyConstraints,
    setMode: (mode: Mode) => state.setMode(mode),
    openLibrary: parts.openLibrary,
    gizmoScreenPoint: (axis?: "x" | "y" | "z") => gizmo.screenPoint(axis),
    /** Client coordinates of a model-space point. */
    screenPoint: (x: number, y: number, z: number) => viewport.toClient(viewport.root.localToWorld(new THREE.Vector3(x, y, z))),
    positions: () => (state.mesh ? Array.from(state.mesh.cur) : []),
    /** The session's current shape as the server has it (GetMesh current GLB: exact float32). */
    serverPositions: async () => Array.from((await parseGlb(await fetchMesh(client, state.sessionName, false, MeshFormat.GLB))).positions),
    restPositions: () => (state.mesh ? Array.from(state.mesh.rest) : []),
    labels: () => (state.mesh ? Array.from(state.mesh.labels) : []),
    measures: () => (state.measures ? { ...state.measures } : null),
    handleTransforms: () => toProtoTransforms(state.handles, state.pivots),
    /** The handles' transforms as the server last confirmed them (null: none seen). */
    confirmedTransforms: () => sync.confirmedTransforms,
    /** The gizmo's pose (its object: the active handle's pivot, rotation, scale). */
    gizmoPose: () => {
      const o = viewport.pivotObject;
      return { position: o.position.toArray(), quaternion: o.quaternion.toArray(), scale: o.scale.toArray() };
    },
    get gizmoMode() {
      return gizmo.mode;
    },
    get gizmoSpace() {
      return gizmo.space;
    },
    get gizmoDragging() {
      return gizmo.dragging;
    },
    get activeHandle() {
      return state.activeHandle;
    },
    setActiveHandle: (h: number) => {
      state.activeHandle = h;
      state.emit("handles", undefined);
    },
    get mode() {
      return state.mode;
    },
    /** Camera position and orbit target (world = model coordinates). */
    camera: () => ({ position: viewport.camera.position.toArray(), target: viewport.orbit.target.toArray(), up: viewport.camera.up.toArray() }),
    get clientId() {
      return parts.editors.identity.clientId;
    },
    get displayName() {
      return parts.editors.identity.displayName;
    },
    /** Several editors: the server answered a grab or sent presence. */
    get multiUser() {
      return parts.editors.multi;
    },
    get grabSupported() {
      return parts.editors.lease.supported;
    },
    presence: () => parts.editors.presence.people.map((p) => ({ ...p })),
    /** The History panel's steps, newest first (what it shows). */
    history: () =>
      parts.history.shown().map(({ step, undone }) => ({
        id: Number(step.id),
        kind: StepKind[step.kind],
        author: step.author,
        clientId: step.clientId,
        target: Number(step.target),
        summary: step.summary,
        undone,
      })),
    snapshotNames: () => parts.snapshots.names(),
    /** The session's handle transforms as the server has them (GetSession), translations only. */
    serverTranslations: async () => (await client.getSession({ name: state.sessionName })).transforms.map((t) => [t.translation?.x ?? 0, t.translation?.y ?? 0, t.translation?.z ?? 0]),
    serverBeta: async () => (await client.getSession({ name: state.sessionName })).beta?.value ?? 0,
    /** Vertex mode: the vertex under the cursor (-1: none). */
    get hoverVertex() {
      return parts.feedback.hoverVertex;
    },
    /** Brush mode: the ring under the cursor (radius in model units). */
    get brushRing() {
      const r = parts.feedback.ring;
      return { visible: r.visible, radius: r.scale.x, expected: tools.brushRadius() };
    },
    /** Vertices of small regions drawn as markers. */
    get markerCount() {
      return parts.markers.count;
    },
    /** The point on the plane through the orbit target (facing the camera) under client (x, y). */
    pointOnTargetPlane: (x: number, y: number) => {
      const r = viewport.canvas.getBoundingClientRect();
      const ndc = new THREE.Vector2(((x - r.left) / r.width) * 2 - 1, -((y - r.top) / r.height) * 2 + 1);
      const ray = new THREE.Raycaster();
      ray.setFromCamera(ndc, viewport.camera);
      const normal = viewport.camera.getWorldDirection(new THREE.Vector3());
      const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(normal, viewport.orbit.target);
      return ray.ray.intersectPlane(plane, new THREE.Vector3())?.toArray() ?? null;
    },
    get configVersion() {
      return Number(state.session?.configVersion ?? 0n);
    },
    get sweepRows() {
      return parts.sweepRows();
    },
    get meshName() {
      return state.session?.meshName ?? "";
    },
    shareLink: (watch: boolean) => shareLink(state.sessionName, watch),
    get watchOnly() {
      return state.watchOnly;
    },
    /** "connected" | "reconnecting" | "gone" */
    get connection() {
      return sync.link.state;
    },
    get reconnects() {
      return sync.reconnects;
    },
    get status() {
      return status.shown;
    },
    /** The tokens this page holds (it sends them with every call anyway). */
    tokens: () => tokens(),
    /**
     * Any Deformation call with the page's own headers (x-session-id, authorization):
     * resolves to { code: "OK" } or the error's code name and message.
     */
    async call(method: string, request: object): Promise<{ code: string; message: string }> {
      try {
        const fn = (client as unknown as Record<string, (r: object) => Promise<unknown>>)[method];
        await fn.call(client, request);
        return { code: "OK", message: "" };
      } catch (err) {
        const e = err instanceof ConnectError ? err : ConnectError.from(err);
        return { code: Code[e.code] ?? String(e.code), message: e.rawMessage };
      }
    },
  };
}

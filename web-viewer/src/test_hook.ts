// The page's test hook (tests/browser/e2e.mjs): state, and the same code paths the UI uses.
import * as THREE from "three";
import { Code, ConnectError } from "@connectrpc/connect";
import { fetchMesh, tokens } from "./api";
import type { App } from "./app";
import { create } from "@bufbuild/protobuf";
import { FrameDecoder } from "./decode/frame_decoder";
import { FrameEncoding, FrameSchema, MeshFormat } from "./gen/hdeform/v1/deform_pb";
import type { FrameApply } from "./frame_apply";
import { shareLink } from "./links";
import type { SelectionTools } from "./selection/tools";
import { verticesInBox } from "./selection/pick";
import type { Mode } from "./state";
import type { Sync } from "./sync/sync";
import { toProtoTransforms } from "./transforms";
import { parseGlb } from "./viewport/glb";
import { gizmoFactor, type HandleGizmo } from "./viewport/handle_gizmo";
import type { MeshDisplay } from "./viewport/mesh_display";
import type { Viewport } from "./viewport/viewport";
import { contentBox } from "./viewport/content_box";
import type { Editors } from "./multi/editors";
import type { CursorFeedback } from "./selection/cursor_feedback";
import type { RegionMarkers } from "./viewport/region_markers";
import type { HistoryList } from "./history/history_list";
import type { SnapshotsPanel } from "./panels/snapshots_panel";
import { StepKind } from "./gen/hdeform/v1/deform_pb";
import type { WeightsView } from "./weights/weights_view";
import { decodeWeights, weightRamp } from "./weights/weight_ramp";
import type { HeldOutline } from "./viewport/held_outline";
import type { TimelinePanel } from "./timeline/timeline_panel";
import type { Scrub } from "./timeline/scrub";
import type { AnimationPlayer } from "./timeline/animation_player";
import { loadAnimation, morphedPositions } from "./timeline/animation_glb";
import type { HandleTransform } from "./gen/hdeform/v1/deform_pb";
import type { RigExport } from "./rig/rig_export";
import { fetchRig } from "./rig/rig_export";
import type { PerfOverlay } from "./perf/perf_overlay";
import { quantile } from "./perf/perf_stats";
import type { SelectionCommand } from "./selection/commands";
import type { ViewSnap } from "./viewport/view_snap";
import type { AxesViewHelper } from "./viewport/axes_view_helper";
import type { GroundGrid } from "./viewport/ground_grid";
import type { AxisEnd } from "./viewport/view_axes";
import { currentProjection } from "./selection/screen_projection";

/** A handle transform as plain numbers (the server answers every scale as a 3×3 stretch). */
function plainTransform(t: HandleTransform) {
  return {
    pivot: t.pivot ? [t.pivot.x, t.pivot.y, t.pivot.z] : null,
    translation: [t.translation?.x ?? 0, t.translation?.y ?? 0, t.translation?.z ?? 0],
    rotation: t.rotation ? [t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z] : [1, 0, 0, 0],
    stretch: t.scale.case === "stretch" ? [...t.scale.value.m] : t.scale.case === "axisScale" ? [t.scale.value.x, 0, 0, 0, t.scale.value.y, 0, 0, 0, t.scale.value.z] : [1, 0, 0, 0, 1, 0, 0, 0, 1],
  };
}

/** A MESHOPT frame: `vertices` the meshopt vertex stream, `box` its min and max corners. */
function meshoptFrame(vertices: number[], box: number[][]) {
  const vec = (a: number[]) => ({ x: a[0], y: a[1], z: a[2] });
  return create(FrameSchema, {
    encoding: FrameEncoding.MESHOPT,
    vertices: Uint8Array.from(vertices),
    positionBox: { min: vec(box[0]), max: vec(box[1]) },
  });
}

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
  sweepRange: () => [number, number];
  editors: Editors;
  feedback: CursorFeedback;
  markers: RegionMarkers;
  history: HistoryList;
  snapshots: SnapshotsPanel;
  weights: WeightsView;
  outline: HeldOutline;
  timeline: TimelinePanel;
  scrub: Scrub;
  player: AnimationPlayer;
  rig: RigExport;
  perf: PerfOverlay;
  select: (command: SelectionCommand) => number;
  viewSnap: ViewSnap;
  axesHelper: AxesViewHelper;
  grid: GroundGrid;
}

export function installTestHook({ state, client, banner, status, edits }: App, parts: HookParts): void {
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
    /** The decode worker's time per frame, newest frames (ms; benches read it). */
    workerDecodeMs: () => [...parts.frameApply.workerDecodeMs],
    /**
     * A MESHOPT frame (`vertices`: the meshopt vertex stream, `box`: min and max corners)
     * decoded `times` times, one after another, by a decode worker of its own: the worker's
     * time per decode (ms), each frame's arrays handed back as the page does (`recycled`) or
     * not (`fresh`). Benches (bench/wan/chromium_drag.mjs).
     */
    async workerDecodeTimes(vertices: number[], box: number[][], vertexCount: number, times: number): Promise<{ fresh: number[]; recycled: number[] }> {
      const frame = meshoptFrame(vertices, box);
      const decoder = new FrameDecoder();
      try {
        for (let k = 0; k < times; k++) await decoder.decode(frame, vertexCount, 0);
        const fresh = [...decoder.workerMs];
        for (let k = 0; k < times; k++) decoder.recycle(await decoder.decode(frame, vertexCount, 0));
        return { fresh, recycled: decoder.workerMs.slice(fresh.length) };
      } finally {
        decoder.close();
      }
    },
    /**
     * Two MESHOPT frames (as in workerDecodeTimes) through the page's decode worker, the
     * second decoded into the first's arrays handed back, and the second alone by a fresh
     * worker: its positions and normals both ways (e2e: equal).
     */
    async workerDecodeRecycled(first: number[], second: number[], box: number[][], vertexCount: number) {
      const plain = (d: { positions: Float32Array | null; normals: Float32Array | null }) => [Array.from(d.positions!), Array.from(d.normals!)];
      const decoder = new FrameDecoder();
      const fresh = new FrameDecoder();
      try {
        decoder.recycle(await decoder.decode(meshoptFrame(first, box), vertexCount, 0));
        const recycled = plain(await decoder.decode(meshoptFrame(second, box), vertexCount, 0));
        return { recycled, fresh: plain(await fresh.decode(meshoptFrame(second, box), vertexCount, 0)) };
      } finally {
        decoder.close();
        fresh.close();
      }
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
    /** Box select as the tool does it (X-ray or visible-only as the page is set). */
    selectScreenRect: (a: { x: number; y: number }, b: { x: number; y: number }, label: number) => tools.selectScreenRect(a, b, label),
    /** The camera's turn to a keypad / view-helper view is under way. */
    get viewAnimating() {
      return parts.viewSnap.animating;
    },
    /** Client coordinates of the axes view helper's end ("posX", "negZ", …). */
    viewHelperPoint: (end: AxisEnd) => parts.axesHelper.endPoint(end),
    /** The axis end a click at client (x, y) would take (null: none). */
    viewHelperEndAt: (x: number, y: number) => parts.axesHelper.endAt(x, y),
    /** The ground grid: shown, and its plane's normal (the model's up). */
    grid: () => ({ visible: parts.grid.visible, normal: parts.grid.normal }),
    get xray() {
      return tools.xray.enabled;
    },
    /** The last Lasso outline (viewport pixels) and the last visible-only depth pass's time (ms). */
    lastLasso: () => tools.lastLasso.map((p) => ({ ...p })),
    get depthPassMs() {
      return tools.depthMs;
    },
    /** What the Box and Lasso tools project with: canvas size and the model → clip matrix (column-major), and the canvas's client origin. */
    projection: () => {
      const r = viewport.element.getBoundingClientRect();
      return { ...currentProjection(viewport), left: r.left, top: r.top };
    },
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
    /** The picture is orthographic (Numpad 5), and the projection it is drawn with (column-major). */
    get orthographic() {
      return viewport.orthographic;
    },
    projectionMatrix: () => viewport.viewCamera.projectionMatrix.toArray(),
    /** The session's current mesh as GetMesh's GLB (base64): what a GLB download starts from. */
    meshGlb: async () => {
      const bytes = await fetchMesh(client, state.sessionName, false, MeshFormat.GLB);
      let s = "";
      for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
      return btoa(s);
    },
    /** What Home frames: [min, max] of the current shape, the handles and the gizmo. */
    contentBox: () => {
      const b = contentBox(state);
      return b ? [b.min.toArray(), b.max.toArray()] : null;
    },
    /** Current vertices, and gizmo points (centre, arrow tips; when shown), outside the canvas. */
    offScreen: () => {
      const r = viewport.canvas.getBoundingClientRect();
      const out = (p: { x: number; y: number } | null) => !!p && (p.x < r.left || p.x > r.right || p.y < r.top || p.y > r.bottom);
      let vertices = 0;
      const mesh = state.mesh;
      const v = new THREE.Vector3();
      if (mesh) {
        for (let i = 0; i < mesh.n; i++) {
          const w = viewport.root.localToWorld(v.fromArray(mesh.cur, 3 * i));
          const cam = viewport.viewCamera;
          const inFront = w.clone().sub(cam.position).dot(cam.getWorldDirection(new THREE.Vector3())) > 0;
          if (!inFront || out(viewport.toClient(w))) vertices++;
        }
      }
      const points = [gizmo.screenPoint(), gizmo.screenPoint("x"), gizmo.screenPoint("y"), gizmo.screenPoint("z")];
      return { vertices, gizmo: points.filter(out).length, gizmoShown: points[0] !== null };
    },
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
    /** The weight preview: on, the field the page colours the mesh with, and its note. */
    get weightsOn() {
      return state.weightsOn;
    },
    weightsShown: () => {
      const w = state.weights;
      const values = state.shownWeights;
      return values && w ? { handle: w.handle, version: Number(w.version), values: Array.from(values) } : null;
    },
    get weightsNote() {
      return parts.weights.note;
    },
    /** GetHandleWeights for handle h (0-based), decoded as the page decodes it. */
    serverWeights: async (h: number) => {
      const r = await client.getHandleWeights({ name: state.sessionName, handle: h });
      return { handle: r.handle, version: Number(r.version), values: Array.from(decodeWeights(r.weights, state.mesh!.n)) };
    },
    /** The weight ramp's colour at t, as the page computes it (float32). */
    weightColour: (t: number) => {
      const c = new Float32Array(3);
      weightRamp(t, c, 0);
      return Array.from(c);
    },
    /** The colours the mesh display draws (3 per vertex, or per corner when split). */
    displayColours: () => Array.from(parts.display.colours()),
    /** Handles another editor holds, outlined: label, colour, boundary edges. */
    heldOutlines: () => parts.outline.summary(),
    /** The session's handle transforms as the server has them (GetSession): rotation and scale too. */
    serverTransforms: async () =>
      (await client.getSession({ name: state.sessionName })).transforms.map((t) => ({
        translation: [t.translation?.x ?? 0, t.translation?.y ?? 0, t.translation?.z ?? 0],
        rotation: t.rotation ? { w: t.rotation.w, x: t.rotation.x, y: t.rotation.y, z: t.rotation.z } : null,
        /** The server's 3×3 stretch S (row-major; it answers every scale so), identity when unset. */
        stretch: t.scale.case === "stretch" ? [...t.scale.value.m] : [1, 0, 0, 0, 1, 0, 0, 0, 1],
      })),
    /**
     * Rotate gizmo: the client point on `axis`'s ring nearest the camera, and the screen
     * direction (unit) a drag there turns it (positive angle about the axis).
     */
    gizmoRingPoint: (axis: "x" | "y" | "z") => {
      const { gizmo: g, pivotObject, viewCamera: camera } = viewport;
      if (!g.object) return null;
      const centre = pivotObject.getWorldPosition(new THREE.Vector3());
      const factor = gizmoFactor(camera, centre);
      const radius = 0.5 * ((factor * g.size) / 4); // TransformControls' rotate rings: radius 0.5
      const a = new THREE.Vector3(axis === "x" ? 1 : 0, axis === "y" ? 1 : 0, axis === "z" ? 1 : 0);
      // TransformControls' eye: towards the camera (orthographic: against its direction).
      const eye =
        camera instanceof THREE.OrthographicCamera ? camera.getWorldDirection(new THREE.Vector3()).negate() : camera.position.clone().sub(centre).normalize();
      const towards = eye.clone().addScaledVector(a, -eye.dot(a)).normalize(); // in the ring's plane
      const at = centre.clone().addScaledVector(towards, radius);
      const tangent = a.clone().cross(eye).normalize(); // TransformControls' angle: offset · (axis × eye)
      const p = viewport.toClient(at);
      const q = viewport.toClient(at.clone().addScaledVector(tangent, radius * 0.1));
      const len = Math.hypot(q.x - p.x, q.y - p.y);
      return { x: p.x, y: p.y, dir: { x: (q.x - p.x) / len, y: (q.y - p.y) / len } };
    },
    /** The session's handle transforms as the server has them (GetSession), translations only. */
    serverTranslations: async () => (await client.getSession({ name: state.sessionName })).transforms.map((t) => [t.translation?.x ?? 0, t.translation?.y ?? 0, t.translation?.z ?? 0]),
    serverBeta: async () => (await client.getSession({ name: state.sessionName })).beta?.value ?? 0,
    /** The timeline strip: keys (times), selection, playhead, its note, Play. */
    timeline: () => ({
      keys: parts.timeline.keys.map((k) => k.timeS),
      /** Each key's own easing to the next key (null: the timeline's). */
      keyEasings: parts.timeline.keys.map((k) => (k.easing === undefined ? null : k.easing)),
      selected: parts.timeline.selected,
      playhead: parts.timeline.playhead,
      note: parts.timeline.note,
      easing: parts.timeline.easing,
      author: parts.timeline.author,
      playing: parts.player.playing,
      liveMeshShown: parts.display.object?.visible ?? false,
      playTime: parts.player.playing ? parts.player.time : null,
      scrubbing: parts.scrub.active,
      posesApplied: parts.scrub.applied,
      glbBytes: parts.timeline.lastGlbBytes,
      /** The time a key is being dragged to (null: no key drag), and Ctrl+C's key time. */
      keyDragTime: parts.timeline.view.keyDragTime,
      copiedFrom: parts.timeline.copiedFrom,
    }),
    /** Client x of timeline time t on the ruler, and the ruler's vertical middle. */
    rulerPoint: (t: number) => {
      const r = parts.timeline.view.ruler.getBoundingClientRect();
      return { x: parts.timeline.view.clientX(t), y: r.top + r.height / 2 };
    },
    /** GetTimeline: keys (time, transforms, β) and easing, as the server holds them. */
    serverTimeline: async () => {
      const t = await client.getTimeline({ name: state.sessionName });
      return {
        easing: t.easing,
        author: t.author,
        keys: t.keys.map((k) => ({ time: k.timeS, transforms: k.transforms.map(plainTransform), beta: k.beta ? k.beta.value : null, easing: k.easing ?? null })),
      };
    },
    /** PoseAt(t): the interpolated transforms. */
    poseAt: async (t: number) => (await client.poseAt({ name: state.sessionName, timeS: t })).transforms.map(plainTransform),
    /** GetSession's transforms in the same form. */
    sessionTransforms: async () => (await client.getSession({ name: state.sessionName })).transforms.map(plainTransform),
    /**
     * The server's exact frame of the pose at t: UpdateHandles with PoseAt(t)'s transforms (a
     * real move of the session), positions as float32 in base-GLB order.
     */
    exactFrameAt: async (t: number) => {
      const pose = await client.poseAt({ name: state.sessionName, timeS: t });
      const name = state.sessionName;
      const clientId = parts.editors.identity.clientId;
      const f = await edits.execute({ method: "updateHandles", what: "Handle update", quiet: true, request: () => ({ name, transforms: pose.transforms, clientId }) });
      const p = f.positions;
      return Array.from(new Float32Array(p.buffer.slice(p.byteOffset, p.byteOffset + p.byteLength)));
    },
    /**
     * The animation GLB (base64) played by three's AnimationMixer: at each clip time, the
     * morph influences and the CPU positions base + Σ influence_i × target_i. Also the clip's
     * sample times (its weights track's input).
     */
    sampleAnimation: async (base64: string, times: number[]) => {
      const bytes = Uint8Array.from(atob(base64), (c) => c.charCodeAt(0));
      const { scene, mesh, clip } = await loadAnimation(bytes);
      const samples = times.map((t) => {
        // A fresh mixer per time, played once and held at the end: with the default repeat,
        // setTime(duration) would wrap to time 0, and a finished action would not move again.
        const mixer = new THREE.AnimationMixer(scene);
        const action = mixer.clipAction(clip).setLoop(THREE.LoopOnce, 1);
        action.clampWhenFinished = true;
        action.play();
        mixer.setTime(t);
        const sample = { t, influences: Array.from(mesh.morphTargetInfluences ?? []), positions: Array.from(morphedPositions(mesh)) };
        mixer.stopAllAction();
        mixer.uncacheRoot(scene);
        return sample;
      });
      return {
        duration: clip.duration,
        clipTimes: Array.from(clip.tracks[0]?.times ?? []),
        tracks: clip.tracks.map((k) => k.name),
        targets: mesh.geometry.morphAttributes.position?.length ?? 0,
        colours: !!mesh.geometry.getAttribute("color"),
        samples,
      };
    },
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
      ray.setFromCamera(ndc, viewport.viewCamera);
      const normal = viewport.viewCamera.getWorldDirection(new THREE.Vector3());
      const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(normal, viewport.orbit.target);
      return ray.ray.intersectPlane(plane, new THREE.Vector3())?.toArray() ?? null;
    },
    get configVersion() {
      return Number(state.session?.configVersion ?? 0n);
    },
    /** The sweep chart's y range for the chosen measure. */
    sweepRange: () => parts.sweepRange(),
    /** The Measures table as shown (cell id → text). */
    measuresShown: () => Object.fromEntries([...document.querySelectorAll("#measures td")].map((td) => [td.id, td.textContent ?? ""])),
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
    /** The rig report the page shows (null: none), and the size of its last rig download. */
    rigReportShown: () => parts.rig.report,
    get rigBytes() {
      return parts.rig.bytes;
    },
    /** ExportRig called afresh (the page's token, its influences and up): the report of its first chunk, as plain numbers. */
    async exportRigReport(influences: number, up: "y" | "z") {
      const { report, bytes } = await fetchRig(client, state.sessionName, influences, up);
      return report
        ? { joints: report.joints, influences: report.influences, bboxDiagonal: report.bboxDiagonal, version: Number(report.version), bytes: bytes.byteLength, poses: report.poses.map((p) => ({ current: p.current, timeS: p.timeS, max: p.max, rms: p.rms })) }
        : null;
    },
    /** The perf overlay: shown, its text, and the page's cost per applied frame since `perfReset` (median, count, all). */
    get perfShown() {
      return parts.perf.shown;
    },
    perfText: () => document.getElementById("perf")?.textContent ?? "",
    perfReset: () => parts.perf.stats.reset(),
    perfCosts: () => {
      const costs = [...parts.perf.stats.costs];
      const decodes = [...parts.perf.stats.decodes];
      return { count: costs.length, median: quantile(costs, 0.5), p90: quantile(costs, 0.9), decodeMedian: quantile(decodes, 0.5), costs, decodes };
    },
    perfSummary: () => parts.perf.stats.summary(performance.now()),
    /** Vertices in the region `label` (the selection when Assign to names it). */
    regionCount: (label: number) => (state.mesh ? state.mesh.labels.reduce((a, l) => a + (l === label ? 1 : 0), 0) : 0),
    get currentLabel() {
      return state.currentLabel;
    },
    select: (command: SelectionCommand) => parts.select(command),
    /** Assigns these vertex ids to `label` (as the tools do); how many changed. */
    selectIds: (ids: number[], label: number) => state.assign(ids, label),
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

// hdeform web viewer: three.js scene, region selection, handle gizmo, live frames over gRPC-Web.
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { TransformControls } from "three/examples/jsm/controls/TransformControls.js";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { fromBinary, fromJsonString, toBinary, toJsonString } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import {
  BetaUnits,
  MeshFormat,
  SnapshotSchema,
  type Frame,
  type HandleTransform,
  type HandleTransformSchema,
  type Measures,
  type Session,
  type SessionEvent,
} from "./gen/hdeform/v1/deform_pb";
import type { MessageInitShape } from "@bufbuild/protobuf";
import {
  createSessionViaUpload,
  describeError,
  fetchMesh,
  floats,
  isAbort,
  isTransient,
  makeClient,
  newSessionId,
  setRoutingSession,
  setTokens,
  tokens,
} from "./api";
import { drawChart, type SweepPoint } from "./chart";
import { drawLegend, fmt, ramp, scaleTop, type EnergyMapping } from "./colormap";

// ---------------------------------------------------------------------------------------------
// DOM

const $ = <T extends HTMLElement = HTMLElement>(id: string) => document.getElementById(id) as T;
const viewport = $("viewport");
// Links: `?session=sessions/ID#edit=EDIT&view=VIEW` (editor) and
// `?session=sessions/ID&watch=1#view=VIEW` (watch only). The tokens live in the fragment,
// which browsers never send to a server (nor do proxies log it); docs/viewer.md "Links".
const params = new URLSearchParams(window.location.search);
const fragment = new URLSearchParams(window.location.hash.replace(/^#/, ""));
const linkTokens = { edit: fragment.get("edit") ?? "", view: fragment.get("view") ?? "" };
if (params.has("edit") || params.has("view")) {
  // A hand-made link with a token in the query: use it, but move it out of the address bar's
  // query (it has been sent to the server once already; it goes no further from here).
  linkTokens.edit ||= params.get("edit") ?? "";
  linkTokens.view ||= params.get("view") ?? "";
  params.delete("edit");
  params.delete("view");
  const url = new URL(window.location.href);
  url.search = params.toString();
  url.hash = tokenFragment(linkTokens.edit, linkTokens.view);
  history.replaceState(null, "", url);
}
const initialSession = params.get("session") ?? "";
// A page opened on a session without its edit token is watch-only whatever else its URL
// says (the server would refuse every edit anyway); `watch=1` also makes an editor's page so.
const watchOnly = initialSession !== "" && (params.get("watch") === "1" || linkTokens.edit === "");
function tokenFragment(edit: string, view: string): string {
  const f = new URLSearchParams();
  if (edit) f.set("edit", edit);
  if (view) f.set("view", view);
  return f.toString();
}
// Another link pasted over this one's fragment (same page, same query) must not leave the
// page on the old tokens: open it afresh.
window.addEventListener("hashchange", () => window.location.reload());
if (watchOnly) {
  document.body.classList.add("watch");
  $("watch-badge").classList.remove("hidden");
}

// ---------------------------------------------------------------------------------------------
// Errors: one banner, never a blank canvas

let bannerKind = "";
let lastError = "";
function showError(message: string, kind = "error"): void {
  lastError = message;
  bannerKind = kind;
  $("banner-text").textContent = message;
  $("banner").classList.remove("hidden");
  console.warn(`[hdeform] ${message}`);
}
function clearError(kind?: string): void {
  if (kind && kind !== bannerKind) return;
  $("banner").classList.add("hidden");
  bannerKind = "";
}
$("banner-close").addEventListener("click", () => clearError());
window.addEventListener("unhandledrejection", (e) => {
  if (!isAbort(e.reason)) showError(describeError(e.reason));
});

// The status line: what the page is doing, or "reconnecting…" while the server is away.
let statusText = "";
let reconnectText = "";
function setStatus(text: string): void {
  statusText = text;
  renderStatus();
}
function renderStatus(): void {
  const el = $("status");
  el.textContent = reconnectText || statusText;
  el.classList.toggle("warn", reconnectText !== "");
}

// ---------------------------------------------------------------------------------------------
// Scene

let renderer: THREE.WebGLRenderer;
try {
  renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
} catch (e) {
  showError(`WebGL is not available in this browser: ${describeError(e)}`);
  throw e;
}
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
viewport.prepend(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x2a2d33);
const camera = new THREE.PerspectiveCamera(40, 1, 0.001, 1000);
camera.position.set(0, 0, 3);
scene.add(camera);
scene.add(new THREE.HemisphereLight(0xffffff, 0x444455, 1.6));
const headLight = new THREE.DirectionalLight(0xffffff, 1.6);
headLight.position.set(0.5, 1, 2);
camera.add(headLight);

// Model space lives under `root` (rotated for z-up models); the gizmo's object too, so its
// position is in model coordinates.
const root = new THREE.Group();
scene.add(root);
const pivotObject = new THREE.Object3D();
root.add(pivotObject);

// TransformControls first: its pointerdown runs before OrbitControls' and disables orbiting.
const gizmo = new TransformControls(camera, renderer.domElement);
gizmo.setSize(0.9);
scene.add(gizmo.getHelper());
const orbit = new OrbitControls(camera, renderer.domElement);
orbit.enableDamping = false;

let needsRender = true;
orbit.addEventListener("change", () => (needsRender = true));
gizmo.addEventListener("change", () => (needsRender = true));

function resize(): void {
  const w = viewport.clientWidth || 1;
  const h = viewport.clientHeight || 1;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
  needsRender = true;
}
new ResizeObserver(resize).observe(viewport);
resize();

const material = new THREE.MeshStandardMaterial({
  vertexColors: true,
  side: THREE.DoubleSide,
  roughness: 0.75,
  metalness: 0.0,
  polygonOffset: true,
  polygonOffsetFactor: 1,
  polygonOffsetUnits: 1,
});
const wireMaterial = new THREE.MeshBasicMaterial({
  color: 0x000000,
  wireframe: true,
  transparent: true,
  opacity: 0.25,
});

// ---------------------------------------------------------------------------------------------
// Mesh state. The display geometry is non-indexed (3 corners per triangle) so per-triangle
// energy colours are exact; frames arrive per base-GLB vertex and are expanded through `index`.

interface MeshState {
  n: number;
  m: number;
  index: Uint32Array;
  rest: Float32Array;
  cur: Float32Array;
  normals: Float32Array;
  energies: Float32Array | null;
  labels: Int16Array; // -1 none, 0 fixed, h ≥ 1 handle h
  geometry: THREE.BufferGeometry;
  object: THREE.Mesh;
  wire: THREE.Mesh;
  diag: number;
}
let mesh: MeshState | null = null;

const REGION_COLOURS = [
  new THREE.Color(0x3b6fd8), // fixed
  new THREE.Color(0xe0483a),
  new THREE.Color(0x3fb950),
  new THREE.Color(0xd29922),
  new THREE.Color(0xb062d9),
  new THREE.Color(0x2fb8b0),
  new THREE.Color(0xe06fa8),
];
const BASE_COLOUR = new THREE.Color(0xc9c4ba);
function regionColour(label: number): THREE.Color {
  return label === 0 ? REGION_COLOURS[0] : REGION_COLOURS[1 + ((label - 1) % (REGION_COLOURS.length - 1))];
}

function buildMesh(positions: Float32Array, normals: Float32Array | null, index: Uint32Array): void {
  if (mesh) {
    root.remove(mesh.object, mesh.wire);
    mesh.geometry.dispose();
  }
  const n = positions.length / 3;
  const m = index.length / 3;
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(9 * m), 3));
  geometry.setAttribute("normal", new THREE.BufferAttribute(new Float32Array(9 * m), 3));
  geometry.setAttribute("color", new THREE.BufferAttribute(new Float32Array(9 * m), 3));
  const object = new THREE.Mesh(geometry, material);
  const wire = new THREE.Mesh(geometry, wireMaterial);
  wire.visible = ($("wireframe") as HTMLInputElement).checked;
  root.add(object, wire);
  const box = new THREE.Box3().setFromArray(positions);
  mesh = {
    n,
    m,
    index,
    rest: positions.slice(),
    cur: positions.slice(),
    normals: normals ? normals.slice() : new Float32Array(3 * n),
    energies: null,
    labels: new Int16Array(n).fill(-1),
    geometry,
    object,
    wire,
    diag: box.getSize(new THREE.Vector3()).length() || 1,
  };
  if (!normals) computeNormals();
  expandPositions();
  updateColours();
  fitCamera(box);
  $("placeholder").classList.add("hidden");
}

function computeNormals(): void {
  if (!mesh) return;
  const { cur, index, normals } = mesh;
  normals.fill(0);
  const a = new THREE.Vector3(), b = new THREE.Vector3(), c = new THREE.Vector3();
  for (let t = 0; t < index.length; t += 3) {
    const i = index[t] * 3, j = index[t + 1] * 3, k = index[t + 2] * 3;
    a.set(cur[j] - cur[i], cur[j + 1] - cur[i + 1], cur[j + 2] - cur[i + 2]);
    b.set(cur[k] - cur[i], cur[k + 1] - cur[i + 1], cur[k + 2] - cur[i + 2]);
    c.crossVectors(a, b);
    for (const v of [i, j, k]) {
      normals[v] += c.x;
      normals[v + 1] += c.y;
      normals[v + 2] += c.z;
    }
  }
  for (let v = 0; v < normals.length; v += 3) {
    const l = Math.hypot(normals[v], normals[v + 1], normals[v + 2]) || 1;
    normals[v] /= l;
    normals[v + 1] /= l;
    normals[v + 2] /= l;
  }
}

function expandPositions(): void {
  if (!mesh) return;
  const pos = mesh.geometry.getAttribute("position") as THREE.BufferAttribute;
  const nor = mesh.geometry.getAttribute("normal") as THREE.BufferAttribute;
  const P = pos.array as Float32Array;
  const N = nor.array as Float32Array;
  const { index, cur, normals } = mesh;
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
  pos.needsUpdate = true;
  nor.needsUpdate = true;
  mesh.geometry.computeBoundingSphere();
  mesh.geometry.computeBoundingBox();
  needsRender = true;
}

let energyMapping: EnergyMapping = "off";
function updateColours(): void {
  if (!mesh) return;
  const col = mesh.geometry.getAttribute("color") as THREE.BufferAttribute;
  const C = col.array as Float32Array;
  const { index, labels, energies } = mesh;
  const useEnergy = energyMapping !== "off" && energies !== null && energies.length === mesh.m;
  const top = useEnergy ? scaleTop(energyMapping, energies!, truncateValue()) : 1;
  for (let c = 0; c < index.length; c++) {
    const o = c * 3;
    const label = labels[index[c]];
    if (label >= 0) {
      const k = regionColour(label);
      C[o] = k.r;
      C[o + 1] = k.g;
      C[o + 2] = k.b;
    } else if (useEnergy) {
      ramp(energies![(c / 3) | 0] / top, C, o);
    } else {
      C[o] = BASE_COLOUR.r;
      C[o + 1] = BASE_COLOUR.g;
      C[o + 2] = BASE_COLOUR.b;
    }
  }
  col.needsUpdate = true;
  const legend = $<HTMLCanvasElement>("legend");
  legend.classList.toggle("hidden", !useEnergy);
  if (useEnergy) drawLegend(legend, top, energyMapping);
  updateRegionCounts();
  needsRender = true;
}

function fitCamera(box: THREE.Box3): void {
  const size = box.getSize(new THREE.Vector3());
  // z-up models (the Botsch–Sorkine set) stand upright on screen.
  root.rotation.x = size.z > 1.3 * size.y ? -Math.PI / 2 : 0;
  root.updateMatrixWorld(true);
  const worldBox = box.clone().applyMatrix4(root.matrixWorld);
  const center = worldBox.getCenter(new THREE.Vector3());
  const radius = worldBox.getSize(new THREE.Vector3()).length() / 2 || 1;
  const dist = (radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2))) * 1.25;
  camera.near = radius / 100;
  camera.far = radius * 100;
  // Look along the shallower horizontal axis so the widest silhouette faces the camera.
  const ws = worldBox.getSize(new THREE.Vector3());
  const offset = ws.z > 1.2 * ws.x ? new THREE.Vector3(dist, radius * 0.15, 0) : new THREE.Vector3(0, radius * 0.15, dist);
  camera.position.copy(center).add(offset);
  camera.updateProjectionMatrix();
  orbit.target.copy(center);
  orbit.update();
  needsRender = true;
}

// ---------------------------------------------------------------------------------------------
// Session state

const client = makeClient();
let session: Session | null = null;
let loaded = false; // a session's mesh is on screen
let sessionName = "";
let watchAbort: AbortController | null = null;
let constraintsApplied = false; // the server holds constraints matching our labels
let labelsDirty = false; // local edits not yet sent
let handleCount = 1; // handle labels offered in the UI
let activeHandle = 1;
let pivots: THREE.Vector3[] = [];
interface HandleState {
  position: THREE.Vector3;
  quaternion: THREE.Quaternion;
  scale: THREE.Vector3;
}
let handles: HandleState[] = [];
let betaValue = 0;
let betaUnits = BetaUnits.AREA;
let lastMeasures: Measures | null = null;
let lastFrameKey = "";
let frameVersion = 0n; // version of the newest frame applied
function shownVersion(): number {
  const v = session ? session.version : 0n;
  return Number(frameVersion > v ? frameVersion : v);
}
let framesApplied = 0;
let sweepPoints: SweepPoint[] = [];
let sweepRows: { beta: number; measures: Measures }[] = [];

// ---------------------------------------------------------------------------------------------
// Connection: the WatchSession loop owns it. When the stream fails for a transient reason
// (server restarting, network) the page goes "reconnecting": it retries with back-off
// (RECONNECT_FIRST_MS doubling to RECONNECT_MAX_MS), re-reads the session (GetSession) and
// its current shape, then watches again. Only NOT_FOUND after a reconnect means the session
// is gone. An edit that fails for a transient reason waits for the reconnect and is sent
// once more (edits carry absolute state, so a repeat cannot apply twice).

type Link = "connected" | "reconnecting" | "gone";
const RECONNECT_FIRST_MS = 250;
const RECONNECT_MAX_MS = 2000;
const LOST_BANNER_AFTER_MS = 5000; // a longer outage also gets the red banner
const EDIT_RETRY_WAIT_MS = 30_000; // how long a failed edit waits for the reconnect
let link: Link = "connected";
let reconnects = 0; // completed reconnects (test hook)
let outageSince = 0;
let linkWaiters: ((ok: boolean) => void)[] = [];
let streamAbort: AbortController | null = null; // the current WatchSession stream

function setLink(next: Link, why = ""): void {
  if (next === "reconnecting" && link !== "reconnecting") outageSince = Date.now();
  link = next;
  if (next === "reconnecting") {
    reconnectText = `reconnecting…${why ? ` (${why})` : ""}`;
  } else {
    reconnectText = "";
    const waiters = linkWaiters;
    linkWaiters = [];
    for (const w of waiters) w(next === "connected");
  }
  renderStatus();
}

/** Resolves true once the page is connected (at once if it is), false on timeout or loss. */
function waitConnected(timeoutMs: number): Promise<boolean> {
  if (link === "connected") return Promise.resolve(true);
  if (link === "gone") return Promise.resolve(false);
  return new Promise((resolve) => {
    const timer = setTimeout(() => {
      linkWaiters = linkWaiters.filter((w) => w !== done);
      resolve(false);
    }, timeoutMs);
    const done = (ok: boolean) => {
      clearTimeout(timer);
      resolve(ok);
    };
    linkWaiters.push(done);
  });
}

/** An edit call failed for a transient reason: reconnect now (the stream may not know yet). */
function kickReconnect(why: string): void {
  if (link !== "connected") return;
  setLink("reconnecting", why);
  streamAbort?.abort(); // the watch loop then re-reads the session
}

/**
 * An edit (SetConstraints, SetBeta, UpdateHandles): waits while the page reconnects, and when
 * the call fails for a transient reason (UNAVAILABLE, a cut connection) it is made once more
 * after the reconnect. `call` builds its request each time, so the retry sends the newest
 * state (the newest pose of a drag).
 */
async function edit<T>(call: () => Promise<T>): Promise<T> {
  if (link !== "connected") await waitConnected(EDIT_RETRY_WAIT_MS);
  try {
    return await call();
  } catch (err) {
    if (!isTransient(err) || link === "gone") throw err;
    kickReconnect("an edit failed");
    if (!(await waitConnected(EDIT_RETRY_WAIT_MS))) throw err;
    return await call();
  }
}

// Coalesced handle updates: at most one UpdateHandles in flight; the newest state wins.
let pending = false;
let inFlight = false;
let dragging = false;
let sequence = 0;

function identityHandle(h: number): HandleState {
  return {
    position: (pivots[h] ?? new THREE.Vector3()).clone(),
    quaternion: new THREE.Quaternion(),
    scale: new THREE.Vector3(1, 1, 1),
  };
}

function fromProtoTransform(t: HandleTransform, h: number): HandleState {
  const q = pivots[h] ?? new THREE.Vector3();
  const rot = t.rotation;
  const R =
    rot && (rot.w !== 0 || rot.x !== 0 || rot.y !== 0 || rot.z !== 0)
      ? new THREE.Quaternion(rot.x, rot.y, rot.z, rot.w).normalize()
      : new THREE.Quaternion();
  const S = new THREE.Vector3(1, 1, 1);
  if (t.scale.case === "uniformScale") S.setScalar(t.scale.value);
  else if (t.scale.case === "axisScale") S.set(t.scale.value.x, t.scale.value.y, t.scale.value.z);
  const tr = new THREE.Vector3(t.translation?.x ?? 0, t.translation?.y ?? 0, t.translation?.z ?? 0);
  if (t.matrix.length === 16) {
    const M = new THREE.Matrix4().fromArray(t.matrix).transpose(); // row-major → three's column-major
    const position = new THREE.Vector3(), quaternion = new THREE.Quaternion(), scale = new THREE.Vector3();
    M.decompose(position, quaternion, scale);
    // x' = M x  ⇔  x' = q + A (x − q) + (M q − q): the gizmo sits at M q.
    return { position: q.clone().applyMatrix4(M), quaternion, scale };
  }
  // x' = p + A (x − p) + t with A = R S; the gizmo at pivot q shows q + t', t' = p − A p + t − q + A q.
  const p = t.pivot ? new THREE.Vector3(t.pivot.x, t.pivot.y, t.pivot.z) : q;
  const A = new THREE.Matrix4().compose(new THREE.Vector3(), R, S);
  const Ap = p.clone().applyMatrix4(A);
  const Aq = q.clone().applyMatrix4(A);
  const position = p.clone().sub(Ap).add(tr).add(Aq);
  return { position, quaternion: R, scale: S };
}

function toProtoTransforms(): MessageInitShape<typeof HandleTransformSchema>[] {
  return handles.map((s, i) => {
    const p = pivots[i] ?? new THREE.Vector3();
    const t = s.position.clone().sub(p);
    const uniform = Math.abs(s.scale.x - 1) < 1e-12 && Math.abs(s.scale.y - 1) < 1e-12 && Math.abs(s.scale.z - 1) < 1e-12;
    return {
      pivot: { x: p.x, y: p.y, z: p.z },
      rotation: { w: s.quaternion.w, x: s.quaternion.x, y: s.quaternion.y, z: s.quaternion.z },
      scale: uniform
        ? { case: undefined }
        : { case: "axisScale" as const, value: { x: s.scale.x, y: s.scale.y, z: s.scale.z } },
      translation: { x: t.x, y: t.y, z: t.z },
    };
  });
}

function vec(v: { x: number; y: number; z: number } | undefined): THREE.Vector3 {
  return v ? new THREE.Vector3(v.x, v.y, v.z) : new THREE.Vector3();
}

/** Adopt a Session message: β, constraints (as labels), pivots, transforms. */
function adoptSession(s: Session, { labels = true, transforms = true } = {}): void {
  session = s;
  betaValue = s.beta?.value ?? 0;
  betaUnits = s.beta?.units ?? BetaUnits.AREA;
  syncBetaUi();
  pivots = s.pivots.map(vec);
  constraintsApplied = s.constrained;
  if (labels && mesh && !labelsDirty) {
    mesh.labels.fill(-1);
    // base-GLB ids (set when they differ from the engine ids in `constraints`: glTF uploads)
    const c = s.baseConstraints ?? s.constraints;
    if (c) {
      for (const id of c.fixed?.ids ?? []) if (id >= 0 && id < mesh.n) mesh.labels[id] = 0;
      c.handles.forEach((h, k) => {
        for (const id of h.ids) if (id >= 0 && id < mesh!.n) mesh!.labels[id] = k + 1;
      });
      handleCount = Math.max(1, c.handles.length);
    }
    updateColours();
    refreshLabelUi();
  }
  if (transforms && !dragging) {
    const count = Math.max(pivots.length, s.transforms.length);
    handles = [];
    for (let h = 0; h < count; h++) {
      handles.push(s.transforms[h] ? fromProtoTransform(s.transforms[h], h) : identityHandle(h));
    }
    placeGizmo();
  }
  updateSessionUi();
}

// ---------------------------------------------------------------------------------------------
// Frames

function applyFrame(frame: Frame, source: "reply" | "watch"): void {
  if (!mesh) return;
  const key = `${frame.version}:${frame.sequence}:${frame.solveMs}`;
  if (key === lastFrameKey) return;
  if (source === "watch" && (dragging || inFlight || pending)) return; // our own edit is newer
  if (frame.positions.byteLength > 0) {
    const p = floats(frame.positions);
    if (p.length !== mesh.n * 3) {
      showError(`Frame has ${p.length / 3} vertices; the mesh has ${mesh.n}`);
      return;
    }
    mesh.cur.set(p);
    if (frame.normals.byteLength === frame.positions.byteLength) mesh.normals.set(floats(frame.normals));
    else computeNormals();
    expandPositions();
    if (source === "watch") scheduleResync();
  }
  if (frame.energies.byteLength > 0) {
    const e = floats(frame.energies);
    if (e.length === mesh.m) {
      const first = mesh.energies === null;
      mesh.energies = e.slice();
      if (first && energyMapping === "truncated" && !truncTouched) defaultTruncation();
      updateColours();
    }
  }
  lastFrameKey = key;
  framesApplied++;
  if (frame.version > frameVersion) {
    frameVersion = frame.version;
    updateSessionUi();
  }
  if (frame.measures) showMeasures(frame.measures, frame.solveMs);
  if (frame.beta && (frame.beta.value !== betaValue || frame.beta.units !== betaUnits)) {
    betaValue = frame.beta.value;
    betaUnits = frame.beta.units;
    syncBetaUi();
  }
}

// Another editor moved a handle: frames carry positions only, so fetch the session once the
// stream goes quiet to bring the gizmo (transforms) and regions up to date.
let resyncTimer: ReturnType<typeof setTimeout> | undefined;
function scheduleResync(): void {
  if (watchOnly) return;
  clearTimeout(resyncTimer);
  resyncTimer = setTimeout(async () => {
    if (dragging || inFlight || pending) return;
    try {
      const s = await client.getSession({ name: sessionName });
      if (!dragging && !inFlight && !pending) adoptSession(s);
    } catch {
      /* the watch loop reports connection problems */
    }
  }, 250);
}

function showMeasures(m: Measures, solveMs: number): void {
  lastMeasures = m;
  $("m-e").textContent = fmt(m.e);
  $("m-iso").textContent = fmt(m.eIsoN);
  $("m-conf").textContent = fmt(m.eConfN);
  $("m-area").textContent = fmt(m.eAreaPct);
  $("m-maxiso").textContent = fmt(m.maxEIso);
  $("m-maxconf").textContent = fmt(m.maxEConf);
  $("m-maxef2").textContent = fmt(m.maxEf2);
  $("m-flips").textContent = String(m.flips);
  $("m-flips").style.color = m.flips > 0 ? "#ff8a80" : "";
  $("m-solve").textContent = `${solveMs.toFixed(1)} ms`;
}

function requestFrame(): void {
  if (!sessionName || watchOnly || !constraintsApplied) return;
  pending = true;
}

function pump(): void {
  if (!pending || inFlight || !sessionName || link !== "connected") return;
  pending = false;
  inFlight = true;
  const name = sessionName;
  let seq = 0;
  edit(() => {
    seq = ++sequence;
    return client.updateHandles({
      name,
      sequence: BigInt(seq),
      transforms: toProtoTransforms(),
      energies: energyMapping !== "off",
      // While the gizmo is held the server may answer with a drag frame (float32 factor);
      // the release sends one more request without it, whose frame is exact.
      dragging,
    });
  })
    .then((frame) => {
      if (name !== sessionName) return; // another session was opened meanwhile
      if (seq === sequence) clearError("rejected");
      applyFrame(frame, "reply");
    })
    .catch((err) => {
      if (isAbort(err)) return;
      showError(`Handle update rejected: ${describeError(err)}`, "rejected");
    })
    .finally(() => {
      inFlight = false;
    });
}

// ---------------------------------------------------------------------------------------------
// Loading sessions

async function loadSession(s: Session): Promise<void> {
  watchAbort?.abort();
  setLink("connected");
  loaded = false;
  lastMeasures = null;
  sessionName = s.name;
  frameVersion = 0n;
  setRoutingSession(s.name);
  // Tokens come with CreateSession / ImportSession answers; a session opened from a link
  // keeps the link's (GetSession never returns them).
  if (s.editToken || s.viewToken) setTokens(s.editToken, s.viewToken);
  labelsDirty = false;
  lastFrameKey = "";
  setStatus(`loading ${s.meshName || s.name}…`);
  const glb = await fetchMesh(client, s.name, true, MeshFormat.GLB);
  const base = await parseGlb(glb);
  buildMesh(base.positions, base.normals, base.index);
  if (s.vertexCount && s.vertexCount !== mesh!.n) {
    showError(`The base GLB has ${mesh!.n} vertices but the session reports ${s.vertexCount}`);
  }
  handles = [];
  adoptSession(s);
  // A shared session may already be deformed: fetch the current shape once.
  if (s.transforms.some((t) => !isIdentity(t))) {
    const current = await parseGlb(await fetchMesh(client, s.name, false, MeshFormat.GLB));
    if (current.positions.length === mesh!.cur.length) {
      mesh!.cur.set(current.positions);
      if (current.normals) mesh!.normals.set(current.normals);
      else computeNormals();
      expandPositions();
    }
  }
  if (!watchOnly) {
    // The address bar becomes this session's editor link, so a reload opens it again.
    const url = new URL(window.location.href);
    url.searchParams.set("session", s.name);
    url.searchParams.delete("watch");
    url.hash = tokenFragment(tokens().edit, tokens().view);
    history.replaceState(null, "", url);
  }
  setMode(watchOnly ? "orbit" : constraintsApplied ? "move" : "box");
  // An editor solves the current pose at once (measures, energies); a watch-only page shows
  // measures from the next frame (a measuring Sweep needs the edit token).
  if (constraintsApplied && !watchOnly) requestFrame();
  else if (constraintsApplied && tokens().edit) void currentMeasures(s);
  watchAbort = new AbortController();
  void watchLoop(s.name, watchAbort.signal);
  loaded = true;
}

/** Measures of the session as it stands, without changing it: a one-β Sweep. */
async function currentMeasures(s: Session): Promise<void> {
  try {
    const res = await client.sweep({ name: s.name, betas: [s.beta?.value ?? 0], units: s.beta?.units ?? BetaUnits.AREA });
    const m = res.rows[0]?.measures;
    if (m && !lastMeasures) showMeasures(m, 0);
  } catch {
    /* measures arrive with the next frame */
  }
}

function isIdentity(t: HandleTransform): boolean {
  if (t.matrix.length === 16) return false;
  const tr = t.translation;
  const r = t.rotation;
  const moved = tr && (tr.x !== 0 || tr.y !== 0 || tr.z !== 0);
  const rotated = r && (r.x !== 0 || r.y !== 0 || r.z !== 0) && !(r.w === 0 && r.x === 0 && r.y === 0 && r.z === 0);
  const scaled =
    (t.scale.case === "uniformScale" && t.scale.value !== 1) ||
    (t.scale.case === "axisScale" && (t.scale.value.x !== 1 || t.scale.value.y !== 1 || t.scale.value.z !== 1)) ||
    t.scale.case === "stretch";
  return !moved && !rotated && !scaled;
}

async function parseGlb(bytes: Uint8Array): Promise<{
  positions: Float32Array;
  normals: Float32Array | null;
  index: Uint32Array;
}> {
  const loader = new GLTFLoader();
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength) as ArrayBuffer;
  const gltf = await loader.parseAsync(buffer, "");
  let found: THREE.Mesh | null = null;
  gltf.scene.traverse((o) => {
    if (!found && (o as THREE.Mesh).isMesh) found = o as THREE.Mesh;
  });
  if (!found) throw new Error("the server's GLB has no mesh");
  const geometry = (found as THREE.Mesh).geometry;
  const pos = geometry.getAttribute("position");
  const n = pos.count;
  const positions = new Float32Array(3 * n);
  for (let i = 0; i < n; i++) {
    positions[3 * i] = pos.getX(i);
    positions[3 * i + 1] = pos.getY(i);
    positions[3 * i + 2] = pos.getZ(i);
  }
  const nor = geometry.getAttribute("normal");
  let normals: Float32Array | null = null;
  if (nor && nor.count === n) {
    normals = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) {
      normals[3 * i] = nor.getX(i);
      normals[3 * i + 1] = nor.getY(i);
      normals[3 * i + 2] = nor.getZ(i);
    }
  }
  const idx = geometry.getIndex();
  const index = idx ? Uint32Array.from(idx.array as ArrayLike<number>) : Uint32Array.from({ length: n }, (_, i) => i);
  return { positions, normals, index };
}

async function openSessionByName(name: string, edit: string, view: string): Promise<void> {
  try {
    setRoutingSession(name);
    setTokens(edit, view);
    const s = await client.getSession({ name });
    await loadSession(s);
  } catch (err) {
    showError(`Could not open ${name}: ${accessError(err, name)}`, "open");
    const placeholder = $("placeholder");
    placeholder.textContent = `Could not open ${name}.`;
    const a = document.createElement("a");
    a.href = window.location.pathname;
    a.textContent = "Start a new session";
    a.style.pointerEvents = "auto";
    a.style.marginLeft = "0.5em";
    placeholder.append(a);
  }
}

/** What an error says about the page's access to `name`, in words a link's user can act on. */
function accessError(err: unknown, name: string): string {
  if (err instanceof ConnectError) {
    if (err.code === Code.Unauthenticated)
      return `this link carries no access token. Open the session with its share link (…#edit=…) or watch link (…#view=…).`;
    if (err.code === Code.PermissionDenied)
      return `the link's token does not open ${name} (a wrong or old link: the session's tokens may have been renewed). [PermissionDenied]`;
    if (err.code === Code.NotFound) return `${name} does not exist on this server. [NotFound]`;
  }
  return describeError(err);
}

async function openLibrary(name: string): Promise<void> {
  try {
    setStatus(`opening ${name}…`);
    const s = await createSessionViaUpload({ library: name });
    await loadSession(s);
    clearError();
  } catch (err) {
    showError(`Could not open ${name}: ${describeError(err)}`);
  }
}

async function uploadFile(file: File): Promise<void> {
  const progress = $<HTMLProgressElement>("upload-progress");
  const label = $("upload-label");
  progress.classList.remove("hidden");
  progress.value = 0;
  label.textContent = file.name;
  try {
    const s = await createSessionViaUpload({ filename: file.name, body: file }, (loaded, total) => {
      progress.value = total > 0 ? loaded / total : 0;
      label.textContent = `${file.name}: ${Math.round((100 * loaded) / (total || file.size || 1))}%`;
    });
    label.textContent = `${file.name}: processing…`;
    await loadSession(s);
    label.textContent = file.name;
    clearError();
  } catch (err) {
    label.textContent = `${file.name}: failed`;
    showError(describeError(err));
  } finally {
    progress.classList.add("hidden");
  }
}

// ---------------------------------------------------------------------------------------------
// WatchSession: every viewer sees every edit

async function watchLoop(name: string, signal: AbortSignal): Promise<void> {
  let delay = RECONNECT_FIRST_MS;
  let resync = false; // re-read the session before watching again
  let attempt = 0;
  let sawDeleted = false;
  while (!signal.aborted) {
    const stream = new AbortController();
    streamAbort = stream;
    const abortStream = () => stream.abort();
    signal.addEventListener("abort", abortStream);
    try {
      if (resync) {
        // GetSession also restores a durable session on a restarted server; NOT_FOUND here is
        // the only proof that the session is gone.
        const s = await client.getSession({ name }, { signal: stream.signal, timeoutMs: 10_000 });
        if (signal.aborted) return;
        frameVersion = 0n; // the server's version is the truth now (a restart may have lost a move)
        adoptSession(s, { labels: true, transforms: !dragging && !inFlight && !pending });
        await refreshShape(name, s, stream.signal);
        resync = false;
        sawDeleted = false;
        attempt = 0;
        delay = RECONNECT_FIRST_MS;
        reconnects++;
        setLink("connected");
        clearError("lost");
      }
      for await (const ev of client.watchSession({ name }, { signal: stream.signal })) {
        if (ev.event.case === "deleted") {
          // Deleted, expired — or the server is stopping: the re-read below tells which.
          sawDeleted = true;
          break;
        }
        handleEvent(ev);
      }
      if (signal.aborted) return;
    } catch (err) {
      if (signal.aborted) return;
      if (err instanceof ConnectError && err.code === Code.NotFound) {
        setLink("gone");
        // Right after a `deleted` event: deleted (or expired). After an outage: it did not
        // survive (a server without durable state, or deleted meanwhile).
        showError(
          sawDeleted && attempt <= 1 ? `Session ${name} was deleted` : `Session ${name} no longer exists on the server`,
          "lost",
        );
        return;
      }
      if (err instanceof ConnectError && (err.code === Code.PermissionDenied || err.code === Code.Unauthenticated)) {
        setLink("gone");
        showError(`Lost access to ${name}: ${accessError(err, name)}`, "lost");
        return;
      }
      if (!isAbort(err) && !isTransient(err)) {
        // An answer, not an outage (e.g. too many watchers): say so, and keep trying.
        showError(`Live updates failed: ${describeError(err)}; retrying…`, "lost");
      }
    } finally {
      signal.removeEventListener("abort", abortStream);
      stream.abort(); // ends a stream left by `break`
    }
    // The stream ended or failed (or an edit found the server away): reconnect with back-off.
    resync = true;
    attempt++;
    setLink("reconnecting", attempt > 1 ? `attempt ${attempt}` : "");
    if (Date.now() - outageSince >= LOST_BANNER_AFTER_MS) {
      showError("Lost connection to the server; reconnecting…", "lost");
    }
    await new Promise<void>((resolve) => {
      const timer = setTimeout(done, delay);
      function done(): void {
        clearTimeout(timer);
        signal.removeEventListener("abort", done);
        resolve();
      }
      signal.addEventListener("abort", done);
    });
    delay = Math.min(delay * 2, RECONNECT_MAX_MS);
  }
}

/** After a reconnect: the session's current shape (frames may have been missed). */
async function refreshShape(name: string, s: Session, signal: AbortSignal): Promise<void> {
  if (!mesh || dragging || inFlight || pending) return; // our own edit brings a newer frame
  const deformed = s.transforms.some((t) => !isIdentity(t));
  const current = deformed
    ? await parseGlb(await fetchMesh(client, name, false, MeshFormat.GLB, signal))
    : { positions: mesh.rest, normals: null };
  if (!mesh || current.positions.length !== mesh.cur.length || dragging || inFlight || pending) return;
  mesh.cur.set(current.positions);
  if (current.normals) mesh.normals.set(current.normals);
  else computeNormals();
  expandPositions();
  lastFrameKey = "";
}

function handleEvent(ev: SessionEvent): void {
  switch (ev.event.case) {
    case "frame":
      applyFrame(ev.event.value, "watch");
      break;
    case "state":
      if (session && ev.event.value.version < session.version) break;
      adoptSession(ev.event.value, { labels: true, transforms: !dragging && !inFlight && !pending });
      break;
  }
  watchEvents++;
}
let watchEvents = 0;

// ---------------------------------------------------------------------------------------------
// Tools: modes, selection

type Mode = "orbit" | "vertex" | "brush" | "box" | "move";
let mode: Mode = "orbit";

function setMode(m: Mode): void {
  mode = watchOnly ? "orbit" : m;
  document.querySelectorAll<HTMLButtonElement>("button.mode").forEach((b) => b.classList.toggle("active", b.dataset.mode === mode));
  const selecting = mode === "vertex" || mode === "brush" || mode === "box";
  // In selection modes the left button selects; the right button orbits and the middle pans.
  orbit.mouseButtons = selecting
    ? { LEFT: null as unknown as THREE.MOUSE, MIDDLE: THREE.MOUSE.PAN, RIGHT: THREE.MOUSE.ROTATE }
    : { LEFT: THREE.MOUSE.ROTATE, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: THREE.MOUSE.PAN };
  renderer.domElement.style.cursor = selecting ? "crosshair" : "";
  if (mode === "move" && labelsDirty) void applyConstraints();
  placeGizmo();
}

function placeGizmo(): void {
  const h = activeHandle - 1;
  const usable = mode === "move" && !watchOnly && constraintsApplied && !labelsDirty && h < handles.length;
  if (!usable) {
    gizmo.detach();
    needsRender = true;
    return;
  }
  const s = handles[h];
  pivotObject.position.copy(s.position);
  pivotObject.quaternion.copy(s.quaternion);
  pivotObject.scale.copy(s.scale);
  pivotObject.updateMatrixWorld(true);
  gizmo.attach(pivotObject);
  needsRender = true;
}

gizmo.addEventListener("dragging-changed", (e) => {
  dragging = (e as unknown as { value: boolean }).value;
  orbit.enabled = !dragging;
  if (!dragging) requestFrame(); // make sure the final pose is solved
});
gizmo.addEventListener("objectChange", () => {
  const h = activeHandle - 1;
  if (h >= handles.length) return;
  handles[h] = {
    position: pivotObject.position.clone(),
    quaternion: pivotObject.quaternion.clone(),
    scale: pivotObject.scale.clone(),
  };
  requestFrame();
});

let currentLabel = 0; // -1 erases
const raycaster = new THREE.Raycaster();
const ndc = new THREE.Vector2();

function toNdc(ev: PointerEvent | MouseEvent): THREE.Vector2 {
  const r = renderer.domElement.getBoundingClientRect();
  ndc.set(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  return ndc;
}

/** The surface point under the pointer in model coordinates, with its triangle. */
function pick(ev: PointerEvent): { point: THREE.Vector3; triangle: number } | null {
  if (!mesh) return null;
  raycaster.setFromCamera(toNdc(ev), camera);
  const hit = raycaster.intersectObject(mesh.object, false)[0];
  if (!hit || hit.faceIndex === undefined || hit.faceIndex === null) return null;
  return { point: root.worldToLocal(hit.point.clone()), triangle: hit.faceIndex };
}

function assign(ids: Iterable<number>, label: number): number {
  if (!mesh) return 0;
  let count = 0;
  for (const id of ids) {
    if (mesh.labels[id] !== label) {
      mesh.labels[id] = label;
      count++;
    }
  }
  if (count > 0) {
    labelsDirty = true;
    if (label > handleCount) handleCount = label;
    placeGizmo();
    updateColours();
    refreshLabelUi();
  }
  return count;
}

/**
 * `v` and every other base vertex at exactly its rest position: the copies of a glTF vertex
 * split at a UV seam, which the server welds into one (so they must share a label). Brush
 * and box selections pick all copies by themselves; a vertex click picks one corner.
 */
function withTwins(v: number): number[] {
  const { rest, n } = mesh!;
  const x = rest[3 * v], y = rest[3 * v + 1], z = rest[3 * v + 2];
  const out: number[] = [];
  for (let u = 0; u < n; u++) {
    if (rest[3 * u] === x && rest[3 * u + 1] === y && rest[3 * u + 2] === z) out.push(u);
  }
  return out;
}

function nearestCorner(point: THREE.Vector3, triangle: number): number {
  const { index, cur } = mesh!;
  let best = index[3 * triangle];
  let bestD = Infinity;
  for (let k = 0; k < 3; k++) {
    const v = index[3 * triangle + k];
    const d = (cur[3 * v] - point.x) ** 2 + (cur[3 * v + 1] - point.y) ** 2 + (cur[3 * v + 2] - point.z) ** 2;
    if (d < bestD) {
      bestD = d;
      best = v;
    }
  }
  return best;
}

function brushRadius(): number {
  return (Number(($("brush-radius") as HTMLInputElement).value) / 100) * (mesh?.diag ?? 1);
}

function verticesWithin(center: THREE.Vector3, radius: number): number[] {
  const out: number[] = [];
  const { cur, n } = mesh!;
  const r2 = radius * radius;
  for (let v = 0; v < n; v++) {
    const d = (cur[3 * v] - center.x) ** 2 + (cur[3 * v + 1] - center.y) ** 2 + (cur[3 * v + 2] - center.z) ** 2;
    if (d <= r2) out.push(v);
  }
  return out;
}

let brushing = false;
let boxStart: { x: number; y: number } | null = null;
const canvas = renderer.domElement;

canvas.addEventListener("pointerdown", (ev) => {
  if (ev.button !== 0 || !mesh || watchOnly) return;
  if (mode === "vertex") {
    const hit = pick(ev);
    if (hit) assign(withTwins(nearestCorner(hit.point, hit.triangle)), currentLabel);
  } else if (mode === "brush") {
    brushing = true;
    canvas.setPointerCapture(ev.pointerId);
    const hit = pick(ev);
    if (hit) assign(verticesWithin(hit.point, brushRadius()), currentLabel);
  } else if (mode === "box") {
    const r = viewport.getBoundingClientRect();
    boxStart = { x: ev.clientX - r.left, y: ev.clientY - r.top };
    canvas.setPointerCapture(ev.pointerId);
    drawBox(boxStart.x, boxStart.y);
  }
});
canvas.addEventListener("pointermove", (ev) => {
  if (brushing && mode === "brush") {
    const hit = pick(ev);
    if (hit) assign(verticesWithin(hit.point, brushRadius()), currentLabel);
  } else if (boxStart) {
    const r = viewport.getBoundingClientRect();
    drawBox(ev.clientX - r.left, ev.clientY - r.top);
  }
});
canvas.addEventListener("pointerup", (ev) => {
  brushing = false;
  if (boxStart) {
    const r = viewport.getBoundingClientRect();
    const end = { x: ev.clientX - r.left, y: ev.clientY - r.top };
    selectScreenRect(boxStart, end, currentLabel);
    boxStart = null;
    $("boxsel").classList.add("hidden");
  }
});

function drawBox(x: number, y: number): void {
  if (!boxStart) return;
  const el = $("boxsel");
  el.classList.remove("hidden");
  el.style.left = `${Math.min(boxStart.x, x)}px`;
  el.style.top = `${Math.min(boxStart.y, y)}px`;
  el.style.width = `${Math.abs(x - boxStart.x)}px`;
  el.style.height = `${Math.abs(y - boxStart.y)}px`;
}

/** Box select: every vertex whose projection falls in the screen rectangle (through the mesh). */
function selectScreenRect(a: { x: number; y: number }, b: { x: number; y: number }, label: number): number {
  if (!mesh) return 0;
  const w = viewport.clientWidth;
  const h = viewport.clientHeight;
  const x0 = Math.min(a.x, b.x), x1 = Math.max(a.x, b.x), y0 = Math.min(a.y, b.y), y1 = Math.max(a.y, b.y);
  if (x1 - x0 < 2 || y1 - y0 < 2) return 0;
  root.updateMatrixWorld(true);
  const M = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse).multiply(root.matrixWorld);
  const p = new THREE.Vector3();
  const ids: number[] = [];
  for (let v = 0; v < mesh.n; v++) {
    p.set(mesh.cur[3 * v], mesh.cur[3 * v + 1], mesh.cur[3 * v + 2]).applyMatrix4(M);
    if (p.z < -1 || p.z > 1) continue;
    const sx = ((p.x + 1) / 2) * w;
    const sy = ((1 - p.y) / 2) * h;
    if (sx >= x0 && sx <= x1 && sy >= y0 && sy <= y1) ids.push(v);
  }
  return assign(ids, label);
}

async function applyConstraints(): Promise<void> {
  if (!mesh || !sessionName) return;
  // Compact handle labels so the handles sent are 1..k without gaps.
  const used = new Set<number>();
  for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] > 0) used.add(mesh.labels[v]);
  const order = [...used].sort((x, y) => x - y);
  const remap = new Map(order.map((l, i) => [l, i + 1]));
  const fixed: number[] = [];
  const handleIds: number[][] = order.map(() => []);
  for (let v = 0; v < mesh.n; v++) {
    const l = mesh.labels[v];
    if (l === 0) fixed.push(v);
    else if (l > 0) {
      const k = remap.get(l)!;
      mesh.labels[v] = k;
      handleIds[k - 1].push(v);
    }
  }
  if (handleIds.length === 0) {
    showError("Select at least one handle region before applying constraints", "rejected");
    return;
  }
  // Vertex indices of the base GLB this viewer loaded: the server maps them through its weld
  // map (glTF uploads), so they need not be engine ids.
  const region = (ids: number[]) => ({ selectors: ids.length ? [{ kind: { case: "baseIds" as const, value: { ids } } }] : [] });
  try {
    setStatus("factorizing…");
    const name = sessionName;
    const s = await edit(() =>
      client.setConstraints({ name, constraints: { fixed: region(fixed), handles: handleIds.map(region) } }),
    );
    if (name !== sessionName) return;
    labelsDirty = false;
    clearError("rejected");
    handles = [];
    adoptSession(s, { labels: true, transforms: false });
    handles = pivots.map((_, h) => identityHandle(h));
    handleCount = Math.max(1, handleIds.length);
    if (activeHandle > handleIds.length) activeHandle = 1;
    refreshLabelUi();
    placeGizmo();
    requestFrame();
  } catch (err) {
    showError(`Constraints rejected: ${describeError(err)}`, "rejected");
  }
}

function refreshLabelUi(): void {
  const sel = $<HTMLSelectElement>("label-select");
  const opts = [`<option value="0">Fixed</option>`];
  for (let h = 1; h <= handleCount; h++) opts.push(`<option value="${h}">Handle ${h}</option>`);
  opts.push(`<option value="-1">Erase</option>`);
  sel.innerHTML = opts.join("");
  sel.value = String(currentLabel <= handleCount ? currentLabel : 0);
  const act = $<HTMLSelectElement>("active-handle");
  const n = Math.max(handles.length, 1);
  act.innerHTML = Array.from({ length: n }, (_, i) => `<option value="${i + 1}">Handle ${i + 1}</option>`).join("");
  act.value = String(Math.min(activeHandle, n));
  updateRegionCounts();
}

function updateRegionCounts(): void {
  if (!mesh) return;
  const counts = new Map<number, number>();
  for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] >= 0) counts.set(mesh.labels[v], (counts.get(mesh.labels[v]) ?? 0) + 1);
  const parts = [`fixed ${counts.get(0) ?? 0}`];
  for (let h = 1; h <= handleCount; h++) parts.push(`handle ${h}: ${counts.get(h) ?? 0}`);
  $("region-counts").textContent = parts.join(" · ") + (labelsDirty ? " — not applied" : "");
}

// ---------------------------------------------------------------------------------------------
// UI wiring

document.querySelectorAll<HTMLButtonElement>("button.mode").forEach((b) =>
  b.addEventListener("click", () => setMode(b.dataset.mode as Mode)),
);
document.querySelectorAll<HTMLButtonElement>("button.gizmo-mode").forEach((b) =>
  b.addEventListener("click", () => {
    gizmo.setMode(b.dataset.gizmo as "translate" | "rotate" | "scale");
    document.querySelectorAll("button.gizmo-mode").forEach((x) => x.classList.toggle("active", x === b));
  }),
);
document.querySelector<HTMLButtonElement>('button[data-gizmo="translate"]')!.classList.add("active");
$<HTMLSelectElement>("label-select").addEventListener("change", (e) => {
  currentLabel = Number((e.target as HTMLSelectElement).value);
});
$("new-handle").addEventListener("click", () => {
  handleCount++;
  currentLabel = handleCount;
  refreshLabelUi();
});
$<HTMLSelectElement>("active-handle").addEventListener("change", (e) => {
  activeHandle = Number((e.target as HTMLSelectElement).value);
  placeGizmo();
});
$("clear-label").addEventListener("click", () => {
  if (!mesh) return;
  const ids: number[] = [];
  for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] === currentLabel) ids.push(v);
  assign(ids, -1);
});
$("clear-all").addEventListener("click", () => {
  if (!mesh) return;
  const ids: number[] = [];
  for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] >= 0) ids.push(v);
  assign(ids, -1);
  handleCount = 1;
  refreshLabelUi();
});
$("apply").addEventListener("click", () => void applyConstraints());
$("reset-handles").addEventListener("click", () => {
  handles = pivots.map((_, h) => identityHandle(h));
  placeGizmo();
  requestFrame();
});
const brushInput = $<HTMLInputElement>("brush-radius");
const showBrush = () => ($("brush-radius-val").textContent = `${brushInput.value}%`);
brushInput.addEventListener("input", showBrush);
showBrush();

// β
const betaInput = $<HTMLInputElement>("beta");
const betaRaw = $<HTMLInputElement>("beta-raw");
function syncBetaUi(): void {
  betaInput.value = String(betaValue);
  $("beta-val").textContent = betaValue.toFixed(2);
  betaRaw.checked = betaUnits === BetaUnits.RAW;
  drawSweep();
}
betaInput.addEventListener("input", () => ($("beta-val").textContent = Number(betaInput.value).toFixed(2)));
async function sendBeta(): Promise<void> {
  if (!sessionName) return;
  const value = Number(betaInput.value);
  const units = betaRaw.checked ? BetaUnits.RAW : BetaUnits.AREA;
  try {
    setStatus("refactorizing for β…");
    const name = sessionName;
    const s = await edit(() => client.setBeta({ name, beta: { value, units } }));
    if (name !== sessionName) return;
    adoptSession(s, { labels: false, transforms: false });
    requestFrame();
  } catch (err) {
    showError(`β rejected: ${describeError(err)}`, "rejected");
    syncBetaUi();
  }
}
betaInput.addEventListener("change", () => void sendBeta());
betaRaw.addEventListener("change", () => void sendBeta());

// Energy map and wireframe
const energySelect = $<HTMLSelectElement>("energy-map");
const truncInput = $<HTMLInputElement>("energy-trunc");
function truncateValue(): number {
  return Number(truncInput.value) || 0;
}
let truncTouched = false; // the user typed a truncation value
function defaultTruncation(): void {
  if (mesh?.energies) truncInput.value = fmt(scaleTop("linear", mesh.energies, 0) / 2);
}
energySelect.addEventListener("change", () => {
  energyMapping = energySelect.value as EnergyMapping;
  truncInput.classList.toggle("hidden", energyMapping !== "truncated");
  if (energyMapping === "truncated" && !truncTouched) defaultTruncation();
  if (energyMapping !== "off" && !mesh?.energies) requestFrame();
  updateColours();
});
truncInput.addEventListener("input", () => {
  truncTouched = true;
  updateColours();
});
$<HTMLInputElement>("wireframe").addEventListener("change", (e) => {
  if (mesh) mesh.wire.visible = (e.target as HTMLInputElement).checked;
  needsRender = true;
});

// Sweep
const sweepSelect = $<HTMLSelectElement>("sweep-measure");
function drawSweep(): void {
  const key = sweepSelect.value as keyof Measures;
  sweepPoints = sweepRows.map((r) => ({ beta: r.beta, value: Number(r.measures[key]) }));
  drawChart($<HTMLCanvasElement>("chart"), sweepPoints, sweepSelect.selectedOptions[0]?.text ?? String(key), betaValue);
}
sweepSelect.addEventListener("change", drawSweep);
$("sweep").addEventListener("click", async () => {
  if (!sessionName) return;
  const betas = [0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95];
  const button = $<HTMLButtonElement>("sweep");
  button.disabled = true;
  button.textContent = "Sweeping…";
  try {
    const res = await client.sweep({
      name: sessionName,
      betas,
      units: betaRaw.checked ? BetaUnits.RAW : BetaUnits.AREA,
      transforms: toProtoTransforms(),
    });
    sweepRows = res.rows.filter((r) => r.measures).map((r) => ({ beta: r.beta, measures: r.measures! }));
    drawSweep();
  } catch (err) {
    showError(`Sweep failed: ${describeError(err)}`, "rejected");
  } finally {
    button.disabled = false;
    button.textContent = "Sweep β";
  }
});

// Downloads
function saveBytes(bytes: Uint8Array | string, filename: string, type: string): void {
  const blob = new Blob([bytes as BlobPart], { type });
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10_000);
}
function baseName(): string {
  return (session?.meshName || "mesh").replace(/\.[^.]+$/, "").replace(/[^\w.-]+/g, "_");
}
async function download(format: MeshFormat, ext: string, type: string): Promise<void> {
  try {
    saveBytes(await fetchMesh(client, sessionName, false, format), `${baseName()}-deformed.${ext}`, type);
  } catch (err) {
    showError(`Download failed: ${describeError(err)}`);
  }
}
$("dl-glb").addEventListener("click", () => void download(MeshFormat.GLB, "glb", "model/gltf-binary"));
$("dl-obj").addEventListener("click", () => void download(MeshFormat.OBJ, "obj", "text/plain"));
async function exportSnapshot(json: boolean): Promise<void> {
  try {
    const snap = await client.exportSession({ name: sessionName, includeMesh: true });
    if (json) saveBytes(toJsonString(SnapshotSchema, snap, { prettySpaces: 2 }), `${baseName()}-session.json`, "application/json");
    else saveBytes(toBinary(SnapshotSchema, snap), `${baseName()}-session.pb`, "application/x-protobuf");
  } catch (err) {
    showError(`Export failed: ${describeError(err)}`);
  }
}
$("dl-json").addEventListener("click", () => void exportSnapshot(true));
$("dl-bin").addEventListener("click", () => void exportSnapshot(false));
$<HTMLInputElement>("import-input").addEventListener("change", async (e) => {
  const input = e.target as HTMLInputElement;
  const file = input.files?.[0];
  input.value = "";
  if (!file) return;
  try {
    const bytes = new Uint8Array(await file.arrayBuffer());
    const snapshot = file.name.endsWith(".json")
      ? fromJsonString(SnapshotSchema, new TextDecoder().decode(bytes))
      : fromBinary(SnapshotSchema, bytes);
    // A client-chosen id, sent as the routing header too: behind a load balancer the import
    // then lands on the replica that every later call of the new session reaches.
    const id = newSessionId();
    setRoutingSession(id);
    const s = await client.importSession({ snapshot, sessionId: id });
    await loadSession(s);
    clearError();
  } catch (err) {
    if (sessionName) setRoutingSession(sessionName); // still showing the previous session
    showError(`Import failed: ${describeError(err)}`);
  }
});

// Share links: the session in the query, the token only in the fragment. The editor link
// carries the edit token (and the view token, so that its users can hand out watch links
// too); the watch link only the view token. "" when this page lacks the token.
function shareLink(watch: boolean): string {
  const { edit, view } = tokens();
  if (!sessionName || (watch ? !view : !edit)) return "";
  const url = new URL(window.location.pathname, window.location.origin);
  url.searchParams.set("session", sessionName);
  if (watch) url.searchParams.set("watch", "1");
  url.hash = watch ? tokenFragment("", view) : tokenFragment(edit, view);
  return url.toString();
}
async function copyLink(watch: boolean): Promise<void> {
  const link = shareLink(watch);
  if (!link) return;
  try {
    await navigator.clipboard.writeText(link);
    setStatus(`copied ${link}`);
  } catch {
    window.prompt("Copy this link", link);
  }
}
$("copy-share").addEventListener("click", () => void copyLink(false));
$("copy-watch").addEventListener("click", () => void copyLink(true));

function updateSessionUi(): void {
  const has = !!sessionName;
  for (const id of ["dl-glb", "dl-obj", "dl-json", "dl-bin"]) $<HTMLButtonElement>(id).disabled = !has;
  $<HTMLButtonElement>("copy-share").disabled = shareLink(false) === "";
  $<HTMLButtonElement>("copy-watch").disabled = shareLink(true) === "";
  $("session-label").textContent = has ? `${session?.meshName ?? ""} · ${sessionName}` : "no session";
  if (mesh && session) {
    setStatus(`${mesh.n} vertices · ${mesh.m} triangles · version ${shownVersion()} · ${session.observers} watching`);
  }
}

// Library and upload
async function listLibrary(): Promise<void> {
  try {
    const res = await client.listMeshes({});
    const sel = $<HTMLSelectElement>("library");
    sel.innerHTML = res.meshes
      .map((m) => `<option value="${m.name}">${m.name}${m.hasBenchmark ? " ★" : ""}</option>`)
      .join("");
    const cactus = res.meshes.find((m) => m.name === "cactus");
    if (cactus) sel.value = "cactus";
  } catch (err) {
    showError(`Cannot reach the server: ${describeError(err)}`, "lost");
  }
}
$("open-library").addEventListener("click", () => void openLibrary($<HTMLSelectElement>("library").value));
$<HTMLInputElement>("upload-input").addEventListener("change", (e) => {
  const input = e.target as HTMLInputElement;
  const file = input.files?.[0];
  input.value = "";
  if (file) void uploadFile(file);
});

// ---------------------------------------------------------------------------------------------
// Main loop: one render per change; handle updates coalesced to the display frame rate.

function frame(): void {
  pump();
  if (needsRender) {
    needsRender = false;
    renderer.render(scene, camera);
  }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);

refreshLabelUi();
setMode("orbit");
drawSweep();
void listLibrary();
if (initialSession) void openSessionByName(initialSession, linkTokens.edit, linkTokens.view);

// ---------------------------------------------------------------------------------------------
// Test hook (tests/browser): state and the same code paths the UI uses.

declare global {
  interface Window {
    hdeform: unknown;
  }
}
window.hdeform = {
  get loaded() {
    return loaded && !!mesh;
  },
  get sessionName() {
    return sessionName;
  },
  /** The newest version seen: of the session, or of a frame (handle moves bump it too). */
  get version() {
    return shownVersion();
  },
  get framesApplied() {
    return framesApplied;
  },
  get watchEvents() {
    return watchEvents;
  },
  get constraintsApplied() {
    return constraintsApplied && !labelsDirty;
  },
  get lastError() {
    return $("banner").classList.contains("hidden") ? "" : lastError;
  },
  get busy() {
    return pending || inFlight || dragging;
  },
  bbox(): number[][] {
    const b = new THREE.Box3().setFromArray(mesh!.rest);
    return [b.min.toArray(), b.max.toArray()];
  },
  /** Assigns every vertex whose rest position lies in the model-space box; returns the count. */
  selectBox(min: number[], max: number[], label: number): number {
    if (!mesh) return 0;
    const ids: number[] = [];
    for (let v = 0; v < mesh.n; v++) {
      const x = mesh.rest[3 * v], y = mesh.rest[3 * v + 1], z = mesh.rest[3 * v + 2];
      if (x >= min[0] && x <= max[0] && y >= min[1] && y <= max[1] && z >= min[2] && z <= max[2]) ids.push(v);
    }
    assign(ids, label);
    return ids.length;
  },
  selectScreenRect: (a: { x: number; y: number }, b: { x: number; y: number }, label: number) =>
    selectScreenRect(a, b, label),
  applyConstraints,
  setMode,
  openLibrary,
  /**
   * Client coordinates of the gizmo's centre (the active handle's pivot), or of a point on
   * one of its translate arrows (world axis, 0.6 of the arrow's length, as TransformControls
   * sizes it).
   */
  gizmoScreenPoint(axis?: "x" | "y" | "z"): { x: number; y: number } | null {
    if (!gizmo.object) return null;
    const world = pivotObject.getWorldPosition(new THREE.Vector3());
    if (axis) {
      const factor =
        world.distanceTo(camera.position) * Math.min((1.9 * Math.tan((Math.PI * camera.fov) / 360)) / camera.zoom, 7);
      const length = (factor * gizmo.size) / 4;
      world.add(new THREE.Vector3(axis === "x" ? 1 : 0, axis === "y" ? 1 : 0, axis === "z" ? 1 : 0).multiplyScalar(0.6 * length));
    }
    const p = world.project(camera);
    const r = renderer.domElement.getBoundingClientRect();
    return { x: r.left + ((p.x + 1) / 2) * r.width, y: r.top + ((1 - p.y) / 2) * r.height };
  },
  /** Client coordinates of a model-space point. */
  screenPoint(x: number, y: number, z: number): { x: number; y: number } {
    const p = root.localToWorld(new THREE.Vector3(x, y, z)).project(camera);
    const r = renderer.domElement.getBoundingClientRect();
    return { x: r.left + ((p.x + 1) / 2) * r.width, y: r.top + ((1 - p.y) / 2) * r.height };
  },
  positions(): number[] {
    return mesh ? Array.from(mesh.cur) : [];
  },
  restPositions(): number[] {
    return mesh ? Array.from(mesh.rest) : [];
  },
  labels(): number[] {
    return mesh ? Array.from(mesh.labels) : [];
  },
  measures() {
    return lastMeasures ? { ...lastMeasures } : null;
  },
  handleTransforms: () => toProtoTransforms(),
  get sweepRows() {
    return sweepRows.length;
  },
  get meshName() {
    return session?.meshName ?? "";
  },
  shareLink,
  get watchOnly() {
    return watchOnly;
  },
  /** "connected" | "reconnecting" | "gone" */
  get connection() {
    return link;
  },
  get reconnects() {
    return reconnects;
  },
  get status() {
    return $("status").textContent ?? "";
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

// hdeform web viewer: wires the session state, the viewport, the selection tools, the panels
// and sync (live frames over gRPC-Web) together, and runs the animation-frame loop.
import { describeError, makeClient } from "./api";
import { CommandLayer } from "./commands/command_layer";
import { reloadAfterConflict } from "./conflict";
import type { App } from "./app";
import { $ } from "./dom";
import { setupFrameApply } from "./frame_apply";
import { frameFormatFromQuery } from "./frame_format";
import { readPageLink } from "./links";
import { Banner } from "./panels/banner";
import { setupBetaPanel } from "./panels/beta";
import { setupDisplayPanel } from "./panels/display";
import { setupFilesPanel } from "./panels/files";
import { setupExportUp } from "./panels/export_up";
import { setupHandleTools } from "./panels/handle_tools";
import { setupLibraryPanel } from "./panels/library";
import { setupMeasuresPanel } from "./panels/measures";
import { setupRegionsPanel } from "./panels/regions";
import { setupSessionBar } from "./panels/session_bar";
import { setupLayout } from "./panels/layout";
import { setupSweepPanel } from "./panels/sweep";
import { StatusLine } from "./panels/status_line";
import { SelectionTools } from "./selection/tools";
import { SessionLoader } from "./session_loader";
import { SessionState } from "./state";
import { Sync } from "./sync/sync";
import { installTestHook } from "./test_hook";
import { fromProtoTransform, toProtoTransforms } from "./transforms";
import { create } from "@bufbuild/protobuf";
import { HandleTransformSchema } from "./gen/hdeform/v1/deform_pb";
import { setupEditors, type Editors } from "./multi/editors";
import { setupPresencePanel } from "./panels/presence_panel";
import { setupShortcuts } from "./panels/shortcuts";
import { setupTransformFields } from "./panels/transform_fields";
import { setupOnboarding } from "./panels/onboarding";
import { setupViewButtons } from "./panels/view_buttons";
import { setupHistoryPanel } from "./panels/history_panel";
import { setupSnapshotsPanel } from "./panels/snapshots_panel";
import { setupWeightsView } from "./weights/weights_view";
import { HeldOutline } from "./viewport/held_outline";
import { setupUndoRedo } from "./history/undo_redo";
import { setupUndoShortcuts } from "./history/undo_shortcuts";
import { CursorFeedback } from "./selection/cursor_feedback";
import { RegionMarkers } from "./viewport/region_markers";
import { HandleGizmo } from "./viewport/handle_gizmo";
import { MeshDisplay } from "./viewport/mesh_display";
import { Viewport } from "./viewport/viewport";
import { contentBox } from "./viewport/content_box";
import { ViewSnap } from "./viewport/view_snap";
import { AxesViewHelper } from "./viewport/axes_view_helper";
import { GroundGrid } from "./viewport/ground_grid";
import { viewDirection } from "./viewport/view_axes";
import { AnimationPlayer } from "./timeline/animation_player";
import { Scrub } from "./timeline/scrub";
import { setupTimelinePanel } from "./timeline/timeline_panel";
import { setupRigExport } from "./rig/rig_export";
import { PerfStats } from "./perf/perf_stats";
import { setupPerfOverlay } from "./perf/perf_overlay";

const link = readPageLink();
// Another link pasted over this one's fragment (same page, same query) must not leave the
// page on the old tokens: open it afresh.
window.addEventListener("hashchange", () => window.location.reload());

const banner = new Banner();
const status = new StatusLine();
let viewport: Viewport;
try {
  viewport = new Viewport($("viewport"));
} catch (e) {
  banner.show(`WebGL is not available in this browser: ${describeError(e)}`);
  throw e;
}

const state = new SessionState(link.watchOnly);
const client = makeClient();
const frameFormat = frameFormatFromQuery(window.location.search);
if (frameFormat.error) banner.show(frameFormat.error);
// The one command layer: every change the page makes goes through it (commands/).
const commands = new CommandLayer({
  client,
  clientId: () => editors.identity.clientId,
  retry: (call) => sync.edit(call),
  refused: (text) => banner.show(text, "rejected"),
  accepted: () => banner.clear("rejected"),
  conflict: (what, err) => reloadAfterConflict(app, what, err),
});
const sync: Sync = new Sync({
  client,
  commands,
  format: frameFormat.format,
  // Pipelined: a second update is sent while the first is solved (coalesce: the server skips
  // one a newer overtook; omit_buffers: frames come once, on the WatchSession stream), so the
  // server has the next pose as soon as it finishes one. Sync keeps the drag's last update
  // solved and its exact frame shown (sync/sync.ts).
  window: 2,
  pose: () => ({
    transforms: toProtoTransforms(state.handles, state.pivots),
    // Several editors: only the handle this page moves, so the others' handles stay theirs
    // (a timeline scrub moves them all: it holds them all).
    handles: editors.multi && !scrub.allHandles ? [state.activeHandle - 1] : undefined,
    energies: state.energyMapping !== "off",
  }),
  participant: () => editors.identity.participant(),
  refreshShape: (name, s, signal) => loader.refreshShape(name, s, signal),
});
const app: App = {
  state,
  client,
  banner,
  status,
  edits: {
    execute: commands.execute.bind(commands),
    lane: (key) => commands.lane(key),
    requestFrame: () => {
      if (state.sessionName && !state.watchOnly && state.constraintsApplied) sync.request();
    },
  },
};
const loader: SessionLoader = new SessionLoader(app, sync);
const editors: Editors = setupEditors(app, sync);

sync.on("link", ({ link, why }) => status.setReconnecting(link === "reconnecting" ? `reconnecting…${why ? ` (${why})` : ""}` : ""));
sync.on("error", ({ message, kind }) => banner.show(message, kind));
sync.on("clearError", (kind) => banner.clear(kind));
sync.on("state", ({ session, source, adoptTransforms }) => {
  if (source === "watch" && state.session && session.version < state.session.version) return;
  if (source === "resync") state.frameVersion = 0n; // the server's version is the truth now
  state.adoptSession(session, { labels: true, transforms: adoptTransforms });
});
// A failed update: the gizmo goes back to the pose the server holds (the mesh shows that one).
sync.on("revert", ({ transforms }) => {
  if (gizmo.dragging) return; // the drag's release sends its pose again
  state.handles = transforms.map((t, h) => fromProtoTransform(create(HandleTransformSchema, t), state.pivots[h]));
  state.emit("handles", undefined);
});
// Every applied frame's cost, bytes and latency, for the perf overlay (P).
const perfStats = new PerfStats();
const frameApply = setupFrameApply(app, sync, perfStats, () => editors.identity.clientId);
// Home, Frame all and the default view frame the current shape and the gizmos; so does a
// session that opens already deformed, once its current shape is in.
viewport.contentBox = () => contentBox(state);
state.on("opened", () => viewport.resetView());

const display = new MeshDisplay(viewport, state);
const grid = new GroundGrid(viewport, state); // after the display: its "mesh" listener sets the up axis
const viewSnap = new ViewSnap(viewport);
const axesHelper = new AxesViewHelper(viewport, viewSnap);
const gizmo = new HandleGizmo(viewport, state, {
  dragging: (held) => sync.setDragging(held),
  moved: () => app.edits.requestFrame(),
  grab: (h) => editors.grab(h),
  release: () => editors.release(),
});
const tools = new SelectionTools(viewport, display, state);
const feedback = new CursorFeedback(viewport, display, state, () => tools.brushRadius());
const markers = new RegionMarkers(viewport, state);
const regions = setupRegionsPanel(app);
setupHandleTools(app, gizmo, () => editors.multi);
setupTransformFields(app, gizmo);
setupPresencePanel(editors, sync);
setupViewButtons(app, viewport);
const weights = setupWeightsView(app);
const outline = new HeldOutline(viewport, state);
// The timeline strip: scrubbing poses the session (PoseAt → updates), Play shows the exported GLB.
const scrub: Scrub = new Scrub(app, sync, editors, (m, e) => timeline.say(m, e));
const player = new AnimationPlayer(viewport, display);
const exportUp = setupExportUp(state, () => viewport.upAxis);
const timeline = setupTimelinePanel(app, sync, editors, scrub, player, exportUp);
const rig = setupRigExport(app, exportUp, (m, e) => timeline.say(m, e));
const perf = setupPerfOverlay(state, perfStats);
setupShortcuts(app, gizmo, viewport, {
  toggleWeights: () => weights.toggle(),
  setKey: () => timeline.setKey(),
  togglePerf: () => perf.toggle(),
  select: (command) => regions.select(command),
  lookFrom: (view) => viewSnap.lookFrom(viewDirection(view, viewport.upAxis)),
  toggleXray: () => tools.xray.toggle(),
});
setupOnboarding(app);
setupBetaPanel(app);
setupDisplayPanel(app, display, grid);
setupMeasuresPanel(state);
const sweep = setupSweepPanel(app);
setupFilesPanel(app, (s) => loader.load(s), exportUp);
setupSessionBar(app);
setupLayout();
// History: undo / redo by this tab's client id (the one presence and updates carry).
const myId = () => editors.identity.clientId;
const undoRedo = setupUndoRedo(app, sync, myId);
setupUndoShortcuts(undoRedo);
const history = setupHistoryPanel(app, sync, undoRedo);
const snapshots = setupSnapshotsPanel(app, sync, undoRedo, myId);
setupLibraryPanel(app, loader, regions.applyConstraints);

// One render per change; handle updates coalesced to the display frame rate.
function frame(): void {
  sync.tick();
  timeline.update();
  viewport.renderIfNeeded();
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);

state.setMode("orbit");
if (link.session) void loader.openByName(link.session, link.edit, link.view);

// window.hdeform (state, tokens, any call with the page's token) is for the browser tests only:
// built into `vite build --mode test` bundles; production ones leave the hook's code out.
if (import.meta.env.MODE === "test") installTestHook(app, {
  sync,
  frameApply,
  display,
  viewport,
  gizmo,
  tools,
  applyConstraints: regions.applyConstraints,
  openLibrary: (name) => loader.openLibrary(name),
  sweepRows: sweep.rows,
  sweepRange: sweep.chartRange,
  editors,
  feedback,
  markers,
  history: history.list,
  snapshots,
  weights,
  outline,
  timeline,
  scrub,
  player,
  rig,
  perf,
  select: regions.select,
  viewSnap,
  axesHelper,
  grid,
});

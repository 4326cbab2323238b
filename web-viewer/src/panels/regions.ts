// The Regions panel: what the tools assign (Fixed, Handle k, Erase), + handle, Clear, the
// per-region counts, and Apply constraints (SetConstraints; also on entering Move with
// unapplied edits).
import { regionColourCss } from "../region_colours";
import { openMeshFirst } from "./banner";
import type { App } from "../app";
import { $ } from "../dom";
import { handleName, handleWord, labelName } from "../handle_names";
import { adjacency, selectionChange, type Adjacency, type SelectionCommand } from "../selection/commands";
import type { MeshData } from "../state";
import type { Session } from "../gen/hdeform/v1/deform_pb";

export interface RegionsPanel {
  applyConstraints: () => Promise<void>;
  /** Select all / none / invert / grow / shrink on the region being assigned; the count changed (−1: not done). */
  select: (command: SelectionCommand) => number;
}

export function setupRegionsPanel(app: App): RegionsPanel {
  const { state, banner, status, edits } = app;
  const labelSelect = $<HTMLSelectElement>("label-select");
  const activeSelect = $<HTMLSelectElement>("active-handle");

  const showCounts = () => {
    const mesh = state.mesh;
    if (!mesh) return;
    const counts = new Map<number, number>();
    for (let v = 0; v < mesh.n; v++) if (mesh.labels[v] >= 0) counts.set(mesh.labels[v], (counts.get(mesh.labels[v]) ?? 0) + 1);
    // Also the legend of the regions' colours on the mesh.
    const swatch = (label: number) => `<span class="swatch" style="background:${state.heldColours.get(label) ?? regionColourCss(label)}"></span>`;
    const parts = [`${swatch(0)}fixed ${counts.get(0) ?? 0}`];
    for (let h = 1; h <= state.handleCount; h++) parts.push(`${swatch(h)}${handleWord(h - 1)}: ${counts.get(h) ?? 0}`);
    $("region-counts").innerHTML = parts.join(" · ") + (state.labelsDirty ? " — <b>not applied</b>" : "");
  };
  const showLabels = () => {
    const opts = [`<option value="0">Fixed</option>`];
    // Values are region labels (h ≥ 1), the text the handle's index (handle_names.ts).
    for (let h = 1; h <= state.handleCount; h++) opts.push(`<option value="${h}">${labelName(h)}</option>`);
    opts.push(`<option value="-1">Erase</option>`);
    labelSelect.innerHTML = opts.join("");
    labelSelect.value = String(state.currentLabel <= state.handleCount ? state.currentLabel : 0);
    const n = Math.max(state.handles.length, 1);
    activeSelect.innerHTML = Array.from({ length: n }, (_, i) => `<option value="${i + 1}">${handleName(i)}</option>`).join("");
    activeSelect.value = String(Math.min(state.activeHandle, n));
    showCounts();
  };

  async function applyConstraints(): Promise<void> {
    const mesh = state.mesh;
    const name = state.sessionName;
    if (!mesh || !name) return openMeshFirst(banner);
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
      banner.show("Select at least one handle region before applying constraints", "rejected");
      return;
    }
    // Vertex indices of the base GLB this viewer loaded: the server maps them through its weld
    // map (glTF uploads), so they need not be engine ids.
    const region = (ids: number[]) => ({ selectors: ids.length ? [{ kind: { case: "baseIds" as const, value: { ids } } }] : [] });
    status.set("factorizing…");
    let s: Session;
    try {
      s = await edits.execute({
        method: "setConstraints",
        what: "Constraints",
        dropsKeys: true,
        request: () => ({
          name,
          constraints: { fixed: region(fixed), handles: handleIds.map(region) },
          expectedConfigVersion: state.session?.configVersion ?? 0n,
        }),
      });
    } catch {
      return; // the layer said why (or re-read the session)
    }
    if (name !== state.sessionName) return;
    state.labelsDirty = false;
    state.handles = [];
    state.adoptSession(s, { labels: true, transforms: false });
    state.handleCount = Math.max(1, handleIds.length);
    if (state.activeHandle > handleIds.length) state.activeHandle = 1;
    state.resetHandles();
    showLabels();
    edits.requestFrame();
  }

  state.on("labels", showLabels);
  state.on("mesh", showLabels); // "Assign to" and the handles offered start afresh
  state.on("colours", showCounts);
  state.on("mode", (mode) => {
    if (mode === "move" && state.labelsDirty) void applyConstraints();
  });
  labelSelect.addEventListener("change", () => (state.currentLabel = Number(labelSelect.value)));
  $("new-handle").addEventListener("click", () => {
    state.handleCount++;
    state.currentLabel = state.handleCount;
    showLabels();
  });
  const clear = (which: (label: number) => boolean) => {
    const mesh = state.mesh;
    if (!mesh) return openMeshFirst(banner);
    const ids: number[] = [];
    for (let v = 0; v < mesh.n; v++) if (which(mesh.labels[v])) ids.push(v);
    state.assign(ids, -1);
  };
  $("clear-label").addEventListener("click", () => clear((l) => l === state.currentLabel));
  $("clear-all").addEventListener("click", () => {
    if (!state.mesh) return openMeshFirst(banner);
    clear((l) => l >= 0);
    state.handleCount = 1;
    showLabels();
  });
  $("apply").addEventListener("click", () => void applyConstraints());

  // Selection commands (selection/commands.ts) on the region "Assign to" names; the mesh's
  // neighbours are worked out once per mesh, on the first grow or shrink.
  const neighbours = new WeakMap<MeshData, Adjacency>();
  const select = (command: SelectionCommand): number => {
    const mesh = state.mesh;
    if (!mesh) {
      openMeshFirst(banner);
      return -1;
    }
    if (state.watchOnly || state.mode === "move") return -1;
    const label = state.currentLabel;
    if (label < 0) {
      status.set("Selection commands work on a region: pick Fixed or a handle in Assign to");
      return -1;
    }
    const adj = () => {
      let a = neighbours.get(mesh);
      if (!a) neighbours.set(mesh, (a = adjacency(mesh.n, mesh.index, mesh.rest)));
      return a;
    };
    const { add, remove } = selectionChange(command, mesh.labels, label, adj);
    return state.assign(add, label) + state.assign(remove, -1);
  };
  for (const command of ["all", "none", "invert", "grow", "shrink"] as const) {
    $(`select-${command}`).addEventListener("click", () => select(command));
  }
  const brush = $<HTMLInputElement>("brush-radius");
  const showBrush = () => ($("brush-radius-val").textContent = `${brush.value}%`);
  brush.addEventListener("input", showBrush);
  showBrush();
  showLabels();
  return { applyConstraints, select };
}

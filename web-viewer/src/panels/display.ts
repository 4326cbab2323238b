// The Display panel: energy colour map (off, linear, truncated at a value) with its legend,
// the wireframe overlay and the ground grid. The energy map and the handle-weight preview (weights/) take turns:
// turning one on turns the other off, and turning the preview off brings back the energy
// mapping it replaced.
import type { App } from "../app";
import { drawLegend, fmt, scaleTop, type EnergyMapping } from "../colormap";
import { $ } from "../dom";
import { energyTop } from "../energy_scale";
import type { GroundGrid } from "../viewport/ground_grid";
import type { MeshDisplay } from "../viewport/mesh_display";
import { autoFit } from "./number_box";

export function setupDisplayPanel({ state, edits }: App, display: MeshDisplay, grid: GroundGrid): void {
  const select = $<HTMLSelectElement>("energy-map");
  const trunc = $<HTMLInputElement>("energy-trunc");
  const legend = $<HTMLCanvasElement>("legend");
  let truncTouched = false; // the user typed a truncation value
  const fitTrunc = autoFit(trunc, 5); // 3.57e-25 whole, not "3.57e-2"
  const readTruncation = () => (state.truncation = Number(trunc.value) || 0);
  const defaultTruncation = () => {
    if (!state.mesh?.energies) return;
    trunc.value = fmt(scaleTop("linear", state.mesh.energies, 0) / 2);
    fitTrunc();
    readTruncation();
  };
  const showLegend = () => {
    const top = energyTop(state);
    $("legend-box").classList.toggle("hidden", top === null);
    if (top !== null) drawLegend(legend, top, state.energyMapping);
  };
  state.on("colours", showLegend);
  state.on("energies", ({ first }) => {
    if (first && state.energyMapping === "truncated" && !truncTouched) defaultTruncation();
  });
  let replaced: EnergyMapping | null = null; // what the weight preview turned off
  const setMapping = (mapping: EnergyMapping) => {
    select.value = mapping;
    state.energyMapping = mapping;
    trunc.classList.toggle("hidden", state.energyMapping !== "truncated");
    if (state.energyMapping === "truncated" && !truncTouched) defaultTruncation();
    if (state.energyMapping !== "off" && !state.mesh?.energies) edits.requestFrame();
    state.emit("colours", undefined);
  };
  select.addEventListener("change", () => {
    const mapping = select.value as EnergyMapping;
    if (mapping !== "off") {
      replaced = null;
      state.setWeightsOn(false);
    }
    setMapping(mapping);
  });
  state.on("weightsToggle", (on) => {
    if (on && state.energyMapping !== "off") {
      replaced = state.energyMapping;
      setMapping("off");
    } else if (!on && replaced) {
      const back = replaced;
      replaced = null;
      setMapping(back);
    }
  });
  // Another mesh: its own energies, so the previous mesh's mapping and threshold go (a 1e-25
  // threshold chosen on one mesh painted the next one's noise as full-range streaks).
  state.on("mesh", () => {
    truncTouched = false;
    replaced = null;
    trunc.value = "1";
    fitTrunc();
    readTruncation();
    if (state.energyMapping !== "off") setMapping("off");
    showLegend();
  });
  trunc.addEventListener("input", () => {
    truncTouched = true;
    readTruncation();
    state.emit("colours", undefined);
  });
  readTruncation();
  const wireframe = $<HTMLInputElement>("wireframe");
  wireframe.addEventListener("change", () => display.setWireframe(wireframe.checked));
  display.setWireframe(wireframe.checked);
  // The Grid button in the heading (as Perf in Measures'): pressed while the grid shows.
  const gridButton = $<HTMLButtonElement>("grid-toggle");
  const showGrid = (on: boolean) => {
    grid.setVisible(on);
    gridButton.setAttribute("aria-pressed", String(on));
    gridButton.classList.toggle("active", on);
  };
  gridButton.addEventListener("click", () => showGrid(!grid.visible));
  showGrid(true);
}

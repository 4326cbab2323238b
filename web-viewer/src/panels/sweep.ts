// The Sweep panel: measures at β = 0 … 0.95 (Sweep with the current transforms) charted
// against β, the current β marked.
import { describeError } from "../api";
import type { App } from "../app";
import { drawChart } from "../chart";
import { $ } from "../dom";
import { BetaUnits, type Measures } from "../gen/hdeform/v1/deform_pb";
import { chartRange, MEASURE_QUANTITY, noiseFloor } from "../noise_floor";
import { toProtoTransforms } from "../transforms";
import { openMeshFirst } from "./banner";

const BETAS = [0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95];

export interface SweepPanel {
  /** How many rows the last sweep charted. */
  rows(): number;
  /** The chart's y range for the chosen measure (tests). */
  chartRange(): [number, number];
}

export function setupSweepPanel({ state, client, banner }: App): SweepPanel {
  const select = $<HTMLSelectElement>("sweep-measure");
  const button = $<HTMLButtonElement>("sweep");
  let rows: { beta: number; measures: Measures }[] = [];
  const draw = () => {
    const key = select.value as keyof Measures;
    const points = rows.map((r) => ({ beta: r.beta, value: Number(r.measures[key]) }));
    const floor = noiseFloor(MEASURE_QUANTITY[key] ?? "ratio", state.mesh?.diag ?? 1);
    drawChart($<HTMLCanvasElement>("chart"), points, select.selectedOptions[0]?.text ?? String(key), state.beta.value, floor);
  };
  // Another mesh: the old mesh's curve goes.
  state.on("mesh", () => {
    rows = [];
    draw();
  });
  state.on("beta", draw);
  select.addEventListener("change", draw);
  button.addEventListener("click", async () => {
    if (!state.sessionName || !state.mesh) return openMeshFirst(banner);
    button.disabled = true;
    button.textContent = "Sweeping…";
    try {
      const res = await client.sweep({
        name: state.sessionName,
        betas: BETAS,
        units: $<HTMLInputElement>("beta-raw").checked ? BetaUnits.RAW : BetaUnits.AREA,
        transforms: toProtoTransforms(state.handles, state.pivots),
      });
      rows = res.rows.filter((r) => r.measures).map((r) => ({ beta: r.beta, measures: r.measures! }));
      draw();
    } catch (err) {
      banner.show(`Sweep failed: ${describeError(err)}`, "rejected");
    } finally {
      button.disabled = false;
      button.textContent = "Sweep β";
    }
  });
  draw();
  return {
    rows: () => rows.length,
    chartRange: () => {
      const key = select.value as keyof Measures;
      return chartRange(rows.map((r) => Number(r.measures[key])), noiseFloor(MEASURE_QUANTITY[key] ?? "ratio", state.mesh?.diag ?? 1));
    },
  };
}

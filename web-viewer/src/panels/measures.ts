// The Measures table, from every frame (on every page: watchers too), with the frame's β and
// solve time; emptied when another mesh opens. Values below the noise floor read 0
// (noise_floor.ts: E 1.41e-27 on an undeformed pose is 0).
import { fmt } from "../colormap";
import { BetaUnits } from "../gen/hdeform/v1/deform_pb";
import { $ } from "../dom";
import { denoise, MEASURE_QUANTITY, noiseFloor } from "../noise_floor";
import type { SessionState } from "../state";

const CELLS = ["m-e", "m-iso", "m-conf", "m-area", "m-maxiso", "m-maxconf", "m-maxef2", "m-flips", "m-solve"];

export function setupMeasuresPanel(state: SessionState): void {
  state.on("mesh", () => {
    for (const id of CELLS) $(id).textContent = "–";
    $("m-flips").style.color = "";
  });
  state.on("beta", () => {
    const { value, units } = state.beta;
    $("m-beta").textContent = `${fmt(value)}${units === BetaUnits.RAW ? " (raw)" : ""}`;
  });
  state.on("measures", ({ measures: m, solveMs }) => {
    const shown = (key: "e" | "eIsoN" | "eConfN" | "eAreaPct" | "maxEIso" | "maxEConf" | "maxEf2") =>
      fmt(denoise(m[key], noiseFloor(MEASURE_QUANTITY[key], state.mesh?.diag ?? 1)));
    $("m-e").textContent = shown("e");
    $("m-iso").textContent = shown("eIsoN");
    $("m-conf").textContent = shown("eConfN");
    $("m-area").textContent = shown("eAreaPct");
    $("m-maxiso").textContent = shown("maxEIso");
    $("m-maxconf").textContent = shown("maxEConf");
    $("m-maxef2").textContent = shown("maxEf2");
    $("m-flips").textContent = String(m.flips);
    $("m-flips").style.color = m.flips > 0 ? "#ff8a80" : "";
    // 0: measures without a solve (a watch page's first look, a one-β Sweep).
    $("m-solve").textContent = solveMs > 0 ? `${solveMs.toFixed(1)} ms` : "–";
  });
}

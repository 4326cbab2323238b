// The Measures table, from every frame (on every page: watchers too), with the frame's β and
// solve time; emptied when another mesh opens.
import { fmt } from "../colormap";
import { BetaUnits } from "../gen/hdeform/v1/deform_pb";
import { $ } from "../dom";
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
    $("m-e").textContent = fmt(m.e);
    $("m-iso").textContent = fmt(m.eIsoN);
    $("m-conf").textContent = fmt(m.eConfN);
    $("m-area").textContent = fmt(m.eAreaPct);
    $("m-maxiso").textContent = fmt(m.maxEIso);
    $("m-maxconf").textContent = fmt(m.maxEConf);
    $("m-maxef2").textContent = fmt(m.maxEf2);
    $("m-flips").textContent = String(m.flips);
    $("m-flips").style.color = m.flips > 0 ? "#ff8a80" : "";
    // 0: measures without a solve (a watch page's first look, a one-β Sweep).
    $("m-solve").textContent = solveMs > 0 ? `${solveMs.toFixed(1)} ms` : "–";
  });
}

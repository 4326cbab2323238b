// The Measures table, from every frame.
import { fmt } from "../colormap";
import { $ } from "../dom";
import type { SessionState } from "../state";

export function setupMeasuresPanel(state: SessionState): void {
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
    $("m-solve").textContent = `${solveMs.toFixed(1)} ms`;
  });
}

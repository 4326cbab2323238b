// The β slider and its raw-units box: SetBeta on release, then a frame at the new β.
import { describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import { BetaUnits } from "../gen/hdeform/v1/deform_pb";

export function setupBetaPanel({ state, banner, status, edits }: App): void {
  const input = $<HTMLInputElement>("beta");
  const raw = $<HTMLInputElement>("beta-raw");
  const show = () => {
    input.value = String(state.beta.value);
    $("beta-val").textContent = state.beta.value.toFixed(2);
    raw.checked = state.beta.units === BetaUnits.RAW;
  };
  state.on("beta", show);
  input.addEventListener("input", () => ($("beta-val").textContent = Number(input.value).toFixed(2)));
  const send = async () => {
    const name = state.sessionName;
    if (!name) return;
    const value = Number(input.value);
    const units = raw.checked ? BetaUnits.RAW : BetaUnits.AREA;
    try {
      status.set("refactorizing for β…");
      const s = await edits.setBeta({ name, beta: { value, units } });
      if (name !== state.sessionName) return;
      state.adoptSession(s, { labels: false, transforms: false });
      edits.requestFrame();
    } catch (err) {
      banner.show(`β rejected: ${describeError(err)}`, "rejected");
      show();
    }
  };
  input.addEventListener("change", () => void send());
  raw.addEventListener("change", () => void send());
}

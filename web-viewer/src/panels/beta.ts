// The β slider, its number box and its raw-units box. β is previewed live while the slider
// moves: SetBeta with at most one call in flight, the newest value sent when it returns (the
// command layer's gesture), then a frame at the new β. Each carries expected_config_version:
// when another editor changed β or the constraints first, the answer is ABORTED and the layer
// re-reads the session.
import type { App } from "../app";
import type { Phase } from "../commands/command_layer";
import { $ } from "../dom";
import { BetaUnits } from "../gen/hdeform/v1/deform_pb";
import { autoFit, faithful } from "./number_box";

export function setupBetaPanel(app: App): void {
  const { state, status, edits } = app;
  const input = $<HTMLInputElement>("beta");
  const num = $<HTMLInputElement>("beta-num");
  const raw = $<HTMLInputElement>("beta-raw");
  const fit = autoFit(num, 4);
  // The β to send: the slider's, or a typed one finer than the slider's 0.01 steps.
  let wanted = state.beta.value;
  const show = () => {
    if (lane.busy) return; // the user is still sliding: keep their value
    wanted = state.beta.value;
    input.value = String(state.beta.value);
    // The server's β as it is (another client may set 0.9875): not rounded to the slider's step.
    if (document.activeElement !== num) num.value = faithful(state.beta.value);
    fit();
    raw.checked = state.beta.units === BetaUnits.RAW;
  };
  // The slider's values are one gesture (one step on the server: the layer sends them one at
  // a time, the newest next); its release, a typed value or the units box end it.
  const lane = edits.lane("beta");
  const send = ({ value, units }: { value: number; units: BetaUnits }, phase: Phase) => {
    if (!state.sessionName) return;
    let name = "";
    void edits
      .execute({
        method: "setBeta",
        what: "β",
        gesture: { key: "beta", phase },
        request: () => {
          name = state.sessionName;
          status.set("refactorizing for β…");
          return { name, beta: { value, units }, expectedConfigVersion: state.session?.configVersion ?? 0n };
        },
      })
      .then(
        (s) => {
          if (!s || name !== state.sessionName) return; // merged into a newer value, or another session
          state.adoptSession(s, { labels: false, transforms: false });
          edits.requestFrame();
        },
        // Refused (the layer said so, or re-read the session): the slider shows the server's β.
        () => void lane.idle.then(show),
      );
  };
  state.on("beta", show);
  const current = () => ({ value: wanted, units: raw.checked ? BetaUnits.RAW : BetaUnits.AREA });
  input.addEventListener("input", () => {
    wanted = Number(input.value);
    num.value = faithful(Number(input.value));
    fit();
    send(current(), "update");
  });
  input.addEventListener("change", () => {
    wanted = Number(input.value);
    send(current(), "end");
  });
  num.addEventListener("change", () => {
    const v = Math.min(0.99, Math.max(0, Number(num.value)));
    if (!Number.isFinite(v)) return show();
    wanted = v;
    input.value = String(v);
    num.value = faithful(v);
    fit();
    send(current(), "end");
  });
  raw.addEventListener("change", () => send(current(), "end"));
}

// The β slider, its number box and its raw-units box. β is previewed live while the slider
// moves: SetBeta with at most one call in flight, the newest value sent when it returns
// (latest wins), then a frame at the new β. Each carries expected_config_version: when another
// editor changed β or the constraints first, the answer is ABORTED and the session is re-read.
import { Code, ConnectError } from "@connectrpc/connect";
import { describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import { BetaUnits } from "../gen/hdeform/v1/deform_pb";
import { LatestWins } from "../latest_wins";
import { reloadAfterConflict } from "../conflict";
import { autoFit, faithful } from "./number_box";

export function setupBetaPanel(app: App): void {
  const { state, banner, status, edits } = app;
  const input = $<HTMLInputElement>("beta");
  const num = $<HTMLInputElement>("beta-num");
  const raw = $<HTMLInputElement>("beta-raw");
  const fit = autoFit(num, 4);
  // The β to send: the slider's, or a typed one finer than the slider's 0.01 steps.
  let wanted = state.beta.value;
  const show = () => {
    if (sender.busy) return; // the user is still sliding: keep their value
    wanted = state.beta.value;
    input.value = String(state.beta.value);
    // The server's β as it is (another client may set 0.9875): not rounded to the slider's step.
    if (document.activeElement !== num) num.value = faithful(state.beta.value);
    fit();
    raw.checked = state.beta.units === BetaUnits.RAW;
  };
  const sender = new LatestWins<{ value: number; units: BetaUnits }>(async ({ value, units }) => {
    const name = state.sessionName;
    if (!name) return;
    try {
      status.set("refactorizing for β…");
      const s = await edits.setBeta({
        name,
        beta: { value, units },
        expectedConfigVersion: state.session?.configVersion ?? 0n,
      });
      if (name !== state.sessionName) return;
      state.adoptSession(s, { labels: false, transforms: false });
      edits.requestFrame();
    } catch (err) {
      if (err instanceof ConnectError && err.code === Code.Aborted) {
        await reloadAfterConflict(app, "β", err);
      } else banner.show(`β rejected: ${describeError(err)}`, "rejected");
      sender.idle.then(show);
    }
  });
  state.on("beta", show);
  const current = () => ({ value: wanted, units: raw.checked ? BetaUnits.RAW : BetaUnits.AREA });
  input.addEventListener("input", () => {
    wanted = Number(input.value);
    num.value = faithful(Number(input.value));
    fit();
    sender.send(current());
  });
  input.addEventListener("change", () => {
    wanted = Number(input.value);
    sender.send(current());
  });
  num.addEventListener("change", () => {
    const v = Math.min(0.99, Math.max(0, Number(num.value)));
    if (!Number.isFinite(v)) return show();
    wanted = v;
    input.value = String(v);
    num.value = faithful(v);
    fit();
    sender.send(current());
  });
  raw.addEventListener("change", () => sender.send(current()));
}

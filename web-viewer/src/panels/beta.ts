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

export function setupBetaPanel(app: App): void {
  const { state, banner, status, edits } = app;
  const input = $<HTMLInputElement>("beta");
  const num = $<HTMLInputElement>("beta-num");
  const raw = $<HTMLInputElement>("beta-raw");
  const show = () => {
    if (sender.busy) return; // the user is still sliding: keep their value
    input.value = String(state.beta.value);
    if (document.activeElement !== num) num.value = String(Number(state.beta.value.toFixed(3)));
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
  const current = () => ({ value: Number(input.value), units: raw.checked ? BetaUnits.RAW : BetaUnits.AREA });
  input.addEventListener("input", () => {
    num.value = String(Number(Number(input.value).toFixed(3)));
    sender.send(current());
  });
  input.addEventListener("change", () => sender.send(current()));
  num.addEventListener("change", () => {
    const v = Math.min(0.99, Math.max(0, Number(num.value)));
    if (!Number.isFinite(v)) return show();
    input.value = String(v);
    num.value = String(v);
    sender.send(current());
  });
  raw.addEventListener("change", () => sender.send(current()));
}

// The soft-selection preview ("show weights", V): the active handle's harmonic weight field Φ_j
// from GetHandleWeights as a colour ramp on the mesh, with its legend. Fetched again when the
// active handle or the constraints change (config_version, also when another editor changes
// them: the watch stream brings the session). The fetch runs beside everything else, so a drag
// never waits for it; answers for an older request are dropped (weights_requests.ts). Before
// any constraints the server answers FAILED_PRECONDITION: that is said in the box, not in the
// error banner (it is not an error of the page).
import { Code, ConnectError } from "@connectrpc/connect";
import { describeError } from "../api";
import type { App } from "../app";
import { drawRampLegend } from "../colormap";
import { $ } from "../dom";
import { handleName } from "../handle_names";
import { decodeWeights, weightRamp } from "./weight_ramp";
import { WeightsRequests } from "./weights_requests";

export const NO_CONSTRAINTS_NOTE = "No constraints yet: mark a fixed region and a handle and Apply constraints to see the handle's weights.";

/** The legend's title for handle index `handle` (0-based, as everywhere: handle_names.ts). */
export function weightsTitle(handle: number): string {
  return `${handleName(handle)} weight (0 = fixed, 1 = moves with handle)`;
}

export interface WeightsView {
  toggle(on?: boolean): void;
  /** What the box says instead of a legend ("" when it shows the legend or is off). */
  readonly note: string;
}

export function setupWeightsView({ state, client }: App): WeightsView {
  const button = $<HTMLButtonElement>("show-weights");
  const box = $("weights-box");
  const title = $("weights-title");
  const legend = $<HTMLCanvasElement>("weights-legend");
  const noteEl = $("weights-note");
  const requests = new WeightsRequests();
  let asked = ""; // session, handle, config version of the newest request ("" = none)
  let note = "";
  drawRampLegend(legend, weightRamp, ["0", "0.5", "1"]);

  const show = () => {
    button.classList.toggle("active", state.weightsOn);
    button.setAttribute("aria-pressed", String(state.weightsOn));
    box.classList.toggle("hidden", !state.weightsOn);
    const field = state.weights;
    title.textContent = weightsTitle(field?.handle ?? state.activeHandle - 1);
    title.classList.toggle("hidden", !!note);
    legend.classList.toggle("hidden", !!note);
    noteEl.textContent = note;
    noteEl.classList.toggle("hidden", !note);
  };
  const setNote = (text: string) => {
    note = text;
    show();
  };

  const fetchIfNeeded = () => {
    const mesh = state.mesh;
    if (!state.weightsOn || !mesh || !state.sessionName) return;
    const handle = state.activeHandle - 1;
    const key = `${state.sessionName}|${handle}|${state.session?.configVersion ?? 0n}`;
    if (key === asked) return;
    asked = key;
    const name = state.sessionName;
    const ticket = requests.begin({ handle, minVersion: state.session?.version ?? 0n });
    client.getHandleWeights({ name, handle }).then(
      (answer) => {
        if (!requests.accept(ticket, answer) || state.mesh !== mesh) return;
        try {
          const values = decodeWeights(answer.weights, mesh.n);
          note = "";
          state.setWeights({ handle, values, version: answer.version });
        } catch (err) {
          setNote((err as Error).message);
        }
      },
      (err) => {
        if (!requests.isLatest(ticket) || state.mesh !== mesh) return;
        state.setWeights(null); // the page's usual colours while there is no field
        if (err instanceof ConnectError && err.code === Code.FailedPrecondition) return setNote(NO_CONSTRAINTS_NOTE);
        if (err instanceof ConnectError && err.code === Code.InvalidArgument) {
          return setNote(`${handleName(handle)} has no applied region yet: Apply constraints to see its weights.`);
        }
        asked = ""; // a lost connection or the like: asked again on the next change
        setNote(`Weights not available: ${describeError(err)}`);
      },
    );
  };

  const toggle = (on = !state.weightsOn) => {
    if (!on) {
      requests.cancel();
      asked = "";
      note = "";
    }
    state.setWeightsOn(on);
    fetchIfNeeded();
  };

  button.addEventListener("click", () => toggle());
  state.on("weightsToggle", show);
  state.on("colours", show);
  state.on("handles", fetchIfNeeded); // the active handle
  state.on("session", fetchIfNeeded); // constraints (config_version), another session
  state.on("mesh", () => {
    // Another mesh: nothing of the old one's field may show.
    requests.cancel();
    asked = "";
    note = "";
    if (state.weights) state.setWeights(null);
  });
  show();
  return {
    toggle,
    get note() {
      return note;
    },
  };
}

// The perf overlay (issue 37, "Measured, not guessed"): P or the Display panel's Perf button shows,
// over the canvas's top right, frames applied per second, the update→frame latency (this page's
// update sent → its frame applied), bytes per frame and the page's own cost per applied frame
// (decode + buffer update + normals, without the GPU draw), over the last 2 s; perf_stats.ts
// keeps the numbers (frame_apply.ts records every applied frame, shown or not).
import { $ } from "../dom";
import type { SessionState } from "../state";
import { perfLines, PerfStats } from "./perf_stats";

export interface PerfOverlay {
  readonly stats: PerfStats;
  readonly shown: boolean;
  toggle(show?: boolean): void;
}

export function setupPerfOverlay(state: SessionState, stats: PerfStats): PerfOverlay {
  const el = $("perf");
  const button = $<HTMLButtonElement>("perf-toggle");
  let timer: ReturnType<typeof setInterval> | undefined;
  const render = () => {
    el.textContent = perfLines(stats.summary(performance.now()), state.mesh?.n ?? 0).join("\n");
  };
  const overlay: PerfOverlay = {
    stats,
    get shown() {
      return !el.classList.contains("hidden");
    },
    toggle(show = !overlay.shown) {
      el.classList.toggle("hidden", !show);
      button.setAttribute("aria-pressed", String(show));
      clearInterval(timer);
      if (show) {
        render();
        timer = setInterval(render, 250);
      }
    },
  };
  button.addEventListener("click", () => overlay.toggle());
  // Another mesh: the numbers were the previous one's.
  state.on("mesh", () => {
    stats.reset();
    if (overlay.shown) render();
  });
  return overlay;
}

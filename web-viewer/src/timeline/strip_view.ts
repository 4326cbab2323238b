// The strip's ruler on screen: ticks in seconds, one marker per key, the playhead and the time.
// Pointer input on the ruler: a press anywhere — on a key's marker too — and dragging moves the
// playhead (snapped to keys within a few pixels) and is reported as a scrub; a press on a marker
// starts at that key's exact time, so a click on it (a scrub that does not move) selects the key
// and puts the playhead on it. Knows nothing of the server (timeline_panel.ts does).
import { $ } from "../dom";
import { rulerEnd, TimeScale } from "./time_scale";

/** A press on a marker that moves no further than this is a click on the key. */
const CLICK_SLOP_PX = 3;

export interface StripInput {
  scrubStart(t: number): void;
  scrub(t: number): void;
  scrubEnd(t: number): void;
}

function fmtTick(t: number, step: number): string {
  return step < 1 ? t.toFixed(step < 0.1 ? 2 : 1) : String(Math.round(t));
}

export class StripView {
  readonly ruler = $("tl-ruler");
  private readonly ticks = $("tl-ticks");
  private readonly keysEl = $("tl-keys");
  private readonly playheadEl = $("tl-playhead");
  private readonly timeEl = $("tl-time");
  private keyTimes: number[] = [];
  private selected = -1;
  private t = 0;
  private scale = new TimeScale(5, 100);

  constructor(input: StripInput) {
    let dragging = false;
    let onKey: number | undefined; // the key time of the marker pressed, while the pointer stays on it
    let pressX = 0;
    this.ruler.addEventListener("pointerdown", (ev) => {
      if (ev.button !== 0) return;
      // A marker does not stop the scrub (it covers the ruler where a key is: scrubbing from a
      // key is what one does most).
      const marker = (ev.target as HTMLElement).closest<HTMLElement>(".tl-key");
      onKey = marker ? this.keyTimes[Number(marker.dataset.index)] : undefined;
      pressX = ev.clientX;
      dragging = true;
      this.ruler.setPointerCapture(ev.pointerId);
      input.scrubStart(onKey ?? this.timeAt(ev));
    });
    this.ruler.addEventListener("pointermove", (ev) => {
      if (!dragging) return;
      // Until the pointer has really left the marker, the playhead stays on its key.
      if (onKey !== undefined && Math.abs(ev.clientX - pressX) <= CLICK_SLOP_PX) return;
      onKey = undefined;
      input.scrub(this.timeAt(ev));
    });
    const end = (ev: PointerEvent) => {
      if (!dragging) return;
      dragging = false;
      input.scrubEnd(onKey ?? this.timeAt(ev));
      onKey = undefined;
    };
    this.ruler.addEventListener("pointerup", end);
    this.ruler.addEventListener("pointercancel", end);
    new ResizeObserver(() => this.render()).observe(this.ruler);
  }

  get playhead(): number {
    return this.t;
  }

  /** The playhead's time under a pointer event (snapped to a key within a few pixels). */
  private timeAt(ev: PointerEvent): number {
    const r = this.ruler.getBoundingClientRect();
    return this.scale.snap(this.scale.toTime(ev.clientX - r.left), this.keyTimes);
  }

  /** Client x of time t on the ruler (for tests and the marker layout). */
  clientX(t: number): number {
    return this.ruler.getBoundingClientRect().left + this.scale.toPx(t);
  }

  setKeys(times: number[], selected: number): void {
    this.keyTimes = times;
    this.selected = selected;
    this.render();
  }

  setPlayhead(t: number): void {
    this.t = t;
    this.timeEl.textContent = `${t.toFixed(3)} s`;
    // The ruler grows when the playhead (playing, scrubbing) runs past its end.
    if (t > this.scale.end) this.render();
    else this.playheadEl.style.left = `${this.scale.toPx(t)}px`;
  }

  render(): void {
    this.scale = new TimeScale(rulerEnd(this.keyTimes, this.t), this.ruler.clientWidth || 400);
    const s = this.scale;
    const step = s.tickStep();
    const ticks: string[] = [];
    for (let i = 0; i * step <= s.end + 1e-9; i++) {
      const t = i * step;
      ticks.push(`<div class="tl-tick" style="left:${s.toPx(t)}px"><span>${fmtTick(t, step)}</span></div>`);
    }
    this.ticks.innerHTML = ticks.join("");
    this.keysEl.innerHTML = this.keyTimes
      .map((t, i) => `<div class="tl-key${i === this.selected ? " selected" : ""}" data-index="${i}" data-time="${t}" style="left:${s.toPx(t)}px" title="key at ${t.toFixed(3)} s"></div>`)
      .join("");
    this.playheadEl.style.left = `${s.toPx(this.t)}px`;
    this.timeEl.textContent = `${this.t.toFixed(3)} s`;
  }
}

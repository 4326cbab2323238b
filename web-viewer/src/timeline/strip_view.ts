// The strip's ruler on screen: ticks in seconds, one marker per key, the playhead and the time.
// Pointer input on the ruler: a press anywhere — on a key's marker too — and dragging moves the
// playhead (snapped to keys within a few pixels) and is reported as a scrub; a press on a marker
// starts at that key's exact time, so a click on it (a scrub that does not move) selects the key
// and puts the playhead on it. A press on the *selected* key's marker that then moves drags the
// key itself along the ruler (Blender's dope sheet: click selects, dragging the selection moves
// it); the time shows beside the playhead, Esc cancels, and the drop is reported once. Pressing
// an unselected marker still scrubs, so scrubbing from a key stays one gesture. Knows nothing of
// the server (timeline_panel.ts does).
import { $ } from "../dom";
import { rulerEnd, TimeScale } from "./time_scale";

/** A press on a marker that moves no further than this is a click on the key. */
const CLICK_SLOP_PX = 3;

export interface StripInput {
  scrubStart(t: number): void;
  scrub(t: number): void;
  scrubEnd(t: number): void;
  /** Whether a press on the selected key's marker may drag the key (editors, not playing). */
  canMoveKey(): boolean;
  /** A key dragged from `fromS` and dropped at `toS` (not called when cancelled). */
  keyMoved(fromS: number, toS: number): void;
}

/** A drag of the selected key: pressed (not yet moved past the click slop) or moving. */
interface KeyDrag {
  index: number;
  fromS: number;
  toS: number;
  moving: boolean;
  pointerId: number;
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
  private keyDrag: KeyDrag | null = null;

  constructor(input: StripInput) {
    let dragging = false;
    let onKey: number | undefined; // the key time of the marker pressed, while the pointer stays on it
    let pressX = 0;
    this.ruler.addEventListener("pointerdown", (ev) => {
      if (ev.button !== 0) return;
      // A marker does not stop the scrub (it covers the ruler where a key is: scrubbing from a
      // key is what one does most).
      const marker = (ev.target as HTMLElement).closest<HTMLElement>(".tl-key");
      const index = marker ? Number(marker.dataset.index) : -1;
      onKey = marker ? this.keyTimes[index] : undefined;
      pressX = ev.clientX;
      this.ruler.setPointerCapture(ev.pointerId);
      if (onKey !== undefined && index === this.selected && input.canMoveKey()) {
        // Not a scrub yet: the first move past the slop makes it a key drag; no move, a click.
        this.keyDrag = { index, fromS: onKey, toS: onKey, moving: false, pointerId: ev.pointerId };
        return;
      }
      dragging = true;
      input.scrubStart(onKey ?? this.timeAt(ev));
    });
    this.ruler.addEventListener("pointermove", (ev) => {
      const kd = this.keyDrag;
      if (kd) {
        if (!kd.moving && Math.abs(ev.clientX - pressX) <= CLICK_SLOP_PX) return;
        kd.moving = true;
        kd.toS = this.keyTimeAt(ev, kd.index);
        this.showKeyDrag();
        return;
      }
      if (!dragging) return;
      // Until the pointer has really left the marker, the playhead stays on its key.
      if (onKey !== undefined && Math.abs(ev.clientX - pressX) <= CLICK_SLOP_PX) return;
      onKey = undefined;
      input.scrub(this.timeAt(ev));
    });
    const end = (ev: PointerEvent) => {
      const kd = this.keyDrag;
      if (kd) {
        this.keyDrag = null;
        if (ev.type === "pointercancel") return this.render();
        if (!kd.moving) {
          // A click on the selected key: as on any marker, the playhead (and pose) goes there.
          input.scrubStart(kd.fromS);
          input.scrubEnd(kd.fromS);
          return;
        }
        this.render(); // the marker back until the server's list comes
        input.keyMoved(kd.fromS, kd.toS);
        return;
      }
      if (!dragging) return;
      dragging = false;
      input.scrubEnd(onKey ?? this.timeAt(ev));
      onKey = undefined;
    };
    this.ruler.addEventListener("pointerup", end);
    this.ruler.addEventListener("pointercancel", end);
    // Esc during a key drag puts the key back (capture: before the page's own Esc, which would
    // close the shortcuts list or cancel a gizmo drag).
    window.addEventListener(
      "keydown",
      (ev) => {
        if (ev.key !== "Escape" || !this.keyDrag) return;
        ev.preventDefault();
        ev.stopPropagation();
        this.cancelKeyDrag();
      },
      true,
    );
    new ResizeObserver(() => this.render()).observe(this.ruler);
  }

  /** The time a key is being dragged to, or null when no key is moving. */
  get keyDragTime(): number | null {
    return this.keyDrag?.moving ? this.keyDrag.toS : null;
  }

  /** Drops a key drag without reporting it (Esc; a new session). */
  cancelKeyDrag(): void {
    const kd = this.keyDrag;
    if (!kd) return;
    this.keyDrag = null;
    if (this.ruler.hasPointerCapture(kd.pointerId)) this.ruler.releasePointerCapture(kd.pointerId);
    this.render();
  }

  /**
   * The time under the pointer for the dragged key: snapped to the other keys (so a drop that
   * looks like it is on a key is exactly on it, and refused, rather than 2 ms beside it) and to
   * the playhead (to move a key to where one scrubbed).
   */
  private keyTimeAt(ev: PointerEvent, index: number): number {
    const r = this.ruler.getBoundingClientRect();
    const others = this.keyTimes.filter((_, i) => i !== index);
    return this.scale.snap(this.scale.toTime(ev.clientX - r.left), [...others, this.t]);
  }

  /** The dragged marker at its new time, and that time where the playhead's is shown. */
  private showKeyDrag(): void {
    const kd = this.keyDrag;
    if (!kd) return;
    const el = this.keysEl.querySelector<HTMLElement>(`.tl-key[data-index="${kd.index}"]`);
    if (el) {
      el.style.left = `${this.scale.toPx(kd.toS)}px`;
      el.classList.add("moving");
    }
    this.timeEl.textContent = `key ${kd.fromS.toFixed(3)} → ${kd.toS.toFixed(3)} s`;
    this.timeEl.classList.add("moving");
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
    // The list changed under a key drag (another editor): follow the key by its time; gone, drop.
    const kd = this.keyDrag;
    if (kd) {
      kd.index = times.indexOf(kd.fromS);
      if (kd.index < 0) this.keyDrag = null;
    }
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
    this.timeEl.classList.remove("moving");
    // Another editor's keys may arrive mid-drag: the dragged marker stays under the pointer.
    if (this.keyDrag?.moving) this.showKeyDrag();
  }
}

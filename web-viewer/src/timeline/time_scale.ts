// The strip's time ruler without the DOM (unit-tested): seconds ⇄ pixels, snapping the playhead
// to keys, and the tick step for the labels.

export const SNAP_PX = 6;

export class TimeScale {
  /** Seconds [0, end] drawn over [padPx, widthPx − padPx]. */
  constructor(
    readonly end: number,
    readonly widthPx: number,
    readonly padPx = 10,
  ) {}

  private get span(): number {
    return Math.max(1, this.widthPx - 2 * this.padPx);
  }

  toPx(t: number): number {
    return this.padPx + (t / this.end) * this.span;
  }

  /** The time at `px`, clamped to [0, end] and rounded to the millisecond (keys read plainly). */
  toTime(px: number): number {
    const t = ((px - this.padPx) / this.span) * this.end;
    return Math.round(Math.min(this.end, Math.max(0, t)) * 1000) / 1000;
  }

  /** `t`, or the nearest key time when one is within `snapPx` on screen. */
  snap(t: number, keyTimes: readonly number[], snapPx = SNAP_PX): number {
    let best = t;
    let bestPx = snapPx;
    for (const k of keyTimes) {
      const d = Math.abs(this.toPx(k) - this.toPx(t));
      if (d <= bestPx) {
        best = k;
        bestPx = d;
      }
    }
    return best;
  }

  /** A 1-2-5 step (seconds) that leaves at least `minPx` between tick labels. */
  tickStep(minPx = 48): number {
    const perSecond = this.span / this.end;
    for (let e = -2; e <= 4; e++) {
      for (const m of [1, 2, 5]) {
        const step = m * 10 ** e;
        if (step * perSecond >= minPx) return step;
      }
    }
    return 10 ** 5;
  }
}

/** The ruler's end: a little past the last key (at least 5 s), in whole seconds. */
export function rulerEnd(keyTimes: readonly number[], playhead = 0): number {
  const last = Math.max(0, playhead, ...keyTimes);
  return Math.max(5, Math.ceil(last * 1.2 + 0.5));
}

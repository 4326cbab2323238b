// The perf overlay's numbers (issue 37, "Measured, not guessed"), without the DOM: per applied
// frame its time, its buffers' bytes, the page's own cost (decode — in the worker or on the main
// thread — plus the buffer update and normals; the GPU draw is not in it) and, for a frame that
// answers this page's own update, the update→frame latency (sent → applied).

export interface AppliedFrame {
  at: number; // performance.now() when applied (ms)
  bytes: number; // the frame's buffers (0: a frame without them)
  costMs: number; // decode + buffer update + normals
  decodeMs?: number; // of which the decode (worker or main thread)
  latencyMs: number | null; // this page's update → this frame applied; null: not ours
}

export interface PerfSummary {
  framesPerS: number; // applied in the last `windowMs`
  latencyMedianMs: number | null;
  bytesPerFrame: number | null; // mean over the window's frames with buffers
  costMedianMs: number | null;
  costP90Ms: number | null;
  frames: number; // in the window
}

/** The value at quantile q (0…1) of `values` (nearest rank); null when empty. */
export function quantile(values: readonly number[], q: number): number | null {
  if (values.length === 0) return null;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.min(sorted.length - 1, Math.max(0, Math.ceil(q * sorted.length) - 1))];
}

export class PerfStats {
  private readonly frames: AppliedFrame[] = [];
  /** Every cost recorded since the last reset (tests take medians over a drag). */
  readonly costs: number[] = [];
  /** The decode part of each (same order). */
  readonly decodes: number[] = [];

  constructor(private readonly windowMs = 2000, private readonly kept = 4096) {}

  record(f: AppliedFrame): void {
    this.frames.push(f);
    this.costs.push(f.costMs);
    this.decodes.push(f.decodeMs ?? 0);
    if (this.decodes.length > this.kept) this.decodes.shift();
    if (this.frames.length > this.kept) this.frames.shift();
    if (this.costs.length > this.kept) this.costs.shift();
  }

  reset(): void {
    this.frames.length = 0;
    this.costs.length = 0;
    this.decodes.length = 0;
  }

  summary(now: number): PerfSummary {
    const recent = this.frames.filter((f) => f.at > now - this.windowMs);
    const withBytes = recent.filter((f) => f.bytes > 0);
    const latencies = recent.map((f) => f.latencyMs).filter((l): l is number => l !== null);
    return {
      framesPerS: (1000 * recent.length) / this.windowMs,
      latencyMedianMs: quantile(latencies, 0.5),
      bytesPerFrame: withBytes.length ? withBytes.reduce((a, f) => a + f.bytes, 0) / withBytes.length : null,
      costMedianMs: quantile(recent.map((f) => f.costMs), 0.5),
      costP90Ms: quantile(recent.map((f) => f.costMs), 0.9),
      frames: recent.length,
    };
  }
}

const ms = (v: number | null) => (v === null ? "–" : `${v.toFixed(v < 10 ? 2 : 1)} ms`);
function size(b: number | null): string {
  if (b === null) return "–";
  return b >= 1 << 20 ? `${(b / (1 << 20)).toFixed(2)} MiB` : b >= 1024 ? `${(b / 1024).toFixed(1)} KiB` : `${Math.round(b)} B`;
}

/** The overlay's lines. */
export function perfLines(s: PerfSummary, vertices: number): string[] {
  return [
    `frames applied/s  ${s.framesPerS.toFixed(1)}`,
    `update→frame      ${ms(s.latencyMedianMs)} (median)`,
    `bytes/frame       ${size(s.bytesPerFrame)}`,
    `page cost/frame   ${ms(s.costMedianMs)} median, ${ms(s.costP90Ms)} p90`,
    `                  (decode + buffers + normals; no GPU draw)`,
    `vertices          ${vertices}`,
  ];
}

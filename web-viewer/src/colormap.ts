// Energy colour maps: viridis-like ramp, linear in [0, max] or truncated linear in [0, t].
// Also the piecewise-linear ramp and legend drawing that other colour ramps share.
import { denoise, noiseFloor } from "./noise_floor";

export type Stops = readonly (readonly [number, number, number])[];

const STOPS: Stops = [
  [0.267, 0.005, 0.329],
  [0.231, 0.322, 0.545],
  [0.129, 0.569, 0.549],
  [0.369, 0.788, 0.384],
  [0.993, 0.906, 0.144],
];

/** `stops` at t ∈ [0, 1] (clamped; NaN counts as 1), linearly between them, into out[at..at+2]. */
export function sampleStops(stops: Stops, t: number, out: Float32Array, at: number): void {
  const x = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 1)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x));
  const f = x - i;
  const a = stops[i];
  const b = stops[i + 1];
  out[at] = a[0] + (b[0] - a[0]) * f;
  out[at + 1] = a[1] + (b[1] - a[1]) * f;
  out[at + 2] = a[2] + (b[2] - a[2]) * f;
}

/** The energy ramp. */
export function ramp(t: number, out: Float32Array, at: number): void {
  sampleStops(STOPS, t, out, at);
}

export type EnergyMapping = "off" | "linear" | "truncated";

/**
 * The top of the scale: max energy (linear) or the chosen value (truncated); never below the
 * noise floor of per-triangle energies (noise_floor.ts), so noise is not stretched over the
 * ramp: an undeformed mesh (every energy noise, i.e. 0) is uniformly the ramp's bottom.
 */
export function scaleTop(mapping: EnergyMapping, energies: Float32Array, truncateAt: number): number {
  const floor = noiseFloor("ratio", 1);
  if (mapping === "truncated") return truncateAt > 0 ? Math.max(truncateAt, floor) : 1;
  let max = 0;
  for (let i = 0; i < energies.length; i++) if (energies[i] > max) max = energies[i];
  return max >= floor ? max : 1;
}

/** Where per-triangle energy `e` lies on a ramp topped at `top`: noise (below the floor) is 0. */
export function rampPosition(e: number, top: number): number {
  return denoise(e, noiseFloor("ratio", 1)) / top;
}

export function drawLegend(canvas: HTMLCanvasElement, top: number, mapping: EnergyMapping): void {
  drawRampLegend(canvas, ramp, ["0", fmt(top / 2), (mapping === "truncated" ? "≥ " : "") + fmt(top)]);
}

/** A horizontal bar of `paint` over [0, 1] with labels at its left end, middle and right end. */
export function drawRampLegend(
  canvas: HTMLCanvasElement,
  paint: (t: number, out: Float32Array, at: number) => void,
  [left, middle, right]: [string, string, string],
): void {
  const ctx = canvas.getContext("2d");
  if (!ctx) return;
  const w = canvas.width;
  const h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  const rgb = new Float32Array(3);
  const barH = 14;
  for (let x = 0; x < w; x++) {
    paint(x / (w - 1), rgb, 0);
    ctx.fillStyle = `rgb(${(rgb[0] * 255) | 0},${(rgb[1] * 255) | 0},${(rgb[2] * 255) | 0})`;
    ctx.fillRect(x, 0, 1, barH);
  }
  ctx.fillStyle = "#ddd";
  ctx.font = "11px system-ui, sans-serif";
  ctx.textBaseline = "top";
  ctx.textAlign = "left";
  ctx.fillText(left, 0, barH + 2);
  ctx.textAlign = "right";
  ctx.fillText(right, w, barH + 2);
  ctx.textAlign = "center";
  ctx.fillText(middle, w / 2, barH + 2);
}

export function fmt(v: number): string {
  if (!Number.isFinite(v)) return String(v);
  const a = Math.abs(v);
  if (a === 0) return "0";
  if (a >= 1e4 || a < 1e-3) return v.toExponential(2);
  return v.toPrecision(4).replace(/\.?0+$/, "");
}

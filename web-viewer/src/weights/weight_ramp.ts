// The colour ramp of the handle-weight preview and the decoding of GetHandleWeights' bytes.
// Plasma-like (perceptually even, and unlike the energy map's viridis it starts in blue-violet
// and runs through magenta and orange), so a glance tells which of the two maps is on.
import { sampleStops, type Stops } from "../colormap";

export const WEIGHT_STOPS: Stops = [
  [0.05, 0.03, 0.528], // 0: fixed (does not follow the handle)
  [0.494, 0.012, 0.658],
  [0.798, 0.28, 0.47],
  [0.973, 0.585, 0.254],
  [0.94, 0.975, 0.131], // 1: moves with the handle
];

export function weightRamp(t: number, out: Float32Array, at: number): void {
  sampleStops(WEIGHT_STOPS, t, out, at);
}

/** HandleWeights.weights (float32 little-endian, one per base-GLB vertex) for a mesh of n vertices. */
export function decodeWeights(bytes: Uint8Array, n: number): Float32Array {
  if (bytes.byteLength !== 4 * n) {
    throw new Error(`GetHandleWeights: ${bytes.byteLength} bytes for ${n} vertices (expected ${4 * n})`);
  }
  // DataView: the bytes are little-endian whatever the machine, and need not be 4-aligned.
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = new Float32Array(n);
  for (let v = 0; v < n; v++) out[v] = view.getFloat32(4 * v, true);
  return out;
}

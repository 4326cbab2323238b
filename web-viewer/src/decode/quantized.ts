// FRAME_ENCODING_QUANTIZED (deform.proto, FrameEncoding): 8 bytes per vertex — 3 × uint16 LE
// position in Frame.position_box, 2 × int8 octahedral normal — and uint16 LE energies scaled
// by Frame.energies_max. The byte layout is the server's (server/service/frames/frame_encoding.cpp);
// the arithmetic mirrors the C++ reference decoder (client-cli/frame_decode.cpp).
import type { Frame } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame, type VertexArrays } from "./decoded_frame";

export const QUANTIZED_VERTEX_BYTES = 8;

/** The part of a Frame a quantized decode reads (what the worker is sent). */
export type QuantizedFrame = Pick<Frame, "vertices" | "positionBox" | "energies" | "energiesMax">;

/** Octahedral normal (Cigolle et al. 2014) of two int8 → unit vector at out[o..o+2]. */
export function octahedralDecode(qu: number, qv: number, out: Float32Array, o: number): void {
  let u = Math.max(qu * (1 / 127), -1);
  let v = Math.max(qv * (1 / 127), -1);
  const z = 1 - Math.abs(u) - Math.abs(v);
  if (z < 0) {
    const fu = (1 - Math.abs(v)) * (u >= 0 ? 1 : -1);
    const fv = (1 - Math.abs(u)) * (v >= 0 ? 1 : -1);
    u = fu;
    v = fv;
  }
  const inv = 1 / Math.sqrt(u * u + v * v + z * z); // not Math.hypot: far slower in V8
  out[o] = u * inv;
  out[o + 1] = v * inv;
  out[o + 2] = z * inv;
}

let octahedralTable: Float32Array | null = null;

/**
 * Every int8 pair's unit normal, indexed by the pair as one little-endian uint16 (u in the
 * low byte): 65,536 × 3 floats (768 KiB), built on first use (≈ 1 ms). A look-up instead of a
 * square root and a division per vertex halves the dequantization (100K in node, interleaved:
 * 1.49 → 0.83 ms; docs/benchmarks.md "WAN bench"), with the same bits.
 */
export function octahedralNormals(): Float32Array {
  if (!octahedralTable) {
    const table = new Float32Array(3 * 65536);
    for (let key = 0; key < 65536; key++) octahedralDecode(((key & 0xff) << 24) >> 24, (key << 16) >> 24, table, 3 * key);
    octahedralTable = table;
  }
  return octahedralTable;
}

/** Box corner arrays, checked: a box that is not one would place vertices anywhere. */
function boxOf(frame: QuantizedFrame): { lo: number[]; step: number[] } {
  const b = frame.positionBox;
  if (!b?.min || !b.max) throw new FrameDecodeError("Frame has quantized vertices but no position_box");
  const lo = [b.min.x, b.min.y, b.min.z];
  const hi = [b.max.x, b.max.y, b.max.z];
  for (let k = 0; k < 3; k++) {
    if (!Number.isFinite(lo[k]) || !Number.isFinite(hi[k]) || hi[k] < lo[k]) {
      throw new FrameDecodeError("Frame position_box is not a box (min > max or not finite)");
    }
  }
  return { lo, step: lo.map((l, k) => (hi[k] - l) / 65535) };
}

/**
 * 8-byte quantized vertices (already unpacked from MESHOPT if need be) → positions, normals,
 * written into `out`'s arrays when they have 3 × vertexCount entries.
 */
export function dequantizeVertices(
  bytes: Uint8Array,
  vertexCount: number,
  frame: QuantizedFrame,
  out?: VertexArrays,
): VertexArrays {
  if (bytes.byteLength !== QUANTIZED_VERTEX_BYTES * vertexCount) {
    throw new FrameDecodeError(
      `Frame has quantized vertices for ${bytes.byteLength / QUANTIZED_VERTEX_BYTES} vertices; the mesh has ${vertexCount} (${bytes.byteLength} bytes, expected ${QUANTIZED_VERTEX_BYTES * vertexCount})`,
    );
  }
  const { lo, step } = boxOf(frame);
  // Typed views, not a DataView, and locals, not array lookups: this loop runs per vertex per
  // frame (100K in node: 14.5 ms with DataView + Math.hypot, 5.0 ms so; docs/benchmarks.md
  // "WAN bench"). Little-endian hosts only, as every browser is; a Uint16Array needs an even
  // offset, so an odd one is copied. The normal's two int8 are the fourth uint16: its key in
  // octahedralNormals().
  const aligned = bytes.byteOffset % 2 === 0 ? bytes : bytes.slice();
  const q = new Uint16Array(aligned.buffer, aligned.byteOffset, 4 * vertexCount);
  const table = octahedralNormals();
  const [x0, y0, z0] = lo;
  const [sx, sy, sz] = step;
  const fits = (a: Float32Array | undefined) => a?.length === 3 * vertexCount;
  const positions = out && fits(out.positions) ? out.positions : new Float32Array(3 * vertexCount);
  const normals = out && fits(out.normals) ? out.normals : new Float32Array(3 * vertexCount);
  for (let i = 0; i < vertexCount; i++) {
    const w = 4 * i;
    const o = 3 * i;
    positions[o] = x0 + q[w] * sx;
    positions[o + 1] = y0 + q[w + 1] * sy;
    positions[o + 2] = z0 + q[w + 2] * sz;
    const t = 3 * q[w + 3];
    normals[o] = table[t];
    normals[o + 1] = table[t + 1];
    normals[o + 2] = table[t + 2];
  }
  return { positions, normals };
}

/** uint16 LE energies → float32, e = q · energies_max / 65535; null when absent. */
export function dequantizeEnergies(frame: QuantizedFrame, triangleCount: number): Float32Array | null {
  const bytes = frame.energies;
  if (bytes.byteLength === 0) return null;
  if (bytes.byteLength !== 2 * triangleCount) {
    throw new FrameDecodeError(
      `Frame has quantized energies for ${bytes.byteLength / 2} triangles; the mesh has ${triangleCount} (${bytes.byteLength} bytes, expected ${2 * triangleCount})`,
    );
  }
  const top = frame.energiesMax;
  if (!Number.isFinite(top) || top < 0) throw new FrameDecodeError("Frame energies_max must be finite and not negative");
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const out = new Float32Array(triangleCount);
  const scale = top / 65535;
  for (let l = 0; l < triangleCount; l++) out[l] = view.getUint16(2 * l, true) * scale;
  return out;
}

export function decodeQuantized(frame: QuantizedFrame, vertexCount: number, triangleCount: number, out?: VertexArrays): DecodedFrame {
  const energies = dequantizeEnergies(frame, triangleCount);
  if (frame.vertices.byteLength === 0) return { positions: null, normals: null, energies };
  return { ...dequantizeVertices(frame.vertices, vertexCount, frame, out), energies };
}

// FRAME_ENCODING_MESHOPT_DELTA (deform.proto FrameEncoding): a WatchSession stream's frames as
// meshopt-packed differences to the previous frame on a key frame's grid. The state is the
// stream's: one MeshoptDeltaStream per stream, fed every frame of it in order — frames the
// page does not show too (advance) — or the deltas after a missed one land wrong.
import { FrameDecodeError, type DecodedFrame } from "./decoded_frame";
import { unpackMeshopt } from "./meshopt";
import { dequantizeEnergies, dequantizeVertices, QUANTIZED_VERTEX_BYTES, type QuantizedFrame } from "./quantized";

export type DeltaFrame = QuantizedFrame & { delta: boolean };

export class MeshoptDeltaStream {
  /** The last frame's quantized vertices (8 bytes each); null before a key frame. */
  private state: Uint8Array | null = null;

  /** `frame` applied to the state; returns its quantized vertices (null: no vertex buffer). */
  advance(frame: DeltaFrame, vertexCount: number): Uint8Array | null {
    if (frame.vertices.byteLength === 0) return null; // superseded: the state stays
    // Taken, not kept: after a frame that fails, every delta fails until the next key frame.
    const before = this.state;
    this.state = null;
    const now = unpackMeshopt(frame.vertices, vertexCount);
    if (frame.delta) {
      if (!before) throw new FrameDecodeError("Frame is a MESHOPT_DELTA delta but no key frame came before it");
      if (before.byteLength !== now.byteLength) {
        throw new FrameDecodeError("Frame is a MESHOPT_DELTA delta for another vertex count than its key frame");
      }
      // Bytes 0–5: three uint16 zigzag differences; 6–7: two uint8 (deform.proto). Typed views:
      // both arrays are fresh, so aligned.
      const q = new Uint16Array(now.buffer, now.byteOffset, now.byteLength / 2);
      const q0 = new Uint16Array(before.buffer, before.byteOffset, before.byteLength / 2);
      for (let w = 0; w < q.length; w += 4) {
        for (let k = 0; k < 3; k++) {
          const z = q[w + k];
          q[w + k] = q0[w + k] + ((z >>> 1) ^ -(z & 1)); // Uint16Array stores mod 65536
        }
      }
      for (let o = 6; o < now.byteLength; o += QUANTIZED_VERTEX_BYTES) {
        for (let k = o; k < o + 2; k++) {
          const z = now[k];
          now[k] = before[k] + ((z >>> 1) ^ -(z & 1)); // Uint8Array stores mod 256
        }
      }
    }
    this.state = now;
    return now;
  }

  /** Advance, then the frame as float32 (the state keeps its own bytes). */
  decode(frame: DeltaFrame, vertexCount: number, triangleCount: number): DecodedFrame {
    const energies = dequantizeEnergies(frame, triangleCount);
    const vertices = this.advance(frame, vertexCount);
    if (!vertices) return { positions: null, normals: null, energies };
    return { ...dequantizeVertices(vertices, vertexCount, frame), energies };
  }

  /** A new stream: nothing to add deltas to until its key frame. */
  reset(): void {
    this.state = null;
  }
}

// FRAME_ENCODING_MESHOPT_DELTA (deform.proto FrameEncoding): a WatchSession stream's frames as
// meshopt-packed differences to the previous frame on a key frame's grid. The state is the
// stream's: one MeshoptDeltaStream per stream, fed every frame of it in order — frames the
// page does not show too (advance) — or the deltas after a missed one land wrong.
import { FrameDecodeError, type DecodedFrame, type VertexArrays } from "./decoded_frame";
import { unpackMeshopt } from "./meshopt";
import { dequantizeEnergies, dequantizeVertices, QUANTIZED_VERTEX_BYTES, type QuantizedFrame } from "./quantized";

export type DeltaFrame = QuantizedFrame & { delta: boolean };

/**
 * now = before + unzigzag(now), per vertex: bytes 0–5 three uint16 (mod 65536), 6–7 two
 * uint8 (mod 256), as deform.proto says. One flat loop over typed views (both arrays are
 * whole buffers, so aligned); `0 - (z & 1)`, not `-(z & 1)`: −0 is a double in V8 and makes
 * the loop several times slower (100K: ≈ 2 ms → 0.3 ms in node).
 */
function addDeltas(now: Uint8Array, before: Uint8Array): void {
  const q = new Uint16Array(now.buffer, now.byteOffset, now.byteLength >> 1);
  const q0 = new Uint16Array(before.buffer, before.byteOffset, before.byteLength >> 1);
  for (let w = 0, o = 6; w < q.length; w += 4, o += 8) {
    let z = q[w];
    q[w] = q0[w] + ((z >>> 1) ^ (0 - (z & 1)));
    z = q[w + 1];
    q[w + 1] = q0[w + 1] + ((z >>> 1) ^ (0 - (z & 1)));
    z = q[w + 2];
    q[w + 2] = q0[w + 2] + ((z >>> 1) ^ (0 - (z & 1)));
    z = now[o];
    now[o] = before[o] + ((z >>> 1) ^ (0 - (z & 1)));
    z = now[o + 1];
    now[o + 1] = before[o + 1] + ((z >>> 1) ^ (0 - (z & 1)));
  }
}

export class MeshoptDeltaStream {
  /** The last frame's quantized vertices (8 bytes each); null before a key frame. */
  private state: Uint8Array | null = null;
  /** The buffer the next frame unpacks into (the state before last: no allocation per frame). */
  private spare: Uint8Array | null = null;

  /**
   * `frame` applied to the state; returns its quantized vertices (null: no vertex buffer),
   * valid until the next call.
   */
  advance(frame: DeltaFrame, vertexCount: number): Uint8Array | null {
    if (frame.vertices.byteLength === 0) return null; // superseded: the state stays
    // Taken, not kept: after a frame that fails, every delta fails until the next key frame.
    const before = this.state;
    this.state = null;
    const target = this.spare?.byteLength === QUANTIZED_VERTEX_BYTES * vertexCount ? this.spare : undefined;
    this.spare = null;
    const now = unpackMeshopt(frame.vertices, vertexCount, target);
    if (frame.delta) {
      if (!before) throw new FrameDecodeError("Frame is a MESHOPT_DELTA delta but no key frame came before it");
      if (before.byteLength !== now.byteLength) {
        throw new FrameDecodeError("Frame is a MESHOPT_DELTA delta for another vertex count than its key frame");
      }
      addDeltas(now, before);
    }
    this.state = now;
    this.spare = before;
    return now;
  }

  /** Advance, then the frame as float32 (the state keeps its own bytes). */
  decode(frame: DeltaFrame, vertexCount: number, triangleCount: number, out?: VertexArrays): DecodedFrame {
    const energies = dequantizeEnergies(frame, triangleCount);
    const vertices = this.advance(frame, vertexCount);
    if (!vertices) return { positions: null, normals: null, energies };
    return { ...dequantizeVertices(vertices, vertexCount, frame, out), energies };
  }

  /** A new stream: nothing to add deltas to until its key frame. */
  reset(): void {
    this.state = null;
  }
}

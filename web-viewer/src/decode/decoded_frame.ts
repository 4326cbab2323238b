// What frame decoders read and return, whatever the wire encoding.
import type { Frame } from "../gen/hdeform/v1/deform_pb";

/** The part of a Frame that decoding reads (all the decode worker is sent). */
export type FrameBuffers = Pick<Frame, "encoding" | "positions" | "normals" | "energies" | "vertices" | "positionBox" | "energiesMax" | "delta">;

/**
 * A frame's buffers as float32, in the base GLB's vertex and triangle order; null when the
 * frame does not carry that buffer (e.g. energies not asked for). The arrays may view the
 * frame's own bytes: copy them to keep them.
 */
export interface DecodedFrame {
  positions: Float32Array | null; // 3 per vertex
  normals: Float32Array | null; // 3 per vertex
  energies: Float32Array | null; // 1 per triangle
  /** The decode worker's time for this frame (ms); absent when decoded on the main thread. */
  workerMs?: number;
}

/**
 * Float32 arrays a decode may write into instead of allocating (3 per vertex each). Fresh
 * arrays cost a page fault per 4 KiB on first touch: in Chromium's decode worker that was most
 * of an 84K frame's decode (docs/benchmarks.md "WAN bench", "The decode").
 */
export interface VertexArrays {
  positions: Float32Array;
  normals: Float32Array;
}

/** A frame whose buffers do not fit the mesh, or that this viewer cannot decode. */
export class FrameDecodeError extends Error {
  override name = "FrameDecodeError";
}

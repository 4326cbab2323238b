// What every frame decoder returns, whatever the wire encoding.

/**
 * A frame's buffers as float32, in the base GLB's vertex and triangle order; null when the
 * frame does not carry that buffer (e.g. energies not asked for). The arrays may view the
 * frame's own bytes: copy them to keep them.
 */
export interface DecodedFrame {
  positions: Float32Array | null; // 3 per vertex
  normals: Float32Array | null; // 3 per vertex
  energies: Float32Array | null; // 1 per triangle
}

/** A frame whose buffers do not fit the mesh, or that this viewer cannot decode. */
export class FrameDecodeError extends Error {
  override name = "FrameDecodeError";
}

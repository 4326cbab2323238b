// FRAME_ENCODING_FLOAT32: positions / normals as 3 × float32 LE per vertex, energies as one
// float32 LE per triangle.
import { FrameDecodeError, type DecodedFrame, type FrameBuffers } from "./decoded_frame";

/** float32 LE bytes → Float32Array (copies only when the bytes are not 4-aligned). */
function floats(bytes: Uint8Array): Float32Array {
  if (bytes.byteOffset % 4 === 0) {
    return new Float32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength >>> 2);
  }
  return new Float32Array(bytes.slice().buffer);
}

/** `bytes` as `count` items of `width` floats, null when empty; a wrong length throws. */
function buffer(bytes: Uint8Array, width: number, count: number, what: string, units: string): Float32Array | null {
  if (bytes.byteLength === 0) return null;
  const expected = 4 * width * count;
  if (bytes.byteLength !== expected) {
    const got = bytes.byteLength / (4 * width);
    throw new FrameDecodeError(
      `Frame has ${what} for ${got} ${units}; the mesh has ${count} (${bytes.byteLength} bytes, expected ${expected})`,
    );
  }
  return floats(bytes);
}

export function decodeFloat32(frame: Pick<FrameBuffers, "positions" | "normals" | "energies">, vertexCount: number, triangleCount: number): DecodedFrame {
  return {
    positions: buffer(frame.positions, 3, vertexCount, "positions", "vertices"),
    normals: buffer(frame.normals, 3, vertexCount, "normals", "vertices"),
    energies: buffer(frame.energies, 1, triangleCount, "energies", "triangles"),
  };
}

// FRAME_ENCODING_MESHOPT: the QUANTIZED vertex buffer through meshoptimizer's vertex codec
// (vertex size 8, count = the mesh's vertices); energies as QUANTIZED. The decoder is
// WebAssembly: await `meshoptReady` once before the first decode.
import { MeshoptDecoder } from "meshoptimizer/decoder";
import { FrameDecodeError, type DecodedFrame, type VertexArrays } from "./decoded_frame";
import { dequantizeEnergies, dequantizeVertices, QUANTIZED_VERTEX_BYTES, type QuantizedFrame } from "./quantized";

export const meshoptReady: Promise<void> = MeshoptDecoder.ready;
let ready = false;
void meshoptReady.then(() => (ready = true));

/** meshopt vertex stream → the 8-byte quantized vertices it packs (into `into` if given). */
export function unpackMeshopt(source: Uint8Array, vertexCount: number, into?: Uint8Array): Uint8Array {
  if (!ready) throw new FrameDecodeError("The meshopt decoder is not loaded yet (await meshoptReady)");
  const target = into ?? new Uint8Array(QUANTIZED_VERTEX_BYTES * vertexCount);
  try {
    MeshoptDecoder.decodeVertexBuffer(target, vertexCount, QUANTIZED_VERTEX_BYTES, source);
  } catch (err) {
    throw new FrameDecodeError(
      `Frame vertices are not a meshopt vertex buffer of ${vertexCount} vertices of ${QUANTIZED_VERTEX_BYTES} bytes (${(err as Error).message})`,
    );
  }
  return target;
}

/** Where MESHOPT frames unpack: one buffer, reused (it is read at once by the dequantization). */
let unpacked: Uint8Array | undefined;

export function decodeMeshopt(frame: QuantizedFrame, vertexCount: number, triangleCount: number, out?: VertexArrays): DecodedFrame {
  const energies = dequantizeEnergies(frame, triangleCount);
  if (frame.vertices.byteLength === 0) return { positions: null, normals: null, energies };
  if (unpacked?.byteLength !== QUANTIZED_VERTEX_BYTES * vertexCount) unpacked = undefined;
  unpacked = unpackMeshopt(frame.vertices, vertexCount, unpacked);
  return { ...dequantizeVertices(unpacked, vertexCount, frame, out), energies };
}

// Frame buffers → float32 arrays, one decoder per FrameEncoding. Pure functions (no DOM, no
// worker): the decode worker and the node tests call them directly. MESHOPT needs
// `meshoptReady` to have resolved; MESHOPT_DELTA also needs its stream's state.
import { FrameEncoding } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame, type FrameBuffers, type VertexArrays } from "./decoded_frame";
import { decodeFloat32 } from "./float32";
import { decodeMeshopt } from "./meshopt";
import type { MeshoptDeltaStream } from "./meshopt_delta";
import { decodeQuantized } from "./quantized";

export { FrameDecodeError, type DecodedFrame, type FrameBuffers, type VertexArrays } from "./decoded_frame";
export { meshoptReady } from "./meshopt";
export { MeshoptDeltaStream } from "./meshopt_delta";

type Decoder = (frame: FrameBuffers, vertexCount: number, triangleCount: number, out?: VertexArrays) => DecodedFrame;

const decoders: Partial<Record<FrameEncoding, Decoder>> = {
  [FrameEncoding.FLOAT32]: decodeFloat32,
  [FrameEncoding.QUANTIZED]: decodeQuantized,
  [FrameEncoding.MESHOPT]: decodeMeshopt,
};

/**
 * The frame's buffers for a mesh of `vertexCount` vertices and `triangleCount` triangles.
 * `stream`: the state of the stream the frame came on, which MESHOPT_DELTA frames need.
 * `out`: arrays the QUANTIZED / MESHOPT / MESHOPT_DELTA positions and normals are written
 * into when they fit (FLOAT32 frames are views of their own bytes and ignore it).
 */
export function decodeFrame(
  frame: FrameBuffers,
  vertexCount: number,
  triangleCount: number,
  stream?: MeshoptDeltaStream,
  out?: VertexArrays,
): DecodedFrame {
  if (frame.encoding === FrameEncoding.MESHOPT_DELTA) {
    if (!stream) throw new FrameDecodeError("A MESHOPT_DELTA frame needs its stream's earlier frames to decode");
    return stream.decode(frame, vertexCount, triangleCount, out);
  }
  const decode = decoders[frame.encoding];
  if (!decode) throw new FrameDecodeError(`Frame encoding #${frame.encoding} is unknown to this viewer`);
  return decode(frame, vertexCount, triangleCount, out);
}

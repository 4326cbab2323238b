// Frame buffers → float32 arrays, one decoder per FrameEncoding. Pure functions (no DOM, no
// worker): the decode worker and the node tests call them directly. MESHOPT needs
// `meshoptReady` to have resolved; MESHOPT_DELTA also needs its stream's state.
import { FrameEncoding } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame, type FrameBuffers } from "./decoded_frame";
import { decodeFloat32 } from "./float32";
import { decodeMeshopt } from "./meshopt";
import type { MeshoptDeltaStream } from "./meshopt_delta";
import { decodeQuantized } from "./quantized";

export { FrameDecodeError, type DecodedFrame, type FrameBuffers } from "./decoded_frame";
export { meshoptReady } from "./meshopt";
export { MeshoptDeltaStream } from "./meshopt_delta";

type Decoder = (frame: FrameBuffers, vertexCount: number, triangleCount: number) => DecodedFrame;

const decoders: Partial<Record<FrameEncoding, Decoder>> = {
  [FrameEncoding.FLOAT32]: decodeFloat32,
  [FrameEncoding.QUANTIZED]: decodeQuantized,
  [FrameEncoding.MESHOPT]: decodeMeshopt,
};

/**
 * The frame's buffers for a mesh of `vertexCount` vertices and `triangleCount` triangles.
 * `stream`: the state of the stream the frame came on, which MESHOPT_DELTA frames need.
 */
export function decodeFrame(
  frame: FrameBuffers,
  vertexCount: number,
  triangleCount: number,
  stream?: MeshoptDeltaStream,
): DecodedFrame {
  if (frame.encoding === FrameEncoding.MESHOPT_DELTA) {
    if (!stream) throw new FrameDecodeError("A MESHOPT_DELTA frame needs its stream's earlier frames to decode");
    return stream.decode(frame, vertexCount, triangleCount);
  }
  const decode = decoders[frame.encoding];
  if (!decode) throw new FrameDecodeError(`Frame encoding #${frame.encoding} is unknown to this viewer`);
  return decode(frame, vertexCount, triangleCount);
}

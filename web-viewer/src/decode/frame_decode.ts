// Frame buffers → float32 arrays, one decoder per FrameEncoding. Pure functions (no DOM, no
// worker): the decode worker and the node tests call them directly. MESHOPT needs
// `meshoptReady` to have resolved.
import { FrameEncoding } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame, type FrameBuffers } from "./decoded_frame";
import { decodeFloat32 } from "./float32";
import { decodeMeshopt } from "./meshopt";
import { decodeQuantized } from "./quantized";

export { FrameDecodeError, type DecodedFrame, type FrameBuffers } from "./decoded_frame";
export { meshoptReady } from "./meshopt";

type Decoder = (frame: FrameBuffers, vertexCount: number, triangleCount: number) => DecodedFrame;

const decoders: Record<FrameEncoding, Decoder> = {
  [FrameEncoding.FLOAT32]: decodeFloat32,
  [FrameEncoding.QUANTIZED]: decodeQuantized,
  [FrameEncoding.MESHOPT]: decodeMeshopt,
};

/** The frame's buffers for a mesh of `vertexCount` vertices and `triangleCount` triangles. */
export function decodeFrame(frame: FrameBuffers, vertexCount: number, triangleCount: number): DecodedFrame {
  const decode = decoders[frame.encoding];
  if (!decode) throw new FrameDecodeError(`Frame encoding #${frame.encoding} is unknown to this viewer`);
  return decode(frame, vertexCount, triangleCount);
}

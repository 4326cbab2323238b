// Frame buffers → float32 arrays, one decoder per FrameEncoding. QUANTIZED and MESHOPT are
// not decoded yet (a follow-up adds them, off the main thread); the viewer asks for FLOAT32.
import { FrameEncoding, type Frame } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame } from "./decoded_frame";
import { decodeFloat32 } from "./float32";

export { FrameDecodeError, type DecodedFrame } from "./decoded_frame";

type Decoder = (frame: Frame, vertexCount: number, triangleCount: number) => DecodedFrame;

function notSupportedYet(encoding: string): Decoder {
  return () => {
    throw new FrameDecodeError(`Frame encoding ${encoding} is not supported yet by this viewer`);
  };
}

const decoders: Record<FrameEncoding, Decoder> = {
  [FrameEncoding.FLOAT32]: decodeFloat32,
  [FrameEncoding.QUANTIZED]: notSupportedYet("QUANTIZED"),
  [FrameEncoding.MESHOPT]: notSupportedYet("MESHOPT"),
};

/** The frame's buffers for a mesh of `vertexCount` vertices and `triangleCount` triangles. */
export function decodeFrame(frame: Frame, vertexCount: number, triangleCount: number): DecodedFrame {
  const decode = decoders[frame.encoding] ?? notSupportedYet(`#${frame.encoding} (unknown)`);
  return decode(frame, vertexCount, triangleCount);
}

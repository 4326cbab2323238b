// The frame encoding this page asks for: `?encoding=float32|quantized|meshopt|meshopt-delta`
// (default meshopt-delta: the watch stream's frames as differences to the previous one;
// replies to this page's own updates then come as meshopt). Exact frames (the one that ends
// a drag) always come as float32, so the pose a drag settles on is exactly the server's.
import type { MessageInitShape } from "@bufbuild/protobuf";
import { FrameEncoding, type FrameFormatSchema } from "./gen/hdeform/v1/deform_pb";

const ENCODINGS: Record<string, FrameEncoding> = {
  float32: FrameEncoding.FLOAT32,
  quantized: FrameEncoding.QUANTIZED,
  meshopt: FrameEncoding.MESHOPT,
  "meshopt-delta": FrameEncoding.MESHOPT_DELTA,
};

/** The format for the page's query string; an unknown encoding is named in `error`. */
export function frameFormatFromQuery(search: string): { format: MessageInitShape<typeof FrameFormatSchema>; error: string } {
  const asked = new URLSearchParams(search).get("encoding")?.toLowerCase() ?? "meshopt-delta";
  const encoding = ENCODINGS[asked];
  if (encoding === undefined) {
    return {
      format: { encoding: FrameEncoding.MESHOPT_DELTA, exactAsFloat32: true },
      error: `Unknown ?encoding=${asked} (float32, quantized, meshopt or meshopt-delta); using meshopt-delta`,
    };
  }
  return { format: { encoding, exactAsFloat32: true }, error: "" };
}

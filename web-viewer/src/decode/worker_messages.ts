// What the page and the decode worker send each other.
import type { DecodedFrame, FrameBuffers } from "./decoded_frame";

export interface DecodeRequest {
  id: number;
  /** Only what a QUANTIZED / MESHOPT decode reads, with buffers of its own (transferred). */
  frame: FrameBuffers;
  vertexCount: number;
  triangleCount: number;
  /** MESHOPT_DELTA frames the page does not show: only the stream's state moves on. */
  advanceOnly?: boolean;
}

/** `ms`: the worker's time for the decode (performance.now, in the worker). */
export type DecodeReply = { id: number; decoded: DecodedFrame; ms: number } | { id: number; error: string };

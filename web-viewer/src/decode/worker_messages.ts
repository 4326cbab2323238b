// What the page and the decode worker send each other.
import type { DecodedFrame, FrameBuffers, VertexArrays } from "./decoded_frame";

export interface DecodeRequest {
  id: number;
  /** Only what a QUANTIZED / MESHOPT decode reads, with buffers of its own (transferred). */
  frame: FrameBuffers;
  vertexCount: number;
  triangleCount: number;
  /** MESHOPT_DELTA frames the page does not show: only the stream's state moves on. */
  advanceOnly?: boolean;
  /** Arrays of earlier frames the page is done with (transferred): decoded into if they fit. */
  reuse?: VertexArrays;
}

/**
 * `ms`: the worker's time for the decode (performance.now, in the worker). `spent`: the
 * request's vertex bytes, handed back for the next request to copy into.
 */
export type DecodeReply = { id: number; decoded: DecodedFrame; ms: number; spent?: Uint8Array } | { id: number; error: string; spent?: Uint8Array };

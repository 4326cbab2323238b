// The page's frame decoder: FLOAT32 frames are views of the received bytes and decode on the
// main thread (which so never loads the meshopt WebAssembly); QUANTIZED / MESHOPT /
// MESHOPT_DELTA frames go to the decode worker (one, which answers in order and keeps the
// watch stream's MESHOPT_DELTA state). Callers that need frames in order chain the promises
// (frame_apply.ts).
import { FrameEncoding, type Frame } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame } from "./decoded_frame";
import { decodeFloat32 } from "./float32";
import type { DecodeReply, DecodeRequest } from "./worker_messages";

const KEPT_TIMES = 256;

export class FrameDecoder {
  /** The worker's decode times of the newest frames it decoded (ms; at most 256). */
  readonly workerMs: number[] = [];
  private worker: Worker | null = null;
  private nextId = 0;
  private readonly waiting = new Map<number, { resolve: (d: DecodedFrame) => void; reject: (e: Error) => void }>();

  decode(frame: Frame, vertexCount: number, triangleCount: number): Promise<DecodedFrame> {
    if (frame.encoding !== FrameEncoding.FLOAT32) return this.inWorker(frame, vertexCount, triangleCount);
    try {
      return Promise.resolve(decodeFloat32(frame, vertexCount, triangleCount));
    } catch (err) {
      return Promise.reject(err);
    }
  }

  /**
   * A MESHOPT_DELTA frame of the watch stream the page will not show: the worker's state
   * must still take it, or the deltas after it land wrong. Other encodings: nothing to do.
   */
  skip(frame: Frame, vertexCount: number, triangleCount: number): Promise<void> {
    if (frame.encoding !== FrameEncoding.MESHOPT_DELTA) return Promise.resolve();
    return this.inWorker(frame, vertexCount, triangleCount, true).then(() => undefined);
  }

  /** Ends the worker (frames still decoding fail); a later decode starts a new one. */
  close(): void {
    for (const w of this.waiting.values()) w.reject(new FrameDecodeError("Frame decoder closed"));
    this.waiting.clear();
    this.worker?.terminate();
    this.worker = null;
  }

  private inWorker(frame: Frame, vertexCount: number, triangleCount: number, advanceOnly = false): Promise<DecodedFrame> {
    const worker = (this.worker ??= this.start());
    const id = ++this.nextId;
    // Own copies of the bytes (they are views into the whole response) to transfer.
    const vertices = frame.vertices.slice();
    const energies = frame.energies.slice();
    const request: DecodeRequest = {
      id,
      frame: {
        encoding: frame.encoding,
        vertices,
        energies,
        positionBox: frame.positionBox,
        energiesMax: frame.energiesMax,
        delta: frame.delta,
        positions: new Uint8Array(0),
        normals: new Uint8Array(0),
      },
      vertexCount,
      triangleCount,
      advanceOnly,
    };
    return new Promise((resolve, reject) => {
      this.waiting.set(id, { resolve, reject });
      worker.postMessage(request, [vertices.buffer, energies.buffer]);
    });
  }

  private start(): Worker {
    const worker = new Worker(new URL("./decode_worker.ts", import.meta.url), { type: "module" });
    worker.onmessage = ({ data }: MessageEvent<DecodeReply>) => {
      const w = this.waiting.get(data.id);
      if (!w) return;
      this.waiting.delete(data.id);
      if ("error" in data) {
        w.reject(new FrameDecodeError(data.error));
        return;
      }
      if (data.decoded.positions) {
        this.workerMs.push(data.ms);
        if (this.workerMs.length > KEPT_TIMES) this.workerMs.shift();
      }
      w.resolve(data.decoded);
    };
    worker.onerror = (e) => {
      // The worker failed to load or crashed: every frame it holds fails, the next starts anew.
      for (const w of this.waiting.values()) w.reject(new FrameDecodeError(`Frame decode worker failed: ${e.message}`));
      this.waiting.clear();
      worker.terminate();
      this.worker = null;
    };
    return worker;
  }
}

// The page's frame decoder: FLOAT32 frames are views of the received bytes and decode on the
// main thread (which so never loads the meshopt WebAssembly); QUANTIZED / MESHOPT /
// MESHOPT_DELTA frames go to the decode worker (one, which answers in order and keeps the
// watch stream's MESHOPT_DELTA state). Callers that need frames in order chain the promises
// (frame_apply.ts). Buffers go round instead of being allocated per frame: the page hands a
// shown frame's arrays back (recycle) and the worker decodes the next frame into them, and the
// worker hands each request's vertex bytes back for the next request to copy into. A fresh
// 1 MB array costs a page fault per 4 KiB on first touch: that was most of an 84K frame's
// decode in Chromium's worker (docs/benchmarks.md "WAN bench", "The decode").
import { FrameEncoding, type Frame } from "../gen/hdeform/v1/deform_pb";
import { FrameDecodeError, type DecodedFrame, type VertexArrays } from "./decoded_frame";
import { decodeFloat32 } from "./float32";
import type { DecodeReply, DecodeRequest } from "./worker_messages";

const KEPT_TIMES = 256;
/** Spare buffers kept of each kind: about the frames in flight at once. */
const SPARES = 3;

export class FrameDecoder {
  /** The worker's decode times of the newest frames it decoded (ms; at most 256). */
  readonly workerMs: number[] = [];
  private worker: Worker | null = null;
  private nextId = 0;
  private readonly waiting = new Map<number, { resolve: (d: DecodedFrame) => void; reject: (e: Error) => void }>();
  private readonly spareArrays: VertexArrays[] = [];
  private readonly spareBytes: ArrayBuffer[] = [];
  /** Arrays the worker made: only these go round (FLOAT32 frames view their response). */
  private readonly fromWorker = new WeakSet<ArrayBufferLike>();

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

  /**
   * The page is done with a decoded frame (it copied what it keeps): the worker may decode a
   * later frame into its positions and normals. Arrays this decoder did not make are ignored.
   */
  recycle(d: DecodedFrame): void {
    const { positions, normals } = d;
    if (!positions || !normals || !this.fromWorker.has(positions.buffer) || !this.fromWorker.has(normals.buffer)) return;
    this.fromWorker.delete(positions.buffer);
    this.fromWorker.delete(normals.buffer);
    if (this.spareArrays.length < SPARES) this.spareArrays.push({ positions, normals });
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
    const vertices = this.copyBytes(frame.vertices);
    const energies = frame.energies.slice();
    const reuse = advanceOnly ? undefined : this.takeArrays(3 * vertexCount);
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
      reuse,
    };
    const transfer = [vertices.buffer, energies.buffer];
    if (reuse) transfer.push(reuse.positions.buffer, reuse.normals.buffer);
    return new Promise((resolve, reject) => {
      this.waiting.set(id, { resolve, reject });
      worker.postMessage(request, transfer);
    });
  }

  /** Spare arrays of `length` floats, if any (spares of another mesh's size are dropped). */
  private takeArrays(length: number): VertexArrays | undefined {
    let spare: VertexArrays | undefined;
    while (!spare && this.spareArrays.length > 0) {
      const a = this.spareArrays.pop()!;
      if (a.positions.length === length && a.normals.length === length) spare = a;
    }
    return spare;
  }

  /** `bytes` copied into a spare buffer the worker handed back (or a new one, with room). */
  private copyBytes(bytes: Uint8Array): Uint8Array {
    const i = this.spareBytes.findIndex((b) => b.byteLength >= bytes.byteLength);
    const buffer = i >= 0 ? this.spareBytes.splice(i, 1)[0] : new ArrayBuffer(Math.ceil(bytes.byteLength * 1.25));
    const copy = new Uint8Array(buffer, 0, bytes.byteLength);
    copy.set(bytes);
    return copy;
  }

  private start(): Worker {
    const worker = new Worker(new URL("./decode_worker.ts", import.meta.url), { type: "module" });
    worker.onmessage = ({ data }: MessageEvent<DecodeReply>) => {
      if (data.spent?.byteLength && this.spareBytes.length < SPARES) this.spareBytes.push(data.spent.buffer as ArrayBuffer);
      const w = this.waiting.get(data.id);
      if (!w) return;
      this.waiting.delete(data.id);
      if ("error" in data) {
        w.reject(new FrameDecodeError(data.error));
        return;
      }
      for (const a of [data.decoded.positions, data.decoded.normals]) if (a) this.fromWorker.add(a.buffer);
      if (data.decoded.positions) {
        data.decoded.workerMs = data.ms;
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

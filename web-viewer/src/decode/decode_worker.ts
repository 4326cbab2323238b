// The decode worker: QUANTIZED / MESHOPT / MESHOPT_DELTA frames are unpacked here, off the
// main thread, and their float32 arrays transferred back (not copied). Messages are answered
// in order. MESHOPT_DELTA frames only come from the page's one WatchSession stream, in its
// order, so the worker keeps that stream's state.
import { decodeFrame, meshoptReady, MeshoptDeltaStream } from "./frame_decode";
import type { DecodeReply, DecodeRequest } from "./worker_messages";

const scope = self as unknown as {
  onmessage: ((e: MessageEvent<DecodeRequest>) => void) | null;
  postMessage(message: DecodeReply, transfer: Transferable[]): void;
};

let queue: Promise<void> = meshoptReady;
const stream = new MeshoptDeltaStream();

scope.onmessage = ({ data }) => {
  queue = queue.then(() => {
    try {
      const t0 = performance.now();
      if (data.advanceOnly) {
        stream.advance(data.frame, data.vertexCount);
        const spent = data.frame.vertices;
        scope.postMessage({ id: data.id, decoded: { positions: null, normals: null, energies: null }, ms: performance.now() - t0, spent }, spent.byteLength ? [spent.buffer] : []);
        return;
      }
      const { positions, normals, energies } = decodeFrame(data.frame, data.vertexCount, data.triangleCount, stream, data.reuse);
      const ms = performance.now() - t0;
      const spent = data.frame.vertices;
      const transfer = [positions, normals, energies, spent].flatMap((a) => (a?.byteLength ? [a.buffer] : []));
      scope.postMessage({ id: data.id, decoded: { positions, normals, energies }, ms, spent }, [...new Set(transfer)]);
    } catch (err) {
      const spent = data.frame.vertices;
      scope.postMessage({ id: data.id, error: (err as Error).message, spent }, spent.byteLength ? [spent.buffer] : []);
    }
  });
};

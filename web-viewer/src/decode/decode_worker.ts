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
    // The request's vertex bytes go back with every answer, for a later request to copy into.
    const spent = data.frame.vertices;
    const spentBuffers = spent.byteLength ? [spent.buffer] : [];
    try {
      const t0 = performance.now();
      if (data.advanceOnly) {
        stream.advance(data.frame, data.vertexCount);
        scope.postMessage({ id: data.id, decoded: { positions: null, normals: null, energies: null }, ms: performance.now() - t0, spent }, spentBuffers);
        return;
      }
      const { positions, normals, energies } = decodeFrame(data.frame, data.vertexCount, data.triangleCount, stream, data.reuse);
      const ms = performance.now() - t0;
      const arrays = [positions, normals, energies].flatMap((a) => (a ? [a.buffer] : []));
      scope.postMessage({ id: data.id, decoded: { positions, normals, energies }, ms, spent }, [...arrays, ...spentBuffers]);
    } catch (err) {
      scope.postMessage({ id: data.id, error: (err as Error).message, spent }, spentBuffers);
    }
  });
};

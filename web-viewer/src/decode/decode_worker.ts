// The decode worker: QUANTIZED / MESHOPT frames are unpacked here, off the main thread, and
// their float32 arrays transferred back (not copied). Messages are answered in order.
import { decodeFrame, meshoptReady } from "./frame_decode";
import type { DecodeReply, DecodeRequest } from "./worker_messages";

const scope = self as unknown as {
  onmessage: ((e: MessageEvent<DecodeRequest>) => void) | null;
  postMessage(message: DecodeReply, transfer: Transferable[]): void;
};

let queue: Promise<void> = meshoptReady;

scope.onmessage = ({ data }) => {
  queue = queue.then(() => {
    try {
      const { positions, normals, energies } = decodeFrame(data.frame, data.vertexCount, data.triangleCount);
      const transfer = [positions, normals, energies].flatMap((a) => (a ? [a.buffer] : []));
      scope.postMessage({ id: data.id, decoded: { positions, normals, energies } }, transfer);
    } catch (err) {
      scope.postMessage({ id: data.id, error: (err as Error).message }, []);
    }
  });
};

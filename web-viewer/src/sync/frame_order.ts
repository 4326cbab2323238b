// Which frames to apply: never one older (by session version) than the newest applied, never
// the same frame twice, and — with one update in flight — no WatchSession frame while this
// page's own edit is pending (the reply will be newer).
import type { Frame } from "../gen/hdeform/v1/deform_pb";

export type FrameSource = "reply" | "watch";

function hasBuffers(f: Frame): boolean {
  return f.positions.byteLength + f.normals.byteLength + f.vertices.byteLength + f.energies.byteLength > 0;
}

export class FrameOrder {
  /** Session version of the newest frame applied. */
  newest = 0n;
  applied = 0;
  private lastKey = "";
  private lastHadBuffers = false;

  /** Forget what was applied: a new session, or the server's state after a reconnect. */
  reset(): void {
    this.newest = 0n;
    this.forgetLast();
  }

  /** Lets the last frame apply again (the shape was replaced by other means). */
  forgetLast(): void {
    this.lastKey = "";
    this.lastHadBuffers = false;
  }

  /** True when `frame` is to be applied; records it as applied. */
  accept(frame: Frame, source: FrameSource, ownEditPending: boolean): boolean {
    if (frame.superseded) return false; // an acknowledgement: nothing was solved
    const key = `${frame.version}:${frame.sequence}:${frame.solveMs}`;
    const buffers = hasBuffers(frame);
    // The same frame again, unless it now brings the buffers its reply left out (omit_buffers).
    if (key === this.lastKey && (this.lastHadBuffers || !buffers)) return false;
    if (source === "watch" && ownEditPending) return false;
    if (frame.version < this.newest) return false;
    this.lastKey = key;
    this.lastHadBuffers = buffers;
    if (frame.version > this.newest) this.newest = frame.version;
    this.applied++;
    return true;
  }
}

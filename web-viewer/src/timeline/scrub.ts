// Scrubbing the playhead on an editor page: the pose at the playhead (PoseAt) becomes the
// session's pose — a real move, for everyone — sent like a drag through sync's update pump. So
// at its start the page takes every handle (GrabHandles: one step in the history, and nobody else
// drags meanwhile), every pose is sent with `dragging`, and at the end the pose at the final
// time is sent without it (exact frame) and the handles are given back. PoseAt runs one call at
// a time with the newest playhead time sent next (LatestWins), and an answer that arrives after
// a newer one or after the scrub was cancelled is dropped (AnswerOrder).
import { create } from "@bufbuild/protobuf";
import { describeError } from "../api";
import type { App } from "../app";
import { HandleTransformSchema, type Keyframe } from "../gen/hdeform/v1/deform_pb";
import { LatestWins } from "../latest_wins";
import type { Editors } from "../multi/editors";
import { heldMessage } from "../multi/presence_model";
import type { Sync } from "../sync/sync";
import { fromProtoTransform } from "../transforms";
import { AnswerOrder } from "./answer_order";

export class Scrub {
  /** While true the update pump sends every handle (main.ts pose()), not only the active one. */
  allHandles = false;
  /** PoseAt answers applied (tests). */
  applied = 0;
  private readonly order = new AnswerOrder();
  private readonly poses: LatestWins<number>;
  private started: Promise<boolean> | null = null;

  constructor(
    private readonly app: App,
    private readonly sync: Sync,
    private readonly editors: Editors,
    private readonly say: (message: string, error?: boolean) => void,
  ) {
    this.poses = new LatestWins((t) => this.poseAt(t));
  }

  get active(): boolean {
    return this.started !== null;
  }

  /** A press on the ruler: take every handle, then follow the playhead. */
  start(t: number): void {
    const { state } = this.app;
    const name = state.sessionName;
    const handles = state.handles.map((_, h) => h);
    this.started = (async () => {
      for (const h of handles) {
        const holder = this.editors.presence.holderOf(h);
        if (holder) {
          this.say(heldMessage(h, holder.name), true);
          return false;
        }
      }
      const r = await this.editors.lease.grab(name, handles);
      if (!r.ok) {
        this.say(`Cannot scrub: ${r.message}`, true);
        return false;
      }
      if (name !== state.sessionName) return false;
      this.allHandles = true;
      this.sync.setDragging(true);
      return true;
    })();
    this.move(t);
  }

  move(t: number): void {
    const started = this.started;
    if (!started) return;
    void started.then((ok) => {
      if (ok && this.started === started) this.poses.send(t);
    });
  }

  /** The release: the pose at `t`, sent exact; then the handles are given back. */
  async end(t: number): Promise<void> {
    const started = this.started;
    if (!started || !(await started)) {
      this.started = null;
      return;
    }
    this.poses.send(t);
    await this.poses.idle;
    this.started = null;
    this.sync.setDragging(false); // sends the last pose without `dragging`: its frame is exact
    await this.sync.whenSent();
    this.allHandles = false;
    this.editors.release();
  }

  /** Another session, Play, new constraints: no answer still in flight may move the handles. */
  cancel(): void {
    this.order.cancel();
    if (this.started) {
      this.started = null;
      this.sync.setDragging(false);
      void this.sync.whenSent().then(() => {
        this.allHandles = false;
        this.editors.release();
      });
    }
  }

  private async poseAt(t: number): Promise<void> {
    const { state, client } = this.app;
    const name = state.sessionName;
    const ticket = this.order.begin();
    let pose: Keyframe;
    try {
      pose = await client.poseAt({ name, timeS: t });
    } catch (err) {
      if (this.order.accept(ticket)) this.say(`PoseAt: ${describeError(err)}`, true);
      return;
    }
    if (!this.order.accept(ticket) || name !== state.sessionName || pose.transforms.length !== state.handles.length) return;
    state.handles = pose.transforms.map((tr, h) => fromProtoTransform(create(HandleTransformSchema, tr), state.pivots[h]));
    state.emit("handles", undefined);
    this.applied++;
    this.app.edits.requestFrame();
  }
}

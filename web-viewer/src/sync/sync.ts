// The update/frame pump and the connection, as a state machine without DOM or three.js: the
// client is injected, everything the page shows comes out as typed events.
//
// Handle updates: request() marks the pose dirty; tick() (once per animation frame) sends
// one UpdateHandles when fewer than `window` are in flight, built at send time, so the newest
// pose wins. While the gizmo is held the requests carry `dragging`; its release sends one more
// without it, whose frame is exact.
//
// window = 1 (the default): each reply brings its frame; WatchSession frames are ignored while
// this page's own edit is pending (they are older).
// window > 1 (pipelined): requests carry `coalesce` (the server skips an update a newer one
// overtook, answering `superseded`) and, once the WatchSession stream is live (it has brought
// its first event: the server registers a watcher before that), `omit_buffers` (the frame
// comes on the stream; a stream still connecting would miss it); frames apply in version
// order from wherever they come. The update after a
// non-dragging one never coalesces, so a drag's last update is always solved.
import type { MessageInitShape } from "@bufbuild/protobuf";
import { isTransient } from "../api";
import { CommandLayer } from "../commands/command_layer";
import { Emitter } from "../events";
import type {
  Frame,
  FrameFormatSchema,
  HandleTransformSchema,
  HistoryStep,
  ParticipantSchema,
  Timeline,
  Presence,
  Session,
  SessionEvent,
} from "../gen/hdeform/v1/deform_pb";
import { FrameEncoding } from "../gen/hdeform/v1/deform_pb";
import type { SyncClient } from "./client";
import { FrameOrder, type FrameSource } from "./frame_order";
import { LinkState, type Link } from "./link";
import { DEFAULT_TIMING, watchLoop, type SyncTiming, type WatchHost } from "./watch_loop";

export type { Link } from "./link";
export type { FrameSource } from "./frame_order";

/** Banner kinds: a rejected edit, or the connection / session lost. */
export type SyncErrorKind = "rejected" | "lost";

export interface SyncEvents {
  link: { link: Link; why: string };
  /** A frame to show: in version order, not shown before. */
  frame: { frame: Frame; source: FrameSource };
  /**
   * A WatchSession frame not to show (older, repeated, or behind this page's own edit). A
   * MESHOPT_DELTA one must still reach the decoder: the deltas after it build on it.
   */
  skippedFrame: { frame: Frame };
  /** A session state to adopt: from WatchSession, or re-read after a reconnect. */
  state: { session: Session; source: "watch" | "resync"; adoptTransforms: boolean };
  error: { message: string; kind: SyncErrorKind };
  clearError: SyncErrorKind;
  /**
   * An update failed (rejected, session gone, a handle another editor holds): the handles'
   * last pose the server confirmed, so the gizmo goes back to where the mesh is.
   */
  revert: { transforms: MessageInitShape<typeof HandleTransformSchema>[]; message: string };
  /** Who is in the session (WatchSession presence events). */
  presence: Presence;
  /** A new step of the session's history (WatchSession step events). */
  step: HistoryStep;
  /** The session's timeline was set or cleared (WatchSession timeline events; on join too). */
  timeline: Timeline;
  /** open(): the page switched to this session (what it knew of the previous one is stale). */
  opened: string;
}

/** The pose an UpdateHandles sends, read when the request is built. */
export interface Pose {
  /** Every handle's transform. */
  transforms: MessageInitShape<typeof HandleTransformSchema>[];
  /**
   * Several editors: the handles (indices into `transforms`) this page changes; only they are
   * sent (UpdateHandlesRequest.handles), so another editor's handles keep their poses.
   * Unset: every handle (a server without several-editor support needs all of them).
   */
  handles?: number[];
  energies: boolean;
}

export interface SyncOptions {
  client: SyncClient;
  /**
   * The command layer the updates go through (main.ts: the page's one, whose retry is this
   * Sync's edit()); unset: one of its own on `client`.
   */
  commands?: CommandLayer<"updateHandles">;
  pose: () => Pose;
  /** After a reconnect, the session's current shape (frames may have been missed). */
  refreshShape?: (name: string, session: Session, signal: AbortSignal) => Promise<void>;
  /** UpdateHandles calls in flight at most. */
  window?: number;
  /** Who this page is (WatchSession.client, UpdateHandles.client_id); unset: anonymous. */
  participant?: () => MessageInitShape<typeof ParticipantSchema> | undefined;
  /** How UpdateHandles answers and WatchSession frames are to be encoded (unset: FLOAT32). */
  format?: MessageInitShape<typeof FrameFormatSchema>;
  timing?: Partial<SyncTiming>;
}

function carriesShape(frame: Frame): boolean {
  return frame.positions.byteLength + frame.vertices.byteLength > 0;
}

export class Sync extends Emitter<SyncEvents> implements WatchHost {
  readonly client: SyncClient;
  private readonly commands: CommandLayer<"updateHandles">;
  readonly link: LinkState;
  readonly timing: SyncTiming;
  readonly window: number;
  readonly format: MessageInitShape<typeof FrameFormatSchema> | undefined;
  private readonly replyFormat: MessageInitShape<typeof FrameFormatSchema> | undefined;
  /** Completed reconnects. */
  reconnects = 0;
  /** WatchSession events received (frames and states). */
  watchEvents = 0;
  private readonly pose: () => Pose;
  private readonly participantOf: NonNullable<SyncOptions["participant"]>;
  /** Every handle's pose as the server last confirmed it (a reply, a frame, a state). */
  private confirmed: MessageInitShape<typeof HandleTransformSchema>[] | null = null;
  private readonly refreshShape: NonNullable<SyncOptions["refreshShape"]>;
  private readonly order = new FrameOrder();
  private name = "";
  private watchAbort: AbortController | null = null;
  private stream: AbortController | null = null;
  // The pump: `dirty` = a newer pose than the last sent.
  private dirty = false;
  private inFlight = 0;
  private held = false;
  private sequence = 0;
  /** Send times of the newest updates by sequence (sentTime). */
  private readonly sentAt = new Map<number, number>();
  /** The newest of this page's updates answered so far: an older answer confirms nothing. */
  private answeredSeq = 0;
  private lastSentDragging = false;
  /** Pipelined: version of an answered update whose buffers are still to come (0 = none). */
  private awaitingBuffers = 0n;
  /** The WatchSession stream has brought an event, so it receives every frame from now on. */
  private streamLive = false;
  /** whenSent() callers, woken once no pose is left to send or in flight. */
  private sentWaiters: (() => void)[] = [];

  constructor(options: SyncOptions) {
    super();
    this.client = options.client;
    this.commands = options.commands ?? new CommandLayer<"updateHandles">({ client: options.client, retry: (call) => this.edit(call) });
    this.pose = options.pose;
    this.participantOf = options.participant ?? (() => undefined);
    this.refreshShape = options.refreshShape ?? (async () => {});
    this.window = Math.max(1, options.window ?? 1);
    this.format = options.format;
    // MESHOPT_DELTA is a stream's (WatchSession); a reply carries its frame as MESHOPT.
    this.replyFormat =
      options.format?.encoding === FrameEncoding.MESHOPT_DELTA ? { ...options.format, encoding: FrameEncoding.MESHOPT } : options.format;
    this.timing = { ...DEFAULT_TIMING, ...options.timing };
    this.link = new LinkState((link, why) => this.emit("link", { link, why }));
  }

  get sessionName(): string {
    return this.name;
  }
  get pipelined(): boolean {
    return this.window > 1;
  }
  get dragging(): boolean {
    return this.held;
  }
  /** This page's own edit is not yet shown. */
  get busy(): boolean {
    return this.dirty || this.inFlight > 0 || this.held || this.awaitingBuffers > 0n;
  }
  /** Session version of the newest frame shown. */
  get version(): bigint {
    return this.order.newest;
  }
  get framesApplied(): number {
    return this.order.applied;
  }

  /**
   * When this page sent its update `seq` (performance.now(), ms); undefined when unknown (too old,
   * another page's). The perf overlay's update→frame latency (frames name the sequence they answer).
   */
  sentTime(seq: number): number | undefined {
    return this.sentAt.get(seq);
  }

  /** Switches to session `name` (stops watching the previous one); watch() follows. */
  open(name: string): void {
    this.watchAbort?.abort();
    this.watchAbort = null;
    this.link.set("connected");
    this.name = name;
    this.dirty = false;
    this.awaitingBuffers = 0n;
    this.streamLive = false;
    this.confirmed = null;
    this.order.reset();
    this.wakeSent();
    this.emit("opened", name);
  }

  get participant(): MessageInitShape<typeof ParticipantSchema> | undefined {
    return this.participantOf();
  }

  /** The handles' poses the server holds, as far as this page knows (null: none seen yet). */
  get confirmedTransforms(): MessageInitShape<typeof HandleTransformSchema>[] | null {
    return this.confirmed;
  }

  /** Records the server's handle poses (a session state or a frame's transforms). */
  confirm(transforms: MessageInitShape<typeof HandleTransformSchema>[]): void {
    if (transforms.length > 0) this.confirmed = transforms;
  }

  /** Starts the WatchSession loop of the open session. */
  watch(): void {
    this.watchAbort?.abort();
    this.watchAbort = new AbortController();
    void watchLoop(this, this.name, this.watchAbort.signal);
  }

  /** The pose changed: send it at the next tick. */
  request(): void {
    if (this.name) this.dirty = true;
  }

  /** The gizmo is held (or released: then the final pose is sent without `dragging`). */
  setDragging(held: boolean): void {
    const released = this.held && !held;
    this.held = held;
    if (released) this.request();
  }

  /**
   * Resolves once the pose set so far has been sent and answered (no update dirty or in flight),
   * or after `timeoutMs`. A drag's ReleaseHandles waits for it: the server ends the drag's
   * history step at the release, so a release overtaking the drag's last update would make that
   * update a step of its own (and Ctrl+Z would undo only it).
   */
  whenSent(timeoutMs = 5000): Promise<void> {
    if (!this.dirty && this.inFlight === 0) return Promise.resolve();
    return new Promise((resolve) => {
      const timer = setTimeout(done, timeoutMs);
      function done(): void {
        clearTimeout(timer);
        resolve();
      }
      this.sentWaiters.push(done);
    });
  }

  private wakeSent(): void {
    if (this.dirty || this.inFlight > 0) return;
    for (const w of this.sentWaiters.splice(0)) w();
  }

  /** Once per animation frame: sends at most one update. */
  tick(): void {
    if (!this.dirty || this.inFlight >= this.window || !this.name || this.link.state !== "connected") return;
    this.dirty = false;
    this.inFlight++;
    const name = this.name;
    let seq = 0;
    let omitBuffers = false;
    let sent: Pose | null = null;
    // The drag's updates are its gesture (`dragging`: the server may answer with a drag frame,
    // float32 factor, and makes the drag one step); an update of no drag is a step of its own.
    const gesture = this.held ? { phase: "update" as const } : undefined;
    this.commands
      .execute({
        method: "updateHandles",
        what: "Handle update",
        gesture,
        request: () => {
          seq = ++this.sequence;
          this.sentAt.set(seq, performance.now());
          if (this.sentAt.size > 64) this.sentAt.delete(this.sentAt.keys().next().value!);
          omitBuffers = this.pipelined && this.streamLive;
          sent = this.pose();
          const { transforms, handles, energies } = sent;
          const coalesce = this.pipelined && this.lastSentDragging;
          this.lastSentDragging = gesture !== undefined;
          return {
            name,
            sequence: BigInt(seq),
            transforms: handles ? handles.map((h) => transforms[h]) : transforms,
            handles: handles ?? [],
            clientId: this.participantOf()?.clientId ?? "",
            energies,
            coalesce,
            omitBuffers,
            format: this.replyFormat,
          };
        },
        // Shown through the "error" event (main.ts: the banner); the gizmo goes back too.
        showIn: (message) => {
          if (name !== this.name) return;
          this.emit("error", { message, kind: "rejected" });
          // The newest update failed: the server keeps the last pose it confirmed. A newer update
          // still to be sent or in flight will say where the handle is instead.
          if (seq === this.sequence && !this.dirty && this.confirmed) {
            this.emit("revert", { transforms: this.confirmed, message });
          }
        },
      })
      .then((frame) => {
        if (name !== this.name) return; // another session was opened meanwhile
        if (seq === this.sequence) this.emit("clearError", "rejected");
        this.confirmAnswer(seq, sent, frame);
        if (frame.superseded) return; // acknowledged, not solved: a newer update was waiting
        // omit_buffers: the shape comes on the stream (unless it came first).
        if (omitBuffers && !carriesShape(frame) && frame.version > this.order.newest) {
          this.awaitingBuffers = frame.version;
        }
        this.offer(frame, "reply");
      }, () => {
        /* refused: shown by showIn */
      })
      .finally(() => {
        this.inFlight--;
        this.wakeSent();
      });
  }

  /** The server solved `sent` (its frame may name every handle's transform). */
  private confirmAnswer(seq: number, sent: Pose | null, frame: Frame): void {
    // Pipelined answers may come back in any order; the server already refused to let an
    // overtaken update move anything (UpdateHandlesRequest.sequence), so neither does the page.
    if (seq < this.answeredSeq) return;
    this.answeredSeq = seq;
    if (frame.transforms.length > 0) this.confirm(frame.transforms);
    else if (sent && !sent.handles) this.confirm(sent.transforms);
    else if (sent?.handles && this.confirmed) {
      const next = [...this.confirmed];
      for (const h of sent.handles) next[h] = sent.transforms[h];
      this.confirm(next);
    }
  }

  /**
   * An edit waits while the page reconnects; when it fails for a transient reason it starts a
   * reconnect and is made once more after it. `call` builds its request each time (a retry
   * sends the newest state: an update's poses are absolute, and the other edits carry the same
   * request_id, so a repeat cannot apply twice). The command layer's retry.
   */
  async edit<T>(call: () => Promise<T>): Promise<T> {
    if (this.link.state !== "connected") await this.link.waitConnected(this.timing.editRetryWaitMs);
    try {
      return await call();
    } catch (err) {
      if (!isTransient(err) || this.link.state === "gone") throw err;
      this.kickReconnect("an edit failed");
      if (!(await this.link.waitConnected(this.timing.editRetryWaitMs))) throw err;
      return await call();
    }
  }

  /**
   * The watch stream's frames cannot be used any more (a MESHOPT_DELTA frame that did not
   * decode: the ones after it build on it): watch anew, which re-reads the session and its
   * shape, and the new stream starts with a key frame.
   */
  rewatch(why: string): void {
    this.kickReconnect(why);
  }

  /** An edit failed for a transient reason: reconnect now (the stream may not know yet). */
  private kickReconnect(why: string): void {
    if (this.link.state !== "connected") return;
    this.link.set("reconnecting", why);
    this.stream?.abort(); // the watch loop then re-reads the session
  }

  private offer(frame: Frame, source: FrameSource): void {
    const ownEditPending = !this.pipelined && (this.held || this.inFlight > 0 || this.dirty);
    if (!this.order.accept(frame, source, ownEditPending)) {
      if (source === "watch") this.emit("skippedFrame", { frame });
      return;
    }
    if (carriesShape(frame) && frame.version >= this.awaitingBuffers) {
      this.awaitingBuffers = 0n;
    }
    this.emit("frame", { frame, source });
  }

  // WatchHost

  setStream(stream: AbortController): void {
    this.stream = stream;
    this.streamLive = false;
  }

  async resynced(name: string, session: Session, signal: AbortSignal): Promise<void> {
    this.order.reset(); // the server's version is the truth now (a restart may have lost a move)
    this.awaitingBuffers = 0n;
    this.confirm(session.transforms);
    this.emit("state", { session, source: "resync", adoptTransforms: !this.busy });
    await this.refreshShape(name, session, signal);
    this.order.forgetLast();
    this.reconnects++;
  }

  event(ev: SessionEvent): void {
    this.streamLive = true;
    if (ev.event.case === "frame") {
      this.confirm(ev.event.value.transforms);
      this.offer(ev.event.value, "watch");
    } else if (ev.event.case === "state") {
      this.confirm(ev.event.value.transforms);
      this.emit("state", { session: ev.event.value, source: "watch", adoptTransforms: !this.busy });
    } else if (ev.event.case === "presence") this.emit("presence", ev.event.value);
    else if (ev.event.case === "step") this.emit("step", ev.event.value);
    else if (ev.event.case === "timeline") this.emit("timeline", ev.event.value);
    this.watchEvents++;
  }

  error(message: string): void {
    this.emit("error", { message, kind: "lost" });
  }

  clearError(): void {
    this.emit("clearError", "lost");
  }
}

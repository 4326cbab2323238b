// A scripted stand-in for the Deformation client: each UpdateHandles waits until the test
// answers it; WatchSession streams are queues the test pushes events into.
import { create } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import {
  FrameSchema,
  SessionEventSchema,
  SessionSchema,
  type Frame,
  type Session,
  type SessionEvent,
  type UpdateHandlesRequest,
  type WatchSessionRequest,
} from "../src/gen/hdeform/v1/deform_pb";
import type { DeformationClient } from "../src/api";
import type { SyncClient } from "../src/sync/client";

export interface Call<Req, Res> {
  request: Req;
  resolve: (value: Res) => void;
  reject: (err: unknown) => void;
}

export class FakeStream {
  private queue: (SessionEvent | Error)[] = [];
  private wake: (() => void) | null = null;
  ended = false;
  push(item: SessionEvent | Error): void {
    this.queue.push(item);
    this.wake?.();
  }
  end(): void {
    this.ended = true;
    this.wake?.();
  }
  async *events(signal?: AbortSignal): AsyncGenerator<SessionEvent> {
    const onAbort = () => this.wake?.();
    signal?.addEventListener("abort", onAbort);
    try {
      for (;;) {
        if (signal?.aborted) throw new ConnectError("aborted", Code.Canceled);
        const item = this.queue.shift();
        if (item instanceof Error) throw item;
        if (item) {
          yield item;
          continue;
        }
        if (this.ended) return;
        await new Promise<void>((r) => (this.wake = r));
        this.wake = null;
      }
    } finally {
      signal?.removeEventListener("abort", onAbort);
    }
  }
}

export class FakeClient {
  updates: Call<UpdateHandlesRequest, Frame>[] = [];
  streams: FakeStream[] = [];
  watchRequests: WatchSessionRequest[] = [];
  /** What the next GetSession answers (a Session, or an error to throw). */
  session: () => Session = () => create(SessionSchema, { name: "sessions/s" });
  getSessionCalls = 0;
  setBetaCalls = 0;
  /** SetBeta and SetConstraints requests, in order (their client_id and request_id). */
  requests: { clientId?: string; requestId?: string }[] = [];
  /** What each SetBeta answers, in order. */
  betaAnswers: (() => Session)[] = [];

  readonly client = {
    updateHandles: (request: UpdateHandlesRequest) =>
      new Promise<Frame>((resolve, reject) => this.updates.push({ request, resolve, reject })),
    setBeta: async (request: { clientId?: string; requestId?: string }) => {
      this.requests.push(request);
      const answer = this.betaAnswers[this.setBetaCalls++];
      return answer ? answer() : create(SessionSchema, {});
    },
    setConstraints: async (request: { clientId?: string; requestId?: string }) => {
      this.requests.push(request);
      return create(SessionSchema, {});
    },
    getSession: async () => {
      this.getSessionCalls++;
      return this.session();
    },
    watchSession: (request: WatchSessionRequest, options?: { signal?: AbortSignal }) => {
      this.watchRequests.push(request);
      const stream = new FakeStream();
      this.streams.push(stream);
      return stream.events(options?.signal);
    },
  } as unknown as SyncClient & Pick<DeformationClient, "setBeta" | "setConstraints">;

  get stream(): FakeStream {
    return this.streams[this.streams.length - 1];
  }
}

export function frame(init: { version: number; sequence?: number; positions?: number[]; superseded?: boolean }): Frame {
  return create(FrameSchema, {
    version: BigInt(init.version),
    sequence: BigInt(init.sequence ?? 0),
    positions: init.positions ? new Uint8Array(new Float32Array(init.positions).buffer) : new Uint8Array(),
    superseded: init.superseded ?? false,
  });
}

export function frameEvent(f: Frame): SessionEvent {
  return create(SessionEventSchema, { event: { case: "frame", value: f } });
}

/** What the server sends a new watcher first: the session's state. */
export function stateEvent(): SessionEvent {
  return create(SessionEventSchema, { event: { case: "state", value: create(SessionSchema, { name: "sessions/s" }) } });
}

export function deletedEvent(name: string): SessionEvent {
  return create(SessionEventSchema, { event: { case: "deleted", value: name } });
}

/** Lets pending promise callbacks (and zero-delay timers) run. */
export function settle(ms = 0): Promise<void> {
  return new Promise((r) => setTimeout(r, ms));
}

/** Resolves once `cond` holds (polling), or fails after `ms`. */
export async function until(cond: () => boolean, what: string, ms = 2000): Promise<void> {
  const t0 = Date.now();
  while (!cond()) {
    if (Date.now() - t0 > ms) throw new Error(`timed out waiting for ${what}`);
    await settle(1);
  }
}

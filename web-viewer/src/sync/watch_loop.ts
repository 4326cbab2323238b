// The WatchSession loop, which owns the connection. When the stream fails for a transient
// reason (server restarting, network) the link goes "reconnecting": it retries with back-off
// (reconnectFirstMs doubling to reconnectMaxMs), re-reads the session (GetSession, which also
// restores a durable session on a restarted server) and its shape, then watches again. Only
// NOT_FOUND after a `deleted` event or an outage means the session is gone.
import { Code, ConnectError } from "@connectrpc/connect";
import { describeError, isAbort, isTransient } from "../api";
import { accessError } from "../access_error";
import type { MessageInitShape } from "@bufbuild/protobuf";
import type { FrameFormatSchema, ParticipantSchema, Session, SessionEvent } from "../gen/hdeform/v1/deform_pb";
import type { SyncClient } from "./client";
import type { LinkState } from "./link";

export interface SyncTiming {
  reconnectFirstMs: number;
  reconnectMaxMs: number;
  lostBannerAfterMs: number; // a longer outage also gets the red banner
  editRetryWaitMs: number; // how long a failed edit waits for the reconnect
}

export const DEFAULT_TIMING: SyncTiming = {
  reconnectFirstMs: 250,
  reconnectMaxMs: 2000,
  lostBannerAfterMs: 5000,
  editRetryWaitMs: 30_000,
};

/** What the loop needs from sync. */
export interface WatchHost {
  readonly client: SyncClient;
  readonly link: LinkState;
  readonly timing: SyncTiming;
  /** The encoding the stream's frames are to come in. */
  readonly format: MessageInitShape<typeof FrameFormatSchema> | undefined;
  /** Who watches (shown in every watcher's presence); undefined: anonymous. */
  readonly participant: MessageInitShape<typeof ParticipantSchema> | undefined;
  /** The current stream, which an edit that finds the server away aborts. */
  setStream(stream: AbortController): void;
  /** The session as re-read after an outage: adopt it and its shape. */
  resynced(name: string, session: Session, signal: AbortSignal): Promise<void>;
  event(ev: SessionEvent): void;
  error(message: string): void;
  clearError(): void;
}

function sleep(ms: number, signal: AbortSignal): Promise<void> {
  return new Promise((resolve) => {
    const timer = setTimeout(done, ms);
    function done(): void {
      clearTimeout(timer);
      signal.removeEventListener("abort", done);
      resolve();
    }
    signal.addEventListener("abort", done);
  });
}

export async function watchLoop(host: WatchHost, name: string, signal: AbortSignal): Promise<void> {
  const { client, link, timing } = host;
  let delay = timing.reconnectFirstMs;
  let resync = false; // re-read the session before watching again
  let attempt = 0;
  let sawDeleted = false;
  while (!signal.aborted) {
    const stream = new AbortController();
    host.setStream(stream);
    const abortStream = () => stream.abort();
    signal.addEventListener("abort", abortStream);
    try {
      if (resync) {
        const s = await client.getSession({ name }, { signal: stream.signal, timeoutMs: 10_000 });
        if (signal.aborted) return;
        await host.resynced(name, s, stream.signal);
        resync = false;
        sawDeleted = false;
        attempt = 0;
        delay = timing.reconnectFirstMs;
        link.set("connected");
        host.clearError();
      }
      for await (const ev of client.watchSession({ name, format: host.format, client: host.participant }, { signal: stream.signal })) {
        if (ev.event.case === "deleted") {
          // Deleted, expired — or the server is stopping: the re-read below tells which.
          sawDeleted = true;
          break;
        }
        host.event(ev);
      }
      if (signal.aborted) return;
    } catch (err) {
      if (signal.aborted) return;
      // A deleted session's tokens open nothing: after a `deleted` event, PermissionDenied
      // means the same as NotFound (only the operator token gets NotFound for a gone id).
      if (err instanceof ConnectError && (err.code === Code.NotFound || (sawDeleted && err.code === Code.PermissionDenied))) {
        link.set("gone");
        // Right after a `deleted` event: deleted (or expired). After an outage: it did not
        // survive (a server without durable state, or deleted meanwhile).
        host.error(sawDeleted && attempt <= 1 ? `Session ${name} was deleted` : `Session ${name} no longer exists on the server`);
        return;
      }
      if (err instanceof ConnectError && (err.code === Code.PermissionDenied || err.code === Code.Unauthenticated)) {
        link.set("gone");
        host.error(`Lost access to ${name}: ${accessError(err, name)}`);
        return;
      }
      if (!isAbort(err) && !isTransient(err)) {
        // An answer, not an outage (e.g. too many watchers): say so, and keep trying.
        host.error(`Live updates failed: ${describeError(err)}; retrying…`);
      }
    } finally {
      signal.removeEventListener("abort", abortStream);
      stream.abort(); // ends a stream left by `break`
    }
    // The stream ended or failed (or an edit found the server away): reconnect with back-off.
    resync = true;
    attempt++;
    link.set("reconnecting", attempt > 1 ? `attempt ${attempt}` : "");
    if (Date.now() - link.outageSince >= timing.lostBannerAfterMs) {
      host.error("Lost connection to the server; reconnecting…");
    }
    await sleep(delay, signal);
    delay = Math.min(delay * 2, timing.reconnectMaxMs);
  }
}

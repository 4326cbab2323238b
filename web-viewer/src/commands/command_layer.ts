// The one way the viewer changes anything on the server (issue 37; as the three.js editor's
// execute(cmd)). A command names its method, what the user would call it, and how its request
// is built; the layer
//   - attaches this tab's client_id and a request_id, the same on every attempt, so a retry
//     after a lost answer is applied once (docs/api.md "Retries");
//   - sends it once more after a reconnect when it failed for a transient reason (the methods
//     that are safe to repeat: methods.ts RETRIED_METHODS);
//   - knows the gesture it belongs to: an UpdateHandles inside a drag carries `dragging` (the
//     server makes the drag one step), and the commands of a keyed gesture (a β slider drag) go
//     one at a time with stale waiting updates merged away (gesture_lane.ts);
//   - asks before a change that would drop another editor's timeline keys, and resends it with
//     discard_timeline on yes (same request_id: a refused call is not remembered);
//   - shows a refusal in one place, in one form ("β rejected: …", "Undo rejected: …"), or hands
//     a conflict on expected_config_version to the re-read that shows the session as it is.
// Reads (GetSession, GetMesh, ListHistory, Sweep, …) do not come here: methods.ts lists them.
import { Code, ConnectError } from "@connectrpc/connect";
import { describeError, isAbort, type DeformationClient } from "../api";
import { askingToDropKeys, dropsOthersKeys } from "../conflict";
import { newRequestId } from "../request_id";
import { GestureLane, type Phase } from "./gesture_lane";
import { CONFIG_VERSION_METHODS, REQUEST_ID_METHODS, RETRIED_METHODS, type CommandMethod, type DropsKeysMethod } from "./methods";

export type { Phase } from "./gesture_lane";
export type CommandRequest<M extends CommandMethod> = Parameters<DeformationClient[M]>[0];
export type CommandAnswer<M extends CommandMethod> = Awaited<ReturnType<DeformationClient[M]>>;

export interface Command<M extends CommandMethod> {
  method: M;
  /** What the user calls the change, as the refusal names it: "β", "Undo", "Snapshot save". */
  what: string;
  /** The request, built for each attempt (a retry sends the newest state). */
  request: () => CommandRequest<M>;
  /**
   * The gesture it is part of. `key`: commands of the same gesture go one at a time and a
   * waiting update is replaced by a newer command (its promise resolves undefined, unsent).
   */
  gesture?: { phase: Phase; key?: string };
  /** It may drop timeline keys another editor set: ask, and send it again with discard_timeline. */
  dropsKeys?: M extends DropsKeysMethod ? boolean : never;
  /** Shown somewhere of the caller's own (the timeline strip's note) instead of the banner. */
  showIn?: (text: string) => void;
  /** A conflict on expected_config_version answered the caller's way (instead of re-reading the session). */
  conflict?: (err: ConnectError) => Promise<void> | void;
  /** Nothing shown: the caller reads the refusal (a probe; a grab, whose refusal names the holder). */
  quiet?: boolean;
}

export interface CommandLayerOptions<K extends CommandMethod> {
  client: Pick<DeformationClient, K>;
  /** This tab's client id (the author of its steps; Undo finds its own by it). */
  clientId?: () => string;
  /** Runs a call, and once more after a reconnect if it fails for a transient reason (Sync.edit). */
  retry?: <T>(call: () => Promise<T>) => Promise<T>;
  /** The one place a refusal is shown (the banner). */
  refused?: (text: string) => void;
  /** A command was accepted: a refusal shown earlier is over. */
  accepted?: () => void;
  /** ABORTED on expected_config_version: show the session as it now is (conflict.ts). */
  conflict?: (what: string, err: ConnectError) => Promise<void> | void;
  /** Asks the user (window.confirm); tests answer for them. */
  confirm?: (message: string) => boolean;
}

/** The text a refusal shows: the server's own words when they already name the change. */
export function refusalText(what: string, err: unknown, keptKeys = false): string {
  const message = describeError(err);
  if (keptKeys) return `${what} not applied, the timeline kept: ${message}`;
  return message.startsWith(what) ? message : `${what} rejected: ${message}`;
}

export class CommandLayer<K extends CommandMethod = CommandMethod> {
  private readonly client: Pick<DeformationClient, K>;
  private readonly clientId: () => string;
  private readonly retry: <T>(call: () => Promise<T>) => Promise<T>;
  private readonly refused: (text: string) => void;
  private readonly accepted: () => void;
  private readonly onConflict: (what: string, err: ConnectError) => Promise<void> | void;
  private readonly confirm: ((message: string) => boolean) | undefined;
  private readonly lanes = new Map<string, GestureLane>();

  constructor(options: CommandLayerOptions<K>) {
    this.client = options.client;
    this.clientId = options.clientId ?? (() => "");
    this.retry = options.retry ?? ((call) => call());
    this.refused = options.refused ?? (() => {});
    this.accepted = options.accepted ?? (() => {});
    this.onConflict = options.conflict ?? ((what, err) => this.refused(refusalText(what, err)));
    this.confirm = options.confirm;
  }

  /** The gesture `key`'s lane (busy while one of its commands is in flight or waiting). */
  lane(key: string): GestureLane {
    let lane = this.lanes.get(key);
    if (!lane) this.lanes.set(key, (lane = new GestureLane()));
    return lane;
  }

  /** Sends `command`: its answer; a refusal is shown (unless quiet) and thrown. */
  execute<M extends K>(command: Command<M> & { gesture: { key: string } }): Promise<CommandAnswer<M> | undefined>;
  execute<M extends K>(command: Command<M>): Promise<CommandAnswer<M>>;
  execute<M extends K>(command: Command<M>): Promise<CommandAnswer<M> | undefined> {
    const key = command.gesture?.key;
    return key === undefined ? this.send(command) : this.lane(key).add(command.gesture!.phase, () => this.send(command));
  }

  private async send<M extends K>(command: Command<M>): Promise<CommandAnswer<M>> {
    const { method } = command;
    const requestId = REQUEST_ID_METHODS.has(method) ? newRequestId() : "";
    const attempt = (discardTimeline: boolean) => {
      const call = () => this.call(method, this.complete(command, requestId, discardTimeline));
      return RETRIED_METHODS.has(method) ? this.retry(call) : call();
    };
    try {
      const answer = command.dropsKeys ? await askingToDropKeys(attempt, this.confirm) : await attempt(false);
      if (!command.quiet && !command.showIn) this.accepted();
      return answer;
    } catch (err) {
      await this.refuse(command, err);
      throw err;
    }
  }

  /** The request as sent: client_id (unless it names one), request_id, the gesture's `dragging`. */
  private complete<M extends K>(command: Command<M>, requestId: string, discardTimeline: boolean): CommandRequest<M> {
    const request: Record<string, unknown> = { ...(command.request() as object) };
    if (requestId) {
      request.clientId = request.clientId || this.clientId();
      request.requestId = request.requestId || requestId;
    }
    if (command.dropsKeys) request.discardTimeline = discardTimeline;
    if (command.method === "updateHandles") request.dragging = command.gesture?.phase === "begin" || command.gesture?.phase === "update";
    return request as CommandRequest<M>;
  }

  private call<M extends K>(method: M, request: CommandRequest<M>): Promise<CommandAnswer<M>> {
    const fn = this.client[method] as unknown as (r: CommandRequest<M>) => Promise<CommandAnswer<M>>;
    return fn.call(this.client, request);
  }

  private async refuse<M extends K>(command: Command<M>, err: unknown): Promise<void> {
    if (command.quiet || isAbort(err)) return;
    if (CONFIG_VERSION_METHODS.has(command.method) && err instanceof ConnectError && err.code === Code.Aborted && !dropsOthersKeys(err)) {
      await (command.conflict ? command.conflict(err) : this.onConflict(command.what, err));
      return;
    }
    const text = refusalText(command.what, err, command.dropsKeys === true && dropsOthersKeys(err));
    (command.showIn ?? this.refused)(text);
  }
}

// Taking a handle before dragging it (GrabHandles), keeping it while it is held without moving
// (a grab every RENEW_MS; updates naming it renew the lease too) and giving it back at the
// drag's end (ReleaseHandles). A server without several-editor support answers UNIMPLEMENTED:
// then every grab succeeds locally and nothing more is asked. The calls go through the command
// layer, quiet: a refused grab is said by the caller, who names the holder.
import type { MessageInitShape } from "@bufbuild/protobuf";
import { Code, ConnectError } from "@connectrpc/connect";
import type { CommandLayer } from "../commands/command_layer";
import type { ParticipantSchema, Presence } from "../gen/hdeform/v1/deform_pb";

export const RENEW_MS = 2000;
export const LEASE_MS = 5000;

export type GrabCommands = Pick<CommandLayer, "execute">;

export type GrabResult = { ok: true } | { ok: false; message: string; code: Code };

export class HandleLease {
  /** null: not known yet; false: the server has no GrabHandles. */
  supported: boolean | null = null;
  private held: number[] = [];
  private name = "";
  private timer: ReturnType<typeof setInterval> | undefined;

  constructor(
    private readonly commands: GrabCommands,
    private readonly participant: () => MessageInitShape<typeof ParticipantSchema>,
    /** A Presence from an answer, with the session it is of (answers may outlive a switch). */
    private readonly presence: (p: Presence, name: string) => void,
  ) {}

  get holding(): number[] {
    return this.held;
  }

  /** Grabs `handles` (0-based) of session `name` for this page. */
  async grab(name: string, handles: number[]): Promise<GrabResult> {
    if (this.supported === false) return { ok: true };
    try {
      const res = await this.commands.execute({
        method: "grabHandles",
        what: "Grab",
        gesture: { phase: "begin" },
        quiet: true,
        request: () => ({ name, client: this.participant(), handles, leaseMs: LEASE_MS }),
      });
      this.supported = true;
      this.name = name;
      this.held = handles;
      if (res.presence) this.presence(res.presence, name);
      clearInterval(this.timer);
      this.timer = setInterval(() => void this.renew(), RENEW_MS);
      return { ok: true };
    } catch (err) {
      const e = ConnectError.from(err);
      if (e.code === Code.Unimplemented) {
        this.supported = false;
        return { ok: true };
      }
      return { ok: false, message: e.rawMessage, code: e.code };
    }
  }

  /** Gives back what this page holds (at a drag's end, or when it is cancelled). */
  async release(): Promise<void> {
    clearInterval(this.timer);
    this.timer = undefined;
    if (!this.supported || this.held.length === 0) return;
    const { name, held } = this;
    this.held = [];
    try {
      const res = await this.commands.execute({
        method: "releaseHandles",
        what: "Release",
        gesture: { phase: "end" },
        quiet: true,
        request: () => ({ name, clientId: this.participant().clientId ?? "", handles: held }),
      });
      if (res.presence) this.presence(res.presence, name);
    } catch {
      /* the lease runs out by itself */
    }
  }

  private async renew(): Promise<void> {
    if (this.held.length === 0) return;
    try {
      const { name, held } = this;
      await this.commands.execute({
        method: "grabHandles",
        what: "Grab",
        gesture: { phase: "update" },
        quiet: true,
        request: () => ({ name, client: this.participant(), handles: held, leaseMs: LEASE_MS }),
      });
    } catch {
      /* the next update or grab says more */
    }
  }
}

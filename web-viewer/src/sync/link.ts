// The connection's state machine: connected → reconnecting → connected, or → gone (the
// session no longer exists or the page lost access). Edits wait on it while reconnecting.

export type Link = "connected" | "reconnecting" | "gone";

export class LinkState {
  state: Link = "connected";
  /** When the current outage began (Date.now()), for the "lost connection" banner's delay. */
  outageSince = 0;
  private waiters: ((ok: boolean) => void)[] = [];

  constructor(private readonly onChange: (state: Link, why: string) => void) {}

  set(next: Link, why = ""): void {
    if (next === "reconnecting" && this.state !== "reconnecting") this.outageSince = Date.now();
    this.state = next;
    if (next !== "reconnecting") {
      const waiters = this.waiters;
      this.waiters = [];
      for (const w of waiters) w(next === "connected");
    }
    this.onChange(next, why);
  }

  /** Resolves true once connected (at once if it is), false on timeout or when gone. */
  waitConnected(timeoutMs: number): Promise<boolean> {
    if (this.state === "connected") return Promise.resolve(true);
    if (this.state === "gone") return Promise.resolve(false);
    return new Promise((resolve) => {
      const timer = setTimeout(() => {
        this.waiters = this.waiters.filter((w) => w !== done);
        resolve(false);
      }, timeoutMs);
      const done = (ok: boolean) => {
        clearTimeout(timer);
        resolve(ok);
      };
      this.waiters.push(done);
    });
  }
}

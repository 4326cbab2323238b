// At most one call in flight; values given meanwhile replace each other, and the newest is
// sent when the call returns (a slider's live preview: the server never queues stale values).

export class LatestWins<T> {
  private next: { value: T } | null = null;
  private running: Promise<void> | null = null;
  /** Calls made (for tests). */
  calls = 0;

  constructor(private readonly call: (value: T) => Promise<void>) {}

  get busy(): boolean {
    return this.running !== null;
  }

  /** Resolves once nothing is in flight or waiting. */
  get idle(): Promise<void> {
    return this.running ?? Promise.resolve();
  }

  send(value: T): void {
    this.next = { value };
    if (!this.running) this.running = this.drain();
  }

  private async drain(): Promise<void> {
    try {
      while (this.next) {
        const { value } = this.next;
        this.next = null;
        this.calls++;
        try {
          await this.call(value);
        } catch {
          /* the call reports its own errors */
        }
      }
    } finally {
      this.running = null;
    }
  }
}

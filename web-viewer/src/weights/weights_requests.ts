// Which GetHandleWeights answer may be shown. Requests are not cancelled (the field is cheap to
// compute and a drag never waits for one): each gets a ticket, and an answer is shown only if
// it is for the newest request, for the handle that request asked about, and read at a session
// version no older than the state the page held when it asked. So switching handles quickly, or
// constraints changing under a request, never leaves an older field on screen.

export interface WeightsWanted {
  handle: number; // 0-based
  /** The session version the page had seen when it asked. */
  minVersion: bigint;
}

export interface WeightsAnswer {
  handle: number;
  version: bigint;
}

export class WeightsRequests {
  private next = 0;
  private wanted: (WeightsWanted & { ticket: number }) | null = null;

  /** A new request: every earlier one is stale from now on. */
  begin(wanted: WeightsWanted): number {
    this.next++;
    this.wanted = { ...wanted, ticket: this.next };
    return this.next;
  }

  /** The request is the newest one and the preview was not turned off since. */
  isLatest(ticket: number): boolean {
    return this.wanted?.ticket === ticket;
  }

  accept(ticket: number, answer: WeightsAnswer): boolean {
    const w = this.wanted;
    return !!w && w.ticket === ticket && answer.handle === w.handle && answer.version >= w.minVersion;
  }

  /** The preview was turned off (or another mesh opened): nothing in flight may be shown. */
  cancel(): void {
    this.wanted = null;
  }
}

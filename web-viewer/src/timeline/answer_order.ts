// Which answers of a stream of requests may still be applied (unit-tested): each request gets a
// ticket; an answer is applied only if no newer request's answer was applied already and
// nothing cancelled the requests (the scrub ended, another session opened, Play started). So a
// slow PoseAt answer never puts the handles back to where the playhead was earlier.
export class AnswerOrder {
  private issued = 0;
  private applied = 0;
  private floor = 0; // tickets at or below it are cancelled

  begin(): number {
    return ++this.issued;
  }

  /** True (and recorded) when `ticket`'s answer may be applied now. */
  accept(ticket: number): boolean {
    if (ticket <= this.floor || ticket <= this.applied) return false;
    this.applied = ticket;
    return true;
  }

  /** Every request issued so far is stale. */
  cancel(): void {
    this.floor = this.issued;
  }
}

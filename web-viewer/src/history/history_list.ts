// The History panel's list, without the DOM (unit-tested): steps from ListHistory pages (newest
// first, older pages appended) and live ones from SessionEvent.step, merged by id, newest first.
//
// Whether a step is undone comes from the server (HistoryStep.undone) as of when it was listed;
// a later UNDO / REDO (which names the step it reverted or re-applied as `target`) changes it.
// So the newest UNDO / REDO held for a step decides, else the listed flag: the held steps are
// one unbroken run from the oldest page loaded up to the newest live step, and an UNDO / REDO
// is always newer than its target, so the deciding one is never in a page not yet loaded.
import { StepKind, type HistoryStep } from "../gen/hdeform/v1/deform_pb";

export interface HistoryPage {
  steps: HistoryStep[];
  nextPageToken: string;
}

export interface ShownStep {
  step: HistoryStep;
  undone: boolean;
}

export class HistoryList {
  private readonly steps = new Map<bigint, HistoryStep>();
  /** Token of the next older page ("" = none, or nothing loaded yet: see `hasOlder`). */
  private token = "";
  private firstLoaded = false;

  /** Forgets everything (another session, or a reconnect: steps may have been missed). */
  clear(): void {
    this.steps.clear();
    this.token = "";
    this.firstLoaded = false;
  }

  /** The newest page (ListHistory without a token): live steps received meanwhile are kept. */
  addFirstPage(page: HistoryPage): void {
    for (const s of page.steps) this.steps.set(s.id, s);
    this.token = page.nextPageToken;
    this.firstLoaded = true;
  }

  /** An older page (from `olderToken`). */
  addOlderPage(page: HistoryPage): void {
    for (const s of page.steps) if (!this.steps.has(s.id)) this.steps.set(s.id, s);
    this.token = page.nextPageToken;
  }

  /** A step from the watch stream. */
  addLive(step: HistoryStep): void {
    this.steps.set(step.id, step);
  }

  get olderToken(): string {
    return this.token;
  }

  /** The newest page has been read (an empty list then means no steps). */
  get loaded(): boolean {
    return this.firstLoaded;
  }

  get hasOlder(): boolean {
    return this.firstLoaded && this.token !== "";
  }

  get size(): number {
    return this.steps.size;
  }

  /** Newest first, with whether each step is undone now. */
  shown(): ShownStep[] {
    const ordered = [...this.steps.values()].sort((a, b) => (a.id < b.id ? 1 : a.id > b.id ? -1 : 0));
    // Newest first: the first UNDO / REDO seen for a target is its newest.
    const decided = new Map<bigint, boolean>();
    for (const s of ordered) {
      if ((s.kind === StepKind.UNDO || s.kind === StepKind.REDO) && !decided.has(s.target)) {
        decided.set(s.target, s.kind === StepKind.UNDO);
      }
    }
    return ordered.map((step) => ({ step, undone: decided.get(step.id) ?? step.undone }));
  }
}

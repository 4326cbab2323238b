// The commands of one gesture (a β slider drag: its values, then the release) reach the server
// one at a time and in order. An update still waiting when a newer command of the gesture comes
// is replaced by it and never sent, so the server gets the newest value next rather than a
// queue of stale ones. Begin and end are never replaced: they open and close the step.

/** Where a command stands in its gesture; a command with no gesture is a step of its own. */
export type Phase = "begin" | "update" | "end";

interface Waiting {
  phase: Phase;
  run: () => Promise<void>;
  drop: () => void;
}

export class GestureLane {
  private waiting: Waiting[] = [];
  private running: Promise<void> | null = null;
  /** Updates replaced before they were sent. */
  merged = 0;

  /** A command of the gesture is in flight or waiting. */
  get busy(): boolean {
    return this.running !== null;
  }

  /** Resolves once nothing of the gesture is in flight or waiting. */
  get idle(): Promise<void> {
    return this.running ?? Promise.resolve();
  }

  /** Queues `run`: its answer, or undefined when a newer command replaced it unsent. */
  add<T>(phase: Phase, run: () => Promise<T>): Promise<T | undefined> {
    return new Promise<T | undefined>((resolve, reject) => {
      this.waiting = this.waiting.filter((w) => {
        if (w.phase !== "update") return true;
        w.drop();
        this.merged++;
        return false;
      });
      this.waiting.push({ phase, run: () => run().then(resolve, reject), drop: () => resolve(undefined) });
      if (!this.running) this.running = this.drain();
    });
  }

  private async drain(): Promise<void> {
    try {
      for (let w = this.waiting.shift(); w; w = this.waiting.shift()) await w.run();
    } finally {
      this.running = null;
    }
  }
}

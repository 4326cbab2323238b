// Undo / Redo of this tab's own changes (by its client id, the one presence and updates carry),
// or of one named step (the History panel). The server either applies it as a new step — then
// the session it answers is adopted here at once, and the same state and a frame of it come on
// the watch stream for every page — or refuses it (ABORTED: a later change touched the same
// thing, the message names it; FAILED_PRECONDITION: nothing to undo), and then nothing changes
// but the banner, which shows the server's own words (the command layer's refusal).
// A retry after a transient failure carries the same request_id, so the server answers it as
// the first and never undoes a second step.
import type { App } from "../app";
import type { Session } from "../gen/hdeform/v1/deform_pb";
import type { Sync } from "../sync/sync";

export type UndoKind = "undo" | "redo";

export interface UndoRedo {
  /** Undoes (redoes) this tab's latest step, or step `step` (any author); false when refused. */
  run(kind: UndoKind, step?: bigint): Promise<boolean>;
  /** Adopts a session an undo-like call (also RestoreSnapshot) answered with. */
  adopt(s: Session): void;
}

export function setupUndoRedo(app: App, sync: Sync, clientId: () => string): UndoRedo {
  const { state, edits } = app;
  const adopt = (s: Session) => {
    if (s.name !== state.sessionName) return; // another session opened meanwhile
    if (state.session && s.version < state.session.version) return; // a newer state came first
    sync.confirm(s.transforms);
    state.adoptSession(s, { labels: true, transforms: !sync.dragging });
  };
  let running = false;
  return {
    adopt,
    async run(kind, step) {
      if (state.watchOnly || !state.sessionName || running) return false;
      if (sync.dragging) return false; // the drag is not a step yet
      running = true;
      const name = state.sessionName;
      try {
        adopt(
          await edits.execute({
            method: kind,
            what: kind === "undo" ? "Undo" : "Redo",
            dropsKeys: true,
            request: () => ({ name, clientId: clientId(), step: step ?? 0n }),
          }),
        );
        return true;
      } catch {
        return false;
      } finally {
        running = false;
      }
    },
  };
}

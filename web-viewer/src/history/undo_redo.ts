// Undo / Redo of this tab's own changes (by its client id, the one presence and updates carry),
// or of one named step (the History panel). The server either applies it as a new step — then
// the session it answers is adopted here at once, and the same state and a frame of it come on
// the watch stream for every page — or refuses it (ABORTED: a later change touched the same
// thing, the message names it; FAILED_PRECONDITION: nothing to undo), and then nothing changes
// but the banner, which shows the server's own words.
//
// Not sent through sync.edit: that retries after a transient failure, and an undo that had in
// fact reached the server would then undo a second step.
import { describeError } from "../api";
import type { App } from "../app";
import type { Session } from "../gen/hdeform/v1/deform_pb";
import type { Sync } from "../sync/sync";
import { askingToDropKeys } from "../conflict";
import { newRequestId } from "../request_id";

export type UndoKind = "undo" | "redo";

export interface UndoRedo {
  /** Undoes (redoes) this tab's latest step, or step `step` (any author); false when refused. */
  run(kind: UndoKind, step?: bigint): Promise<boolean>;
  /** Adopts a session an undo-like call (also RestoreSnapshot) answered with. */
  adopt(s: Session): void;
}

export function setupUndoRedo(app: App, sync: Sync, clientId: () => string): UndoRedo {
  const { state, client, banner } = app;
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
      const request = { name: state.sessionName, clientId: clientId(), step: step ?? 0n, requestId: newRequestId() };
      try {
        adopt(
          await askingToDropKeys((discardTimeline) =>
            kind === "undo" ? client.undo({ ...request, discardTimeline }) : client.redo({ ...request, discardTimeline }),
          ),
        );
        banner.clear("rejected");
        return true;
      } catch (err) {
        // The server's words ("Undo of step 4 (Alice: …) refused: …"); named so when they are not.
        const what = kind === "undo" ? "Undo" : "Redo";
        const message = describeError(err);
        banner.show(message.startsWith(what) ? message : `${what}: ${message}`, "rejected");
        return false;
      } finally {
        running = false;
      }
    },
  };
}

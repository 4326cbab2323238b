// What an empty History list says. The server stores a session's history with it (docs/api.md
// "History and snapshots"), but a session made by ImportSession, or restored from state that
// kept no history (a crash within the flush window, a server from before histories were
// stored), has its state — constraints, β, poses, version — and no steps. So an empty list for
// a session that has been changed means the steps are gone, not that nothing happened.
import { BetaUnits, type Session } from "../gen/hdeform/v1/deform_pb";
import { isIdentity } from "../transforms";

/** The session is not as a new session starts: constraints, a β, or a moved handle. */
export function sessionChanged(s: Session): boolean {
  return s.constrained || (s.beta?.value ?? 0) !== 0 || (s.beta?.units ?? BetaUnits.AREA) !== BetaUnits.AREA || s.transforms.some((t) => !isIdentity(t));
}

/** The note an empty History list shows for session `s`. */
export function emptyHistoryNote(s: Session | null): string {
  if (s && sessionChanged(s)) {
    return "History starts at this session's import, or at a server restart that found no stored history: earlier changes are not listed and cannot be undone.";
  }
  return "No changes yet: each edit will be listed here, newest first.";
}

// What an empty History list says. The server keeps a session's history in memory only
// (docs/api.md "History and snapshots"): a session restored after a server restart, or made by
// ImportSession, has its state — constraints, β, poses, version — but no steps. So an empty list
// for a session that has been changed means the steps are gone, not that nothing happened.
import { BetaUnits, type Session } from "../gen/hdeform/v1/deform_pb";
import { isIdentity } from "../transforms";

/** The session is not as a new session starts: constraints, a β, or a moved handle. */
export function sessionChanged(s: Session): boolean {
  return s.constrained || (s.beta?.value ?? 0) !== 0 || (s.beta?.units ?? BetaUnits.AREA) !== BetaUnits.AREA || s.transforms.some((t) => !isIdentity(t));
}

/** The note an empty History list shows for session `s`. */
export function emptyHistoryNote(s: Session | null): string {
  if (s && sessionChanged(s)) {
    return "History starts at the server's last restart (or at this session's import): the server keeps steps in memory only, so earlier changes are not listed and cannot be undone.";
  }
  return "No changes yet: each edit will be listed here, newest first.";
}

// Another editor changed the constraints or β first (ABORTED on expected_config_version):
// say so plainly and show the session as it now is (GetSession), rather than overwrite it.
import { Code, ConnectError } from "@connectrpc/connect";
import { describeError } from "./api";
import type { App } from "./app";

export async function reloadAfterConflict(app: Pick<App, "state" | "client" | "banner">, what: string, err: unknown): Promise<void> {
  const { state, client, banner } = app;
  banner.show(
    `Your ${what.toLowerCase()} change was not applied: someone else changed the constraints or β first (${describeError(err)}). The session was reloaded; make the change again if you still want it.`,
    "rejected",
  );
  try {
    const s = await client.getSession({ name: state.sessionName });
    state.labelsDirty = false;
    state.adoptSession(s, { labels: true, transforms: true });
  } catch {
    /* the watch loop reports connection problems */
  }
}

/** The server refused a change because it would drop timeline keys another editor set. */
export function dropsOthersKeys(err: unknown): err is ConnectError {
  return err instanceof ConnectError && err.code === Code.Aborted && err.rawMessage.includes("discard_timeline");
}

/**
 * Runs a change that may drop the timeline's keys (new constraints renumber the handles). The
 * server refuses it when another editor set them; then the user is asked, with the server's
 * own words, and on yes it is sent again with discardTimeline (Undo brings the keys back).
 * On no, the refusal is thrown as it came.
 */
export async function askingToDropKeys<T>(
  call: (discardTimeline: boolean) => Promise<T>,
  confirm: (message: string) => boolean = (m) => window.confirm(m),
): Promise<T> {
  try {
    return await call(false);
  } catch (err) {
    if (!dropsOthersKeys(err) || !confirm(`${err.rawMessage}\n\nDrop those keys? (Undo brings them back.)`)) throw err;
    return await call(true);
  }
}

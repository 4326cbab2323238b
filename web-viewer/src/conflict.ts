// Another editor changed the constraints or β first (ABORTED on expected_config_version):
// say so plainly and show the session as it now is (GetSession), rather than overwrite it.
import { describeError } from "./api";
import type { App } from "./app";

export async function reloadAfterConflict(app: App, what: string, err: unknown): Promise<void> {
  const { state, client, banner } = app;
  banner.show(
    `Your ${what} change was not applied: someone else changed the constraints or β first (${describeError(err)}). The session was reloaded; make the change again if you still want it.`,
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

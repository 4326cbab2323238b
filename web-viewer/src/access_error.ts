// Errors about a page's access to a session, in words a link's user can act on.
import { Code, ConnectError } from "@connectrpc/connect";
import { describeError } from "./api";

/** What `err` says about the page's access to session `name`. */
export function accessError(err: unknown, name: string): string {
  if (err instanceof ConnectError) {
    if (err.code === Code.Unauthenticated)
      return `this link carries no access token. Open the session with its share link (…#edit=…) or watch link (…#view=…).`;
    if (err.code === Code.PermissionDenied)
      return `the link's token does not open ${name} (a wrong or old link: the session's tokens may have been renewed, or the session deleted or expired). [PermissionDenied]`;
    if (err.code === Code.NotFound) return `${name} does not exist on this server. [NotFound]`;
  }
  return describeError(err);
}

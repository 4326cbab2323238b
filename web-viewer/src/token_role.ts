// What the page's token may do. The API has no call that names a token's role before the page
// watches (Participant.editor comes only with presence), so the page asks an edit-only call that
// changes nothing: ReleaseHandles for a throwaway client id, which holds no handle (nothing is
// released, no history step, no presence event). The server checks the token first. Through the
// command layer, quiet: the answer is the role, not a refusal to show.
import { Code, ConnectError } from "@connectrpc/connect";
import type { CommandLayer } from "./commands/command_layer";
import { randomHex } from "./request_id";

/** "view": the token only reads; "edit": it edits; "unknown": the server did not say. */
export type TokenRole = "edit" | "view" | "unknown";

export async function tokenRole(commands: Pick<CommandLayer, "execute">, name: string): Promise<TokenRole> {
  const clientId = `role-probe-${randomHex(6)}`;
  try {
    await commands.execute({ method: "releaseHandles", what: "Role probe", quiet: true, request: () => ({ name, clientId, handles: [] }) });
    return "edit";
  } catch (err) {
    // A server without ReleaseHandles (UNIMPLEMENTED) or a failure says nothing: stay an editor,
    // as before; edits then show the server's answer.
    return ConnectError.from(err).code === Code.PermissionDenied ? "view" : "unknown";
  }
}

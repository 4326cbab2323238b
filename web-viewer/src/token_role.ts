// What the page's token may do. The API has no call that names a token's role before the page
// watches (Participant.editor comes only with presence), so the page asks an edit-only call that
// changes nothing: ReleaseHandles for a throwaway client id, which holds no handle (nothing is
// released, no history step, no presence event). The server checks the token first.
import { Code, ConnectError } from "@connectrpc/connect";
import type { DeformationClient } from "./api";
import { randomHex } from "./request_id";

/** "view": the token only reads; "edit": it edits; "unknown": the server did not say. */
export type TokenRole = "edit" | "view" | "unknown";

export async function tokenRole(client: Pick<DeformationClient, "releaseHandles">, name: string): Promise<TokenRole> {
  try {
    await client.releaseHandles({ name, clientId: `role-probe-${randomHex(6)}`, handles: [] });
    return "edit";
  } catch (err) {
    // A server without ReleaseHandles (UNIMPLEMENTED) or a failure says nothing: stay an editor,
    // as before; edits then show the server's answer.
    return ConnectError.from(err).code === Code.PermissionDenied ? "view" : "unknown";
  }
}

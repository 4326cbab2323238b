// The part of the generated Deformation client that sync uses: injected, so tests can fake it.
// Its reads are its own; UpdateHandles goes through the command layer (commands/).
import type { DeformationClient } from "../api";

export type SyncClient = Pick<DeformationClient, "updateHandles" | "getSession" | "watchSession">;

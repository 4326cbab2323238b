// The part of the generated Deformation client that sync uses: injected, so tests can fake it.
import type { DeformationClient } from "../api";

export type SyncClient = Pick<DeformationClient, "updateHandles" | "setBeta" | "setConstraints" | "getSession" | "watchSession">;

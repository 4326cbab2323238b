// Which Deformation methods change something on the server (a session, its history, its
// snapshots or timeline, who holds a handle, the set of sessions) and which only read. The
// mutating ones are called by the command layer alone (command_layer.ts); a read is called
// directly by whatever shows its answer. A test checks that every method of the service is
// in one list, so a new RPC needs a decision, and that no module outside this folder calls a
// mutating one.
import type { DeformationClient } from "../api";

export const MUTATING_METHODS = [
  "createSession",
  "deleteSession",
  "importSession",
  "rotateTokens",
  "setConstraints",
  "setBeta",
  "updateHandles",
  "deform",
  "grabHandles",
  "releaseHandles",
  "undo",
  "redo",
  "saveSnapshot",
  "restoreSnapshot",
  "deleteSnapshot",
  "setTimeline",
] as const satisfies readonly (keyof DeformationClient)[];

// Sweep and the exports solve on the server but change nothing there (a measuring Sweep needs
// the edit token only because of its cost).
export const READ_METHODS = [
  "getSession",
  "listSessions",
  "listMeshes",
  "getMesh",
  "sweep",
  "watchSession",
  "exportSession",
  "listHistory",
  "listSnapshots",
  "getHandleWeights",
  "getTimeline",
  "poseAt",
  "exportAnimation",
  "exportRig",
] as const satisfies readonly (keyof DeformationClient)[];

export type MutatingMethod = (typeof MUTATING_METHODS)[number];

/**
 * The mutating methods a browser can call: gRPC-Web has no client streams, so CreateSession
 * is the gateway's POST /upload (api.ts) and Deform is not used.
 */
export type CommandMethod = Exclude<MutatingMethod, "createSession" | "deform">;

/** Requests that carry request_id (docs/api.md "Retries") and client_id (the step's author). */
export const REQUEST_ID_METHODS: ReadonlySet<CommandMethod> = new Set<CommandMethod>([
  "setConstraints",
  "setBeta",
  "undo",
  "redo",
  "saveSnapshot",
  "restoreSnapshot",
  "deleteSnapshot",
  "setTimeline",
]);

/**
 * Sent once more after a reconnect when they fail for a transient reason: the request-id ones
 * (the server answers a repeat as the first) and UpdateHandles (absolute poses; `sequence`
 * keeps an old one from moving anything).
 */
export const RETRIED_METHODS: ReadonlySet<CommandMethod> = new Set<CommandMethod>([...REQUEST_ID_METHODS, "updateHandles"]);

/** Requests with expected_config_version: ABORTED means another editor changed β or the constraints first. */
export const CONFIG_VERSION_METHODS: ReadonlySet<CommandMethod> = new Set<CommandMethod>(["setConstraints", "setBeta", "restoreSnapshot", "setTimeline"]);

/** Requests with discard_timeline: they may drop timeline keys another editor set. */
export type DropsKeysMethod = "setConstraints" | "restoreSnapshot" | "undo" | "redo";

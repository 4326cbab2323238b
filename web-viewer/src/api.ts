// The API client: gRPC-Web (binary) to hdeform-server's own HTTP port, same origin as the page.
import { randomHex } from "./request_id";
import { fromBinary } from "@bufbuild/protobuf";
import { Code, ConnectError, createClient, type Client } from "@connectrpc/connect";
import { createGrpcWebTransport } from "@connectrpc/connect-web";
import {
  Deformation,
  MeshFormat,
  SessionSchema,
  type Session,
} from "./gen/hdeform/v1/deform_pb";

export type DeformationClient = Client<typeof Deformation>;

// Every call carries x-session-id (the {id} of sessions/{id}) so that a load balancer in
// front of several replicas can hash it to the replica that owns the session, and the
// session's capability token as `authorization: Bearer TOKEN` (docs/api.md "Access"): the
// edit token when this page has it, else the view token (enough for GetSession, GetMesh,
// WatchSession).
let routingId = "";
let editToken = "";
let viewToken = "";
export function setRoutingSession(name: string): void {
  routingId = name.startsWith("sessions/") ? name.slice("sessions/".length) : name;
}
/** The tokens this page holds for the current session ("" = not known). */
export function setTokens(edit: string, view: string): void {
  editToken = edit;
  viewToken = view;
}
export function tokens(): { edit: string; view: string } {
  return { edit: editToken, view: viewToken };
}
function bearer(): string {
  const t = editToken || viewToken;
  return t ? `Bearer ${t}` : "";
}
/** A fresh client-chosen session id (CreateSessionHeader.session_id). */
export function newSessionId(): string {
  return randomHex(12);
}

export function makeClient(baseUrl: string = window.location.origin): DeformationClient {
  const transport = createGrpcWebTransport({
    baseUrl,
    useBinaryFormat: true,
    interceptors: [
      (next) => async (req) => {
        if (routingId) req.header.set("x-session-id", routingId);
        const auth = bearer();
        if (auth) req.header.set("authorization", auth);
        return next(req);
      },
    ],
  });
  return createClient(Deformation, transport);
}

/**
 * A failure of the connection rather than an answer from the server: UNAVAILABLE (the
 * gateway's "shutting down", HTTP 502/503/504), a deadline, or a fetch that failed or was cut
 * (connect-web reports those as UNKNOWN without any grpc-status from the server).
 */
export function isTransient(err: unknown): boolean {
  if (!(err instanceof ConnectError)) return err instanceof TypeError; // fetch: network error
  if (err.code === Code.Unavailable || err.code === Code.DeadlineExceeded) return true;
  if (err.code === Code.Unknown || err.code === Code.Internal) return !err.metadata.has("grpc-status");
  return false;
}

/** A readable one-line message for any error thrown by a call. */
export function describeError(err: unknown): string {
  if (err instanceof ConnectError) {
    const code = Code[err.code] ?? String(err.code);
    if (err.code === Code.Unavailable || err.code === Code.Unknown) {
      if (/fetch|network|Failed/i.test(err.rawMessage)) {
        return `Lost connection to the server (${err.rawMessage})`;
      }
    }
    return `${err.rawMessage || "request failed"} [${code}]`;
  }
  if (err instanceof Error) return err.message;
  return String(err);
}

export function isAbort(err: unknown): boolean {
  return (
    (err instanceof ConnectError && err.code === Code.Canceled) ||
    (err instanceof DOMException && err.name === "AbortError")
  );
}

/** GetMesh is server-streaming: concatenate its chunks. */
export async function fetchMesh(
  client: DeformationClient,
  name: string,
  rest: boolean,
  format: MeshFormat,
  signal?: AbortSignal,
): Promise<Uint8Array> {
  const parts: Uint8Array[] = [];
  let total = 0;
  for await (const chunk of client.getMesh({ name, rest, format }, { signal })) {
    parts.push(chunk.data);
    total += chunk.data.byteLength;
  }
  const out = new Uint8Array(total);
  let at = 0;
  for (const p of parts) {
    out.set(p, at);
    at += p.byteLength;
  }
  return out;
}

/** An upload the server answered with an error: its HTTP status, grpc-status and message. */
export class UploadRejected extends Error {
  constructor(readonly httpStatus: number, readonly grpcStatus: number | null, readonly reason: string) {
    super(`Upload rejected (HTTP ${httpStatus}): ${reason}`);
  }
}

/**
 * CreateSession is client-streaming, which browsers cannot do over gRPC-Web; the gateway's
 * POST /upload turns the raw request body into that call. XMLHttpRequest gives upload
 * progress (fetch does not). `repair`: repair the file first, merging vertices this close
 * (docs/api.md "Repair"; the answer's Session.repair says what changed).
 */
export function createSessionViaUpload(
  query: { filename: string; body: Blob; repair?: number } | { library: string },
  onProgress?: (loaded: number, total: number) => void,
): Promise<Session> {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    const id = newSessionId();
    const q =
      ("library" in query
        ? `library=${encodeURIComponent(query.library)}`
        : `filename=${encodeURIComponent(query.filename)}` + (query.repair === undefined ? "" : `&repair=${query.repair}`)) +
      `&session_id=${id}`;
    xhr.open("POST", `upload?${q}`);
    xhr.setRequestHeader("x-session-id", id);
    // The new session needs no token; sending the page's current one is harmless and keeps
    // every request of the page alike.
    const auth = bearer();
    if (auth) xhr.setRequestHeader("authorization", auth);
    xhr.responseType = "arraybuffer";
    if (onProgress) {
      xhr.upload.onprogress = (e) => onProgress(e.loaded, e.lengthComputable ? e.total : 0);
    }
    xhr.onload = () => {
      if (xhr.status === 200) {
        try {
          resolve(fromBinary(SessionSchema, new Uint8Array(xhr.response as ArrayBuffer)));
        } catch (e) {
          reject(new Error(`upload: unreadable reply (${(e as Error).message})`));
        }
      } else {
        const text = new TextDecoder().decode(xhr.response as ArrayBuffer).trim();
        const grpc = xhr.getResponseHeader("grpc-status");
        reject(new UploadRejected(xhr.status, grpc === null ? null : Number(grpc), text || xhr.statusText));
      }
    };
    xhr.onerror = () => reject(new Error("Upload failed: lost connection to the server"));
    xhr.onabort = () => reject(new Error("Upload cancelled"));
    if ("library" in query) {
      xhr.send();
    } else {
      xhr.setRequestHeader("Content-Type", "application/octet-stream");
      xhr.send(query.body);
    }
  });
}

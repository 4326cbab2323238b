// What the panels and the session loader share: the state, the client, the banner and
// status line, and the edits (carried out by sync).
import type { MessageInitShape } from "@bufbuild/protobuf";
import type { DeformationClient } from "./api";
import type { Session, SetBetaRequestSchema, SetConstraintsRequestSchema } from "./gen/hdeform/v1/deform_pb";
import type { Banner } from "./panels/banner";
import type { StatusLine } from "./panels/status_line";
import type { SessionState } from "./state";

export interface Edits {
  setBeta(request: MessageInitShape<typeof SetBetaRequestSchema>): Promise<Session>;
  setConstraints(request: MessageInitShape<typeof SetConstraintsRequestSchema>): Promise<Session>;
  /** The pose (or what a frame carries) changed: have it solved, if this page edits. */
  requestFrame(): void;
}

export interface App {
  state: SessionState;
  client: DeformationClient;
  banner: Banner;
  status: StatusLine;
  edits: Edits;
}

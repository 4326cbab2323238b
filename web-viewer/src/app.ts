// What the panels and the session loader share: the state, the client (for reads), the banner
// and status line, and the edits: every change goes through the command layer.
import type { DeformationClient } from "./api";
import type { CommandLayer } from "./commands/command_layer";
import type { Banner } from "./panels/banner";
import type { StatusLine } from "./panels/status_line";
import type { SessionState } from "./state";

export interface Edits extends Pick<CommandLayer, "execute" | "lane"> {
  /** The pose (or what a frame carries) changed: have it solved, if this page edits (sync's update pump). */
  requestFrame(): void;
}

export interface App {
  state: SessionState;
  /** For reads only: a mutating call goes through `edits` (commands/methods.ts). */
  client: DeformationClient;
  banner: Banner;
  status: StatusLine;
  edits: Edits;
}

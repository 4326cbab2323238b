// Who is in the session and who holds which handle, from the server's Presence events and
// GrabHandles answers: what the presence panel lists and what the gizmo asks before a drag.
import { handleName } from "../handle_names";
import type { Participant, Presence } from "../gen/hdeform/v1/deform_pb";

export interface Person {
  clientId: string;
  name: string;
  color: string;
  editor: boolean;
  held: number[]; // 0-based handle indices
  me: boolean;
}

export class PresenceModel {
  people: Person[] = [];
  version = 0n;

  constructor(private readonly myId: string) {}

  /** Adopts a Presence (newer or same version only; a GrabHandles answer may come late). */
  update(p: Presence): boolean {
    if (p.version < this.version) return false;
    this.version = p.version;
    this.people = p.participants.map((x: Participant) => ({
      clientId: x.clientId,
      name: x.displayName || "anonymous",
      color: x.color || "#9aa0a6",
      editor: x.editor,
      held: [...x.heldHandles],
      me: x.clientId === this.myId,
    }));
    return true;
  }

  clear(): void {
    this.people = [];
    this.version = 0n;
  }

  /** Someone other than this page who holds handle `h` (0-based), or null. */
  holderOf(h: number): Person | null {
    return this.people.find((p) => !p.me && p.held.includes(h)) ?? null;
  }
}

/** "Handle 1 is being moved by Alice" (handle index 1) from an ABORTED answer's message, or our own presence. */
export function heldMessage(handle: number, holder: string): string {
  return `${handleName(handle)} is being moved by ${holder}`;
}

/**
 * The holder's name in a refusal (ABORTED) message, when the server names one. The server's
 * wording is not part of the API: fall back to the whole message.
 */
export function holderFromMessage(message: string): string {
  const m = /(?:held|moved|grabbed) by ([^(),;]+?)(?:\s*\(|[,;.]|$)/i.exec(message);
  return m ? m[1].trim() : message;
}

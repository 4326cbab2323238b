// Who this tab is to the other people in a session: a random client id per tab
// (sessionStorage: a reload keeps it, so the server sees the same editor come back; a second
// tab is a second editor), a display name the person may change (localStorage: remembered
// across sessions) and a colour picked from the id, so everyone sees the same colour for it.
import { randomHex } from "../request_id";

/** Anything with getItem / setItem (window.sessionStorage, localStorage, a Map in tests). */
export interface KeyValueStore {
  getItem(key: string): string | null;
  setItem(key: string, value: string): void;
}

// No blues: a held handle is drawn in its holder's colour, and blue is the fixed region's.
const PALETTE = ["#e57373", "#81c784", "#ffb74d", "#ba68c8", "#4db6ac", "#f06292", "#aed581", "#ffd54f", "#a1887f", "#ff8a65"];

/** A colour for `clientId`: the same on every page that sees it. */
export function colorFor(clientId: string): string {
  let h = 0;
  for (let i = 0; i < clientId.length; i++) h = (h * 31 + clientId.charCodeAt(i)) >>> 0;
  return PALETTE[h % PALETTE.length];
}

/** "Editor 3f2a": the default name, from the id. */
export function defaultName(clientId: string): string {
  return `Editor ${clientId.slice(0, 4)}`;
}

/** What the server accepts as a display name: ≤ 64 characters, no control characters. */
export function cleanName(name: string): string {
  return name.replace(/[\u0000-\u001f\u007f]/g, "").trim().slice(0, 64);
}

function randomId(): string {
  return randomHex(8);
}

export class Identity {
  readonly clientId: string;
  private name: string;

  constructor(tab: KeyValueStore, private readonly user: KeyValueStore) {
    let id = tab.getItem("hdeform.clientId") ?? "";
    if (!/^[A-Za-z0-9_-]{1,64}$/.test(id)) {
      id = randomId();
      tab.setItem("hdeform.clientId", id);
    }
    this.clientId = id;
    this.name = cleanName(user.getItem("hdeform.displayName") ?? "") || defaultName(id);
  }

  get displayName(): string {
    return this.name;
  }

  get color(): string {
    return colorFor(this.clientId);
  }

  /** Sets (and remembers) the name; an empty one goes back to the default. */
  setDisplayName(name: string): void {
    const clean = cleanName(name);
    this.name = clean || defaultName(this.clientId);
    this.user.setItem("hdeform.displayName", clean);
  }

  participant(): { clientId: string; displayName: string; color: string } {
    return { clientId: this.clientId, displayName: this.name, color: this.color };
  }
}

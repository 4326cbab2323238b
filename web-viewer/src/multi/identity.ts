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

// A handle someone holds is drawn in their colour instead of its region colour, so no editor
// colour may pass for a region's (region_colours.ts: blue, red, green, amber, purple, teal,
// pink — the whole hue circle): light, pale or earthy tones, each at least ΔE*ab 34 from every
// region colour (#aed581, ΔE 32 from handle 1's green, looked like it; test/finished_editor.test.ts)
// and at least 20 from each other.
export const PALETTE = ["#fff176", "#f5f5f5", "#8d6e63", "#b39ddb", "#ffab91", "#b0bec5", "#ffe0b2"];

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

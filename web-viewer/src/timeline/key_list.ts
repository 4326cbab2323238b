// Editing the timeline's key list without the DOM (unit-tested). The server wants keys strictly
// increasing in time, so the list is kept sorted; a key set within SAME_TIME_S of an existing one
// replaces it (a click on a marker snaps the playhead there, and "Set key" then means "this key").

/** Two keys closer than this (seconds) are the same key. */
export const SAME_TIME_S = 1e-3;

export interface Timed {
  timeS: number;
}

/** `keys` with `key` added, or replacing the key at the same time; sorted by time. */
export function setKey<K extends Timed>(keys: readonly K[], key: K): K[] {
  const out = keys.filter((k) => Math.abs(k.timeS - key.timeS) >= SAME_TIME_S);
  out.push(key);
  return out.sort((a, b) => a.timeS - b.timeS);
}

/** `keys` without the key at `index` (out of range: unchanged). */
export function deleteKey<K extends Timed>(keys: readonly K[], index: number): K[] {
  return keys.filter((_, i) => i !== index);
}

/** The index of the key at `timeS` (within SAME_TIME_S), or -1. */
export function keyAt(keys: readonly Timed[], timeS: number): number {
  return keys.findIndex((k) => Math.abs(k.timeS - timeS) < SAME_TIME_S);
}

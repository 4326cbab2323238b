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

/** What moving a key gives: the new sorted list, or which other key's time it was dropped on. */
export type MoveResult<K> = { keys: K[]; index: number } | { onto: number };

/**
 * `keys` with the key at `index` moved to `timeS` (sorted again), or, when another key sits at
 * that time (within SAME_TIME_S), which one: a move never silently replaces a key — that would
 * lose a pose on a slip of the mouse (setting a key, by contrast, means "this pose here").
 */
export function moveKey<K extends Timed>(keys: readonly K[], index: number, timeS: number): MoveResult<K> {
  const onto = keys.findIndex((k, i) => i !== index && Math.abs(k.timeS - timeS) < SAME_TIME_S);
  if (onto >= 0) return { onto };
  const moved = { ...keys[index], timeS };
  const out = keys.filter((_, i) => i !== index);
  out.push(moved);
  out.sort((a, b) => a.timeS - b.timeS);
  return { keys: out, index: out.indexOf(moved) };
}

/**
 * `keys` with the key at `index` easing its segment to the next key by `easing` (undefined: the
 * timeline's). The other keys are the same objects.
 */
export function withKeyEasing<K extends Timed & { easing?: unknown }>(keys: readonly K[], index: number, easing: K["easing"] | undefined): K[] {
  return keys.map((k, i) => {
    if (i !== index) return k;
    const { easing: _old, ...rest } = k;
    return (easing === undefined ? rest : { ...rest, easing }) as K;
  });
}

// Selection commands on the region being assigned ("Assign to"), as in Blender and the three.js
// editor: select all / none / invert / grow / shrink. The "selection" is that region's vertices;
// the other regions are left alone (all, invert and grow never take another region's vertices).
// Grow and shrink go by one ring of mesh neighbours (vertices sharing a triangle edge). Without the
// DOM (unit-tested); panels/regions.ts and the keys (panels/shortcuts.ts) carry them out.

export type SelectionCommand = "all" | "none" | "invert" | "grow" | "shrink";

/** Each vertex's neighbours (sharing a triangle edge) in CSR form: neighbours of v are ids[start[v] .. start[v+1]). */
export interface Adjacency {
  start: Uint32Array;
  ids: Uint32Array;
}

export function adjacency(n: number, index: Uint32Array): Adjacency {
  const count = new Uint32Array(n + 1);
  for (let t = 0; t < index.length; t += 3)
    for (let k = 0; k < 3; k++) {
      count[index[t + k]] += 2; // each corner has two edges in its triangle
    }
  const start = new Uint32Array(n + 1);
  for (let v = 0; v < n; v++) start[v + 1] = start[v] + count[v];
  const fill = start.slice(0, n);
  const ids = new Uint32Array(start[n]);
  for (let t = 0; t < index.length; t += 3)
    for (let k = 0; k < 3; k++) {
      const v = index[t + k];
      ids[fill[v]++] = index[t + ((k + 1) % 3)];
      ids[fill[v]++] = index[t + ((k + 2) % 3)];
    }
  return { start, ids };
}

/**
 * The vertices to relabel for `command` on region `label` (≥ 0): `add` get `label`, `remove` get
 * −1 (unlabelled). Labels: −1 none, 0 fixed, h ≥ 1 handle h.
 */
export function selectionChange(command: SelectionCommand, labels: Int16Array, label: number, adj: () => Adjacency): { add: number[]; remove: number[] } {
  const add: number[] = [];
  const remove: number[] = [];
  const n = labels.length;
  switch (command) {
    case "all":
      for (let v = 0; v < n; v++) if (labels[v] === -1) add.push(v);
      break;
    case "none":
      for (let v = 0; v < n; v++) if (labels[v] === label) remove.push(v);
      break;
    case "invert":
      for (let v = 0; v < n; v++) {
        if (labels[v] === label) remove.push(v);
        else if (labels[v] === -1) add.push(v);
      }
      break;
    case "grow": {
      const { start, ids } = adj();
      for (let v = 0; v < n; v++) {
        if (labels[v] !== -1) continue;
        for (let i = start[v]; i < start[v + 1]; i++)
          if (labels[ids[i]] === label) {
            add.push(v);
            break;
          }
      }
      break;
    }
    case "shrink": {
      const { start, ids } = adj();
      for (let v = 0; v < n; v++) {
        if (labels[v] !== label) continue;
        for (let i = start[v]; i < start[v + 1]; i++)
          if (labels[ids[i]] !== label) {
            remove.push(v);
            break;
          }
      }
      break;
    }
  }
  return { add, remove };
}

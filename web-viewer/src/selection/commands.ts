// Selection commands on the region being assigned ("Assign to"), as in Blender and the three.js
// editor: select all / none / invert / grow / shrink. The "selection" is that region's vertices;
// the other regions are left alone (all, invert and grow never take another region's vertices).
// Grow and shrink go by one ring of mesh neighbours (vertices sharing a triangle edge; coincident
// copies along a glTF upload's seams count as one vertex). Without the
// DOM (unit-tested); panels/regions.ts and the keys (panels/shortcuts.ts) carry them out.

export type SelectionCommand = "all" | "none" | "invert" | "grow" | "shrink";

/** Each vertex's neighbours (sharing a triangle edge) in CSR form: neighbours of v are ids[start[v] .. start[v+1]). */
export interface Adjacency {
  start: Uint32Array;
  ids: Uint32Array;
}

/**
 * Vertices at the same rest position as one: a glTF upload's base mesh splits a vertex along UV and
 * normal seams into copies with bitwise-equal positions (the server welds them back), so without
 * this a grow stopped at every seam. Returns each vertex's class representative (the lowest id).
 */
export function coincident(n: number, rest: Float32Array): Uint32Array {
  const bits = new Uint32Array(rest.buffer, rest.byteOffset, 3 * n);
  const order = new Uint32Array(n);
  for (let v = 0; v < n; v++) order[v] = v;
  const cmp = (a: number, b: number) => bits[3 * a] - bits[3 * b] || bits[3 * a + 1] - bits[3 * b + 1] || bits[3 * a + 2] - bits[3 * b + 2] || a - b;
  order.sort(cmp);
  const rep = new Uint32Array(n);
  for (let i = 0; i < n; i++) {
    const v = order[i];
    const u = i > 0 ? order[i - 1] : v;
    const same = i > 0 && bits[3 * u] === bits[3 * v] && bits[3 * u + 1] === bits[3 * v + 1] && bits[3 * u + 2] === bits[3 * v + 2];
    rep[v] = same ? rep[u] : v;
  }
  return rep;
}

/**
 * Edge neighbours of every vertex. With `rest` (x, y, z per vertex), coincident vertices count as
 * one: each copy has the neighbours of all copies (and their copies), and the copies are
 * neighbours of each other, so grow and shrink cross seams as on the welded surface.
 */
export function adjacency(n: number, index: Uint32Array, rest?: Float32Array): Adjacency {
  if (!rest) return edgeAdjacency(n, index);
  const rep = coincident(n, rest);
  // Copies of each class, CSR by representative.
  const count = new Uint32Array(n + 1);
  for (let v = 0; v < n; v++) count[rep[v]]++;
  const cstart = new Uint32Array(n + 1);
  for (let v = 0; v < n; v++) cstart[v + 1] = cstart[v] + count[v];
  const cfill = cstart.slice(0, n);
  const copies = new Uint32Array(n);
  for (let v = 0; v < n; v++) copies[cfill[rep[v]]++] = v;
  // Edge adjacency of the welded mesh (on representatives), then expanded to every copy.
  const welded = edgeAdjacency(n, index.map((v) => rep[v]));
  const sizes = new Uint32Array(n + 1);
  for (let v = 0; v < n; v++) {
    const r = rep[v];
    let k = count[r] - 1; // the other copies of v
    for (let i = welded.start[r]; i < welded.start[r + 1]; i++) k += count[welded.ids[i]];
    sizes[v] = k;
  }
  const start = new Uint32Array(n + 1);
  for (let v = 0; v < n; v++) start[v + 1] = start[v] + sizes[v];
  const ids = new Uint32Array(start[n]);
  for (let v = 0; v < n; v++) {
    const r = rep[v];
    let at = start[v];
    for (let j = cstart[r]; j < cstart[r + 1]; j++) if (copies[j] !== v) ids[at++] = copies[j];
    for (let i = welded.start[r]; i < welded.start[r + 1]; i++) {
      const w = welded.ids[i];
      for (let j = cstart[w]; j < cstart[w + 1]; j++) ids[at++] = copies[j];
    }
  }
  return { start, ids };
}

function edgeAdjacency(n: number, index: Uint32Array): Adjacency {
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

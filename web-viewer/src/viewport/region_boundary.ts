// The outline of a region on the mesh: the edges of its triangles (all three corners in the
// region) that only one such triangle has. Vertices at the same rest position count as one
// (glTF seams split a surface vertex in the base GLB), so a seam through the region draws no line.

/** A canonical id per vertex: the first vertex at the same rest position. */
export function weldByPosition(rest: Float32Array): Uint32Array {
  const n = rest.length / 3;
  const first = new Map<string, number>();
  const out = new Uint32Array(n);
  for (let v = 0; v < n; v++) {
    const key = `${rest[3 * v]},${rest[3 * v + 1]},${rest[3 * v + 2]}`;
    const k = first.get(key);
    if (k === undefined) first.set(key, v);
    out[v] = k ?? v;
  }
  return out;
}

/** The region's boundary edges as vertex pairs [a0, b0, a1, b1, …] (ids of the mesh, not welded). */
export function regionBoundaryEdges(index: Uint32Array, labels: Int16Array, label: number, weld: Uint32Array): number[] {
  const n = labels.length;
  // welded edge → [count, a, b]
  const edges = new Map<number, [number, number, number]>();
  for (let t = 0; t < index.length; t += 3) {
    const a = index[t], b = index[t + 1], c = index[t + 2];
    if (labels[a] !== label || labels[b] !== label || labels[c] !== label) continue;
    for (const [u, v] of [[a, b], [b, c], [c, a]]) {
      const wu = weld[u], wv = weld[v];
      const key = wu < wv ? wu * n + wv : wv * n + wu;
      const e = edges.get(key);
      if (e) e[0]++;
      else edges.set(key, [1, u, v]);
    }
  }
  const out: number[] = [];
  for (const [count, u, v] of edges.values()) if (count === 1) out.push(u, v);
  return out;
}

// Botsch–Sorkine .sel files (data/README.md): "#" header lines, then one label per vertex —
// 0 fixed, 1 free, 2 handle. Parsed into the viewer's region labels.

export interface SelRegions {
  fixed: number[];
  handle: number[];
}

/** Vertex ids labelled fixed (0) and handle (2); throws when the count is not `n`. */
export function parseSel(text: string, n: number): SelRegions {
  const fixed: number[] = [];
  const handle: number[] = [];
  let v = 0;
  for (const line of text.split("\n")) {
    const t = line.trim();
    if (t === "" || t.startsWith("#")) continue;
    if (t === "0") fixed.push(v);
    else if (t === "2") handle.push(v);
    v++;
  }
  if (v !== n) throw new Error(`the benchmark's .sel file has ${v} vertices, the mesh ${n}`);
  return { fixed, handle };
}

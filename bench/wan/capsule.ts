// The procedural capsule of bench/procedural.cpp (capsule, capsule_size, capsule_case) in
// TypeScript, so the WAN bench deforms the same mesh as service_bench: rings of `segments`
// vertices, every other ring rotated half a segment, two poles; base = bottom 5 % of the
// height (fixed), cap = top 5 % (the handle). Written as OFF: file order = engine order =
// base-GLB order, so these ids are valid as Selector.ids and in the frame buffers.

export interface Capsule {
  positions: Float64Array; // 3 per vertex
  triangles: Uint32Array; // 3 per triangle
  base: number[];
  cap: number[];
}

export function capsuleSize(target: number, radius = 1, body = 8): { segments: number; rings: number } {
  // rings ≈ length / (√3/2 · 2πr/s), n ≈ s · rings  ⇒  s² ≈ n · √3/2 · 2πr / length.
  const length = Math.PI * radius + body;
  const k = length / ((Math.sqrt(3) / 2) * 2 * Math.PI * radius); // rings per segment
  const segments = Math.max(3, Math.round(Math.sqrt(target / k)));
  return { segments, rings: Math.max(1, Math.round(k * segments)) };
}

export function capsule(target: number, fraction = 0.05, radius = 1, body = 8): Capsule {
  const { segments, rings } = capsuleSize(target, radius, body);
  const quarter = 0.5 * Math.PI * radius; // one hemisphere's meridian arc
  const length = 2 * quarter + body; // meridian, pole to pole
  const n = rings * segments + 2;
  const V = new Float64Array(3 * n);
  const south = 0;
  const north = n - 1;
  V.set([0, 0, -radius], 3 * south);
  V.set([0, 0, body + radius], 3 * north);
  for (let i = 0; i < rings; ++i) {
    const t = (length * (i + 1)) / (rings + 1); // arc length along the meridian
    let rho: number;
    let z: number;
    if (t < quarter) {
      const phi = t / radius;
      rho = radius * Math.sin(phi);
      z = -radius * Math.cos(phi);
    } else if (t <= quarter + body) {
      rho = radius;
      z = t - quarter;
    } else {
      const phi = (t - quarter - body) / radius;
      rho = radius * Math.cos(phi);
      z = body + radius * Math.sin(phi);
    }
    const offset = 0.5 * (i % 2);
    for (let j = 0; j < segments; ++j) {
      const theta = (2 * Math.PI * (j + offset)) / segments;
      V.set([rho * Math.cos(theta), rho * Math.sin(theta), z], 3 * (1 + i * segments + j));
    }
  }
  const ring = (i: number, j: number) => 1 + i * segments + (j % segments);
  const F: number[] = [];
  // Pole fans, counter-clockwise seen from outside.
  for (let j = 0; j < segments; ++j) F.push(south, ring(0, j + 1), ring(0, j));
  for (let j = 0; j < segments; ++j) F.push(ring(rings - 1, j), ring(rings - 1, j + 1), north);
  for (let i = 0; i + 1 < rings; ++i)
    for (let j = 0; j < segments; ++j) {
      if (i % 2 === 0) {
        F.push(ring(i, j), ring(i, j + 1), ring(i + 1, j));
        F.push(ring(i + 1, j), ring(i, j + 1), ring(i + 1, j + 1));
      } else {
        F.push(ring(i, j), ring(i + 1, j + 1), ring(i + 1, j));
        F.push(ring(i, j), ring(i, j + 1), ring(i + 1, j + 1));
      }
    }
  let lo = Infinity;
  let hi = -Infinity;
  for (let v = 0; v < n; ++v) {
    lo = Math.min(lo, V[3 * v + 2]);
    hi = Math.max(hi, V[3 * v + 2]);
  }
  const band = fraction * (hi - lo);
  const base: number[] = [];
  const cap: number[] = [];
  for (let v = 0; v < n; ++v) {
    const z = V[3 * v + 2];
    if (z <= lo + band) base.push(v);
    else if (z >= hi - band) cap.push(v);
  }
  return { positions: V, triangles: Uint32Array.from(F), base, cap };
}

/** OFF text; coordinates in shortest round-trip form so the server reads exactly these. */
export function toOff(c: Capsule): string {
  const n = c.positions.length / 3;
  const m = c.triangles.length / 3;
  const lines: string[] = ["OFF", `${n} ${m} 0`];
  for (let v = 0; v < n; ++v) lines.push(`${c.positions[3 * v]} ${c.positions[3 * v + 1]} ${c.positions[3 * v + 2]}`);
  for (let f = 0; f < m; ++f) lines.push(`3 ${c.triangles[3 * f]} ${c.triangles[3 * f + 1]} ${c.triangles[3 * f + 2]}`);
  return lines.join("\n") + "\n";
}

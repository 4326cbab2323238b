// Numerical noise is not data: an undeformed pose solves to E ≈ 1e-27 and a sweep of it to
// curves of 1e-16, which a plain display shows as values (and a chart auto-scales into a
// curve). Values below a floor relative to the mesh's scale read 0:
//
//   floor = NOISE_RELATIVE × the quantity's scale, NOISE_RELATIVE = 1e-12:
//   - dimensionless quantities (per-triangle energies ‖r_l‖²_F, E_iso,n, E_conf,n, max E_iso,
//     max E_conf, max ‖e‖²_F: ratios of lengths, of order 1 when something moved): 1;
//   - E = Σ a_l ‖r_l‖²_F (model units²): the bounding-box diagonal squared;
//   - E_area % (a percentage): 100;
//   - counts (flips): none, they are exact.
//
// 1e-12 is far above double-precision noise (≈ 1e-16 relative, its square ≈ 1e-30) and far
// below anything visible: a deformation-gradient difference of 1e-6 (a millionth of the
// model's size) gives ‖r‖² ≈ 1e-12. The scale is the mesh's, not the largest value shown:
// when every value is noise, the largest one is noise too.
export const NOISE_RELATIVE = 1e-12;

export type Quantity = "ratio" | "area" | "percent" | "count";

/** Which kind each Measures field is. */
export const MEASURE_QUANTITY: Record<string, Quantity> = {
  e: "area",
  eIsoN: "ratio",
  eConfN: "ratio",
  eAreaPct: "percent",
  maxEIso: "ratio",
  maxEConf: "ratio",
  maxEf2: "ratio",
  flips: "count",
};

/** The noise floor of a quantity on a mesh of bounding-box diagonal `diag`. */
export function noiseFloor(quantity: Quantity, diag: number): number {
  switch (quantity) {
    case "ratio":
      return NOISE_RELATIVE;
    case "area":
      return NOISE_RELATIVE * (diag > 0 && Number.isFinite(diag) ? diag * diag : 1);
    case "percent":
      return NOISE_RELATIVE * 100;
    case "count":
      return 0;
  }
}

/** `v`, or 0 when it is below the floor (|v| < floor). */
export function denoise(v: number, floor: number): number {
  return Math.abs(v) < floor ? 0 : v;
}

/**
 * The y range a chart of `values` spans: never less than the noise floor (relative to the
 * mesh's scale, or to the values themselves when they are larger), so a flat curve with noise
 * on it draws flat. An all-zero (or all-noise) curve gets [0, 1] and lies on the x axis.
 */
export function chartRange(values: number[], floor: number): [number, number] {
  const ys = values.filter(Number.isFinite).map((v) => denoise(v, floor));
  if (ys.length === 0) return [0, 1];
  let lo = Math.min(...ys);
  let hi = Math.max(...ys);
  const big = Math.max(Math.abs(lo), Math.abs(hi));
  if (hi - lo > NOISE_RELATIVE * big && hi - lo > floor) return [lo, hi];
  // Flat: a band around the value (or [0, 1] at 0), so its noise does not show.
  const mid = (lo + hi) / 2;
  if (Math.abs(mid) < floor || mid === 0) return [0, 1];
  lo = mid - Math.abs(mid) * 0.1;
  hi = mid + Math.abs(mid) * 0.1;
  return [lo, hi];
}

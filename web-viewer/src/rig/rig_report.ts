// The rig export's report (ExportRig's first chunk, RigReport): how far linear blend skinning of
// the handle joints is from the exact solve, per exported pose — the current one first, then each
// timeline key — as max and RMS over vertices in units of the bounding-box diagonal. Shown as a
// percentage of the diagonal, 3 significant digits (rig_export.ts).

export interface RigPoseRow {
  current: boolean;
  timeS: number;
  max: number; // fraction of the diagonal
  rms: number;
}

/** A fraction of the diagonal as a percentage: 3 significant digits ("11.5", "0.0123", "1.00e-12"). */
export function percentOfDiagonal(fraction: number): string {
  if (!Number.isFinite(fraction)) return "–";
  if (fraction === 0) return "0";
  const p = fraction * 100;
  return Math.abs(p) >= 1e-3 && Math.abs(p) < 1e5 ? String(Number(p.toPrecision(3))) : p.toExponential(2);
}

/** The pose's name as the report shows it: "current", or the key's time ("1.000 s"). */
export function poseName(row: Pick<RigPoseRow, "current" | "timeS">): string {
  return row.current ? "current" : `${row.timeS.toFixed(3)} s`;
}

/** The report's rows as shown: [pose, max %, rms %]. */
export function reportCells(rows: readonly RigPoseRow[]): [string, string, string][] {
  return rows.map((r) => [poseName(r), percentOfDiagonal(r.max), percentOfDiagonal(r.rms)]);
}

/** One line: "rig vs exact (% of diagonal): current max 11.5 rms 6.9 · 1.000 s max … (worst: …)". */
export function reportSummary(rows: readonly RigPoseRow[]): string {
  if (rows.length === 0) return "no poses";
  const parts = reportCells(rows).map(([pose, max, rms]) => `${pose} max ${max} rms ${rms}`);
  return `rig vs exact, % of the diagonal: ${parts.join(" · ")}`;
}

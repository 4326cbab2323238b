// The opt-in repair of an upload (POST /upload?repair=TOL, docs/api.md "Repair"): which
// refusals it can fix, and the notice of what it changed. Pure (node tests).

/**
 * The server refused an upload for a defect the repair fixes: zero-area triangles, duplicate
 * triangles or a bowtie vertex ("non-manifold vertex"). Non-manifold edges and inconsistent
 * orientation are not repaired. As the CLI's `--repair may fix it`.
 */
export function repairFixes(httpStatus: number, grpcStatus: number | null, reason: string): boolean {
  if (httpStatus !== 400 || (grpcStatus !== null && grpcStatus !== 3)) return false; // 3: INVALID_ARGUMENT
  return ["zero-area triangles", "duplicate triangles", "non-manifold vertex"].some((p) => reason.startsWith(p));
}

/** "Repaired: LINE; LINE" for MeshRepairReport.lines, "" when nothing changed. */
export function repairNotice(lines: readonly string[]): string {
  return lines.length ? `Repaired: ${lines.join("; ")}` : "";
}

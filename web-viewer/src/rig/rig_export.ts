// "Export rig" (issue 39) in the timeline strip: ExportRig (edit token) with the strip's choice of
// 4 or 8 influences per vertex and the top bar's up axis — the server writes the z-up node itself
// (ExportRigRequest.up), so the GLB is saved as it comes — and the timeline's keys as a skeletal
// animation when the session has keys (the server adds it; skip_animation stays false). The file is
// SESSIONID-rig.glb; the first chunk's RigReport (how far linear blend skinning is from the exact
// solve at the current pose and at each key) shows in a small panel over the canvas and in the
// strip's note. A refusal (a sheared stretch: FAILED_PRECONDITION; too big: RESOURCE_EXHAUSTED)
// shows the server's message. Watch pages have no button (the call needs the edit token).
import type { DeformationClient } from "../api";
import { describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import { UpAxis, type RigReport } from "../gen/hdeform/v1/deform_pb";
import type { ExportUp } from "../panels/export_up";
import { saveBytes } from "../panels/files";
import { reportCells, reportSummary, type RigPoseRow } from "./rig_report";

export interface RigDownload {
  bytes: Uint8Array;
  report: RigReport | null;
}

/** ExportRig's GLB (its chunks joined) and the report its first chunk carries. */
export async function fetchRig(
  client: DeformationClient,
  name: string,
  influences: number,
  up: "y" | "z",
  progress?: (bytes: number) => void,
): Promise<RigDownload> {
  const parts: Uint8Array[] = [];
  let total = 0;
  let report: RigReport | null = null;
  for await (const chunk of client.exportRig({ name, influences, up: up === "z" ? UpAxis.Z : UpAxis.Y })) {
    if (chunk.rigReport && !report) report = chunk.rigReport;
    parts.push(chunk.data);
    total += chunk.data.byteLength;
    progress?.(total);
  }
  const bytes = new Uint8Array(total);
  let at = 0;
  for (const p of parts) {
    bytes.set(p, at);
    at += p.byteLength;
  }
  return { bytes, report };
}

export interface RigExport {
  /** The report last shown (null: none yet, or refused). */
  readonly report: RigPoseRow[] | null;
  readonly bytes: number;
}

export function setupRigExport({ state, client }: App, exportUp: ExportUp, say: (message: string, error?: boolean) => void): RigExport {
  const button = $<HTMLButtonElement>("tl-rig");
  const influences = $<HTMLSelectElement>("tl-rig-influences");
  const panel = $("rig-report");
  const table = $("rig-report-rows");
  let shown: RigPoseRow[] | null = null;
  let bytes = 0;
  let busy = false;

  const render = () => {
    button.disabled = busy || state.watchOnly || !state.sessionName || !state.constraintsApplied || state.labelsDirty;
  };
  const hide = () => {
    panel.classList.add("hidden");
    shown = null;
  };
  $("rig-report-close").addEventListener("click", hide);

  const show = (rows: RigPoseRow[], report: RigReport) => {
    shown = rows;
    $("rig-report-title").textContent = `Rig: ${report.joints} joints, ${report.influences} influences — LBS vs exact (% of the diagonal)`;
    table.innerHTML = "";
    for (const [pose, max, rms] of reportCells(rows)) {
      const tr = document.createElement("tr");
      for (const text of [pose, max, rms]) {
        const td = document.createElement("td");
        td.textContent = text;
        tr.appendChild(td);
      }
      table.appendChild(tr);
    }
    panel.classList.remove("hidden");
  };

  button.addEventListener("click", async () => {
    const name = state.sessionName;
    if (!name || busy) return;
    busy = true;
    render();
    say("Export rig: solving each pose…");
    try {
      const n = Number(influences.value) === 8 ? 8 : 4;
      const rig = await fetchRig(client, name, n, exportUp.value, (b) => say(`Export rig: ${(b / 1024).toFixed(0)} KiB…`));
      if (name !== state.sessionName) return;
      bytes = rig.bytes.byteLength;
      const id = name.replace(/^sessions\//, "");
      saveBytes(rig.bytes, `${id}-rig.glb`, "model/gltf-binary");
      const rows: RigPoseRow[] = (rig.report?.poses ?? []).map((p) => ({ current: p.current, timeS: p.timeS, max: p.max, rms: p.rms }));
      if (rig.report) show(rows, rig.report);
      say(`Exported ${id}-rig.glb (${(bytes / 1024).toFixed(0)} KiB); ${reportSummary(rows)}`);
    } catch (err) {
      // A sheared stretch (FAILED_PRECONDITION), too big (RESOURCE_EXHAUSTED), …: the server says which.
      hide();
      say(`Export rig failed: ${describeError(err)}`, true);
    } finally {
      busy = false;
      render();
    }
  });
  for (const ev of ["session", "labels", "access"] as const) state.on(ev, render);
  state.on("mesh", hide);
  render();
  return {
    get report() {
      return shown;
    },
    get bytes() {
      return bytes;
    },
  };
}

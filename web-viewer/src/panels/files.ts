// Downloads (GLB / OBJ of the deformed mesh, snapshots as JSON or binary) and Import….
import { fromBinary, fromJsonString, toBinary, toJsonString } from "@bufbuild/protobuf";
import { describeError, fetchMesh, newSessionId, setRoutingSession } from "../api";
import { repairNotice } from "../mesh_repair";
import type { App } from "../app";
import { $ } from "../dom";
import { MeshFormat, SnapshotSchema, type Session, type Snapshot } from "../gen/hdeform/v1/deform_pb";
import { withUpAxis } from "../glb_up_axis";
import type { ExportUp } from "./export_up";

/** A normal browser download of `bytes` as `filename`. */
export function saveBytes(bytes: Uint8Array | string, filename: string, type: string): void {
  const blob = new Blob([bytes as BlobPart], { type });
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob);
  a.download = filename;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10_000);
}

export function setupFilesPanel({ state, client, banner, edits }: App, load: (s: Session) => Promise<void>, exportUp: ExportUp): void {
  const baseName = () => (state.session?.meshName || "mesh").replace(/\.[^.]+$/, "").replace(/[^\w.-]+/g, "_");
  const download = async (format: MeshFormat, ext: string, type: string) => {
    try {
      const bytes = await fetchMesh(client, state.sessionName, false, format);
      // A GLB stands up in glTF's y-up when the model is z-up (the export's up axis).
      saveBytes(format === MeshFormat.GLB ? withUpAxis(bytes, exportUp.value) : bytes, `${baseName()}-deformed.${ext}`, type);
    } catch (err) {
      banner.show(`Download failed: ${describeError(err)}`);
    }
  };
  const exportSnapshot = async (json: boolean) => {
    try {
      const snap = await client.exportSession({ name: state.sessionName, includeMesh: true });
      if (json) saveBytes(toJsonString(SnapshotSchema, snap, { prettySpaces: 2 }), `${baseName()}-session.json`, "application/json");
      else saveBytes(toBinary(SnapshotSchema, snap), `${baseName()}-session.pb`, "application/x-protobuf");
    } catch (err) {
      banner.show(`Export failed: ${describeError(err)}`);
    }
  };
  $("dl-glb").addEventListener("click", () => void download(MeshFormat.GLB, "glb", "model/gltf-binary"));
  $("dl-obj").addEventListener("click", () => void download(MeshFormat.OBJ, "obj", "text/plain"));
  $("dl-json").addEventListener("click", () => void exportSnapshot(true));
  $("dl-bin").addEventListener("click", () => void exportSnapshot(false));
  $<HTMLInputElement>("import-input").addEventListener("change", async (e) => {
    const input = e.target as HTMLInputElement;
    const file = input.files?.[0];
    input.value = "";
    if (!file) return;
    let snapshot: Snapshot;
    try {
      const bytes = new Uint8Array(await file.arrayBuffer());
      snapshot = file.name.endsWith(".json") ? fromJsonString(SnapshotSchema, new TextDecoder().decode(bytes)) : fromBinary(SnapshotSchema, bytes);
    } catch (err) {
      return banner.show(`Import failed: ${describeError(err)}`);
    }
    // A client-chosen id, sent as the routing header too: behind a load balancer the import
    // then lands on the replica that every later call of the new session reaches.
    const id = newSessionId();
    setRoutingSession(id);
    let s: Session;
    try {
      s = await edits.execute({ method: "importSession", what: "Import", request: () => ({ snapshot, sessionId: id }) });
    } catch {
      if (state.sessionName) setRoutingSession(state.sessionName); // still showing the previous session
      return; // the layer said why
    }
    try {
      await load(s);
      banner.clear();
      if (s.repair?.lines.length) banner.notice(repairNotice(s.repair.lines), "repaired"); // a repaired upload's snapshot
    } catch (err) {
      banner.show(`Import failed: ${describeError(err)}`);
    }
  });
}

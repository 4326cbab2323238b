// Opening meshes: the bundled library (ListMeshes, Open) and Upload… with its progress bar. An
// upload refused for a defect the server's repair fixes offers "Repair and open" (the same file).
import { createSessionViaUpload, describeError, UploadRejected } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import type { SessionLoader } from "../session_loader";
import { bundledRegions, hasBundledRegions } from "../benchmark_regions";
import { repairFixes, repairNotice } from "../mesh_repair";

export function setupLibraryPanel({ state, client, banner }: App, loader: SessionLoader, applyConstraints: () => Promise<void>): void {
  // An old "x.obj: failed" goes when another mesh opens.
  state.on("mesh", () => ($("upload-label").textContent = ""));
  const select = $<HTMLSelectElement>("library");
  const list = async () => {
    try {
      const res = await client.listMeshes({});
      select.innerHTML = res.meshes
        .map((m) => `<option value="${m.name}" data-benchmark="${m.hasBenchmark && hasBundledRegions(m.name) ? 1 : 0}">${m.name}${m.hasBenchmark ? " ★" : ""}</option>`)
        .join("");
      if (res.meshes.some((m) => m.name === "cactus")) select.value = "cactus";
      showBenchmark();
    } catch (err) {
      banner.show(`Cannot reach the server: ${describeError(err)}`, "lost");
    }
  };
  /** `repair`: the merge tolerance of a repair first (0: equal positions only). */
  const upload = async (file: File, repair?: number) => {
    const progress = $<HTMLProgressElement>("upload-progress");
    const label = $("upload-label");
    progress.classList.remove("hidden");
    progress.value = 0;
    label.textContent = file.name;
    label.title = file.name;
    try {
      const s = await createSessionViaUpload({ filename: file.name, body: file, repair }, (loaded, total) => {
        progress.value = total > 0 ? loaded / total : 0;
        label.textContent = `${file.name}: ${Math.round((100 * loaded) / (total || file.size || 1))}%`;
      });
      label.textContent = `${file.name}: processing…`;
      await loader.load(s);
      label.textContent = ""; // the session label names the mesh now
      banner.clear();
      if (s.repair?.lines.length) banner.notice(repairNotice(s.repair.lines), "repaired");
    } catch (err) {
      label.textContent = `${file.name}: failed`;
      const fixable = repair === undefined && err instanceof UploadRejected && repairFixes(err.httpStatus, err.grpcStatus, err.reason);
      banner.show(describeError(err), "error", fixable ? { label: "Repair and open", run: () => void upload(file, 0) } : undefined);
    } finally {
      progress.classList.add("hidden");
    }
  };
  $("open-library").addEventListener("click", () => void loader.openLibrary(select.value));
  // ★ models: open with the benchmark's fixed and handle regions applied, in one click.
  const benchmark = $<HTMLButtonElement>("open-benchmark");
  const showBenchmark = () => (benchmark.disabled = select.selectedOptions[0]?.dataset.benchmark !== "1");
  select.addEventListener("change", showBenchmark);
  benchmark.addEventListener("click", async () => {
    const name = select.value;
    await loader.openLibrary(name);
    const mesh = state.mesh;
    if (!mesh || state.session?.meshName.replace(/\.[^.]+$/, "") !== name) return;
    try {
      const r = await bundledRegions(name, mesh.n);
      state.assign(r.fixed, 0);
      state.assign(r.handle, 1);
      await applyConstraints();
      if (state.constraintsApplied && !state.labelsDirty) state.setMode("move"); // next: drag the handle
    } catch (err) {
      banner.show(`Benchmark regions of ${name}: ${describeError(err)}`);
    }
  });
  $<HTMLInputElement>("upload-input").addEventListener("change", (e) => {
    const input = e.target as HTMLInputElement;
    const file = input.files?.[0];
    input.value = "";
    if (file) void upload(file);
  });
  void list();
}

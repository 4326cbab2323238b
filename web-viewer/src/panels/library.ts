// Opening meshes: the bundled library (ListMeshes, Open) and Upload… with its progress bar.
import { createSessionViaUpload, describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import type { SessionLoader } from "../session_loader";

export function setupLibraryPanel({ state, client, banner }: App, loader: SessionLoader): void {
  // An old "x.obj: failed" goes when another mesh opens.
  state.on("mesh", () => ($("upload-label").textContent = ""));
  const select = $<HTMLSelectElement>("library");
  const list = async () => {
    try {
      const res = await client.listMeshes({});
      select.innerHTML = res.meshes.map((m) => `<option value="${m.name}">${m.name}${m.hasBenchmark ? " ★" : ""}</option>`).join("");
      if (res.meshes.some((m) => m.name === "cactus")) select.value = "cactus";
    } catch (err) {
      banner.show(`Cannot reach the server: ${describeError(err)}`, "lost");
    }
  };
  const upload = async (file: File) => {
    const progress = $<HTMLProgressElement>("upload-progress");
    const label = $("upload-label");
    progress.classList.remove("hidden");
    progress.value = 0;
    label.textContent = file.name;
    label.title = file.name;
    try {
      const s = await createSessionViaUpload({ filename: file.name, body: file }, (loaded, total) => {
        progress.value = total > 0 ? loaded / total : 0;
        label.textContent = `${file.name}: ${Math.round((100 * loaded) / (total || file.size || 1))}%`;
      });
      label.textContent = `${file.name}: processing…`;
      await loader.load(s);
      label.textContent = ""; // the session label names the mesh now
      banner.clear();
    } catch (err) {
      label.textContent = `${file.name}: failed`;
      banner.show(describeError(err));
    } finally {
      progress.classList.add("hidden");
    }
  };
  $("open-library").addEventListener("click", () => void loader.openLibrary(select.value));
  $<HTMLInputElement>("upload-input").addEventListener("change", (e) => {
    const input = e.target as HTMLInputElement;
    const file = input.files?.[0];
    input.value = "";
    if (file) void upload(file);
  });
  void list();
}

// The top bar's session part: its name, Share / Watch link buttons, the download buttons'
// state, and the status line's summary (size, version, watchers).
import type { App } from "../app";
import { $ } from "../dom";
import { shareLink } from "../links";

export function setupSessionBar({ state, status }: App): void {
  const copyLink = async (watch: boolean) => {
    const link = shareLink(state.sessionName, watch);
    if (!link) return;
    try {
      await navigator.clipboard.writeText(link);
      status.set(`copied ${link}`);
    } catch {
      window.prompt("Copy this link", link);
    }
  };
  $("copy-share").addEventListener("click", () => void copyLink(false));
  $("copy-watch").addEventListener("click", () => void copyLink(true));
  state.on("session", () => {
    const name = state.sessionName;
    for (const id of ["dl-glb", "dl-obj", "dl-json", "dl-bin"]) $<HTMLButtonElement>(id).disabled = !name;
    $<HTMLButtonElement>("copy-share").disabled = shareLink(name, false) === "";
    $<HTMLButtonElement>("copy-watch").disabled = shareLink(name, true) === "";
    $("session-label").textContent = name ? `${state.session?.meshName ?? ""} · ${name}` : "no session";
    const { mesh, session } = state;
    if (mesh && session) {
      status.set(`${mesh.n} vertices · ${mesh.m} triangles · version ${state.version} · ${session.observers} watching`);
    }
  });
  if (state.watchOnly) {
    document.body.classList.add("watch");
    $("watch-badge").classList.remove("hidden");
  }
}

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
      // Never the link itself: the status line is on screen (shared screens, screenshots).
      status.set(watch ? "Watch link copied (read-only)" : "Share link copied: it lets whoever opens it edit");
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
  const showAccess = () => {
    document.body.classList.toggle("watch", state.watchOnly);
    $("watch-badge").classList.toggle("hidden", !state.watchOnly);
  };
  state.on("access", showAccess);
  showAccess();
}

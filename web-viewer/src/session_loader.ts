// Opening a session: from a link, the library, an upload or an import. Fetches the base GLB
// (and the current shape of a deformed session), adopts the session, and starts watching.
import * as THREE from "three";
import { createSessionViaUpload, describeError, fetchMesh, setRoutingSession, setTokens, tokens } from "./api";
import { accessError } from "./access_error";
import type { App } from "./app";
import { $ } from "./dom";
import { BetaUnits, MeshFormat, type Session } from "./gen/hdeform/v1/deform_pb";
import { showEditorLink, showWatchLink } from "./links";
import { tokenRole } from "./token_role";
import type { Sync } from "./sync/sync";
import { isIdentity } from "./transforms";
import { parseGlb } from "./viewport/glb";

export class SessionLoader {
  constructor(private readonly app: App, private readonly sync: Sync) {}

  async load(s: Session): Promise<void> {
    const { state, client, banner, status } = this.app;
    const sync = this.sync;
    sync.open(s.name);
    state.loaded = false;
    state.measures = null;
    state.sessionName = s.name;
    state.frameVersion = 0n;
    setRoutingSession(s.name);
    // Tokens come with CreateSession / ImportSession answers; a session opened from a link
    // keeps the link's (GetSession never returns them).
    if (s.editToken || s.viewToken) setTokens(s.editToken, s.viewToken);
    state.labelsDirty = false;
    banner.clear("no-mesh");
    status.set(`loading ${s.meshName || s.name}…`);
    const base = await parseGlb(await fetchMesh(client, s.name, true, MeshFormat.GLB));
    const diag = new THREE.Box3().setFromArray(base.positions).getSize(new THREE.Vector3()).length() || 1;
    state.setMesh(base.positions, base.normals, base.index, diag);
    $("placeholder").classList.add("hidden");
    const mesh = state.mesh!;
    if (s.vertexCount && s.vertexCount !== mesh.n) {
      banner.show(`The base GLB has ${mesh.n} vertices but the session reports ${s.vertexCount}`);
    }
    state.handles = [];
    sync.confirm(s.transforms);
    state.adoptSession(s, { transforms: !sync.dragging });
    // A shared session may already be deformed: fetch the current shape once.
    if (s.transforms.some((t) => !isIdentity(t))) {
      const current = await parseGlb(await fetchMesh(client, s.name, false, MeshFormat.GLB));
      if (current.positions.length === mesh.cur.length) state.setShape(current.positions, current.normals);
    }
    state.emit("opened", undefined); // the camera frames the current shape, not only the rest one
    if (!state.watchOnly) showEditorLink(s.name);
    state.setMode(state.watchOnly ? "orbit" : state.constraintsApplied ? "move" : "box");
    // An editor solves the current pose at once (measures, energies); a watch-only page shows
    // measures from the next frame (a measuring Sweep needs the edit token).
    if (state.constraintsApplied && !state.watchOnly) this.app.edits.requestFrame();
    else if (state.constraintsApplied && tokens().edit) void this.currentMeasures(s);
    sync.watch();
    state.loaded = true;
  }

  /** After a reconnect: the session's current shape (frames may have been missed). */
  async refreshShape(name: string, s: Session, signal: AbortSignal): Promise<void> {
    const { state, client } = this.app;
    const busy = () => this.sync.busy;
    const mesh = state.mesh;
    if (!mesh || busy()) return; // our own edit brings a newer frame
    const deformed = s.transforms.some((t) => !isIdentity(t));
    const current = deformed
      ? await parseGlb(await fetchMesh(client, name, false, MeshFormat.GLB, signal))
      : { positions: mesh.rest, normals: null };
    if (state.mesh !== mesh || current.positions.length !== mesh.cur.length || busy()) return;
    state.setShape(current.positions, current.normals);
  }

  /** Measures of the session as it stands, without changing it: a one-β Sweep. */
  private async currentMeasures(s: Session): Promise<void> {
    const { state, client } = this.app;
    try {
      const res = await client.sweep({ name: s.name, betas: [s.beta?.value ?? 0], units: s.beta?.units ?? BetaUnits.AREA });
      const m = res.rows[0]?.measures;
      if (m && !state.measures) state.setMeasures(m, 0);
    } catch {
      /* measures arrive with the next frame */
    }
  }

  async openByName(name: string, edit: string, view: string): Promise<void> {
    try {
      setRoutingSession(name);
      setTokens(edit, view);
      const { client, state, banner } = this.app;
      // A view token pasted as `#edit=` opens the session (it reads) but every edit would be
      // refused: ask what the token may do (in parallel with GetSession) and watch if it reads only.
      const role = edit && !state.watchOnly ? tokenRole(this.app.edits, name) : Promise.resolve("unknown");
      const s = await client.getSession({ name });
      if ((await role) === "view") {
        setTokens("", edit); // it opened the session, so it is the view token
        state.becomeWatcher();
        showWatchLink(name);
        banner.notice(
          "This link carries the session's view token, not its edit token: opened watch-only. Ask for its Share link to edit.",
          "access",
        );
      }
      await this.load(s);
    } catch (err) {
      this.app.banner.show(`Could not open ${name}: ${accessError(err, name)}`, "open");
      const placeholder = $("placeholder");
      placeholder.textContent = `Could not open ${name}.`;
      const a = document.createElement("a");
      a.href = window.location.pathname;
      a.textContent = "Start a new session";
      a.style.pointerEvents = "auto";
      a.style.marginLeft = "0.5em";
      placeholder.append(a);
    }
  }

  async openLibrary(name: string): Promise<void> {
    const { banner, status } = this.app;
    try {
      status.set(`opening ${name}…`);
      const s = await createSessionViaUpload({ library: name });
      await this.load(s);
      banner.clear();
    } catch (err) {
      banner.show(`Could not open ${name}: ${describeError(err)}`);
    }
  }
}

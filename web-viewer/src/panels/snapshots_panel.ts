// Named snapshots of the session (its constraints, β and transforms, kept by the server with
// the session): a name and Save, then the list — name, author, when — with Restore and Delete.
// The list is read again after each action (and when a session opens). A restore is a step like
// an undo: its answer is adopted at once, its state and frame come on the watch stream.
import { describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import type { NamedSnapshot } from "../gen/hdeform/v1/deform_pb";
import { relativeTime } from "../history/relative_time";
import type { UndoRedo } from "../history/undo_redo";
import type { Sync } from "../sync/sync";
import { StepKind } from "../gen/hdeform/v1/deform_pb";
import { openMeshFirst } from "./banner";

function escape(s: string): string {
  return s.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

export interface SnapshotsPanel {
  /** The names listed (the last ListSnapshots). */
  names(): string[];
}

export function setupSnapshotsPanel(app: App, sync: Sync, undo: UndoRedo, clientId: () => string): SnapshotsPanel {
  const { state, client, banner, edits } = app;
  const nameField = $<HTMLInputElement>("snapshot-name");
  const save = $<HTMLButtonElement>("snapshot-save");
  const ul = $("snapshot-list");
  let listed: NamedSnapshot[] = [];
  let shownFor = "";
  // The snapshot whose Delete was pressed once: it asks before deleting (a second, explicit
  // click), since a click too many should not lose a named pose.
  let confirming: string | null = null;

  const render = () => {
    const now = Date.now();
    ul.innerHTML = listed
      .map((s) => {
        const actions =
          s.name === confirming
            ? `<span class="confirm">Delete it? <button data-act="confirm-delete" class="danger" title="Delete this snapshot (Ctrl+Z undoes it)">Delete</button><button data-act="cancel">Cancel</button></span>`
            : `<button data-act="restore">Restore</button><button data-act="delete" title="Delete this snapshot (asks first)">Delete</button>`;
        return (
          `<li data-name="${escape(s.name)}"><span class="what">${escape(s.name)}</span> ` +
          `<span class="muted">${escape(s.author || "anonymous")}, ${relativeTime(Number(s.timeUnixMs), now)}</span>` +
          `<span class="actions">${actions}</span></li>`
        );
      })
      .join("");
  };

  const refresh = async () => {
    const name = state.sessionName;
    if (!name || state.watchOnly) return;
    try {
      const res = await client.listSnapshots({ name });
      if (name !== state.sessionName) return;
      listed = res.snapshots;
      render();
    } catch (err) {
      banner.show(`Snapshots: ${describeError(err)}`, "rejected");
    }
  };

  // The command layer shows a refusal ("Snapshot save rejected: …"); the list is read again
  // either way.
  const act = async (call: () => Promise<unknown>) => {
    try {
      await call();
    } catch {
      /* shown by the layer */
    }
    await refresh();
  };

  const doSave = () => {
    if (!state.sessionName) return openMeshFirst(banner);
    const snapshot = nameField.value.trim();
    if (!snapshot) {
      nameField.focus();
      return;
    }
    const name = state.sessionName;
    void act(() => edits.execute({ method: "saveSnapshot", what: "Snapshot save", request: () => ({ name, snapshot, clientId: clientId() }) }));
  };
  save.addEventListener("click", doSave);
  nameField.addEventListener("keydown", (ev) => {
    if (ev.key === "Enter") doSave();
  });

  ul.addEventListener("click", (ev) => {
    const button = (ev.target as HTMLElement).closest<HTMLButtonElement>("button[data-act]");
    const snapshot = button?.closest<HTMLElement>("li[data-name]")?.dataset.name;
    if (!button || snapshot === undefined) return;
    const name = state.sessionName;
    const which = button.dataset.act;
    if (which === "delete" || which === "cancel") {
      confirming = which === "delete" ? snapshot : null;
      render();
      return;
    }
    confirming = null;
    if (which === "restore") {
      void act(async () =>
        undo.adopt(
          await edits.execute({
            method: "restoreSnapshot",
            what: "Snapshot restore",
            dropsKeys: true,
            request: () => ({ name, snapshot, clientId: clientId(), expectedConfigVersion: state.session?.configVersion ?? 0n }),
          }),
        ),
      );
    } else {
      void act(() => edits.execute({ method: "deleteSnapshot", what: "Snapshot delete", request: () => ({ name, snapshot, clientId: clientId() }) }));
    }
  });

  // Saves and deletes are steps (anyone's, and their undos): the list follows them live.
  sync.on("step", (step) => {
    if (step.snapshot !== "" && step.kind !== StepKind.RESTORE) void refresh();
  });

  state.on("session", () => {
    if (state.sessionName === shownFor) return;
    shownFor = state.sessionName;
    listed = [];
    render();
    void refresh();
  });
  return { names: () => listed.map((s) => s.name) };
}

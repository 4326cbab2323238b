// The History panel: the session's steps newest first (ListHistory, then live from
// SessionEvent.step), each with its author, when, and the server's summary; undone steps
// greyed. Clicking a step undoes that step (UndoRequest.step; an undone one is redone); a
// refusal shows the server's message. "Load older" pages on with next_page_token.
import { describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import { StepKind } from "../gen/hdeform/v1/deform_pb";
import { emptyHistoryNote } from "../history/empty_history";
import { HistoryList } from "../history/history_list";
import { relativeTime } from "../history/relative_time";
import type { UndoRedo } from "../history/undo_redo";
import { colorFor } from "../multi/identity";
import type { Sync } from "../sync/sync";

const PAGE_SIZE = 30;

function escape(s: string): string {
  return s.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

export interface HistoryPanel {
  readonly list: HistoryList;
}

export function setupHistoryPanel(app: App, sync: Sync, undo: UndoRedo): HistoryPanel {
  const { state, client, banner } = app;
  const list = new HistoryList();
  const ul = $("history-list");
  const older = $<HTMLButtonElement>("history-older");
  let shownFor = "";
  let generation = 0; // a page answered for a session no longer open is dropped

  const render = () => {
    const now = Date.now();
    ul.innerHTML = list
      .shown()
      .map(({ step, undone }) => {
        const who = step.author || "anonymous";
        const title = state.watchOnly ? "" : undone ? "click: redo this step" : "click: undo this step";
        return (
          `<li class="step${undone ? " undone" : ""}" data-step="${step.id}" data-kind="${StepKind[step.kind]}" title="${title}">` +
          // The id: summaries name steps by it ("undo step 3 …").
          `<span class="id muted">${step.id}</span> ` +
          `<span class="who" style="color:${escape(colorFor(step.clientId || who))}">${escape(who)}</span> ` +
          `<span class="when muted" data-time="${step.timeUnixMs}">${relativeTime(Number(step.timeUnixMs), now)}</span> ` +
          `<span class="what">${escape(step.summary)}</span></li>`
        );
      })
      .join("");
    // Empty: say why (after a server restart the steps are gone, not undone).
    if (list.size === 0 && list.loaded) ul.innerHTML = `<li class="empty note">${escape(emptyHistoryNote(state.session))}</li>`;
    older.classList.toggle("hidden", !list.hasOlder);
  };

  const loadFirst = async () => {
    const gen = ++generation;
    list.clear();
    render();
    if (!state.sessionName) return;
    try {
      const res = await client.listHistory({ name: state.sessionName, pageSize: PAGE_SIZE });
      if (gen !== generation) return;
      list.addFirstPage(res);
      render();
    } catch (err) {
      if (gen === generation) banner.show(`History: ${describeError(err)}`, "rejected");
    }
  };

  older.addEventListener("click", async () => {
    const gen = generation;
    older.disabled = true;
    try {
      const res = await client.listHistory({ name: state.sessionName, pageSize: PAGE_SIZE, pageToken: list.olderToken });
      if (gen !== generation) return;
      list.addOlderPage(res);
      render();
    } catch (err) {
      banner.show(`History: ${describeError(err)}`, "rejected");
    } finally {
      older.disabled = false;
    }
  });

  ul.addEventListener("click", (ev) => {
    const li = (ev.target as HTMLElement).closest<HTMLElement>("li[data-step]");
    if (!li || state.watchOnly) return;
    void undo.run(li.classList.contains("undone") ? "redo" : "undo", BigInt(li.dataset.step!));
  });

  // Another session: its history. After a reconnect: again (steps may have been missed).
  state.on("session", () => {
    if (state.sessionName === shownFor) return;
    shownFor = state.sessionName;
    void loadFirst();
  });
  sync.on("state", ({ source }) => {
    if (source === "resync") void loadFirst();
  });
  sync.on("step", (step) => {
    list.addLive(step);
    render();
  });
  // "3 min ago" moves on.
  setInterval(() => {
    const now = Date.now();
    for (const el of ul.querySelectorAll<HTMLElement>(".when")) el.textContent = relativeTime(Number(el.dataset.time), now);
  }, 15_000);
  return { list };
}

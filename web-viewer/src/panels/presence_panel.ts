// Who is in the session (live, from presence events): a coloured dot, the name, editor or
// viewer, and the handle each one is moving; and this tab's own name field.
import { $ } from "../dom";
import { handleWord } from "../handle_names";
import type { Editors } from "../multi/editors";
import type { Sync } from "../sync/sync";

function escape(s: string): string {
  return s.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

export function setupPresencePanel(editors: Editors, sync: Sync): void {
  const { identity, presence } = editors;
  const nameInput = $<HTMLInputElement>("display-name");
  nameInput.value = identity.displayName;
  nameInput.style.borderColor = identity.color;
  nameInput.addEventListener("change", () => {
    identity.setDisplayName(nameInput.value);
    nameInput.value = identity.displayName;
    // WatchSession.client is read when the stream starts: watch again under the new name.
    if (sync.sessionName) sync.watch();
  });
  const list = $("presence");
  const render = () => {
    list.innerHTML = presence.people
      .map((p) => {
        const held = p.held.length ? ` · moving ${p.held.map(handleWord).join(", ")}` : "";
        return (
          `<span class="person${p.me ? " me" : ""}" data-client="${escape(p.clientId)}" title="${p.editor ? "editor" : "viewer"}">` +
          `<span class="dot" style="background:${escape(p.color)}"></span>${escape(p.name)}${p.me ? " (you)" : ""}` +
          `<span class="muted small"> ${p.editor ? "editor" : "viewer"}${held}</span></span>`
        );
      })
      .join("");
    $("presence-section").classList.toggle("hidden", presence.people.length === 0);
  };
  editors.onPresence(render);
  render();
}

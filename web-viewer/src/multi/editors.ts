// Several editors in one session: this tab's identity, who else is there (presence), taking a
// handle before dragging it, and other editors' frames moving their handles' gizmos here.
import { create } from "@bufbuild/protobuf";
import { Code } from "@connectrpc/connect";
import type { App } from "../app";
import { HandleTransformSchema, type Presence } from "../gen/hdeform/v1/deform_pb";
import type { Sync } from "../sync/sync";
import { fromProtoTransform } from "../transforms";
import { HandleLease } from "./handle_lease";
import { Identity } from "./identity";
import { heldMessage, holderFromMessage, PresenceModel } from "./presence_model";
import { handleWord } from "../handle_names";

export interface Editors {
  identity: Identity;
  presence: PresenceModel;
  lease: HandleLease;
  /** The server supports several editors (a presence event or a granted grab came). */
  readonly multi: boolean;
  /** GrabHandles for a drag of handle h (0-based); false (and a message) when refused. */
  grab(h: number): Promise<boolean>;
  release(): void;
  onPresence(listener: () => void): void;
}

export function setupEditors(app: App, sync: Sync): Editors {
  const { state, banner } = app;
  const identity = new Identity(window.sessionStorage, window.localStorage);
  const presence = new PresenceModel(identity.clientId);
  const listeners: (() => void)[] = [];
  let sawPresence = false;
  let grabs = 0; // a release waiting for the drag's last update must not end a newer grab
  const adopt = (p: Presence) => {
    sawPresence = true;
    if (!presence.update(p)) return;
    // Handles someone else holds are drawn in their colour.
    state.heldColours = new Map();
    for (const person of presence.people) if (!person.me) for (const h of person.held) state.heldColours.set(h + 1, person.color);
    state.emit("colours", undefined);
    state.emit("handles", undefined); // the gizmo of a held handle does not start drags
    for (const l of listeners) l();
  };
  // A late GrabHandles / ReleaseHandles answer of the previous session must not list its people.
  const lease = new HandleLease(app.edits, () => identity.participant(), (p, name) => {
    if (name === sync.sessionName) adopt(p);
  });
  sync.on("presence", adopt);
  // Another session: its people come with its own presence (whose versions may be lower than
  // the old session's, so the model must forget that one's too).
  sync.on("opened", () => {
    void lease.release();
    presence.clear();
    state.heldColours = new Map();
    state.emit("colours", undefined);
    state.emit("handles", undefined);
    for (const l of listeners) l();
  });

  // Another editor's frame: it names every handle's transform; move the gizmos of the handles
  // this page is not dragging.
  sync.on("frame", ({ frame }) => {
    if (!frame.clientId || frame.clientId === identity.clientId || frame.transforms.length === 0) return;
    const mine = sync.dragging || sync.busy ? state.activeHandle - 1 : -1;
    let changed = false;
    frame.transforms.forEach((t, h) => {
      if (h === mine || h >= state.handles.length) return;
      state.setHandle(h, fromProtoTransform(create(HandleTransformSchema, t), state.pivots[h]));
      changed = true;
    });
    if (changed) state.emit("handles", undefined);
  });

  return {
    identity,
    presence,
    lease,
    get multi() {
      return sawPresence || lease.supported === true;
    },
    async grab(h: number): Promise<boolean> {
      if (state.watchOnly || !state.sessionName) return false;
      const holder = presence.holderOf(h);
      if (holder) {
        banner.show(heldMessage(h, holder.name), "rejected");
        return false;
      }
      grabs++;
      const r = await lease.grab(state.sessionName, [h]);
      if (r.ok) {
        banner.clear("rejected");
        return true;
      }
      banner.show(
        r.code === Code.Aborted ? heldMessage(h, holderFromMessage(r.message)) : `Cannot take ${handleWord(h)}: ${r.message}`,
        "rejected",
      );
      return false;
    },
    // After the drag's last update is answered: the server ends the drag's history step at the
    // release, and the last update must be part of it (one drag, one step to undo).
    release: () => {
      const g = grabs;
      void sync.whenSent().then(() => {
        if (g === grabs) void lease.release();
      });
    },
    onPresence: (l) => listeners.push(l),
  };
}

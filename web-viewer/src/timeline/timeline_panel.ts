// The timeline strip along the bottom of the viewport: the session's keys (GetTimeline, then
// live from SessionEvent.timeline), the playhead and its time; for editors Set key (K), Delete
// key, easing, scrubbing (scrub.ts), moving the selected key (a drag of its marker), copy / paste
// of a key's pose (Ctrl+C / Ctrl+V), Play (the exported GLB in the viewport) and Export (the same
// GLB as a download). Every change sends the whole edited key list (SetTimeline). Watch pages
// see the keys and move their own playhead; they change nothing (the calls need the edit token).
import type { MessageInitShape } from "@bufbuild/protobuf";
import { describeError } from "../api";
import type { App } from "../app";
import { $ } from "../dom";
import { Easing, type KeyframeSchema, type Timeline } from "../gen/hdeform/v1/deform_pb";
import type { Editors } from "../multi/editors";
import { saveBytes } from "../panels/files";
import type { ExportUp } from "../panels/export_up";
import { withUpAxis } from "../glb_up_axis";
import type { Sync } from "../sync/sync";
import { toProtoTransforms } from "../transforms";
import { fetchAnimation } from "./animation_glb";
import type { AnimationPlayer } from "./animation_player";
import { deleteKey, keyAt, moveKey, SAME_TIME_S, setKey, withKeyEasing } from "./key_list";
import { setupKeyClipboardKeys } from "./key_clipboard_keys";
import type { Scrub } from "./scrub";
import { StripView } from "./strip_view";

type Key = MessageInitShape<typeof KeyframeSchema> & { timeS: number };

export interface TimelinePanel {
  readonly keys: readonly Key[];
  readonly easing: Easing;
  readonly author: string;
  readonly selected: number;
  readonly playhead: number;
  /** The time of the key whose pose Ctrl+C copied (null: nothing copied). */
  readonly copiedFrom: number | null;
  readonly note: string;
  readonly view: StripView;
  /** The last GLB Play or Export fetched (tests compare it with the download). */
  readonly lastGlbBytes: number;
  setKey(): void;
  /** An inline message in the strip (error: in red). */
  say(message: string, error?: boolean): void;
  /** Once per animation frame: the playing animation and the playhead that follows it. */
  update(): void;
}

function kib(n: number): string {
  return n >= 1 << 20 ? `${(n / (1 << 20)).toFixed(1)} MiB` : `${(n / 1024).toFixed(0)} KiB`;
}

export function setupTimelinePanel(app: App, sync: Sync, editors: Editors, scrub: Scrub, player: AnimationPlayer, exportUp: ExportUp): TimelinePanel {
  const { state, client, edits } = app;
  const strip = $("timeline");
  const viewportEl = $("viewport");
  const play = $<HTMLButtonElement>("tl-play");
  const setKeyButton = $<HTMLButtonElement>("tl-setkey");
  const delKey = $<HTMLButtonElement>("tl-delkey");
  const keyBeta = $<HTMLInputElement>("tl-keybeta");
  const easingSelect = $<HTMLSelectElement>("tl-easing");
  const keyEasingSelect = $<HTMLSelectElement>("tl-key-easing");
  const fps = $<HTMLInputElement>("tl-fps");
  const exportButton = $<HTMLButtonElement>("tl-export");
  const noteEl = $("tl-note");
  let keys: Key[] = [];
  let easing = Easing.LINEAR;
  let author = "";
  let selected = -1;
  let note = "";
  let lastGlbBytes = 0;
  let shownFor = "";
  // The newest history step seen: a clear that new constraints caused comes right after their
  // step, at its version (a SetTimeline is a TIMELINE step of its own).
  let lastStep: { version: bigint; author: string } | null = null;
  let beforePlay = 0; // the playhead where Play started (Stop puts it back)
  let busy = false; // an export or SetTimeline in flight
  // Ctrl+C's pose (transforms, β), kept in the page: a pose fits only this session's handles.
  let copied: { fromS: number; transforms: Key["transforms"]; beta: Key["beta"] } | null = null;

  const say = (message: string, error = false) => {
    note = message;
    noteEl.textContent = message;
    noteEl.title = message;
    noteEl.classList.toggle("err", error);
    noteEl.classList.toggle("hidden", !message);
  };

  // A click on a key's marker is a scrub that starts and ends on its time: it selects the key.
  const view = new StripView({
    scrubStart: (t) => {
      if (player.playing) stopPlaying();
      selected = keyAt(keys, t);
      render();
      view.setPlayhead(t);
      if (canScrub()) scrub.start(t);
    },
    scrub: (t) => {
      view.setPlayhead(t);
      scrub.move(t);
    },
    scrubEnd: (t) => {
      view.setPlayhead(t);
      selected = keyAt(keys, t);
      render();
      void scrub.end(t);
    },
    canMoveKey: () => editable() && !player.playing,
    keyMoved: (fromS, toS) => doMoveKey(fromS, toS),
  });

  const editable = () => !state.watchOnly && !!state.sessionName && state.constraintsApplied && !state.labelsDirty;
  const canScrub = () => editable() && keys.length > 0;

  function render(): void {
    view.setKeys(keys.map((k) => k.timeS), selected);
    delKey.disabled = selected < 0 || !editable();
    easingSelect.value = String(easing);
    easingSelect.disabled = state.watchOnly;
    // The last key starts no segment: its easing would change nothing.
    const own = keys[selected]?.easing;
    keyEasingSelect.value = own === undefined ? "" : String(own);
    keyEasingSelect.disabled = selected < 0 || selected === keys.length - 1 || !editable() || busy;
    const noKeys = keys.length === 0;
    play.disabled = !player.playing && (noKeys || busy || state.watchOnly);
    exportButton.disabled = noKeys || busy;
    setKeyButton.disabled = !editable();
  }

  const adopt = (timeline: Timeline, from: "get" | "watch" | "set") => {
    if (from === "watch" && timeline.keys.length === 0 && keys.length > 0) {
      say(
        lastStep && lastStep.version === timeline.version
          ? `Timeline cleared: ${lastStep.author || "someone"} changed the constraints (keys hold one pose per handle).`
          : `Timeline cleared by ${timeline.author || "another editor"}.`,
      );
    } else if (from === "watch" && timeline.keys.length > 0 && timeline.clientId !== editors.identity.clientId) say("");
    // (Our own change comes back as a watch event too: its note, "Key moved …", stays.)
    const selectedTime = keys[selected]?.timeS;
    keys = timeline.keys.map((k) => k as Key);
    easing = timeline.easing;
    author = timeline.author;
    selected = selectedTime === undefined ? -1 : keyAt(keys, selectedTime);
    render();
  };

  const load = async () => {
    const name = state.sessionName;
    if (!name) return;
    try {
      const t = await client.getTimeline({ name });
      if (name === state.sessionName) adopt(t, "get");
    } catch (err) {
      // A server without timelines: the strip stays empty and says why.
      if (name === state.sessionName) say(`Timeline: ${describeError(err)}`, true);
    }
  };

  // `select`: the time of the key to select once the server's list is in (the index into `next`
  // would not do: adopt() maps the selection through the list it replaces).
  const save = async (next: Key[], nextEasing: Easing, what: string, select?: number) => {
    const name = state.sessionName;
    busy = true;
    render();
    try {
      const t = await edits.execute({
        method: "setTimeline",
        what: "Timeline",
        request: () => ({
          name,
          timeline: { keys: next, easing: nextEasing },
          clientId: editors.identity.clientId,
          expectedConfigVersion: state.session?.configVersion ?? 0n,
        }),
        // The strip's note says what became of the timeline's edits, refusals too.
        showIn: (text) => say(text, true),
        conflict: async (err) => {
          say(`Not saved: someone else changed the constraints or β first (${describeError(err)}).`, true);
          await load();
        },
      });
      if (name !== state.sessionName) return;
      adopt(t, "set");
      if (select !== undefined) {
        selected = keyAt(keys, select);
        render();
      }
      say(what);
    } catch {
      /* said in the strip */
    } finally {
      busy = false;
      render();
    }
  };

  const doSetKey = () => {
    if (!editable()) {
      if (!state.watchOnly && state.sessionName) say("Apply constraints first: a key holds every handle's pose.", true);
      return;
    }
    const t = view.playhead;
    const key: Key = { timeS: t, transforms: toProtoTransforms(state.handles, state.pivots) };
    if (keyBeta.checked) key.beta = { value: state.beta.value, units: state.beta.units };
    void save(setKey(keys, key), easing, `Key at ${t.toFixed(3)} s set.`, t);
  };

  const doDeleteKey = () => {
    if (selected < 0) return;
    if (!editable()) return refuse("delete a key");
    const t = keys[selected].timeS;
    const next = deleteKey(keys, selected);
    selected = -1;
    void save(next, easing, `Key at ${t.toFixed(3)} s deleted.`);
  };

  // One SetTimeline with the key at its new time (one TIMELINE step: one Undo).
  const doMoveKey = (fromS: number, toS: number) => {
    if (!editable()) return refuse("move a key");
    const index = keyAt(keys, fromS);
    if (index < 0) return say(`Key not moved: the key at ${fromS.toFixed(3)} s is gone (another editor changed the timeline).`, true);
    if (Math.abs(toS - fromS) < SAME_TIME_S) return;
    const moved = moveKey(keys, index, toS);
    if ("onto" in moved) {
      render(); // the marker back where it was
      return say(`Key not moved: there is a key at ${keys[moved.onto].timeS.toFixed(3)} s already (keys need ${SAME_TIME_S * 1000} ms between them; delete that one first).`, true);
    }
    void save(moved.keys, easing, `Key moved from ${fromS.toFixed(3)} s to ${toS.toFixed(3)} s.`, toS);
  };

  // Watch pages (and editors before Apply) change no key: say why rather than ignore the key.
  function refuse(what: string): void {
    if (state.watchOnly) say(`Watch-only: this page cannot ${what} (the edit link can).`, true);
    else if (state.sessionName) say(`Cannot ${what} yet: apply constraints first (a key holds every handle's pose).`, true);
  }

  const doCopyKey = () => {
    if (!editable()) return refuse("copy a key");
    if (selected < 0) return say("Copy: select a key first (click its marker).", true);
    const key = keys[selected];
    copied = { fromS: key.timeS, transforms: key.transforms, beta: key.beta };
    say(`Copied the key at ${key.timeS.toFixed(3)} s (${key.transforms?.length ?? 0} handles${key.beta ? ", β" : ""}); Ctrl+V keys it at the playhead.`);
  };

  const doPasteKey = () => {
    if (!editable()) return refuse("paste a key");
    if (!copied) return say("Paste: copy a key first (select it, Ctrl+C).", true);
    if ((copied.transforms?.length ?? 0) !== state.handles.length) {
      return say("Paste: the copied key was for other constraints (it holds a pose per handle of those).", true);
    }
    const t = view.playhead;
    const key: Key = { timeS: t, transforms: copied.transforms };
    if (copied.beta) key.beta = copied.beta;
    void save(setKey(keys, key), easing, `Pasted the key from ${copied.fromS.toFixed(3)} s at ${t.toFixed(3)} s.`, t);
  };

  const exportGlb = async (label: string): Promise<Uint8Array | null> => {
    const name = state.sessionName;
    busy = true;
    render();
    say(`${label}: exporting…`);
    try {
      const bytes = await fetchAnimation(client, name, { fps: Number(fps.value), energies: state.energyMapping !== "off" }, (n) =>
        say(`${label}: exporting… ${kib(n)}`),
      );
      lastGlbBytes = bytes.byteLength;
      return name === state.sessionName ? bytes : null;
    } catch (err) {
      // RESOURCE_EXHAUSTED (too many frames or bytes), a bad fps, no timeline: the server says which.
      say(`${label} failed: ${describeError(err)}`, true);
      return null;
    } finally {
      busy = false;
      render();
    }
  };

  function stopPlaying(): void {
    player.stop();
    play.textContent = "Play";
    view.setPlayhead(beforePlay);
    render();
  }

  play.addEventListener("click", async () => {
    if (player.playing) return stopPlaying();
    scrub.cancel();
    beforePlay = view.playhead;
    const bytes = await exportGlb("Play");
    if (!bytes || keys.length === 0) return;
    try {
      await player.play(bytes, keys[0].timeS);
      play.textContent = "Stop";
      say(`Playing ${kib(bytes.byteLength)} (${fps.value} fps); Stop returns to the live mesh.`);
      render();
    } catch (err) {
      say(`Play failed: ${describeError(err)}`, true);
    }
  });
  exportButton.addEventListener("click", async () => {
    const bytes = await exportGlb("Export");
    if (!bytes) return;
    const id = state.sessionName.replace(/^sessions\//, "");
    // The download carries the model's up axis (Play shows the bytes as fetched: the model's frame).
    saveBytes(withUpAxis(bytes, exportUp.value), `${id}-animation.glb`, "model/gltf-binary");
    say(`Exported ${id}-animation.glb (${kib(bytes.byteLength)}).`);
  });
  setKeyButton.addEventListener("click", doSetKey);
  delKey.addEventListener("click", doDeleteKey);
  easingSelect.addEventListener("change", () => {
    const next = Number(easingSelect.value) as Easing;
    if (keys.length === 0) {
      easing = next;
      return;
    }
    void save(keys, next, `Easing: ${Easing[next].toLowerCase()}.`);
  });
  keyEasingSelect.addEventListener("change", () => {
    if (selected < 0 || !editable()) return;
    const v = keyEasingSelect.value;
    const t = keys[selected].timeS;
    const own = v === "" ? undefined : (Number(v) as Easing);
    const what = own === undefined ? "the timeline's easing" : Easing[own].toLowerCase();
    void save(withKeyEasing(keys, selected, own), easing, `Key at ${t.toFixed(3)} s to the next: ${what}.`, t);
  });
  // Delete / Backspace while the strip has the focus: the selected key (not the region, which
  // the same keys clear elsewhere: panels/shortcuts.ts never sees them).
  strip.addEventListener("keydown", (ev) => {
    if ((ev.key === "Delete" || ev.key === "Backspace") && (ev.target === strip || !/INPUT|SELECT/.test((ev.target as HTMLElement).tagName))) {
      if (selected >= 0) {
        ev.preventDefault();
        ev.stopPropagation();
        doDeleteKey();
      }
    }
  });
  setupKeyClipboardKeys(strip, (what) => (what === "copy" ? doCopyKey() : doPasteKey()));
  // A press on the ruler gives the strip the focus (so Delete means the key).
  view.ruler.addEventListener("pointerdown", () => strip.focus({ preventScroll: true }));

  state.on("mesh", () => {
    strip.classList.remove("hidden");
    viewportEl.classList.add("with-timeline");
    view.render();
  });
  state.on("session", () => {
    render();
    if (state.sessionName === shownFor) return;
    shownFor = state.sessionName;
    scrub.cancel();
    view.cancelKeyDrag();
    if (player.playing) stopPlaying();
    keys = [];
    selected = -1;
    copied = null;
    say("");
    view.setPlayhead(0);
    render();
    void load();
  });
  state.on("labels", render);
  sync.on("timeline", (t) => adopt(t, "watch"));
  sync.on("step", (step) => (lastStep = { version: step.version, author: step.author }));
  // Timeline events may have been missed while away.
  sync.on("state", ({ source }) => {
    if (source === "resync") void load();
  });
  render();

  return {
    get keys() {
      return keys;
    },
    get easing() {
      return easing;
    },
    get author() {
      return author;
    },
    get selected() {
      return selected;
    },
    get playhead() {
      return view.playhead;
    },
    get copiedFrom() {
      return copied?.fromS ?? null;
    },
    get note() {
      return note;
    },
    get lastGlbBytes() {
      return lastGlbBytes;
    },
    view,
    setKey: doSetKey,
    say,
    update: () => {
      if (!player.playing) return;
      player.update();
      view.setPlayhead(player.time);
    },
  };
}

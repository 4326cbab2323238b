// Errors (and amber notices): one banner over the top of the canvas, never a blank canvas. A
// kind ("rejected", "lost", …) lets the success of the same kind of call clear only its own error.
// An error may offer one action (a button after the message, e.g. "Repair and open").
import { describeError, isAbort } from "../api";
import { $ } from "../dom";

export class Banner {
  private kind = "";
  private message = "";

  private action: (() => void) | null = null;

  constructor() {
    $("banner-close").addEventListener("click", () => this.clear());
    $("banner-action").addEventListener("click", () => {
      const run = this.action;
      this.clear();
      run?.();
    });
    window.addEventListener("unhandledrejection", (e) => {
      if (!isAbort(e.reason)) this.show(describeError(e.reason));
    });
  }

  /** The message shown ("" when the banner is hidden). */
  get shown(): string {
    return $("banner").classList.contains("hidden") ? "" : this.message;
  }

  /** An error; `action`: a button that clears the banner and runs `run`. */
  show(message: string, kind = "error", action?: { label: string; run: () => void }): void {
    this.put(message, kind, false);
    if (action) {
      this.action = action.run;
      $("banner-action").textContent = action.label;
      $("banner-action").classList.remove("hidden");
    }
    console.warn(`[hdeform] ${message}`);
  }

  /** Something to know rather than a failure (amber, not red): e.g. "open a mesh first". */
  notice(message: string, kind: string): void {
    this.put(message, kind, true);
  }

  private put(message: string, kind: string, notice: boolean): void {
    this.message = message;
    this.kind = kind;
    this.action = null;
    $("banner-action").classList.add("hidden");
    $("banner-text").textContent = message;
    $("banner").classList.toggle("notice", notice);
    $("banner").classList.remove("hidden");
  }

  /** Hides the banner; with `kind`, only when it shows an error of that kind. */
  clear(kind?: string): void {
    if (kind && kind !== this.kind) return;
    $("banner").classList.add("hidden");
    this.kind = "";
    this.action = null;
  }
}

/** A button that needs a mesh was pressed before one is open: say so (a page never acts silently). */
export function openMeshFirst(banner: Banner): void {
  banner.notice("Open a mesh first: pick one at the top and click Open, or Upload… your own.", "no-mesh");
}

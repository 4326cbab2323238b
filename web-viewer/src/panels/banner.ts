// Errors: one banner, never a blank canvas. A kind ("rejected", "lost", …) lets the success
// of the same kind of call clear only its own error.
import { describeError, isAbort } from "../api";
import { $ } from "../dom";

export class Banner {
  private kind = "";
  private message = "";

  constructor() {
    $("banner-close").addEventListener("click", () => this.clear());
    window.addEventListener("unhandledrejection", (e) => {
      if (!isAbort(e.reason)) this.show(describeError(e.reason));
    });
  }

  /** The message shown ("" when the banner is hidden). */
  get shown(): string {
    return $("banner").classList.contains("hidden") ? "" : this.message;
  }

  show(message: string, kind = "error"): void {
    this.message = message;
    this.kind = kind;
    $("banner-text").textContent = message;
    $("banner").classList.remove("hidden");
    console.warn(`[hdeform] ${message}`);
  }

  /** Hides the banner; with `kind`, only when it shows an error of that kind. */
  clear(kind?: string): void {
    if (kind && kind !== this.kind) return;
    $("banner").classList.add("hidden");
    this.kind = "";
  }
}

// The status line: what the page is doing and the size of the frames it receives, or
// "reconnecting…" while the server is away.
import { $ } from "../dom";

export class StatusLine {
  private text = "";
  private reconnect = "";
  private frameSizes = "";

  get shown(): string {
    return $("status").textContent ?? "";
  }

  set(text: string): void {
    this.text = text;
    this.render();
  }

  /** E.g. "frames: meshopt 20.1 KiB, float32 120.3 KiB" (the newest frame of each encoding). */
  setFrameSizes(text: string): void {
    this.frameSizes = text;
    this.render();
  }

  /** "" once connected again. */
  setReconnecting(text: string): void {
    this.reconnect = text;
    this.render();
  }

  private render(): void {
    const el = $("status");
    el.textContent = this.reconnect || [this.text, this.frameSizes].filter(Boolean).join(" · ");
    el.classList.toggle("warn", this.reconnect !== "");
  }
}

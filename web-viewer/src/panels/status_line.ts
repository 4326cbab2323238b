// The status line: what the page is doing, or "reconnecting…" while the server is away.
import { $ } from "../dom";

export class StatusLine {
  private text = "";
  private reconnect = "";

  get shown(): string {
    return $("status").textContent ?? "";
  }

  set(text: string): void {
    this.text = text;
    this.render();
  }

  /** "" once connected again. */
  setReconnecting(text: string): void {
    this.reconnect = text;
    this.render();
  }

  private render(): void {
    const el = $("status");
    el.textContent = this.reconnect || this.text;
    el.classList.toggle("warn", this.reconnect !== "");
  }
}

// X-ray (Blender's Alt+Z): Box and Lasso select through the mesh. Off by default: they take only
// the vertices the camera sees (visibility.ts). The checkbox after the brush radius and Alt+Z set it.
import { $ } from "../dom";

export class XrayToggle {
  private on = false;
  private readonly box = $<HTMLInputElement>("xray");

  constructor() {
    this.box.checked = false;
    this.box.addEventListener("change", () => (this.on = this.box.checked));
  }

  get enabled(): boolean {
    return this.on;
  }

  set(on: boolean): void {
    this.on = on;
    this.box.checked = on;
  }

  toggle(): void {
    this.set(!this.on);
  }
}

// Play: the exported GLB in the viewport in place of the live mesh, driven by an AnimationMixer
// (the same path three.js apps and Blender take with it), looping; Stop puts the live mesh (and
// the gizmo) back. The GLB is in the model's own frame (up Y: no root rotation), like the scene.
import * as THREE from "three";
import type { MeshDisplay } from "../viewport/mesh_display";
import type { Viewport } from "../viewport/viewport";
import { loadAnimation, type LoadedAnimation } from "./animation_glb";

export class AnimationPlayer {
  private loaded: LoadedAnimation | null = null;
  private mixer: THREE.AnimationMixer | null = null;
  private action: THREE.AnimationAction | null = null;
  private last = 0;
  /** Timeline time of the clip's time 0 (the first sample). */
  private start = 0;

  constructor(
    private readonly viewport: Viewport,
    private readonly display: MeshDisplay,
  ) {}

  get playing(): boolean {
    return this.loaded !== null;
  }

  /** The timeline time shown (NaN when not playing). */
  get time(): number {
    return this.action ? this.start + this.action.time : NaN;
  }

  get duration(): number {
    return this.loaded?.clip.duration ?? 0;
  }

  async play(bytes: Uint8Array, start: number): Promise<void> {
    this.stop();
    const loaded = await loadAnimation(bytes);
    const { mesh } = loaded;
    const colours = !!mesh.geometry.getAttribute("color");
    // The live mesh's look (two-sided, matte); the energy colours when the GLB has them.
    mesh.material = new THREE.MeshStandardMaterial({
      color: colours ? 0xffffff : 0xc9c4ba,
      vertexColors: colours,
      side: THREE.DoubleSide,
      roughness: 0.75,
      metalness: 0,
    });
    this.loaded = loaded;
    this.start = start;
    this.mixer = new THREE.AnimationMixer(loaded.scene);
    this.action = this.mixer.clipAction(loaded.clip);
    this.action.setLoop(THREE.LoopRepeat, Infinity).play();
    this.mixer.setTime(0);
    this.viewport.root.add(loaded.scene);
    this.display.setHidden(true);
    this.viewport.gizmo.getHelper().visible = false;
    this.last = performance.now();
    this.viewport.requestRender();
  }

  /** Once per animation frame: advances the clip by the wall-clock time since the last one. */
  update(): void {
    if (!this.mixer) return;
    const now = performance.now();
    this.mixer.update((now - this.last) / 1000);
    this.last = now;
    this.viewport.requestRender();
  }

  stop(): void {
    const loaded = this.loaded;
    if (!loaded) return;
    this.mixer?.stopAllAction();
    this.viewport.root.remove(loaded.scene);
    loaded.mesh.geometry.dispose();
    (loaded.mesh.material as THREE.Material).dispose();
    this.loaded = null;
    this.mixer = null;
    this.action = null;
    this.display.setHidden(false);
    this.viewport.gizmo.getHelper().visible = true;
    this.viewport.requestRender();
  }
}

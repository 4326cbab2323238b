// The three.js scene: renderer, camera, lights, orbit controls and the handle gizmo. Renders
// only when something changed (requestRender).
//
// The scene is the model's own frame (root is never rotated): a z-up model gets camera.up =
// +z instead, so the gizmo's "world" axes are the model's axes in every gizmo mode (Scale,
// which TransformControls always orients to the object, agreed with Move only this way).
//
// Orthographic view (Numpad 5, Blender's toggle): `camera`, the perspective camera, stays the
// one that orbits, frames and turns to the keypad views; the picture is drawn with `viewCamera`,
// which in orthographic mode is an OrthographicCamera posed as `camera` and as wide at the orbit
// target as the perspective view is there. So dolly-zoom and pan work unchanged (the width
// follows the distance), and everything that projects or picks (the gizmo, the tools, the
// depth pass) asks for `viewCamera`.
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { TransformControls } from "three/examples/jsm/controls/TransformControls.js";

export type ScreenPoint = { x: number; y: number };

export class Viewport {
  readonly renderer: THREE.WebGLRenderer;
  readonly scene = new THREE.Scene();
  readonly camera = new THREE.PerspectiveCamera(40, 1, 0.001, 1000);
  private readonly orthoCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1000);
  private ortho = false;
  /** Model space (= the scene's frame); the gizmo's object too, so its pose is in model coordinates. */
  readonly root = new THREE.Group();
  readonly pivotObject = new THREE.Object3D();
  readonly gizmo: TransformControls;
  readonly orbit: OrbitControls;
  private needsRender = true;
  /** Drawn over the scene after each render (the axes view helper). */
  readonly overlays: ((renderer: THREE.WebGLRenderer) => void)[] = [];

  /** Throws when WebGL is not available. */
  constructor(readonly element: HTMLElement) {
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    element.prepend(this.renderer.domElement);
    this.scene.background = new THREE.Color(0x2a2d33);
    this.camera.position.set(0, 0, 3);
    this.scene.add(this.camera);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x444455, 1.6));
    const headLight = new THREE.DirectionalLight(0xffffff, 1.6);
    headLight.position.set(0.5, 1, 2);
    this.camera.add(headLight);
    this.scene.add(this.root);
    this.root.add(this.pivotObject);
    // TransformControls first: its pointerdown runs before OrbitControls' and disables orbiting.
    this.gizmo = new TransformControls(this.camera, this.renderer.domElement);
    this.gizmo.setSize(0.9);
    this.scene.add(this.gizmo.getHelper());
    this.orbit = new OrbitControls(this.camera, this.renderer.domElement);
    this.orbit.enableDamping = false;
    this.orbit.zoomToCursor = true; // as in Blender / the three.js editor: the point under the cursor stays put
    this.orbit.addEventListener("change", () => this.requestRender());
    this.gizmo.addEventListener("change", () => this.requestRender());
    new ResizeObserver(() => this.resize()).observe(element);
    this.resize();
  }

  get canvas(): HTMLCanvasElement {
    return this.renderer.domElement;
  }

  requestRender(): void {
    this.needsRender = true;
  }

  /** The picture is orthographic (Numpad 5). */
  get orthographic(): boolean {
    return this.ortho;
  }

  /** The camera the picture is drawn, projected and picked with, posed as `camera` now. */
  get viewCamera(): THREE.PerspectiveCamera | THREE.OrthographicCamera {
    if (!this.ortho) return this.camera;
    this.poseOrtho();
    return this.orthoCamera;
  }

  /** Numpad 5: perspective ⇄ orthographic, from where the camera is. */
  toggleOrthographic(): void {
    this.ortho = !this.ortho;
    this.gizmo.camera = this.viewCamera;
    this.requestRender();
  }

  private poseOrtho(): void {
    const { camera, orthoCamera: o } = this;
    camera.updateMatrixWorld();
    const dist = camera.position.distanceTo(this.orbit.target);
    const half = dist * Math.tan(THREE.MathUtils.degToRad(camera.fov / 2));
    o.top = half;
    o.bottom = -half;
    o.left = -half * camera.aspect;
    o.right = half * camera.aspect;
    // Backed off along the view: an orthographic picture shows what lies behind the perspective
    // camera's position too (a close-up of the model's middle keeps its front half).
    const back = Math.max(dist, this.modelRadius()) * 2;
    const forward = camera.getWorldDirection(new THREE.Vector3());
    o.position.copy(camera.position).addScaledVector(forward, -back);
    o.quaternion.copy(camera.quaternion);
    o.up.copy(camera.up);
    o.near = 0;
    o.far = back + camera.far;
    o.updateProjectionMatrix();
    o.updateMatrixWorld();
  }

  /** Called once per animation frame. */
  renderIfNeeded(): void {
    if (!this.needsRender) return;
    this.needsRender = false;
    this.renderer.render(this.scene, this.viewCamera);
    for (const draw of this.overlays) draw(this.renderer);
  }

  private resize(): void {
    const w = this.element.clientWidth || 1;
    const h = this.element.clientHeight || 1;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  /** The model's rest box, from the last fitCamera: its up axis and the camera's near / far. */
  private modelBox: THREE.Box3 | null = null;
  /**
   * What Home, Frame all and the default view frame: the model as it is now (deformed) and its
   * handles' gizmos (viewport/content_box.ts); null: the rest box.
   */
  contentBox: () => THREE.Box3 | null = () => null;

  /** The box the camera frames for "everything": the current content, else the rest shape. */
  private everything(): THREE.Box3 | null {
    const box = this.contentBox();
    return box && !box.isEmpty() ? box : this.modelBox;
  }

  /** A new model: its up axis, and the default 3/4 view of `box`. */
  fitCamera(box: THREE.Box3): void {
    const size = box.getSize(new THREE.Vector3());
    // z-up models (the Botsch–Sorkine set) stand upright on screen.
    this.setUp(size.z > 1.3 * size.y ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(0, 1, 0));
    this.modelBox = box.clone();
    this.resetView();
  }

  /**
   * The default view: from (1, 0.8, 1.2) (right, up, front) of the model's diagonal, so no
   * gizmo arrow points at the viewer and all three can be grabbed.
   */
  resetView(): void {
    const box = this.everything();
    if (!box) return;
    const up = this.camera.up;
    const zUp = up.z > 0.5;
    // right, up, front in model coordinates
    const dir = zUp ? new THREE.Vector3(1, -1.2, 0.8) : new THREE.Vector3(1, 0.8, 1.2);
    this.frameBox(box, dir.normalize());
  }

  /** Home: the whole model as it is now (deformed, with its gizmos), from the current direction. */
  frameAll(): void {
    const box = this.everything();
    if (box) this.frameBox(box);
  }

  /** "z" when the model is shown z-up (camera up = +z), else "y": what exports default to. */
  get upAxis(): "y" | "z" {
    return this.camera.up.z > 0.5 ? "z" : "y";
  }

  /**
   * Frames `box` (model = world coordinates) from `direction` (unit, target → camera; default:
   * the current one) and orbits around its centre from now on.
   */
  frameBox(box: THREE.Box3, direction?: THREE.Vector3): void {
    const { camera, orbit } = this;
    const center = box.getCenter(new THREE.Vector3());
    const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, (this.modelRadius() || 1) * 0.05);
    const dist = (radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2))) * 1.1;
    const dir = direction ?? camera.position.clone().sub(orbit.target).normalize();
    const modelRadius = this.modelRadius() || radius;
    camera.near = modelRadius / 100;
    camera.far = modelRadius * 100;
    camera.position.copy(center).addScaledVector(dir, dist);
    camera.updateProjectionMatrix();
    orbit.target.copy(center);
    orbit.update();
    this.requestRender();
  }

  private modelRadius(): number {
    return this.modelBox ? this.modelBox.getSize(new THREE.Vector3()).length() / 2 : 0;
  }

  private setUp(up: THREE.Vector3): void {
    this.camera.up.copy(up);
    // OrbitControls takes its "up" from camera.up once, in its constructor (_quat maps it to
    // +y); a model with another up axis needs it again.
    const o = this.orbit as unknown as { _quat: THREE.Quaternion; _quatInverse: THREE.Quaternion };
    o._quat.setFromUnitVectors(up, new THREE.Vector3(0, 1, 0));
    o._quatInverse.copy(o._quat).invert();
  }

  /** Client coordinates of a world-space point. */
  toClient(world: THREE.Vector3): ScreenPoint {
    const p = world.clone().project(this.viewCamera);
    const r = this.canvas.getBoundingClientRect();
    return { x: r.left + ((p.x + 1) / 2) * r.width, y: r.top + ((1 - p.y) / 2) * r.height };
  }
}

// The three.js scene: renderer, camera, lights, orbit controls and the handle gizmo. Renders
// only when something changed (requestRender).
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { TransformControls } from "three/examples/jsm/controls/TransformControls.js";

export type ScreenPoint = { x: number; y: number };

export class Viewport {
  readonly renderer: THREE.WebGLRenderer;
  readonly scene = new THREE.Scene();
  readonly camera = new THREE.PerspectiveCamera(40, 1, 0.001, 1000);
  /** Model space (rotated for z-up models); the gizmo's object too, so its pose is in model coordinates. */
  readonly root = new THREE.Group();
  readonly pivotObject = new THREE.Object3D();
  readonly gizmo: TransformControls;
  readonly orbit: OrbitControls;
  private needsRender = true;

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

  /** Called once per animation frame. */
  renderIfNeeded(): void {
    if (!this.needsRender) return;
    this.needsRender = false;
    this.renderer.render(this.scene, this.camera);
  }

  private resize(): void {
    const w = this.element.clientWidth || 1;
    const h = this.element.clientHeight || 1;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  /** Frames the model-space box `box`. */
  fitCamera(box: THREE.Box3): void {
    const { camera, root, orbit } = this;
    const size = box.getSize(new THREE.Vector3());
    // z-up models (the Botsch–Sorkine set) stand upright on screen.
    root.rotation.x = size.z > 1.3 * size.y ? -Math.PI / 2 : 0;
    root.updateMatrixWorld(true);
    const worldBox = box.clone().applyMatrix4(root.matrixWorld);
    const center = worldBox.getCenter(new THREE.Vector3());
    const radius = worldBox.getSize(new THREE.Vector3()).length() / 2 || 1;
    const dist = (radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2))) * 1.25;
    camera.near = radius / 100;
    camera.far = radius * 100;
    // Look along the shallower horizontal axis so the widest silhouette faces the camera.
    const ws = worldBox.getSize(new THREE.Vector3());
    const offset = ws.z > 1.2 * ws.x ? new THREE.Vector3(dist, radius * 0.15, 0) : new THREE.Vector3(0, radius * 0.15, dist);
    camera.position.copy(center).add(offset);
    camera.updateProjectionMatrix();
    orbit.target.copy(center);
    orbit.update();
    this.requestRender();
  }

  /** Client coordinates of a world-space point. */
  toClient(world: THREE.Vector3): ScreenPoint {
    const p = world.clone().project(this.camera);
    const r = this.canvas.getBoundingClientRect();
    return { x: r.left + ((p.x + 1) / 2) * r.width, y: r.top + ((1 - p.y) / 2) * r.height };
  }
}

// Visible-only selection (the default; X-ray selects through): a vertex counts as visible when
// no surface lies in front of it at its pixel. One depth pass of the mesh per gesture — drawn
// into an offscreen target and read back once — and then one lookup per candidate vertex, so a
// 100K-vertex box costs a render and a loop, not a raycast per vertex.
//
// The depth is gl_FragCoord.z packed into 24 bits of an RGBA8 target (readable everywhere,
// unlike float or depth textures), compared as distance from the camera: a vertex is visible
// when it is no farther than the farthest surface in its 3×3 pixel neighbourhood plus a small
// tolerance. The neighbourhood keeps vertices on silhouettes and on faces seen at a grazing
// angle (where depth changes fast within a pixel); the tolerance (a fraction of the model's
// size and three pixels' width at the vertex) keeps a vertex from being hidden by its own
// triangles.
import * as THREE from "three";
import type { MeshDisplay } from "../viewport/mesh_display";
import type { Viewport } from "../viewport/viewport";
import type { VertexFilter } from "./screen_rect";

const depthMaterial = new THREE.ShaderMaterial({
  vertexShader: "void main() { gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0); }",
  fragmentShader: `
    precision highp float;
    void main() {
      float d = floor(gl_FragCoord.z * 16777215.0 + 0.5);
      float r = floor(d / 65536.0);
      float g = floor((d - r * 65536.0) / 256.0);
      float b = d - r * 65536.0 - g * 256.0;
      gl_FragColor = vec4(r, g, b, 255.0) / 255.0;
    }`,
  side: THREE.DoubleSide, // an open mesh's inside hides what is behind it too
  blending: THREE.NoBlending,
});

/** The window depth (0 … 1) packed at byte offset `o` of an RGBA8 readback. */
export function unpackDepth(pixels: Uint8Array, o: number): number {
  return (pixels[o] * 65536 + pixels[o + 1] * 256 + pixels[o + 2]) / 16777215;
}

/** Distance along the view axis of window depth `d` for a camera's near / far (an orthographic one's depth is linear). */
export function viewDistance(d: number, near: number, far: number, orthographic = false): number {
  return orthographic ? near + d * (far - near) : (near * far) / (far - d * (far - near));
}

/** A depth picture of the mesh and how to read it. */
export interface DepthImage {
  width: number;
  height: number;
  /** RGBA8, row 0 at the bottom (as WebGL reads it). */
  pixels: Uint8Array;
  near: number;
  far: number;
  /** One pixel's height as a fraction of the distance (2 tan(fov / 2) / height); 0 when orthographic. */
  pixelAngle: number;
  /** An orthographic picture (Numpad 5): linear depth, and one pixel's height in model units. */
  orthographic?: boolean;
  pixelSize?: number;
}

/**
 * The filter for a depth image: keeps (x, y, depth) — viewport pixels, window depth — when no
 * surface lies more than `tolerance` (model units) plus three pixels' width in front of it.
 */
export function visibleFilter(img: DepthImage, tolerance: number): VertexFilter {
  const { width: w, height: h, pixels, near, far, pixelAngle } = img;
  const ortho = img.orthographic === true;
  const pixelSize = img.pixelSize ?? 0;
  return (x, y, depth) => {
    const px = Math.floor(x), py = Math.floor(y);
    let farthest = -1; // none of the 9 pixels shows the mesh: nothing in front
    for (let dy = -1; dy <= 1; dy++)
      for (let dx = -1; dx <= 1; dx++) {
        const cx = px + dx, cy = py + dy;
        if (cx < 0 || cy < 0 || cx >= w || cy >= h) continue;
        const d = unpackDepth(pixels, 4 * ((h - 1 - cy) * w + cx));
        if (d < 1) farthest = Math.max(farthest, viewDistance(d, near, far, ortho));
      }
    if (farthest < 0) return true;
    const dist = viewDistance(depth, near, far, ortho);
    return dist <= farthest + tolerance + 3 * (dist * pixelAngle + pixelSize);
  };
}

export class DepthProbe {
  private target: THREE.WebGLRenderTarget | null = null;
  private readonly scene = new THREE.Scene();
  /** The last capture's time (ms: render + readback), for the tests' log. */
  lastMs = 0;

  constructor(private readonly viewport: Viewport, private readonly display: MeshDisplay) {}

  /** The mesh's depth as the camera sees it now, or null without a mesh. */
  capture(): DepthImage | null {
    const object = this.display.object;
    if (!object) return null;
    const t0 = performance.now();
    const { renderer, viewCamera: camera, element } = this.viewport;
    const width = Math.max(1, element.clientWidth), height = Math.max(1, element.clientHeight);
    if (!this.target || this.target.width !== width || this.target.height !== height) {
      this.target?.dispose();
      this.target = new THREE.WebGLRenderTarget(width, height, { depthBuffer: true }); // RGBA8, no multisampling
    }
    // The display's geometry (current positions) under a material that writes depth as colour.
    const probe = new THREE.Mesh(object.geometry, depthMaterial);
    probe.matrixAutoUpdate = false;
    object.updateMatrixWorld();
    probe.matrix.copy(object.matrixWorld);
    this.scene.add(probe);
    camera.updateMatrixWorld();
    const before = { target: renderer.getRenderTarget(), colour: renderer.getClearColor(new THREE.Color()), alpha: renderer.getClearAlpha() };
    renderer.setRenderTarget(this.target);
    renderer.setClearColor(0xffffff, 1); // depth 1: nothing there
    renderer.clear();
    renderer.render(this.scene, camera);
    const pixels = new Uint8Array(4 * width * height);
    renderer.readRenderTargetPixels(this.target, 0, 0, width, height, pixels);
    renderer.setRenderTarget(before.target);
    renderer.setClearColor(before.colour, before.alpha);
    this.scene.remove(probe);
    this.lastMs = performance.now() - t0;
    if (camera instanceof THREE.OrthographicCamera) {
      const pixelSize = (camera.top - camera.bottom) / camera.zoom / height;
      return { width, height, pixels, near: camera.near, far: camera.far, pixelAngle: 0, orthographic: true, pixelSize };
    }
    return { width, height, pixels, near: camera.near, far: camera.far, pixelAngle: (2 * Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2)) / height };
  }
}

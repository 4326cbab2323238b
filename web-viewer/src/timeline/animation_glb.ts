// The animated GLB of ExportAnimation: fetched (the call streams it in chunks, like GetMesh),
// and loaded with three's GLTFLoader into a scene, its morphed mesh and its weights clip.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import type { DeformationClient } from "../api";
import { UpAxis } from "../gen/hdeform/v1/deform_pb";

export interface AnimationRequest {
  fps: number;
  energies: boolean;
}

/**
 * ExportAnimation's bytes. `up` Y: the viewer shows every model in its own frame (a z-up model
 * gets camera.up = +z, viewport.ts), so the GLB must not add the root rotation a z-up export has.
 */
export async function fetchAnimation(
  client: DeformationClient,
  name: string,
  { fps, energies }: AnimationRequest,
  progress?: (bytes: number) => void,
  signal?: AbortSignal,
): Promise<Uint8Array> {
  const parts: Uint8Array[] = [];
  let total = 0;
  for await (const chunk of client.exportAnimation({ name, fps, energies, up: UpAxis.Y }, { signal })) {
    parts.push(chunk.data);
    total += chunk.data.byteLength;
    progress?.(total);
  }
  const out = new Uint8Array(total);
  let at = 0;
  for (const p of parts) {
    out.set(p, at);
    at += p.byteLength;
  }
  return out;
}

export interface LoadedAnimation {
  scene: THREE.Group;
  mesh: THREE.Mesh;
  clip: THREE.AnimationClip;
}

export async function loadAnimation(bytes: Uint8Array): Promise<LoadedAnimation> {
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength) as ArrayBuffer;
  const gltf = await new GLTFLoader().parseAsync(buffer, "");
  let mesh: THREE.Mesh | null = null;
  gltf.scene.traverse((o) => {
    if (!mesh && (o as THREE.Mesh).isMesh) mesh = o as THREE.Mesh;
  });
  if (!mesh) throw new Error("the animation GLB has no mesh");
  const clip = gltf.animations[0];
  if (!clip) throw new Error("the animation GLB has no animation");
  return { scene: gltf.scene, mesh, clip };
}

/**
 * The mesh's positions as the GPU computes them with the current morph influences: base +
 * Σ influence_i × target_i (glTF targets are deltas: morphTargetsRelative), per vertex.
 */
export function morphedPositions(mesh: THREE.Mesh): Float32Array {
  const g = mesh.geometry;
  const base = g.getAttribute("position");
  const targets = g.morphAttributes.position ?? [];
  const w = mesh.morphTargetInfluences ?? [];
  const out = new Float32Array(3 * base.count);
  for (let v = 0; v < base.count; v++) {
    out[3 * v] = base.getX(v);
    out[3 * v + 1] = base.getY(v);
    out[3 * v + 2] = base.getZ(v);
  }
  targets.forEach((target, i) => {
    const k = w[i] ?? 0;
    if (k === 0) return;
    for (let v = 0; v < base.count; v++) {
      const relative = g.morphTargetsRelative;
      out[3 * v] += k * (target.getX(v) - (relative ? 0 : base.getX(v)));
      out[3 * v + 1] += k * (target.getY(v) - (relative ? 0 : base.getY(v)));
      out[3 * v + 2] += k * (target.getZ(v) - (relative ? 0 : base.getZ(v)));
    }
  });
  return out;
}

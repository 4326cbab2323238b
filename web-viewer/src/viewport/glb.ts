// The server's GLB (GetMesh) → positions, normals and triangle indices, via three's GLTFLoader.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";

export interface GlbMesh {
  positions: Float32Array;
  normals: Float32Array | null;
  index: Uint32Array;
}

function attributeArray(attribute: THREE.BufferAttribute | THREE.InterleavedBufferAttribute, n: number): Float32Array {
  const out = new Float32Array(3 * n);
  for (let i = 0; i < n; i++) {
    out[3 * i] = attribute.getX(i);
    out[3 * i + 1] = attribute.getY(i);
    out[3 * i + 2] = attribute.getZ(i);
  }
  return out;
}

export async function parseGlb(bytes: Uint8Array): Promise<GlbMesh> {
  const loader = new GLTFLoader();
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength) as ArrayBuffer;
  const gltf = await loader.parseAsync(buffer, "");
  let found: THREE.Mesh | null = null;
  gltf.scene.traverse((o) => {
    if (!found && (o as THREE.Mesh).isMesh) found = o as THREE.Mesh;
  });
  if (!found) throw new Error("the server's GLB has no mesh");
  const geometry = (found as THREE.Mesh).geometry;
  const pos = geometry.getAttribute("position");
  const n = pos.count;
  const nor = geometry.getAttribute("normal");
  const idx = geometry.getIndex();
  return {
    positions: attributeArray(pos, n),
    normals: nor && nor.count === n ? attributeArray(nor, n) : null,
    index: idx ? Uint32Array.from(idx.array as ArrayLike<number>) : Uint32Array.from({ length: n }, (_, i) => i),
  };
}

// glTF is y-up; a model the viewer shows z-up (the cactus and the other Botsch–Sorkine meshes:
// camera up = +z, viewport.ts) lies on its back in every other glTF viewer unless its GLB says
// how to stand it up. The server writes GLBs in the model's own frame (GetMesh and
// ExportAnimation with UP_AXIS_Y), so downloads are wrapped here: a new root node rotating
// −90° about x (+z → +y) whose children are the scene's old root nodes. Only the JSON chunk
// changes; the BIN chunk (positions, morph targets, animation) is kept byte for byte, so
// reading the vertices back (which ignores node transforms) gives the model's coordinates.
export type UpAxis = "y" | "z";

const GLB_MAGIC = 0x46546c67; // "glTF"
const CHUNK_JSON = 0x4e4f534a;
const HEADER = 12;

/** −90° about x, as glTF writes quaternions: [x, y, z, w]. Takes +z to +y and +y to −z. */
export const Z_UP_TO_Y_UP: readonly number[] = [-Math.SQRT1_2, 0, 0, Math.SQRT1_2];

/** The name of the node that wraps a z-up model (so it is recognisable, and not added twice). */
export const UP_NODE_NAME = "z-up to glTF y-up";

interface GltfJson {
  nodes?: { name?: string; children?: number[]; rotation?: number[] }[];
  scenes?: { nodes?: number[] }[];
  scene?: number;
}

/** The GLB's JSON chunk as an object, and where its chunks start. */
export function readGlbJson(glb: Uint8Array): { json: GltfJson; jsonEnd: number } {
  const view = new DataView(glb.buffer, glb.byteOffset, glb.byteLength);
  if (glb.byteLength < HEADER + 8 || view.getUint32(0, true) !== GLB_MAGIC) throw new Error("not a GLB (no glTF magic)");
  if (view.getUint32(8, true) !== glb.byteLength) throw new Error(`GLB length ${view.getUint32(8, true)} ≠ ${glb.byteLength} bytes`);
  const jsonLength = view.getUint32(HEADER, true);
  if (view.getUint32(HEADER + 4, true) !== CHUNK_JSON) throw new Error("the GLB's first chunk is not JSON");
  const jsonEnd = HEADER + 8 + jsonLength;
  if (jsonEnd > glb.byteLength) throw new Error("the GLB's JSON chunk runs past its end");
  const text = new TextDecoder().decode(glb.subarray(HEADER + 8, jsonEnd));
  return { json: JSON.parse(text) as GltfJson, jsonEnd };
}

/**
 * `glb` as a GLB whose +y is the model's `up`: unchanged for "y"; for "z", every scene's root
 * nodes go under one new node with the rotation Z_UP_TO_Y_UP. The JSON chunk is padded with
 * spaces to 4 bytes, the chunks after it (BIN) are copied as they are, the lengths updated.
 */
export function withUpAxis(glb: Uint8Array, up: UpAxis): Uint8Array {
  if (up === "y") return glb;
  const { json, jsonEnd } = readGlbJson(glb);
  const nodes = (json.nodes ??= []);
  const scenes = json.scenes ?? [];
  scenes.forEach((scene) => {
    const roots = scene.nodes ?? [];
    if (roots.length === 1 && nodes[roots[0]]?.name === UP_NODE_NAME) return; // already stood up
    nodes.push({ name: UP_NODE_NAME, rotation: [...Z_UP_TO_Y_UP], children: roots });
    scene.nodes = [nodes.length - 1];
  });
  let text = new TextEncoder().encode(JSON.stringify(json));
  const padded = new Uint8Array((text.byteLength + 3) & ~3).fill(0x20); // JSON chunks pad with spaces
  padded.set(text);
  text = padded;
  const rest = glb.subarray(jsonEnd); // the BIN chunk (header, data, padding) untouched
  const out = new Uint8Array(HEADER + 8 + text.byteLength + rest.byteLength);
  const view = new DataView(out.buffer);
  out.set(glb.subarray(0, HEADER));
  view.setUint32(8, out.byteLength, true);
  view.setUint32(HEADER, text.byteLength, true);
  view.setUint32(HEADER + 4, CHUNK_JSON, true);
  out.set(text, HEADER + 8);
  out.set(rest, HEADER + 8 + text.byteLength);
  return out;
}

// What the node-only checks (glb_compression.mjs, rig_glb.mjs) share: their --key value
// arguments, the viewer's node_modules (the Khronos validator, three.js and its GLTFLoader),
// and a GLB's two chunks.
import { mkdirSync } from "node:fs";
import { createRequire } from "node:module";
import { join, resolve } from "node:path";
import { pathToFileURL } from "node:url";

/** `--key value` pairs of argv; each of `required` must be there (made absolute); --out is created. */
export function cliArgs(required) {
  const args = Object.fromEntries(
    process.argv.slice(2).reduce((a, v, i, all) => (i % 2 === 0 ? [...a, [v.replace(/^--/, ""), all[i + 1]]] : a), []),
  );
  for (const k of required) {
    if (!args[k]) throw new Error(`--${k} is required`);
    args[k] = resolve(args[k]);
  }
  if (args.out) mkdirSync(args.out, { recursive: true });
  return args;
}

/** The viewer's modules: require (CommonJS, e.g. gltf-validator), THREE and GLTFLoader. */
export async function viewerModules(viewerDir) {
  const modules = join(viewerDir, "node_modules");
  const require = createRequire(join(viewerDir, "package.json"));
  const THREE = await import(pathToFileURL(join(modules, "three/build/three.module.js")).href);
  const { GLTFLoader } = await import(pathToFileURL(join(modules, "three/examples/jsm/loaders/GLTFLoader.js")).href);
  return { modules, require, THREE, GLTFLoader };
}

/** A GLB's JSON document and BIN chunk (a view into `bytes`). */
export function splitGlb(bytes) {
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const jsonLength = dv.getUint32(12, true);
  const doc = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  const at = 20 + jsonLength;
  const bin = bytes.subarray(at + 8, at + 8 + dv.getUint32(at, true));
  return { doc, bin };
}

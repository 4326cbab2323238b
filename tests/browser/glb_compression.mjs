// Compressed GLB export (GetMesh glb_compression, CLI --glb-compression) checked by the tools a
// user of the files has (node; no browser, no server: the CLI runs the service in-process):
//   - the Khronos glTF validator: 0 errors, 0 warnings for none and quantized; for meshopt the
//     validator does not know EXT_meshopt_compression (npm's latest, 2.0.0-dev.3.10, says so as
//     an info), so the file is also decoded with npm meshoptimizer's decodeGltfBuffer into its
//     uncompressed twin, which must validate clean and carry exactly the quantized file's vertex
//     bytes;
//   - three.js's GLTFLoader (with setMeshoptDecoder, as the viewer would): every vertex's world
//     position within the stated grid error of the float32 file, normals within int8's, the
//     same triangles in the same order (meshopt may start a triangle at another corner).
// Prints bytes per vertex for each encoding.
// Usage: node glb_compression.mjs --cli PATH/hdeform --data DIR --viewer DIR --out DIR
import { execFileSync } from "node:child_process";
import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { pathToFileURL } from "node:url";
import { cliArgs, splitGlb, viewerModules } from "./node_tools.mjs";

const args = cliArgs(["cli", "data", "viewer", "out"]);
const { modules, require, THREE, GLTFLoader } = await viewerModules(args.viewer);
const validator = require("gltf-validator");
const { MeshoptDecoder } = await import(pathToFileURL(join(modules, "meshoptimizer/meshopt_decoder.mjs")).href);
await MeshoptDecoder.ready;

let failures = 0;
const check = (ok, what) => {
  console.log(`${ok ? "ok  " : "FAIL"} ${what}`);
  if (!ok) failures++;
};

// ---- GLB container ---------------------------------------------------------------------------
function joinGlb(doc, bin) {
  const pad = (n) => (n + 3) & ~3;
  const json = new TextEncoder().encode(JSON.stringify(doc));
  const jl = pad(json.length), bl = pad(bin.length);
  const out = new Uint8Array(12 + 8 + jl + 8 + bl);
  const dv = new DataView(out.buffer);
  out.set(new TextEncoder().encode("glTF"), 0);
  dv.setUint32(4, 2, true);
  dv.setUint32(8, out.length, true);
  dv.setUint32(12, jl, true);
  out.set(new TextEncoder().encode("JSON"), 16);
  out.fill(0x20, 20, 20 + jl);
  out.set(json, 20);
  dv.setUint32(20 + jl, bl, true);
  out.set(new TextEncoder().encode("BIN\0"), 24 + jl);
  out.set(bin, 28 + jl);
  return out;
}

// The meshopt file's uncompressed twin: every compressed view decoded into one plain buffer.
function decodeMeshopt(bytes) {
  const { doc, bin } = splitGlb(bytes);
  const parts = [];
  let size = 0;
  const views = doc.bufferViews.map((v) => {
    const e = v.extensions?.EXT_meshopt_compression;
    let data;
    if (e) {
      data = new Uint8Array(e.count * e.byteStride);
      MeshoptDecoder.decodeGltfBuffer(data, e.count, e.byteStride, bin.subarray(e.byteOffset, e.byteOffset + e.byteLength), e.mode, e.filter ?? "NONE");
    } else {
      data = bin.slice(v.byteOffset, v.byteOffset + v.byteLength);
    }
    const { extensions, ...plain } = v;
    const out = { ...plain, buffer: 0, byteOffset: size };
    parts.push(data);
    size += (data.length + 3) & ~3;
    return out;
  });
  const merged = new Uint8Array(size);
  views.forEach((v, i) => merged.set(parts[i], v.byteOffset));
  const twin = {
    ...doc,
    extensionsUsed: doc.extensionsUsed.filter((x) => x !== "EXT_meshopt_compression"),
    extensionsRequired: doc.extensionsRequired.filter((x) => x !== "EXT_meshopt_compression"),
    buffers: [{ byteLength: size }],
    bufferViews: views,
  };
  return { glb: joinGlb(twin, merged), views: parts };
}
function plainViews(bytes) {
  const { doc, bin } = splitGlb(bytes);
  return doc.bufferViews.map((v) => bin.slice(v.byteOffset, v.byteOffset + v.byteLength));
}

// `expectedInfo(m)`: an info message the file is allowed (none by default).
async function validate(bytes, what, expectedInfo = () => false) {
  const report = await validator.validateBytes(bytes);
  const { numErrors, numWarnings } = report.issues;
  const unexpected = report.issues.messages.filter((m) => !(m.severity >= 2 && expectedInfo(m)));
  check(numErrors === 0 && numWarnings === 0 && unexpected.length === 0,
    `${what}: Khronos validator ${numErrors} errors, ${numWarnings} warnings, ${report.issues.numInfos} infos` +
      (unexpected.length ? ` (${unexpected.slice(0, 3).map((m) => `${m.code} ${m.pointer ?? ""}`).join("; ")})` : ""));
}

// World-space positions, normals and triangles as three.js loads them.
async function load(bytes) {
  const loader = new GLTFLoader();
  loader.setMeshoptDecoder(MeshoptDecoder);
  const gltf = await loader.parseAsync(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), "");
  gltf.scene.updateMatrixWorld(true);
  let mesh;
  gltf.scene.traverse((o) => { if (o.isMesh) mesh = o; });
  const g = mesh.geometry;
  const p = new THREE.Vector3(), n = new THREE.Vector3();
  const normalMatrix = new THREE.Matrix3().getNormalMatrix(mesh.matrixWorld);
  const count = g.attributes.position.count;
  const P = new Float64Array(3 * count), N = new Float64Array(3 * count);
  for (let i = 0; i < count; i++) {
    p.fromBufferAttribute(g.attributes.position, i).applyMatrix4(mesh.matrixWorld);
    n.fromBufferAttribute(g.attributes.normal, i).applyMatrix3(normalMatrix).normalize();
    P.set([p.x, p.y, p.z], 3 * i);
    N.set([n.x, n.y, n.z], 3 * i);
  }
  // Triangles rotated to start at their smallest id: meshopt's index codec may rotate them.
  const idx = g.index.array, T = [];
  for (let t = 0; t < idx.length; t += 3) {
    const tri = [idx[t], idx[t + 1], idx[t + 2]];
    const k = tri.indexOf(Math.min(...tri));
    T.push(`${tri[k]},${tri[(k + 1) % 3]},${tri[(k + 2) % 3]}`);
  }
  return { P, N, T: T.join(" "), count };
}

// ---- the cases -------------------------------------------------------------------------------
const BS = join(args.data, "botsch-sorkine");
const cases = [
  { name: "cactus", argv: ["cactus", "--sel", join(BS, "cactus.sel"), "--def", join(BS, "cactus.def")] },
  { name: "hand", argv: [join(args.data, "models/hand.off"), "--fixed", "half:0,-1,0,0", "--handle", "half:0,1,0,0.05", "--translate", "0.01,0.02,0"] },
];
for (const c of cases) {
  const files = {};
  for (const enc of ["none", "quantized", "meshopt"]) {
    const path = join(args.out, `${c.name}-${enc}.glb`);
    execFileSync(args.cli, ["deform", ...c.argv, "--glb-compression", enc, "-o", path], { stdio: ["ignore", "ignore", "inherit"] });
    files[enc] = new Uint8Array(readFileSync(path));
  }
  await validate(files.none, `${c.name} none`);
  await validate(files.quantized, `${c.name} quantized`);
  // The validator cannot read the extension, so it also sees the BIN buffer as unused when
  // every view is compressed (only the extension points into it).
  await validate(files.meshopt, `${c.name} meshopt`, (m) =>
    (m.code === "UNSUPPORTED_EXTENSION" && m.message.includes("'EXT_meshopt_compression'")) ||
    (m.code === "UNUSED_OBJECT" && m.pointer === "/buffers/0"));
  const twin = decodeMeshopt(files.meshopt);
  await validate(twin.glb, `${c.name} meshopt decoded by npm meshoptimizer`);
  const q = plainViews(files.quantized);
  check(Buffer.compare(q[0], twin.views[0]) === 0 && Buffer.compare(q[1], twin.views[1]) === 0,
    `${c.name} meshopt: decoded positions and normals are the quantized file's bytes`);

  const ref = await load(files.none);
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity], mag = 0;
  for (let i = 0; i < ref.P.length; i++) {
    lo[i % 3] = Math.min(lo[i % 3], ref.P[i]);
    hi[i % 3] = Math.max(hi[i % 3], ref.P[i]);
    mag = Math.max(mag, Math.abs(ref.P[i]));
  }
  const extent = Math.max(...hi.map((h, k) => h - lo[k]));
  // The stated grid error, plus float32 rounding of the reference and of the renderer's math.
  const bound = extent / 131070 + 8 * 2 ** -24 * (mag + extent);
  for (const enc of ["quantized", "meshopt"]) {
    const got = await load(files[enc]);
    let dp = 0, dn = 0;
    for (let i = 0; i < ref.P.length; i++) dp = Math.max(dp, Math.abs(got.P[i] - ref.P[i]));
    for (let i = 0; i < ref.count; i++) {
      const dot = ref.N[3 * i] * got.N[3 * i] + ref.N[3 * i + 1] * got.N[3 * i + 1] + ref.N[3 * i + 2] * got.N[3 * i + 2];
      dn = Math.max(dn, Math.acos(Math.min(1, dot)) * 180 / Math.PI);
    }
    check(got.count === ref.count && got.T === ref.T && dp <= bound && dn <= 1.0,
      `${c.name} ${enc} in three.js: ${got.count} vertices, same triangles; position error ${dp.toExponential(2)} ≤ ${bound.toExponential(2)} (extent / 131070), normals within ${dn.toFixed(2)}° (≤ 1°)`);
  }
  const per = (b) => (b.length / ref.count).toFixed(1);
  console.log(`     ${c.name} (${ref.count} vertices, ${ref.T.split(" ").length} triangles): none ${files.none.length} B (${per(files.none)} B/vertex), quantized ${files.quantized.length} B (${per(files.quantized)}), meshopt ${files.meshopt.length} B (${per(files.meshopt)})`);
}

// A glTF upload is written back as itself with the deformed positions (rewrite_gltf): also
// when its scene has no nodes and a material has no properties (tinygltf would write those
// objects as null, which no reader accepts). Made from the cactus GLB above.
{
  const { doc, bin } = splitGlb(new Uint8Array(readFileSync(join(args.out, "cactus-none.glb"))));
  doc.scenes = [{}];
  doc.materials = [{}];
  doc.meshes[0].primitives[0].material = 0;
  const input = join(args.out, "nodeless.glb");
  writeFileSync(input, joinGlb(doc, bin));
  const output = join(args.out, "nodeless-deformed.glb");
  execFileSync(args.cli, ["deform", input, ...cases[0].argv.slice(1), "-o", output],
    { stdio: ["ignore", "ignore", "inherit"] });
  const written = new Uint8Array(readFileSync(output));
  // Nodes no scene shows are reported as unused (infos), as in the input.
  await validate(written, "a glTF upload whose scene has no nodes, deformed", (m) => m.code === "UNUSED_OBJECT");
  const back = splitGlb(written).doc;
  check(JSON.stringify(back.scenes) === "[{}]" && JSON.stringify(back.materials) === "[{}]",
    `its scene and material stay {} (${JSON.stringify(back.scenes)}, ${JSON.stringify(back.materials)})`);
}

// Bad requests name the problem (and write nothing).
const bad = (argv, expect, what) => {
  let out = "";
  try {
    execFileSync(args.cli, argv, { stdio: ["ignore", "pipe", "pipe"] });
  } catch (e) {
    out = `${e.stdout}${e.stderr}`;
  }
  check(out.includes(expect), `${what}: ${out.trim().split("\n").pop()}`);
};
bad(["deform", ...cases[0].argv, "--glb-compression", "meshopt", "-o", join(args.out, "x.obj")],
  "glb_compression applies to GLB only", "a compression for OBJ output is refused");
bad(["deform", ...cases[0].argv, "--glb-compression", "draco", "-o", join(args.out, "x.glb")],
  "--glb-compression", "an unknown compression is refused by the CLI");
bad(["deform", join(args.out, "cactus-quantized.glb"), "--fixed", "half:0,0,-1,0", "--handle", "half:0,0,1,0", "-o", join(args.out, "y.glb")],
  "requires the glTF extension KHR_mesh_quantization", "a quantized GLB uploaded back is refused by name");

console.log(failures ? `${failures} check(s) failed` : "all checks passed");
process.exit(failures ? 1 : 0);

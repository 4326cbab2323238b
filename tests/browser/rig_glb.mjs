// Rig export (ExportRig, `hdeform rig`) checked by the tools a user of the file has (node; no
// browser, no server: the CLI runs the service in-process), on the cactus bend animated over
// 2 s (keys: rest at 0 s, the bend at 2 s), z-up:
//   - the Khronos glTF validator: 0 errors, 0 warnings, for 4 and for 8 influences;
//   - the skin's bytes: every vertex's normalized weights sum to exactly 65535, joints exist;
//   - three.js (GLTFLoader, SkinnedMesh, AnimationMixer) plays the animation: at each key time
//     its skinned vertices equal LBS computed here in double from the file's own weights,
//     inverse bind matrices and key TRS (within 1e-6 of the bbox diagonal); at 0 s they are
//     the input mesh (float32 rounding); at 2 s their distance to the exact deformation
//     (`hdeform deform … -o exact.obj`) is the max / rms the server's report gives.
// Prints the sizes and the report.
// Usage: node rig_glb.mjs --cli PATH/hdeform --data DIR --viewer DIR --out DIR
import { execFileSync } from "node:child_process";
import { readFileSync } from "node:fs";
import { join } from "node:path";
import { cliArgs, splitGlb, viewerModules } from "./node_tools.mjs";

const args = cliArgs(["cli", "data", "viewer", "out"]);
const { require, THREE, GLTFLoader } = await viewerModules(args.viewer);
const validator = require("gltf-validator");

let failures = 0;
const check = (ok, what) => {
  console.log(`${ok ? "ok  " : "FAIL"} ${what}`);
  if (!ok) failures++;
};

const bs = join(args.data, "botsch-sorkine");
const constraints = ["--sel", join(bs, "cactus.sel"), "--def", join(bs, "cactus.def")];
const run = (...a) => execFileSync(args.cli, a, { encoding: "utf8" });
const exactObj = join(args.out, "exact.obj");
run("deform", "cactus", ...constraints, "-o", exactObj);
const exact = readFileSync(exactObj, "utf8").split("\n").filter((l) => l.startsWith("v "))
  .map((l) => l.split(/\s+/).slice(1, 4).map(Number));

function accessorArray(doc, bin, index) {
  const a = doc.accessors[index];
  const v = doc.bufferViews[a.bufferView];
  const width = { SCALAR: 1, VEC3: 3, VEC4: 4, MAT4: 16 }[a.type];
  const Type = { 5121: Uint8Array, 5123: Uint16Array, 5125: Uint32Array, 5126: Float32Array }[a.componentType];
  const offset = bin.byteOffset + (v.byteOffset ?? 0) + (a.byteOffset ?? 0);
  return new Type(bin.buffer.slice(offset, offset + a.count * width * Type.BYTES_PER_ELEMENT));
}

// z-up model → glTF y-up world: (x, y, z) → (x, z, −y); the inverse brings three's world back.
const toModel = (p) => [p.x, -p.z, p.y];

async function checkRig(influences) {
  const glbPath = join(args.out, `rig-${influences}.glb`);
  const csvPath = join(args.out, `rig-${influences}.csv`);
  const printed = run("rig", "cactus", ...constraints, "-o", glbPath, "--animate", "2", "--up", "z",
                      "--influences", String(influences), "--report", csvPath);
  process.stdout.write(printed);
  const bytes = new Uint8Array(readFileSync(glbPath));
  const report = await validator.validateBytes(bytes);
  const { numErrors, numWarnings, numInfos } = report.issues;
  const messages = report.issues.messages.filter((m) => m.severity <= 1).slice(0, 5).map((m) => `${m.code}: ${m.message}`);
  check(numErrors === 0 && numWarnings === 0,
        `${influences} influences: glTF validator ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos (${bytes.length} bytes)${messages.length ? " " + messages.join("; ") : ""}`);

  const { doc, bin } = splitGlb(bytes);
  const prim = doc.meshes[0].primitives[0];
  const P = accessorArray(doc, bin, prim.attributes.POSITION);
  const n = P.length / 3;
  const sets = influences / 4;
  const J = [], W = [];
  for (let s = 0; s < sets; s++) {
    J.push(accessorArray(doc, bin, prim.attributes[`JOINTS_${s}`]));
    W.push(accessorArray(doc, bin, prim.attributes[`WEIGHTS_${s}`]));
  }
  const skin = doc.skins[0];
  let sums = 0, badJoint = 0;
  for (let v = 0; v < n; v++) {
    let sum = 0;
    for (let s = 0; s < sets; s++) for (let k = 0; k < 4; k++) {
      sum += W[s][4 * v + k];
      if (J[s][4 * v + k] >= skin.joints.length) badJoint++;
    }
    if (sum === 65535) sums++;
  }
  check(sums === n && badJoint === 0, `${influences} influences: ${sums}/${n} vertices' weights sum to exactly 65535; ${badJoint} joint indices out of range`);

  // LBS in double from the file alone: joint world = up · root · TRS(key), times its IBM.
  const ibm = accessorArray(doc, bin, skin.inverseBindMatrices);
  const anim = doc.animations[0];
  const times = accessorArray(doc, bin, anim.samplers[0].input);
  const lbsAt = (keyIndex) => {
    const mats = skin.joints.map((node, j) => {
      const m = new THREE.Matrix4();
      if (j > 0) {
        const trs = {};
        for (const ch of anim.channels.filter((c) => c.target.node === node)) {
          const out = accessorArray(doc, bin, anim.samplers[ch.sampler].output);
          const w = ch.target.path === "rotation" ? 4 : 3;
          trs[ch.target.path] = Array.from(out.slice(keyIndex * w, keyIndex * w + w));
        }
        m.compose(new THREE.Vector3(...trs.translation), new THREE.Quaternion(...trs.rotation), new THREE.Vector3(...trs.scale));
      }
      return m.multiply(new THREE.Matrix4().fromArray(Array.from(ibm.slice(16 * j, 16 * j + 16))));
    });
    const out = new Float64Array(3 * n);
    for (let v = 0; v < n; v++) {
      const x = new THREE.Vector3(P[3 * v], P[3 * v + 1], P[3 * v + 2]);
      for (let s = 0; s < sets; s++) for (let k = 0; k < 4; k++) {
        const w = W[s][4 * v + k] / 65535;
        if (w === 0) continue;
        const y = x.clone().applyMatrix4(mats[J[s][4 * v + k]]);
        out[3 * v] += w * y.x; out[3 * v + 1] += w * y.y; out[3 * v + 2] += w * y.z;
      }
    }
    return out;
  };

  // three.js plays it.
  const loader = new GLTFLoader();
  const gltf = await loader.parseAsync(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), "");
  let mesh;
  gltf.scene.traverse((o) => { if (o.isSkinnedMesh) mesh = o; });
  check(mesh !== undefined && gltf.animations.length === 1, `${influences} influences: three.js loads a SkinnedMesh and ${gltf.animations.length} animation`);
  if (!mesh) return;
  const mixer = new THREE.AnimationMixer(gltf.scene);
  // Played once and held at its end: a repeating action wraps t = duration back to 0.
  const action = mixer.clipAction(gltf.animations[0]);
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;
  action.play();
  let xmin = [Infinity, Infinity, Infinity], xmax = [-Infinity, -Infinity, -Infinity];
  for (let v = 0; v < n; v++) for (let c = 0; c < 3; c++) {
    xmin[c] = Math.min(xmin[c], P[3 * v + c]); xmax[c] = Math.max(xmax[c], P[3 * v + c]);
  }
  const diag = Math.hypot(xmax[0] - xmin[0], xmax[1] - xmin[1], xmax[2] - xmin[2]);
  const rows = readFileSync(csvPath, "utf8").trim().split("\n").slice(1).map((l) => l.split(","));
  for (let k = 0; k < times.length; k++) {
    mixer.setTime(times[k]);
    gltf.scene.updateMatrixWorld(true);
    mesh.skeleton.update();
    const lbs = lbsAt(k);
    let vsLbs = 0, vsInput = 0, max = 0, sq = 0;
    const p = new THREE.Vector3();
    for (let v = 0; v < n; v++) {
      mesh.getVertexPosition(v, p);
      const m = toModel(p);
      for (let c = 0; c < 3; c++) {
        vsLbs = Math.max(vsLbs, Math.abs(m[c] - lbs[3 * v + c]));
        vsInput = Math.max(vsInput, Math.abs(m[c] - P[3 * v + c]));
      }
      const d = Math.hypot(m[0] - exact[v][0], m[1] - exact[v][1], m[2] - exact[v][2]);
      max = Math.max(max, d);
      sq += d * d;
    }
    check(vsLbs <= 1e-6 * diag, `${influences} influences, t=${times[k]} s: three.js skinned vertices vs LBS from the file's data: max ${(vsLbs / diag).toExponential(2)} of the diagonal (≤ 1e-6)`);
    if (times[k] === 0) check(vsInput <= 1e-6 * diag, `${influences} influences, t=0 s (rest key): skinned mesh vs input max ${(vsInput / diag).toExponential(2)} of the diagonal (float32 rounding)`);
    else {
      const row = rows.find((r) => r[0] === "key" && Number(r[1]) === times[k]);
      const rmax = Number(row?.[2]), rrms = Number(row?.[3]);
      const tmax = max / diag, trms = Math.sqrt(sq / n) / diag;
      check(row && Math.abs(tmax - rmax) <= 1e-6 && Math.abs(trms - rrms) <= 1e-6,
            `${influences} influences, t=${times[k]} s: three.js's distance to the exact solve max ${tmax.toExponential(4)} rms ${trms.toExponential(4)} = the server's report ${rmax.toExponential(4)} / ${rrms.toExponential(4)} (within 1e-6)`);
    }
  }
}

await checkRig(4);
await checkRig(8);
if (failures > 0) {
  console.log(`${failures} check(s) failed`);
  process.exit(1);
}
console.log("rig GLB: all checks passed");

// Issue 37's pure parts: numerical noise read as 0 and the chart's floor, the empty History's
// note, one handle numbering, editor colours apart from region colours, and the GLB wrapped
// for glTF's y-up (its BIN chunk untouched; three.js's GLTFLoader stands the model up).
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { describe, it } from "node:test";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { SessionSchema } from "../src/gen/hdeform/v1/deform_pb";
import { emptyHistoryNote } from "../src/history/empty_history";
import { handleName, labelName } from "../src/handle_names";
import { PALETTE } from "../src/multi/identity";
import { heldMessage } from "../src/multi/presence_model";
import { chartRange, denoise, MEASURE_QUANTITY, NOISE_RELATIVE, noiseFloor } from "../src/noise_floor";
import { rampPosition, scaleTop } from "../src/colormap";
import { regionColourCss } from "../src/region_colours";
import { readGlbJson, UP_NODE_NAME, withUpAxis, Z_UP_TO_Y_UP } from "../src/glb_up_axis";
import { weightsTitle } from "../src/weights/weights_view";

describe("noise floor", () => {
  it("reads values below 1e-12 of the mesh's scale as 0", () => {
    const diag = 3;
    const eFloor = noiseFloor(MEASURE_QUANTITY.e, diag);
    assert.equal(eFloor, NOISE_RELATIVE * 9);
    assert.equal(denoise(1.41e-27, eFloor), 0); // E of an undeformed pose
    assert.equal(denoise(1e-3, eFloor), 1e-3);
    assert.equal(denoise(3e-16, noiseFloor("ratio", diag)), 0);
    assert.equal(denoise(-3e-16, noiseFloor("ratio", diag)), 0);
    assert.equal(noiseFloor(MEASURE_QUANTITY.eAreaPct, diag), 1e-10);
    assert.equal(noiseFloor(MEASURE_QUANTITY.flips, diag), 0);
  });
  it("never scales a chart below the floor: a flat noisy curve is flat", () => {
    const floor = noiseFloor("ratio", 1);
    // 1e-16 noise: flat at 0, the axis [0, 1] (not 0 … 1e-16).
    assert.deepEqual(chartRange([1e-16, 3e-16, 2e-17, 0], floor), [0, 1]);
    // A constant with noise on it: a band around the value, far wider than the noise.
    const [lo, hi] = chartRange([5, 5 + 1e-14, 5 - 1e-14], floor);
    assert.ok(lo < 4.6 && hi > 5.4, `${lo} … ${hi}`);
    // A real curve keeps its own range.
    assert.deepEqual(chartRange([0.1, 0.5, 0.3], floor), [0.1, 0.5]);
  });
  it("colours noise energies as 0 and never tops the ramp below the floor", () => {
    const noise = new Float32Array([1e-27, 3e-20, 2e-16]);
    assert.equal(scaleTop("linear", noise, 0), 1);
    assert.equal(rampPosition(2e-16, scaleTop("linear", noise, 0)), 0);
    assert.equal(scaleTop("truncated", noise, 1e-25), NOISE_RELATIVE); // a 1e-25 threshold paints no noise
    assert.equal(rampPosition(3e-20, scaleTop("truncated", noise, 1e-25)), 0);
    assert.equal(scaleTop("linear", new Float32Array([0.5, 2]), 0), 2);
  });
});

describe("empty History", () => {
  it("says why a changed session has no steps (a restart or an import), and not for a new one", () => {
    const fresh = create(SessionSchema, { name: "sessions/a", version: 1n });
    assert.match(emptyHistoryNote(fresh), /No changes yet/);
    const restored = create(SessionSchema, { name: "sessions/a", version: 7n, constrained: true });
    assert.match(emptyHistoryNote(restored), /import, or at a server restart/);
    const moved = create(SessionSchema, { name: "sessions/a", transforms: [{ translation: { x: 0.1, y: 0, z: 0 } }] });
    assert.match(emptyHistoryNote(moved), /import, or at a server restart/);
  });
});

describe("handle numbering", () => {
  it("is 0-based everywhere, as the server's messages", () => {
    assert.equal(labelName(1), "Handle 0"); // region label 1 is handle index 0
    assert.equal(labelName(0), "Fixed");
    assert.equal(handleName(2), "Handle 2");
    assert.equal(heldMessage(0, "Alice"), "Handle 0 is being moved by Alice");
    assert.equal(weightsTitle(0), "Handle 0 weight (0 = fixed, 1 = moves with handle)");
  });
});

/** CIE L*a*b* of a #rrggbb colour (D65). */
function lab(hex: string): [number, number, number] {
  const lin = (c: number) => (c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);
  const [r, g, b] = [1, 3, 5].map((i) => lin(parseInt(hex.slice(i, i + 2), 16) / 255));
  const f = (t: number) => (t > 216 / 24389 ? Math.cbrt(t) : ((24389 / 27) * t + 16) / 116);
  const x = f((0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047);
  const y = f(0.2126 * r + 0.7152 * g + 0.0722 * b);
  const z = f((0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883);
  return [116 * y - 16, 500 * (x - y), 200 * (y - z)];
}
const deltaE = (a: string, b: string) => Math.hypot(...lab(a).map((v, k) => v - lab(b)[k]));

describe("editor colours", () => {
  it("stay apart from every region colour (a held handle is drawn in its holder's)", () => {
    const regions = [0, 1, 2, 3, 4, 5, 6].map(regionColourCss);
    assert.ok(!PALETTE.includes("#aed581"));
    for (const c of PALETTE) for (const r of regions) assert.ok(deltaE(c, r) >= 34, `${c} vs region ${r}: ΔE ${deltaE(c, r).toFixed(1)}`);
    for (const c of PALETTE) for (const d of PALETTE) if (c !== d) assert.ok(deltaE(c, d) >= 20, `${c} vs ${d}`);
  });
});

/** A GLB of one triangle: a node with a mesh, positions in a BIN chunk (as the server writes). */
function triangleGlb(): Uint8Array {
  const pos = new Float32Array([0, 0, 0, 1, 0, 0, 0, 0, 1]);
  const bin = new Uint8Array(pos.buffer); // 36 bytes: 4-aligned
  const gltf = {
    asset: { version: "2.0" },
    buffers: [{ byteLength: bin.byteLength }],
    bufferViews: [{ buffer: 0, byteOffset: 0, byteLength: bin.byteLength }],
    accessors: [{ bufferView: 0, componentType: 5126, count: 3, type: "VEC3", min: [0, 0, 0], max: [1, 0, 1] }],
    meshes: [{ primitives: [{ attributes: { POSITION: 0 } }] }],
    nodes: [{ mesh: 0, name: "mesh" }],
    scenes: [{ nodes: [0] }],
    scene: 0,
  };
  let json = new TextEncoder().encode(JSON.stringify(gltf));
  const padded = new Uint8Array((json.length + 3) & ~3).fill(0x20);
  padded.set(json);
  json = padded;
  const out = new Uint8Array(12 + 8 + json.length + 8 + bin.length);
  const v = new DataView(out.buffer);
  v.setUint32(0, 0x46546c67, true);
  v.setUint32(4, 2, true);
  v.setUint32(8, out.length, true);
  v.setUint32(12, json.length, true);
  v.setUint32(16, 0x4e4f534a, true);
  out.set(json, 20);
  v.setUint32(20 + json.length, bin.length, true);
  v.setUint32(24 + json.length, 0x004e4942, true);
  out.set(bin, 28 + json.length);
  return out;
}

describe("GLB up axis", () => {
  it("y: the GLB as it is", () => {
    const glb = triangleGlb();
    assert.equal(withUpAxis(glb, "y"), glb);
  });
  it("z: a root node rotating +z to +y over the old roots; the BIN chunk byte for byte", async () => {
    const glb = triangleGlb();
    const { jsonEnd } = readGlbJson(glb);
    const out = withUpAxis(glb, "z");
    const view = new DataView(out.buffer, out.byteOffset, out.byteLength);
    assert.equal(view.getUint32(0, true), 0x46546c67);
    assert.equal(view.getUint32(8, true), out.byteLength);
    assert.equal(out.byteLength % 4, 0);
    const { json, jsonEnd: outJsonEnd } = readGlbJson(out);
    assert.equal(outJsonEnd % 4, 0);
    assert.deepEqual(out.subarray(outJsonEnd), glb.subarray(jsonEnd)); // BIN chunk header, data, padding
    const root = json.scenes![0].nodes![0];
    assert.equal(json.nodes![root].name, UP_NODE_NAME);
    assert.deepEqual(json.nodes![root].rotation, [...Z_UP_TO_Y_UP]);
    assert.deepEqual(json.nodes![root].children, [0]);
    assert.deepEqual(withUpAxis(out, "z"), out.slice(), "not wrapped twice");
    // three.js reads it: the model's +z vertex stands at +y in the scene.
    const buffer = out.buffer.slice(out.byteOffset, out.byteOffset + out.byteLength) as ArrayBuffer;
    const gltf = await new GLTFLoader().parseAsync(buffer, "");
    gltf.scene.updateMatrixWorld(true);
    let mesh: THREE.Mesh | null = null;
    gltf.scene.traverse((o) => {
      if ((o as THREE.Mesh).isMesh) mesh = o as THREE.Mesh;
    });
    assert.ok(mesh);
    const m = mesh as THREE.Mesh;
    const top = new THREE.Vector3().fromBufferAttribute(m.geometry.getAttribute("position") as THREE.BufferAttribute, 2);
    assert.deepEqual(top.toArray(), [0, 0, 1], "the vertices keep the model's coordinates");
    const world = top.applyMatrix4(m.matrixWorld);
    assert.ok(world.distanceTo(new THREE.Vector3(0, 1, 0)) < 1e-6, `+z → ${world.toArray()}`);
  });
});

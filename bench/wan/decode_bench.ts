// The viewer's MESHOPT frame decode in node, per stage: meshopt's vertex codec (WebAssembly)
// and the dequantization (web-viewer/src/decode/quantized.ts) into fresh and into reused
// arrays (as the decode worker now does), against the per-vertex octahedral decode it
// replaced, interleaved in one process. Not a CI test: it reports.
//
//   web-viewer/node_modules/.bin/tsx bench/wan/decode_bench.ts [--vertices 100000,84000] [--repeats 300]
//
// The frame is the bench's capsule (bench/wan/capsule.ts) quantized the server's way: 3 ×
// uint16 positions in the bounding box, 2 × int8 octahedral normals.
import { parseArgs } from "node:util";
import { MeshoptEncoder } from "../../web-viewer/node_modules/meshoptimizer/meshopt_encoder.js";
import { meshoptReady, unpackMeshopt } from "../../web-viewer/src/decode/meshopt";
import { dequantizeVertices, octahedralDecode, type QuantizedFrame } from "../../web-viewer/src/decode/quantized";
import { capsule } from "./capsule";

const { values } = parseArgs({ options: { vertices: { type: "string", default: "100000,84000" }, repeats: { type: "string", default: "300" } } });
const repeats = Number(values.repeats);
function quantizedCapsule(target: number): { n: number; packed: Uint8Array; frame: QuantizedFrame } {
  const P = capsule(target).positions;
  const n = P.length / 3;
  const lo = [0, 1, 2].map((k) => P.filter((_, j) => j % 3 === k).reduce((a, b) => Math.min(a, b)));
  const hi = [0, 1, 2].map((k) => P.filter((_, j) => j % 3 === k).reduce((a, b) => Math.max(a, b)));
  const bytes = new Uint8Array(8 * n);
  const view = new DataView(bytes.buffer);
  for (let i = 0; i < n; i++) {
    for (let k = 0; k < 3; k++) view.setUint16(8 * i + 2 * k, Math.round(((P[3 * i + k] - lo[k]) / (hi[k] - lo[k])) * 65535), true);
    const r = Math.hypot(P[3 * i], P[3 * i + 1]) || 1; // the tube's outward normal, z = 0
    view.setInt8(8 * i + 6, Math.round((P[3 * i] / r) * 0.5 * 127));
    view.setInt8(8 * i + 7, Math.round((P[3 * i + 1] / r) * 0.5 * 127));
  }
  const vec = (a: number[]) => ({ x: a[0], y: a[1], z: a[2] });
  const frame = { vertices: new Uint8Array(0), positionBox: { min: vec(lo), max: vec(hi) }, energies: new Uint8Array(0), energiesMax: 0 } as unknown as QuantizedFrame;
  return { n, packed: MeshoptEncoder.encodeVertexBuffer(bytes, n, 8), frame };
}

/** The dequantization before the look-up table: one octahedralDecode per vertex. */
function perVertex(bytes: Uint8Array, n: number, frame: QuantizedFrame): Float32Array[] {
  const b = frame.positionBox!;
  const lo = [b.min!.x, b.min!.y, b.min!.z];
  const step = [b.max!.x - lo[0], b.max!.y - lo[1], b.max!.z - lo[2]].map((e) => e / 65535);
  const q = new Uint16Array(bytes.buffer, bytes.byteOffset, 4 * n);
  const s8 = new Int8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const positions = new Float32Array(3 * n);
  const normals = new Float32Array(3 * n);
  for (let i = 0; i < n; i++) {
    const w = 4 * i;
    positions[3 * i] = lo[0] + q[w] * step[0];
    positions[3 * i + 1] = lo[1] + q[w + 1] * step[1];
    positions[3 * i + 2] = lo[2] + q[w + 2] * step[2];
    octahedralDecode(s8[2 * w + 6], s8[2 * w + 7], normals, 3 * i);
  }
  return [positions, normals];
}

async function main(): Promise<void> {
  await meshoptReady;
  await MeshoptEncoder.ready;
  const median = (a: number[]) => [...a].sort((x, y) => x - y)[a.length >> 1];
  console.log("| vertices | meshopt bytes | unpack (meshopt codec) | dequantize, table | … into reused arrays | dequantize, per vertex | unpack + dequantize (reused) |");
  console.log("|---|---|---|---|---|---|---|");
  for (const target of values.vertices!.split(",").map(Number)) {
    const { n, packed, frame } = quantizedCapsule(target);
    const t = { unpack: [] as number[], table: [] as number[], reused: [] as number[], perVertex: [] as number[] };
    const out = { positions: new Float32Array(3 * n), normals: new Float32Array(3 * n) };
    const into = new Uint8Array(8 * n); // as decodeMeshopt's scratch
    for (let r = 0; r < repeats + 50; r++) {
      const t0 = performance.now();
      const raw = unpackMeshopt(packed, n, into);
      const t1 = performance.now();
      const got = dequantizeVertices(raw, n, frame);
      const t2 = performance.now();
      const old = perVertex(raw, n, frame);
      const t3 = performance.now();
      dequantizeVertices(raw, n, frame, out);
      const t4 = performance.now();
      if (r === 0 && old[1].some((x, i) => x !== got.normals[i])) throw new Error("the table's normals differ from the per-vertex decode");
      if (r < 50) continue; // warm-up: V8 optimizes the loops first
      t.unpack.push(t1 - t0);
      t.table.push(t2 - t1);
      t.perVertex.push(t3 - t2);
      t.reused.push(t4 - t3);
    }
    const f = (x: number) => `${x.toFixed(2)} ms`;
    console.log(`| ${n} | ${packed.byteLength} | ${f(median(t.unpack))} | ${f(median(t.table))} | ${f(median(t.reused))} | ${f(median(t.perVertex))} | ${f(median(t.unpack.map((u, i) => u + t.reused[i])))} |`);
  }
}

void main();

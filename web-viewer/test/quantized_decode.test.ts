// QUANTIZED and MESHOPT frames: a buffer built here the way the server builds it
// (server/service/frames/frame_encoding.cpp) decodes within deform.proto's stated error bounds;
// MESHOPT decodes to exactly the QUANTIZED buffer it packs; wrong sizes and bad boxes fail
// with a clear error.
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { MeshoptEncoder } from "meshoptimizer/encoder";
import { before, describe, it } from "node:test";
import { decodeFrame, FrameDecodeError, meshoptReady } from "../src/decode/frame_decode";
import { octahedralDecode, octahedralNormals } from "../src/decode/quantized";
import { BoxSchema, FrameEncoding, FrameSchema, type Box, type Frame } from "../src/gen/hdeform/v1/deform_pb";

type QuantizedFields = Partial<Pick<Frame, "energies" | "energiesMax" | "positionBox">>;

/** A deterministic scattered point set with unit normals all around the sphere. */
function sample(n: number): { positions: Float32Array; normals: Float32Array } {
  const positions = new Float32Array(3 * n);
  const normals = new Float32Array(3 * n);
  for (let i = 0; i < n; i++) {
    positions.set([Math.sin(i * 1.7) * 3.25 - 1, Math.cos(i * 0.31) * 0.5 + 7, (i * 0.137) % 2.5], 3 * i);
    const t = Math.acos(1 - (2 * (i + 0.5)) / n); // Fibonacci sphere: every octant
    const p = i * 2.399963;
    normals.set([Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)], 3 * i);
  }
  return { positions, normals };
}

/** The server's quantization: box, 3 × uint16 positions, 2 × int8 octahedral normals. */
function quantize(positions: Float32Array, normals: Float32Array): { vertices: Uint8Array; box: Box } {
  const n = positions.length / 3;
  const lo = [0, 1, 2].map((k) => Math.min(...positions.filter((_, j) => j % 3 === k)));
  const hi = [0, 1, 2].map((k) => Math.max(...positions.filter((_, j) => j % 3 === k)));
  const vertices = new Uint8Array(8 * n);
  const view = new DataView(vertices.buffer);
  for (let i = 0; i < n; i++) {
    for (let k = 0; k < 3; k++) {
      view.setUint16(8 * i + 2 * k, Math.round(((positions[3 * i + k] - lo[k]) * 65535) / (hi[k] - lo[k])), true);
    }
    const [x, y, z] = normals.subarray(3 * i, 3 * i + 3);
    const l1 = Math.abs(x) + Math.abs(y) + Math.abs(z);
    let u = x / l1;
    let v = y / l1;
    if (z < 0) [u, v] = [(1 - Math.abs(v)) * (u >= 0 ? 1 : -1), (1 - Math.abs(u)) * (v >= 0 ? 1 : -1)];
    view.setInt8(8 * i + 6, Math.round(u * 127));
    view.setInt8(8 * i + 7, Math.round(v * 127));
  }
  const vec = (a: number[]) => ({ x: a[0], y: a[1], z: a[2] });
  return { vertices, box: create(BoxSchema, { min: vec(lo), max: vec(hi) }) };
}

function quantizeEnergies(e: number[]): { energies: Uint8Array; energiesMax: number } {
  const energiesMax = Math.fround(Math.max(...e));
  const energies = new Uint8Array(2 * e.length);
  e.forEach((x, l) => new DataView(energies.buffer).setUint16(2 * l, Math.round((x / energiesMax) * 65535), true));
  return { energies, energiesMax };
}

const N = 500;
const { positions, normals } = sample(N);
const q = quantize(positions, normals);
const energyValues = [0, 0.5, 1.25, 3.75e-3, 7];
const qe = quantizeEnergies(energyValues);

describe("decodeFrame QUANTIZED / MESHOPT", () => {
  before(() => meshoptReady);

  it("the normals' look-up table is octahedralDecode of every int8 pair, keyed as the frame's bytes", () => {
    const table = octahedralNormals();
    const bytes = new Uint8Array(2);
    const key = new Uint16Array(bytes.buffer); // the frame's fourth uint16, little-endian
    const want = new Float32Array(3);
    for (let qu = -128; qu <= 127; qu++) {
      for (let qv = -128; qv <= 127; qv++) {
        new Int8Array(bytes.buffer).set([qu, qv]);
        octahedralDecode(qu, qv, want, 0);
        const t = 3 * key[0];
        assert.deepEqual([table[t], table[t + 1], table[t + 2]], [...want], `pair (${qu}, ${qv})`);
      }
    }
  });

  it("QUANTIZED: positions, normals and energies within the proto's bounds", () => {
    const frame = create(FrameSchema, { encoding: FrameEncoding.QUANTIZED, vertices: q.vertices, positionBox: q.box, ...qe });
    const d = decodeFrame(frame, N, energyValues.length);
    const box = frame.positionBox!;
    const extent = [box.max!.x - box.min!.x, box.max!.y - box.min!.y, box.max!.z - box.min!.z];
    for (let i = 0; i < 3 * N; i++) {
      const k = i % 3;
      const bound = extent[k] / 131070 + 2 * Math.abs(positions[i]) * 2 ** -24; // + float32 rounding
      assert.ok(Math.abs(d.positions![i] - positions[i]) <= bound, `position ${i}: ${d.positions![i]} vs ${positions[i]}`);
    }
    let worst = 0;
    for (let i = 0; i < N; i++) {
      const a = normals.subarray(3 * i, 3 * i + 3);
      const b = d.normals!.subarray(3 * i, 3 * i + 3);
      assert.ok(Math.abs(Math.hypot(...b) - 1) < 1e-6, "decoded normals are unit vectors");
      const cos = Math.min(1, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
      worst = Math.max(worst, (Math.acos(cos) * 180) / Math.PI);
    }
    assert.ok(worst <= 1.2, `normal error ${worst.toFixed(3)}° > 1.2°`);
    energyValues.forEach((e, l) => {
      assert.ok(Math.abs(d.energies![l] - e) <= qe.energiesMax / 131070 + e * 2 ** -23, `energy ${l}: ${d.energies![l]} vs ${e}`);
    });
  });

  it("QUANTIZED / MESHOPT without vertices (omitted buffers) decode to nulls", () => {
    for (const encoding of [FrameEncoding.QUANTIZED, FrameEncoding.MESHOPT]) {
      const d = decodeFrame(create(FrameSchema, { encoding }), N, 3);
      assert.deepEqual(d, { positions: null, normals: null, energies: null });
    }
  });

  it("MESHOPT: decode(encode(quantized)) is the quantized decode, bit for bit", async () => {
    await MeshoptEncoder.ready;
    const packed = MeshoptEncoder.encodeVertexBuffer(q.vertices, N, 8);
    const common = { positionBox: q.box, ...qe };
    const raw = decodeFrame(create(FrameSchema, { encoding: FrameEncoding.QUANTIZED, vertices: q.vertices, ...common }), N, energyValues.length);
    const viaMeshopt = decodeFrame(create(FrameSchema, { encoding: FrameEncoding.MESHOPT, vertices: packed, ...common }), N, energyValues.length);
    assert.deepEqual(viaMeshopt, raw);
  });

  it("wrong sizes, a bad box and bad meshopt data are clear errors", () => {
    const quantized = (init: QuantizedFields) => create(FrameSchema, { encoding: FrameEncoding.QUANTIZED, vertices: q.vertices, positionBox: q.box, ...init });
    const isDecodeError = (re: RegExp) => (err: unknown) => err instanceof FrameDecodeError && re.test(err.message);
    assert.throws(
      () => decodeFrame(quantized({}), N + 1, 0),
      isDecodeError(/Frame has quantized vertices for 500 vertices; the mesh has 501 \(4000 bytes, expected 4008\)/),
    );
    assert.throws(() => decodeFrame(quantized(qe), N, 4), isDecodeError(/quantized energies for 5 triangles; the mesh has 4/));
    assert.throws(() => decodeFrame(quantized({ ...qe, energiesMax: NaN }), N, 5), isDecodeError(/energies_max must be finite/));
    const flipped = create(BoxSchema, { min: q.box.max, max: q.box.min });
    assert.throws(() => decodeFrame(quantized({ positionBox: flipped }), N, 0), isDecodeError(/position_box is not a box/));
    assert.throws(
      () => decodeFrame(create(FrameSchema, { encoding: FrameEncoding.QUANTIZED, vertices: q.vertices }), N, 0),
      isDecodeError(/no position_box/),
    );
    const garbage = create(FrameSchema, { encoding: FrameEncoding.MESHOPT, vertices: new Uint8Array([1, 2, 3, 4]), positionBox: q.box });
    assert.throws(() => decodeFrame(garbage, N, 0), isDecodeError(/not a meshopt vertex buffer of 500 vertices of 8 bytes/));
  });
});

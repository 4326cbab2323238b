// MESHOPT_DELTA frames: deltas built here from deform.proto's formula (zigzag differences on
// the key frame's grid, through meshopt's vertex codec) decode to exactly the quantized
// vertices they stand for, whatever the sign or size of a difference, frames the page skips
// included; a delta with nothing to add to is a clear error, and so is every delta after a
// bad frame until the next key frame.
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { MeshoptEncoder } from "meshoptimizer/encoder";
import { before, describe, it } from "node:test";
import { decodeFrame, meshoptReady, MeshoptDeltaStream } from "../src/decode/frame_decode";
import { dequantizeVertices } from "../src/decode/quantized";
import { BoxSchema, FrameEncoding, FrameSchema, type Frame } from "../src/gen/hdeform/v1/deform_pb";

const N = 700;
const box = create(BoxSchema, { min: { x: -1, y: 0, z: 2 }, max: { x: 3, y: 0.5, z: 2.25 } });

/** Quantized vertices of a smooth field at time t: 3 × uint16 positions, 2 × int8 normals. */
function quantizedAt(t: number): Uint8Array {
  const bytes = new Uint8Array(8 * N);
  const q = new Uint16Array(bytes.buffer);
  const s8 = new Int8Array(bytes.buffer);
  for (let i = 0; i < N; i++) {
    // Values near both ends of the range too, so differences wrap mod 65536 / 256.
    q[4 * i] = Math.round(32767 + 32767 * Math.sin(0.01 * i + t));
    q[4 * i + 1] = Math.round(30000 * (1 + Math.cos(0.02 * i - 2 * t))) & 0xffff;
    q[4 * i + 2] = (i * 97 + Math.round(4000 * t)) & 0xffff;
    s8[8 * i + 6] = Math.round(127 * Math.sin(0.05 * i + 3 * t));
    s8[8 * i + 7] = Math.round(-127 * Math.cos(0.05 * i + 3 * t));
  }
  return bytes;
}

/** deform.proto's delta: zigzag of (now − before) per uint16 position and int8 normal. */
function deltaBytes(now: Uint8Array, before: Uint8Array): Uint8Array {
  const out = new Uint8Array(now.byteLength);
  const q = new Uint16Array(now.buffer), q0 = new Uint16Array(before.buffer), z = new Uint16Array(out.buffer);
  for (let w = 0; w < q.length; w += 4) {
    for (let k = 0; k < 3; k++) {
      const d = ((q[w + k] - q0[w + k]) << 16) >> 16; // as int16
      z[w + k] = (d << 1) ^ (d >> 15);
    }
  }
  for (let o = 6; o < now.byteLength; o += 8) {
    for (let k = o; k < o + 2; k++) {
      const d = ((now[k] - before[k]) << 24) >> 24; // as int8
      out[k] = (d << 1) ^ (d >> 7);
    }
  }
  return out;
}

function frameOf(vertices: Uint8Array, delta: boolean): Frame {
  return create(FrameSchema, {
    encoding: FrameEncoding.MESHOPT_DELTA,
    vertices: MeshoptEncoder.encodeVertexBuffer(vertices, N, 8),
    positionBox: box,
    delta,
  });
}

describe("decodeFrame MESHOPT_DELTA", () => {
  before(async () => {
    await meshoptReady;
    await MeshoptEncoder.ready;
  });

  it("a key frame and the deltas after it decode to exactly their quantized vertices", () => {
    const stream = new MeshoptDeltaStream();
    let before = quantizedAt(0);
    let d = decodeFrame(frameOf(before, false), N, 0, stream);
    assert.deepEqual(d.positions, dequantizeVertices(before, N, { vertices: before, positionBox: box, energies: new Uint8Array(0), energiesMax: 0 }).positions);
    for (let k = 1; k <= 6; k++) {
      const now = quantizedAt(0.01 * k);
      const frame = frameOf(deltaBytes(now, before), true);
      if (k === 3) {
        stream.advance(frame, N); // a frame the page skips still moves the state on
      } else {
        d = decodeFrame(frame, N, 0, stream);
        const want = dequantizeVertices(now, N, { vertices: now, positionBox: box, energies: new Uint8Array(0), energiesMax: 0 });
        assert.deepEqual(d.positions, want.positions, `frame ${k}: positions`);
        assert.deepEqual(d.normals, want.normals, `frame ${k}: normals`);
      }
      before = now;
    }
  });

  it("a delta with no key frame, or after a bad frame, is a clear error until a key frame", () => {
    const k0 = quantizedAt(0), k1 = quantizedAt(0.01), k2 = quantizedAt(0.02);
    const key = frameOf(k0, false), d1 = frameOf(deltaBytes(k1, k0), true), d2 = frameOf(deltaBytes(k2, k1), true);
    assert.throws(() => decodeFrame(d1, N, 0), /needs its stream's earlier frames/);
    const stream = new MeshoptDeltaStream();
    assert.throws(() => decodeFrame(d1, N, 0, stream), /no key frame came before it/);
    decodeFrame(key, N, 0, stream);
    const corrupt = create(FrameSchema, { ...d1, vertices: d1.vertices.subarray(0, 10) });
    assert.throws(() => decodeFrame(corrupt, N, 0, stream), /not a meshopt vertex buffer/);
    assert.throws(() => decodeFrame(d2, N, 0, stream), /no key frame came before it/);
    decodeFrame(key, N, 0, stream);
    decodeFrame(d1, N, 0, stream);
    const want = dequantizeVertices(k2, N, { vertices: k2, positionBox: box, energies: new Uint8Array(0), energiesMax: 0 });
    assert.deepEqual(decodeFrame(d2, N, 0, stream).positions, want.positions);
    // A key frame of another size, then a delta for this one.
    stream.reset();
    assert.throws(() => decodeFrame(d1, N, 0, stream), /no key frame/);
  });
});

// The decode worker decodes into the arrays the page handed back (frame_decoder.ts): every
// quantized encoding writes them whole, and gives the same values as into fresh arrays.
describe("decodeFrame into given arrays", () => {
  before(() => Promise.all([meshoptReady, MeshoptEncoder.ready]));

  it("QUANTIZED, MESHOPT and MESHOPT_DELTA fill `out` with the fresh decode; other sizes are not used", () => {
    const k1 = quantizedAt(0.3), k2 = quantizedAt(0.7);
    const frames: Frame[] = [
      create(FrameSchema, { encoding: FrameEncoding.QUANTIZED, vertices: k2, positionBox: box }),
      create(FrameSchema, { encoding: FrameEncoding.MESHOPT, vertices: MeshoptEncoder.encodeVertexBuffer(k2, N, 8), positionBox: box }),
    ];
    const delta = create(FrameSchema, {
      encoding: FrameEncoding.MESHOPT_DELTA,
      delta: true,
      vertices: MeshoptEncoder.encodeVertexBuffer(deltaBytes(k2, k1), N, 8),
      positionBox: box,
    });
    const key = create(FrameSchema, { encoding: FrameEncoding.MESHOPT_DELTA, vertices: MeshoptEncoder.encodeVertexBuffer(k1, N, 8), positionBox: box });
    const want = dequantizeVertices(k2, N, { vertices: k2, positionBox: box, energies: new Uint8Array(0), energiesMax: 0 });
    const stale = () => ({ positions: new Float32Array(3 * N).fill(NaN), normals: new Float32Array(3 * N).fill(NaN) });
    for (const frame of frames) {
      const out = stale();
      const d = decodeFrame(frame, N, 0, undefined, out);
      assert.equal(d.positions, out.positions, `encoding ${frame.encoding}: decoded into the given positions`);
      assert.equal(d.normals, out.normals);
      assert.deepEqual([d.positions, d.normals], [want.positions, want.normals], `encoding ${frame.encoding}`);
    }
    const stream = new MeshoptDeltaStream();
    decodeFrame(key, N, 0, stream);
    const out = stale();
    const d = decodeFrame(delta, N, 0, stream, out);
    assert.equal(d.positions, out.positions);
    assert.deepEqual([d.positions, d.normals], [want.positions, want.normals], "MESHOPT_DELTA");
    // Arrays of another mesh's size are left alone.
    const small = { positions: new Float32Array(3), normals: new Float32Array(3) };
    const other = decodeFrame(frames[1], N, 0, undefined, small);
    assert.notEqual(other.positions, small.positions);
    assert.deepEqual(small.positions, new Float32Array(3));
    assert.deepEqual(other.positions, want.positions);
  });
});

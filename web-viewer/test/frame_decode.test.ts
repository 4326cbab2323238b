// The frame decoder, FLOAT32: buffers round trip; wrong lengths fail with a clear error.
// (QUANTIZED and MESHOPT: quantized_decode.test.ts.)
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { describe, it } from "node:test";
import { decodeFrame, FrameDecodeError } from "../src/decode/frame_decode";
import { FrameEncoding, FrameSchema } from "../src/gen/hdeform/v1/deform_pb";

const bytes = (values: number[]) => new Uint8Array(new Float32Array(values).buffer);

describe("decodeFrame", () => {
  it("FLOAT32: positions, normals and energies round trip", () => {
    const positions = [0, 1, 2, 3.5, -4.25, 5e-7];
    const normals = [0, 0, 1, 1, 0, 0];
    const energies = [0.125];
    const frame = create(FrameSchema, { positions: bytes(positions), normals: bytes(normals), energies: bytes(energies) });
    const d = decodeFrame(frame, 2, 1);
    assert.deepEqual(Array.from(d.positions!), Array.from(new Float32Array(positions)));
    assert.deepEqual(Array.from(d.normals!), normals);
    assert.deepEqual(Array.from(d.energies!), energies);
  });

  it("FLOAT32: bytes that are not 4-aligned in their buffer", () => {
    const padded = new Uint8Array(1 + 12);
    padded.set(bytes([1, 2, 3]), 1);
    const frame = create(FrameSchema, { positions: padded.subarray(1) });
    assert.deepEqual(Array.from(decodeFrame(frame, 1, 0).positions!), [1, 2, 3]);
  });

  it("FLOAT32: absent buffers are null", () => {
    const d = decodeFrame(create(FrameSchema, { positions: bytes([1, 2, 3]) }), 1, 4);
    assert.equal(d.normals, null);
    assert.equal(d.energies, null);
    assert.equal(decodeFrame(create(FrameSchema, {}), 1, 4).positions, null);
  });

  it("FLOAT32: a buffer of the wrong length is a clear error", () => {
    const frame = create(FrameSchema, { positions: bytes([1, 2, 3, 4, 5, 6]) });
    assert.throws(() => decodeFrame(frame, 3, 0), (err: unknown) => {
      assert.ok(err instanceof FrameDecodeError);
      assert.equal(err.message, "Frame has positions for 2 vertices; the mesh has 3 (24 bytes, expected 36)");
      return true;
    });
    const energies = create(FrameSchema, { positions: bytes([1, 2, 3]), energies: bytes([1, 2]) });
    assert.throws(() => decodeFrame(energies, 1, 3), /Frame has energies for 2 triangles; the mesh has 3/);
  });

  it("an unknown encoding is a clear error", () => {
    const frame = create(FrameSchema, { encoding: 7 as FrameEncoding, vertices: new Uint8Array(8) });
    assert.throws(() => decodeFrame(frame, 1, 0), /Frame encoding #7 is unknown/);
  });
});

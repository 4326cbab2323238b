// Handle transforms between the gizmo and the proto, including the form the server answers in.
import assert from "node:assert/strict";
import { create } from "@bufbuild/protobuf";
import { describe, it } from "node:test";
import * as THREE from "three";
import { HandleTransformSchema, Mat3Schema } from "../src/gen/hdeform/v1/deform_pb";
import { fromProtoTransform, toProtoTransforms } from "../src/transforms";

describe("transforms", () => {
  const pivot = new THREE.Vector3(0.5, 0.25, 1);
  const pose = {
    position: new THREE.Vector3(0.6, 0.25, 1.2),
    quaternion: new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 0, 1), Math.PI / 4),
    scale: new THREE.Vector3(1.5, 1, 0.5),
  };
  const same = (a: { toArray(): number[] }, b: { toArray(): number[] }) => a.toArray().every((x, i) => Math.abs(x - b.toArray()[i]) < 1e-12);

  it("reads back the axis scale it sent", () => {
    const t = create(HandleTransformSchema, toProtoTransforms([pose], [pivot])[0]);
    assert.equal(t.scale.case, "axisScale");
    const back = fromProtoTransform(t, pivot);
    assert.ok(same(back.position, pose.position) && same(back.quaternion, pose.quaternion) && same(back.scale, pose.scale));
  });
  it("reads the server's answer, where the same scale is a diagonal stretch", () => {
    const sent = toProtoTransforms([pose], [pivot])[0];
    const answered = create(HandleTransformSchema, sent);
    answered.scale = { case: "stretch", value: create(Mat3Schema, { m: [1.5, 0, 0, 0, 1, 0, 0, 0, 0.5] }) };
    const back = fromProtoTransform(answered, pivot);
    assert.ok(same(back.scale, pose.scale), `scale ${back.scale.toArray()}`);
    assert.ok(same(back.position, pose.position) && same(back.quaternion, pose.quaternion));
  });
});

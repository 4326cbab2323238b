// Handle transforms: the gizmo's pose (position of the pivot, rotation, scale) ⇄ the proto's
// HandleTransform (pivot, rotation, scale, translation, or a matrix).
import * as THREE from "three";
import type { MessageInitShape } from "@bufbuild/protobuf";
import type { HandleTransform, HandleTransformSchema } from "./gen/hdeform/v1/deform_pb";

export interface HandleState {
  position: THREE.Vector3;
  quaternion: THREE.Quaternion;
  scale: THREE.Vector3;
}

export function vec(v: { x: number; y: number; z: number } | undefined): THREE.Vector3 {
  return v ? new THREE.Vector3(v.x, v.y, v.z) : new THREE.Vector3();
}

export function identityHandle(pivot: THREE.Vector3 | undefined): HandleState {
  return {
    position: (pivot ?? new THREE.Vector3()).clone(),
    quaternion: new THREE.Quaternion(),
    scale: new THREE.Vector3(1, 1, 1),
  };
}

export function fromProtoTransform(t: HandleTransform, pivot: THREE.Vector3 | undefined): HandleState {
  const q = pivot ?? new THREE.Vector3();
  const rot = t.rotation;
  const R =
    rot && (rot.w !== 0 || rot.x !== 0 || rot.y !== 0 || rot.z !== 0)
      ? new THREE.Quaternion(rot.x, rot.y, rot.z, rot.w).normalize()
      : new THREE.Quaternion();
  const S = new THREE.Vector3(1, 1, 1);
  if (t.scale.case === "uniformScale") S.setScalar(t.scale.value);
  else if (t.scale.case === "axisScale") S.set(t.scale.value.x, t.scale.value.y, t.scale.value.z);
  // The server answers every scale as `stretch` (its own form), so the axis scale this page
  // sent comes back as a diagonal matrix: read back as the same per-axis scale. A stretch with
  // off-diagonal terms (another client's) has no gizmo pose (three.js has no shear): its
  // diagonal is shown.
  else if (t.scale.case === "stretch" && t.scale.value.m.length === 9) S.set(t.scale.value.m[0], t.scale.value.m[4], t.scale.value.m[8]);
  const tr = new THREE.Vector3(t.translation?.x ?? 0, t.translation?.y ?? 0, t.translation?.z ?? 0);
  if (t.matrix.length === 16) {
    const M = new THREE.Matrix4().fromArray(t.matrix).transpose(); // row-major → three's column-major
    const position = new THREE.Vector3(), quaternion = new THREE.Quaternion(), scale = new THREE.Vector3();
    M.decompose(position, quaternion, scale);
    // x' = M x  ⇔  x' = q + A (x − q) + (M q − q): the gizmo sits at M q.
    return { position: q.clone().applyMatrix4(M), quaternion, scale };
  }
  // x' = p + A (x − p) + t with A = R S; the gizmo at pivot q shows q + t', t' = p − A p + t − q + A q.
  const p = t.pivot ? new THREE.Vector3(t.pivot.x, t.pivot.y, t.pivot.z) : q;
  const A = new THREE.Matrix4().compose(new THREE.Vector3(), R, S);
  const Ap = p.clone().applyMatrix4(A);
  const Aq = q.clone().applyMatrix4(A);
  const position = p.clone().sub(Ap).add(tr).add(Aq);
  return { position, quaternion: R, scale: S };
}

export function toProtoTransforms(handles: HandleState[], pivots: THREE.Vector3[]): MessageInitShape<typeof HandleTransformSchema>[] {
  return handles.map((s, i) => {
    const p = pivots[i] ?? new THREE.Vector3();
    const t = s.position.clone().sub(p);
    const uniform = Math.abs(s.scale.x - 1) < 1e-12 && Math.abs(s.scale.y - 1) < 1e-12 && Math.abs(s.scale.z - 1) < 1e-12;
    return {
      pivot: { x: p.x, y: p.y, z: p.z },
      rotation: { w: s.quaternion.w, x: s.quaternion.x, y: s.quaternion.y, z: s.quaternion.z },
      scale: uniform
        ? { case: undefined }
        : { case: "axisScale" as const, value: { x: s.scale.x, y: s.scale.y, z: s.scale.z } },
      translation: { x: t.x, y: t.y, z: t.z },
    };
  });
}

export function isIdentity(t: HandleTransform): boolean {
  if (t.matrix.length === 16) return false;
  const tr = t.translation;
  const r = t.rotation;
  const moved = tr && (tr.x !== 0 || tr.y !== 0 || tr.z !== 0);
  const rotated = r && (r.x !== 0 || r.y !== 0 || r.z !== 0) && !(r.w === 0 && r.x === 0 && r.y === 0 && r.z === 0);
  const scaled =
    (t.scale.case === "uniformScale" && t.scale.value !== 1) ||
    (t.scale.case === "axisScale" && (t.scale.value.x !== 1 || t.scale.value.y !== 1 || t.scale.value.z !== 1)) ||
    t.scale.case === "stretch";
  return !moved && !rotated && !scaled;
}

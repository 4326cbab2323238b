// Typed-in values for the active handle: translation (model units, from its pivot), rotation
// (XYZ Euler angles in degrees) and scale per axis. Shown live while the gizmo moves; a typed
// value is sent like a drag (the handle taken, moved, given back).
import * as THREE from "three";
import type { App } from "../app";
import { $ } from "../dom";
import type { HandleGizmo } from "../viewport/handle_gizmo";

const FIELDS = ["tx", "ty", "tz", "rx", "ry", "rz", "sx", "sy", "sz"] as const;
type Field = (typeof FIELDS)[number];

/** Rounds for display: enough digits to see a small move, not float noise. */
function show(v: number): string {
  const r = Number(v.toPrecision(6));
  return String(Object.is(r, -0) ? 0 : r);
}

export function setupTransformFields({ state }: App, gizmo: HandleGizmo): void {
  const input = (f: Field) => $<HTMLInputElement>(`tf-${f}`);
  const fill = () => {
    const h = state.activeHandle - 1;
    const s = state.handles[h];
    const enabled = !!s && state.canMoveHandle;
    $("transform-fields").classList.toggle("disabled", !enabled);
    if (!s) return;
    const t = s.position.clone().sub(state.pivots[h] ?? new THREE.Vector3());
    const e = new THREE.Euler().setFromQuaternion(s.quaternion, "XYZ");
    const values: Record<Field, number> = {
      tx: t.x,
      ty: t.y,
      tz: t.z,
      rx: THREE.MathUtils.radToDeg(e.x),
      ry: THREE.MathUtils.radToDeg(e.y),
      rz: THREE.MathUtils.radToDeg(e.z),
      sx: s.scale.x,
      sy: s.scale.y,
      sz: s.scale.z,
    };
    for (const f of FIELDS) {
      const el = input(f);
      el.disabled = !enabled;
      if (document.activeElement !== el) el.value = show(values[f]);
    }
  };
  state.on("handles", fill);
  state.on("pose", fill);
  const commit = () => {
    const h = state.activeHandle - 1;
    if (!state.handles[h]) return;
    const v = (f: Field) => Number(input(f).value);
    if (FIELDS.some((f) => !Number.isFinite(v(f)))) return fill();
    const pivot = state.pivots[h] ?? new THREE.Vector3();
    const d = THREE.MathUtils.degToRad;
    void gizmo
      .setPose({
        position: new THREE.Vector3(v("tx"), v("ty"), v("tz")).add(pivot),
        quaternion: new THREE.Quaternion().setFromEuler(new THREE.Euler(d(v("rx")), d(v("ry")), d(v("rz")), "XYZ")),
        scale: new THREE.Vector3(v("sx") || 1, v("sy") || 1, v("sz") || 1),
      })
      .then((ok) => {
        if (!ok) fill();
      });
  };
  for (const f of FIELDS) {
    input(f).addEventListener("change", commit);
    input(f).addEventListener("keydown", (ev) => {
      if (ev.key === "Enter") input(f).blur();
    });
  }
  fill();
}

// Issue 37's orientation and selection tools: Blender's keypad views (keys, directions for z-up
// and y-up models, the roll of top and bottom views), the lasso's inside test, the projection the
// Box and Lasso tools share, the visible-only depth comparison and the ground grid's step.
import assert from "node:assert/strict";
import { describe, it } from "node:test";
import * as THREE from "three";
import { keyAction, SHORTCUTS } from "../src/keymap";
import { insidePolygon, polygonArea } from "../src/selection/lasso";
import { forEachProjected } from "../src/selection/screen_projection";
import { unpackDepth, viewDistance, visibleFilter, type DepthImage } from "../src/selection/visibility";
import { roundStep } from "../src/viewport/ground_grid";
import { axisEndDirection, orbitSafeDirection, viewDirection } from "../src/viewport/view_axes";

describe("keypad views", () => {
  it("maps Numpad 1 / 3 / 7 (Ctrl: the other side), Numpad . and Alt+Z by physical key", () => {
    assert.equal(keyAction({ key: "1", code: "Numpad1" }), "viewFront");
    assert.equal(keyAction({ key: "1", code: "Numpad1", ctrlKey: true }), "viewBack");
    assert.equal(keyAction({ key: "3", code: "Numpad3" }), "viewRight");
    assert.equal(keyAction({ key: "3", code: "Numpad3", metaKey: true }), "viewLeft");
    assert.equal(keyAction({ key: "Home", code: "Numpad7" }), "viewTop"); // Num Lock off
    assert.equal(keyAction({ key: "7", code: "Numpad7", ctrlKey: true }), "viewBottom");
    assert.equal(keyAction({ key: ".", code: "NumpadDecimal" }), "frameSelection");
    assert.equal(keyAction({ key: "Home", code: "Home" }), "frameAll"); // the real Home key
    assert.equal(keyAction({ key: "1", code: "Digit1" }), null); // the top row is not the keypad
    assert.equal(keyAction({ key: "5", code: "Numpad5" }), "toggleOrthographic"); // Blender's perspective / orthographic
    assert.equal(keyAction({ key: "Clear", code: "Numpad5" }), "toggleOrthographic"); // Num Lock off
    assert.equal(keyAction({ key: "5", code: "Numpad5", ctrlKey: true }), null);
    assert.equal(keyAction({ key: "5", code: "Digit5" }), null);
    assert.equal(keyAction({ key: "Ω", code: "KeyZ", altKey: true }), "toggleXray");
    assert.equal(keyAction({ key: "z", code: "KeyZ" }), "axisZ");
    const keys = SHORTCUTS.map(([k]) => k).join(" | ");
    assert.match(keys, /Numpad 1 \/ 3 \/ 7/);
    assert.match(keys, /Ctrl\+Numpad/);
    assert.match(keys, /Numpad \./);
    assert.match(keys, /Numpad 5/);
    assert.match(keys, /Alt\+Z/);
  });

  it("looks as Blender does: front from −y for z-up models, from +z for y-up ones", () => {
    assert.deepEqual(viewDirection("front", "z"), [0, -1, 0]);
    assert.deepEqual(viewDirection("back", "z"), [-0, 1, -0]);
    assert.deepEqual(viewDirection("right", "z"), [1, 0, 0]);
    assert.deepEqual(viewDirection("top", "z"), [0, 0, 1]);
    assert.deepEqual(viewDirection("front", "y"), [0, 0, 1]);
    assert.deepEqual(viewDirection("top", "y"), [0, 1, 0]);
    assert.deepEqual(viewDirection("bottom", "y"), [-0, -1, -0]);
    assert.deepEqual(axisEndDirection("negY"), [0, -1, 0]);
    assert.deepEqual(axisEndDirection("posZ"), [0, 0, 1]);
  });

  it("top and bottom views keep x to the right (the roll OrbitControls takes from a tiny offset)", () => {
    for (const up of ["z", "y"] as const) {
      for (const view of ["top", "bottom"] as const) {
        const d = new THREE.Vector3(...orbitSafeDirection(viewDirection(view, up), up));
        assert.ok(d.dot(new THREE.Vector3(...viewDirection(view, up))) > 0.999999, `${view} ${up}: still along the axis`);
        // The camera looks along −d with camera.up = the model's up: screen right = forward × up'.
        const camUp = new THREE.Vector3(...viewDirection("top", up));
        const forward = d.clone().negate();
        const screenUp = camUp.clone().addScaledVector(forward, -camUp.dot(forward)).normalize();
        const right = forward.clone().cross(screenUp);
        assert.ok(right.x > 0.999, `${view} ${up}: x points right (${right.toArray()})`);
      }
    }
    assert.deepEqual(orbitSafeDirection([1, 0, 0], "z"), [1, 0, 0]); // only along the up axis
  });
});

describe("lasso", () => {
  const square = [
    { x: 0, y: 0 },
    { x: 10, y: 0 },
    { x: 10, y: 10 },
    { x: 0, y: 10 },
  ];
  it("takes the points inside the closed outline (even–odd), not those outside", () => {
    assert.ok(insidePolygon(5, 5, square));
    assert.ok(!insidePolygon(11, 5, square));
    assert.ok(!insidePolygon(5, -1, square));
    // A concave outline: a U whose gap (4 < x < 6, y < 8) is outside.
    const u = [
      { x: 0, y: 0 },
      { x: 4, y: 0 },
      { x: 4, y: 8 },
      { x: 6, y: 8 },
      { x: 6, y: 0 },
      { x: 10, y: 0 },
      { x: 10, y: 10 },
      { x: 0, y: 10 },
    ];
    assert.ok(insidePolygon(2, 2, u));
    assert.ok(!insidePolygon(5, 2, u));
    assert.ok(insidePolygon(5, 9, u));
    assert.equal(polygonArea(square), 100);
    assert.equal(polygonArea([{ x: 0, y: 0 }, { x: 1, y: 1 }, { x: 2, y: 2 }]), 0); // a line: a click, nothing
  });

  it("projects vertices as three's Vector3.project does (viewport pixels from the top left)", () => {
    const camera = new THREE.PerspectiveCamera(40, 2, 0.1, 100);
    camera.position.set(1, 2, 5);
    camera.lookAt(0, 0, 0);
    camera.updateMatrixWorld();
    const M = new THREE.Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
    const pos = new Float32Array([0, 0, 0, 0.5, -0.25, 1, 0, 0, 50]);
    const got: number[][] = [];
    forEachProjected({ width: 200, height: 100, matrix: M.toArray() }, pos, 3, (v, x, y, d) => got.push([v, x, y, d]));
    assert.equal(got.length, 2); // the third is behind the camera
    for (const [v, x, y, d] of got) {
      const p = new THREE.Vector3().fromArray(pos, 3 * v).project(camera);
      assert.ok(Math.abs(x - ((p.x + 1) / 2) * 200) < 1e-9 && Math.abs(y - ((1 - p.y) / 2) * 100) < 1e-9 && Math.abs(d - (p.z + 1) / 2) < 1e-12);
    }
  });
});

describe("visible-only", () => {
  const near = 0.1, far = 100;
  /** A 4×4 depth image at distance `dist` everywhere (background where null). */
  const image = (dist: (x: number, y: number) => number | null): DepthImage => {
    const pixels = new Uint8Array(4 * 16);
    for (let y = 0; y < 4; y++)
      for (let x = 0; x < 4; x++) {
        const z = dist(x, y);
        // window depth of view distance z: the inverse of viewDistance
        const d = z === null ? 1 : (far - (near * far) / z) / (far - near);
        const q = Math.round(d * 16777215);
        const o = 4 * ((3 - y) * 4 + x);
        pixels.set([q >> 16, (q >> 8) & 255, q & 255, 255], o);
      }
    return { width: 4, height: 4, pixels, near, far, pixelAngle: 1e-4 };
  };
  const depthAt = (z: number) => (far - (near * far) / z) / (far - near);

  it("unpacks 24-bit depth and turns it into distance", () => {
    const img = image(() => 5);
    assert.ok(Math.abs(viewDistance(unpackDepth(img.pixels, 0), near, far) - 5) < 1e-3);
  });

  it("keeps a vertex on the nearest surface, drops one behind it, keeps silhouettes and empty pixels", () => {
    const wall = visibleFilter(image(() => 5), 0.01);
    assert.ok(wall(1.5, 1.5, depthAt(5.005)));
    assert.ok(!wall(1.5, 1.5, depthAt(6)));
    const empty = visibleFilter(image(() => null), 0.01);
    assert.ok(empty(1.5, 1.5, depthAt(60)));
    // A step: near (5) on the left column, far (8) elsewhere; a vertex at 8 one pixel away from the step is on the far surface.
    const step = visibleFilter(image((x) => (x === 0 ? 5 : 8)), 0.01);
    assert.ok(step(1.5, 1.5, depthAt(8)));
    assert.ok(!step(0.5, 1.5, depthAt(9)));
  });

  it("orthographic (Numpad 5): depth is linear in distance, and the slack is pixels in model units", () => {
    assert.equal(viewDistance(0.25, 2, 10, true), 4);
    assert.equal(viewDistance(0, 2, 10, true), 2);
    const linear = (z: number) => (z - near) / (far - near);
    const pixels = new Uint8Array(4 * 16);
    const q = Math.round(linear(5) * 16777215);
    for (let o = 0; o < 64; o += 4) pixels.set([q >> 16, (q >> 8) & 255, q & 255, 255], o);
    const wall = visibleFilter({ width: 4, height: 4, pixels, near, far, pixelAngle: 0, orthographic: true, pixelSize: 0.01 }, 0.01);
    assert.ok(wall(1.5, 1.5, linear(5.03))); // within the tolerance and three pixels (0.04)
    assert.ok(!wall(1.5, 1.5, linear(5.1)));
    // Read as perspective depth, the same picture would put the wall elsewhere: the flag matters.
    assert.ok(Math.abs(viewDistance(linear(5), near, far) - 5) > 1);
  });
});

describe("ground grid", () => {
  it("steps in 1, 2, 5 × 10^k", () => {
    assert.equal(roundStep(0.37), 0.2);
    assert.equal(roundStep(7), 5);
    assert.equal(roundStep(1), 1);
    assert.equal(roundStep(0), 1);
  });
});

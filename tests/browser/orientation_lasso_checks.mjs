// Orientation and selection tools (issue 37: what Blender and three.js editor users reach for
// first), in real pages against the real server, real mouse and keyboard (`--only orientation`):
//   orientation — on the cactus (z-up): the ground grid is on, lies across +z, and the Display
//     heading's Grid button hides it; each click on an end of the axes view helper (top right) turns the camera to look
//     from that end at the unchanged orbit target, at the same distance (view direction · the
//     expected axis > 0.999); Numpad 1 / 3 / 7 and Ctrl+ those give Blender's front / right / top
//     and back / left / bottom views with the model's up on screen up (top: x right, +y up;
//     bottom: x right, +y down); Numpad . frames the region being assigned (the orbit target is
//     the centre of its box); the ? list names the keys;
//   lasso — on the cactus, X-ray on: a real lasso drag (a concave star) selects exactly the
//     vertices whose projection (recomputed here from the page's positions and camera matrix)
//     lies inside the outline the page recorded (which follows the drawn path); Shift+lasso adds
//     exactly the second outline's, Ctrl+lasso removes exactly the third's; X-ray off, the same
//     star takes a non-empty subset of those (not the back of the trunk); Alt+Z toggles X-ray;
//   visible-only — a closed 100K-vertex sphere (y-up: Numpad 1 looks along −z, 7 along −y) in
//     front view: a real box drag around it selects no vertex on the far side (facing away from
//     the camera: cos < −0.1) and every vertex clearly facing it (cos > 0.1); a lasso around it
//     the same; with X-ray (Alt+Z) the box takes all of them. The depth pass's time is printed.
//     Numpad 5: an orthographic picture looking the same way, where a visible-only box takes the
//     half facing the view direction and nothing behind; Numpad 5 again: perspective.
// Screenshots orient-*.png, lasso-*.png, visible-*.png.

/** The hooks these checks need: a missing one is a failure, not a skip. */
const HOOKS = ["camera", "orthographic", "projectionMatrix", "viewHelperPoint", "viewHelperEndAt", "viewAnimating", "grid", "xray", "lastLasso", "projection", "positions", "labels", "screenPoint", "bbox", "selectBox", "select", "depthPassMs"];

async function hooksPresent(page, check, what) {
  const missing = await page.evaluate((names) => names.filter((k) => !window.hdeform || !(k in window.hdeform)), HOOKS);
  return check(missing.length === 0, `${what}: the test hook has ${missing.length ? `no ${missing.join(", ")}` : "everything these checks use"}`);
}

async function openLibraryMesh(context, base, name, mesh, { watchPage, waitLoaded }) {
  const page = await context.newPage();
  watchPage(page, name);
  await page.setViewportSize({ width: 1400, height: 860 });
  await page.goto(base);
  await page.waitForSelector(`#library option[value="${mesh}"]`, { state: "attached", timeout: 30_000 });
  await page.selectOption("#library", mesh);
  await page.click("#open-library");
  await waitLoaded(page, name);
  return page;
}

const sub = (a, b) => a.map((v, i) => v - b[i]);
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const norm = (a) => Math.hypot(...a);
const unit = (a) => a.map((v) => v / norm(a));

/** The camera's view direction (position → target), the target and the distance. */
async function view(page) {
  const c = await page.evaluate(() => window.hdeform.camera());
  const d = sub(c.target, c.position);
  return { dir: unit(d), target: c.target, dist: norm(d), position: c.position };
}

async function settle(page, sleep) {
  await sleep(30);
  await page.waitForFunction(() => !window.hdeform.viewAnimating, null, { timeout: 5_000 });
  await sleep(60); // a frame drawn with the final pose (for the screenshots)
}

/** Where model-space direction `v` from the orbit target points on screen (client px; y down). */
async function screenDelta(page, target, v, scale) {
  const [a, b] = await page.evaluate(
    ([t, p]) => [window.hdeform.screenPoint(...t), window.hdeform.screenPoint(...p)],
    [target, target.map((x, i) => x + scale * v[i])],
  );
  return { x: b.x - a.x, y: b.y - a.y };
}

/** A sphere of radius r as OFF: `rings` latitude bands × `around` longitudes, closed at both poles, faces outward. */
function sphereOff(rings, around, r = 1) {
  const verts = [[0, r, 0]];
  for (let j = 1; j < rings; j++)
    for (let a = 0; a < around; a++) {
      const t = (Math.PI * j) / rings, p = (2 * Math.PI * a) / around;
      verts.push([r * Math.sin(t) * Math.cos(p), r * Math.cos(t), r * Math.sin(t) * Math.sin(p)]);
    }
  verts.push([0, -r, 0]);
  const S = verts.length - 1;
  const v = (j, a) => 1 + (j - 1) * around + (a % around);
  const tris = [];
  for (let a = 0; a < around; a++) {
    tris.push([0, v(1, a), v(1, a + 1)], [v(rings - 1, a), S, v(rings - 1, a + 1)]);
    for (let j = 1; j + 1 < rings; j++) tris.push([v(j, a), v(j + 1, a), v(j + 1, a + 1)], [v(j, a), v(j + 1, a + 1), v(j, a + 1)]);
  }
  // Outward: the normal along the centroid (the sphere is centred at 0).
  const oriented = tris.map(([i, j, k]) => {
    const [A, B, C] = [verts[i], verts[j], verts[k]];
    const u = sub(B, A), w = sub(C, A);
    const n = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
    const c = [A[0] + B[0] + C[0], A[1] + B[1] + C[1], A[2] + B[2] + C[2]];
    return dot(n, c) >= 0 ? [i, j, k] : [i, k, j];
  });
  const lines = ["OFF", `${verts.length} ${oriented.length} 0`];
  for (const p of verts) lines.push(p.map((x) => x.toFixed(6)).join(" "));
  for (const t of oriented) lines.push(`3 ${t.join(" ")}`);
  return { off: Buffer.from(lines.join("\n") + "\n"), n: verts.length };
}

/** The tools' projection redone here (selection/screen_projection.ts: three's applyMatrix4, then pixels). */
function project(proj, P) {
  const e = proj.matrix, out = [];
  for (let v = 0; v < P.length / 3; v++) {
    const x = P[3 * v], y = P[3 * v + 1], z = P[3 * v + 2];
    const iw = 1 / (e[3] * x + e[7] * y + e[11] * z + e[15]);
    const px = (e[0] * x + e[4] * y + e[8] * z + e[12]) * iw;
    const py = (e[1] * x + e[5] * y + e[9] * z + e[13]) * iw;
    const pz = (e[2] * x + e[6] * y + e[10] * z + e[14]) * iw;
    out.push(pz < -1 || pz > 1 ? null : { x: ((px + 1) / 2) * proj.width, y: ((1 - py) / 2) * proj.height });
  }
  return out;
}

/** Inside a closed polygon (crossing number, written afresh here). */
function inside(pt, poly) {
  let crossings = 0;
  for (let i = 0; i < poly.length; i++) {
    const a = poly[i], b = poly[(i + 1) % poly.length];
    if ((a.y <= pt.y && b.y > pt.y) || (b.y <= pt.y && a.y > pt.y)) {
      const x = a.x + ((pt.y - a.y) / (b.y - a.y)) * (b.x - a.x);
      if (pt.x < x) crossings++;
    }
  }
  return crossings % 2 === 1;
}

/** A real lasso drag through `corners` (client px), closed back to the first, `steps` moves per edge. */
async function lassoDrag(page, corners, sleep, modifier, steps = 8) {
  if (modifier) await page.keyboard.down(modifier);
  await page.mouse.move(corners[0].x, corners[0].y);
  await page.mouse.down();
  for (let i = 1; i <= corners.length; i++) {
    const c = corners[i % corners.length];
    await page.mouse.move(c.x, c.y, { steps });
  }
  await page.mouse.up();
  if (modifier) await page.keyboard.up(modifier);
  await sleep(50);
}

function star(cx, cy, outer, inner, points = 5, turn = 0) {
  const out = [];
  for (let k = 0; k < 2 * points; k++) {
    const a = turn + (Math.PI * k) / points - Math.PI / 2;
    const r = k % 2 ? inner : outer;
    out.push({ x: cx + r * Math.cos(a), y: cy + r * Math.sin(a) });
  }
  return out;
}

const region = (labels, label = 0) => new Set(labels.flatMap((l, v) => (l === label ? [v] : [])));
const same = (a, b) => a.size === b.size && [...a].every((v) => b.has(v));
const diffCount = (a, b) => [...a].filter((v) => !b.has(v)).length + [...b].filter((v) => !a.has(v)).length;

export async function orientationChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded }) {
  const page = await openLibraryMesh(context, base, "orient-oda", "cactus", { watchPage, waitLoaded });
  if (!(await hooksPresent(page, check, "orientation"))) return page.close();
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const up = (await hook(() => window.hdeform.camera())).up;
  check(Math.abs(up[2] - 1) < 1e-9, `orientation: the cactus is shown z-up (camera up ${JSON.stringify(up)})`);

  // The ground grid: on by default, across the model's up axis; Display → grid hides it.
  const g0 = await hook(() => window.hdeform.grid());
  const pressed = () => page.getAttribute("#grid-toggle", "aria-pressed");
  const p0 = await pressed();
  await shot(page, "orient-grid-on");
  await page.click("#grid-toggle");
  const g1 = await hook(() => window.hdeform.grid());
  const p1 = await pressed();
  await shot(page, "orient-grid-off");
  await page.click("#grid-toggle");
  const g2 = await hook(() => window.hdeform.grid());
  check(
    g0.visible && p0 === "true" && g0.normal && Math.abs(g0.normal[2] - 1) < 1e-6 && !g1.visible && p1 === "false" && g2.visible && (await pressed()) === "true",
    `orientation: the ground grid is on (normal ${JSON.stringify(g0.normal)}: the model's +z; Grid pressed: ${p0}), the Grid button hides it (${g1.visible}, ${p1}) and shows it again (${g2.visible})`,
  );

  // The axes view helper: a click on an end puts the camera at that end, looking at the target.
  const v0 = await view(page);
  const ends = { posX: [1, 0, 0], negY: [0, -1, 0], posZ: [0, 0, 1], negX: [-1, 0, 0], posY: [0, 1, 0], negZ: [0, 0, -1] };
  for (const [end, axis] of Object.entries(ends)) {
    const p = await hook((e) => window.hdeform.viewHelperPoint(e), end);
    const aimed = await hook(([x, y]) => window.hdeform.viewHelperEndAt(x, y), [p.x, p.y]);
    await page.mouse.click(p.x, p.y);
    await settle(page, sleep);
    const v = await view(page);
    const along = dot(v.dir, axis.map((x) => -x));
    check(
      aimed === end && along > 0.999 && norm(sub(v.target, v0.target)) < 1e-9 * v0.dist && Math.abs(v.dist - v0.dist) < 1e-6 * v0.dist,
      `orientation: a click on the view helper's ${end} end (at ${p.x.toFixed(0)}, ${p.y.toFixed(0)}; it hits ${aimed}) looks from it: view · ${JSON.stringify(axis.map((x) => -x))} = ${along.toFixed(6)}, target kept, distance ${v.dist.toFixed(4)} (was ${v0.dist.toFixed(4)})`,
    );
    if (end === "posZ" || end === "posX") await shot(page, `orient-helper-${end}`);
  }

  // Blender's keypad (z-up: the front view looks from −y). Focus the page, not a select.
  const vp = await page.locator("#viewport canvas").boundingBox();
  await page.mouse.click(vp.x + 20, vp.y + vp.height / 2); // Box mode: a click selects nothing
  const keys = [
    // key, view direction (camera → target), screen right, screen up (model axes)
    ["Numpad1", [0, 1, 0], [1, 0, 0], [0, 0, 1], "front"],
    ["Numpad3", [-1, 0, 0], [0, 1, 0], [0, 0, 1], "right"],
    ["Numpad7", [0, 0, -1], [1, 0, 0], [0, 1, 0], "top"],
    ["Control+Numpad1", [0, -1, 0], [-1, 0, 0], [0, 0, 1], "back"],
    ["Control+Numpad3", [1, 0, 0], [0, -1, 0], [0, 0, 1], "left"],
    ["Control+Numpad7", [0, 0, 1], [1, 0, 0], [0, -1, 0], "bottom"],
  ];
  for (const [key, want, right, screenUp, name] of keys) {
    await page.keyboard.press(key);
    await settle(page, sleep);
    const v = await view(page);
    const along = dot(v.dir, want);
    const r = await screenDelta(page, v.target, right, 0.1 * v.dist);
    const u = await screenDelta(page, v.target, screenUp, 0.1 * v.dist);
    const len = Math.hypot(r.x, r.y), ulen = Math.hypot(u.x, u.y);
    check(
      along > 0.999 && r.x / len > 0.99 && -u.y / ulen > 0.99 && norm(sub(v.target, v0.target)) < 1e-9 * v0.dist,
      `orientation: ${key} (${name}) looks along ${JSON.stringify(want)} (· = ${along.toFixed(6)}); ${JSON.stringify(right)} points right (${(r.x / len).toFixed(3)}), ${JSON.stringify(screenUp)} up (${(-u.y / ulen).toFixed(3)})`,
    );
    if (name === "front" || name === "top") await shot(page, `orient-numpad-${name}`);
  }

  // Numpad . frames the region being assigned (Box mode: Fixed): the bottom tenth.
  const [bmin, bmax] = await hook(() => window.hdeform.bbox());
  const h = bmax[2] - bmin[2];
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 0), [bmin.map((x) => x - 1), [bmax[0] + 1, bmax[1] + 1, bmin[2] + 0.1 * h]]);
  await page.keyboard.press("Numpad3");
  await settle(page, sleep);
  await page.keyboard.press("NumpadDecimal");
  await settle(page, sleep);
  const { P, L } = await hook(() => ({ P: window.hdeform.positions(), L: window.hdeform.labels() }));
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  L.forEach((l, v) => {
    if (l !== 0) return;
    for (let k = 0; k < 3; k++) {
      lo[k] = Math.min(lo[k], P[3 * v + k]);
      hi[k] = Math.max(hi[k], P[3 * v + k]);
    }
  });
  const centre = lo.map((x, k) => (x + hi[k]) / 2);
  const vf = await view(page);
  check(
    norm(sub(vf.target, centre)) < 1e-6 * h && dot(vf.dir, [-1, 0, 0]) > 0.999 && vf.dist < v0.dist,
    `orientation: Numpad . frames the fixed region: target ${JSON.stringify(vf.target.map((x) => +x.toFixed(4)))} = its box centre ${JSON.stringify(centre.map((x) => +x.toFixed(4)))}, closer (${vf.dist.toFixed(3)} < ${v0.dist.toFixed(3)}), same direction`,
  );
  await shot(page, "orient-numpad-frame-selection");

  await page.keyboard.press("?");
  const help = (await page.textContent("#shortcuts-list")) ?? "";
  check(/Numpad 1 \/ 3 \/ 7/.test(help) && /Ctrl\+Numpad 1 \/ 3 \/ 7/.test(help) && /Numpad \./.test(help) && /Alt\+Z/.test(help) && /Lasso/.test(help), "orientation: the ? list has Numpad 1 / 3 / 7, Ctrl+Numpad, Numpad ., Alt+Z (X-ray) and Lasso");
  await shot(page, "orient-shortcuts");
  await page.keyboard.press("Escape");
  await page.close();
}

export async function lassoChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded }) {
  const page = await openLibraryMesh(context, base, "lasso-lea", "cactus", { watchPage, waitLoaded });
  if (!(await hooksPresent(page, check, "lasso"))) return page.close();
  const hook = (fn, arg) => page.evaluate(fn, arg);
  await page.click('button[data-mode="lasso"]');
  await page.selectOption("#label-select", "0");
  // X-ray by its checkbox; Alt+Z turns it off and on again.
  await page.click("#xray");
  const byBox = await hook(() => window.hdeform.xray);
  await page.keyboard.press("Alt+z");
  const byKeyOff = await hook(() => window.hdeform.xray);
  await page.keyboard.press("Alt+z");
  const byKeyOn = await hook(() => window.hdeform.xray);
  check(byBox && !byKeyOff && byKeyOn && (await page.isChecked("#xray")), `lasso: the X-ray box turns X-ray on (${byBox}), Alt+Z off (${!byKeyOff}) and on (${byKeyOn}), the box follows`);

  const vp = await page.locator("#viewport canvas").boundingBox();
  const cx = vp.x + vp.width / 2, cy = vp.y + vp.height / 2;
  const expected = async () => {
    const { poly, proj, P } = await hook(() => ({ poly: window.hdeform.lastLasso(), proj: window.hdeform.projection(), P: window.hdeform.positions() }));
    const pts = project(proj, P);
    return { poly, proj, ids: new Set(pts.flatMap((p, v) => (p && inside(p, poly) ? [v] : []))) };
  };
  /** Every drawn corner (client px) lies on the recorded outline (viewport px) within 1.5 px. */
  const follows = (corners, poly, proj) => corners.every((c) => poly.some((p) => Math.hypot(p.x + proj.left - c.x, p.y + proj.top - c.y) < 1.5));

  const s1 = star(cx, cy, 200, 80);
  await lassoDrag(page, s1, sleep);
  const e1 = await expected();
  const got1 = region(await hook(() => window.hdeform.labels()));
  const n = (await hook(() => window.hdeform.labels())).length;
  check(
    e1.poly.length >= 20 && follows(s1, e1.poly, e1.proj) && got1.size > 50 && got1.size < n && same(got1, e1.ids),
    `lasso (X-ray): a star-shaped lasso (${e1.poly.length} points on the drawn path) selects ${got1.size} of ${n}: exactly the ${e1.ids.size} vertices projected inside it (${diffCount(got1, e1.ids)} differ)`,
  );
  await shot(page, "lasso-star-xray");

  // Shift adds the second outline's vertices, Ctrl removes the third's.
  const s2 = star(cx + 70, cy - 190, 120, 55, 4, 0.3); // the top of the trunk and the right arm, past the first star
  await lassoDrag(page, s2, sleep, "Shift");
  const e2 = await expected();
  const got2 = region(await hook(() => window.hdeform.labels()));
  const want2 = new Set([...got1, ...e2.ids]);
  const s3 = star(cx - 40, cy, 110, 110, 6); // a hexagon
  await lassoDrag(page, s3, sleep, "Control");
  const e3 = await expected();
  const got3 = region(await hook(() => window.hdeform.labels()));
  const want3 = new Set([...got2].filter((v) => !e3.ids.has(v)));
  check(
    follows(s2, e2.poly, e2.proj) && follows(s3, e3.poly, e3.proj) && got2.size > got1.size && same(got2, want2) && got3.size < got2.size && got3.size > 0 && same(got3, want3),
    `lasso (X-ray): Shift+lasso adds (${got1.size} → ${got2.size}, ${diffCount(got2, want2)} differ from the union), Ctrl+lasso removes (→ ${got3.size}, ${diffCount(got3, want3)} differ from the difference)`,
  );
  await shot(page, "lasso-shift-ctrl");

  // Visible only (X-ray off): the same star takes part of what X-ray took.
  await page.click("#xray");
  await hook(() => window.hdeform.select("none"));
  await lassoDrag(page, s1, sleep);
  const e4 = await expected();
  const got4 = region(await hook(() => window.hdeform.labels()));
  const outside = [...got4].filter((v) => !e4.ids.has(v)).length;
  check(
    !(await hook(() => window.hdeform.xray)) && got4.size > 20 && outside === 0 && got4.size < 0.9 * e4.ids.size,
    `lasso (visible only): the star takes ${got4.size} of the ${e4.ids.size} vertices inside it (${outside} outside it); the rest are behind the cactus's front (depth pass ${(await hook(() => window.hdeform.depthPassMs)).toFixed(1)} ms)`,
  );
  await shot(page, "lasso-star-visible");
  await page.close();
}

export async function visibleOnlyChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle }) {
  const page = await context.newPage();
  watchPage(page, "visible-vic");
  await page.setViewportSize({ width: 1400, height: 860 });
  await page.goto(base);
  await page.waitForSelector("#upload-input", { state: "attached", timeout: 30_000 });
  const { off, n } = sphereOff(250, 400);
  const t0 = Date.now();
  await page.setInputFiles("#upload-input", { name: "sphere-100k.off", mimeType: "text/plain", buffer: off });
  await page.waitForFunction(() => window.hdeform && window.hdeform.loaded && window.hdeform.sessionName !== "", null, { timeout: 180_000 });
  if (!(await hooksPresent(page, check, "visible-only"))) return page.close();
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const L0 = await hook(() => window.hdeform.labels());
  log(`visible-only: a closed sphere of ${L0.length} vertices (sent ${n}) open in ${Date.now() - t0} ms`);
  const cam = await hook(() => window.hdeform.camera());
  check(Math.abs(cam.up[1] - 1) < 1e-9, `visible-only: the sphere is shown y-up (camera up ${JSON.stringify(cam.up)})`);

  // The keypad on a y-up model: front looks along −z, top along −y, Ctrl+3 (left) along +x.
  const vp = await page.locator("#viewport canvas").boundingBox();
  await page.mouse.click(vp.x + 20, vp.y + vp.height / 2);
  for (const [key, want] of [["Numpad7", [0, -1, 0]], ["Control+Numpad3", [1, 0, 0]], ["Numpad1", [0, 0, -1]]]) {
    await page.keyboard.press(key);
    await settle(page, sleep);
    const v = await view(page);
    check(dot(v.dir, want) > 0.999, `visible-only: ${key} on a y-up model looks along ${JSON.stringify(want)} (· = ${dot(v.dir, want).toFixed(6)})`);
  }

  // Front view: a real box drag around the whole sphere, visible only (X-ray is off by default).
  await page.click('button[data-mode="box"]');
  await page.selectOption("#label-select", "0");
  const [bmin, bmax] = await hook(() => window.hdeform.bbox());
  const corners = [];
  for (const x of [bmin[0], bmax[0]]) for (const y of [bmin[1], bmax[1]]) for (const z of [bmin[2], bmax[2]]) corners.push(await hook(([a, b, c]) => window.hdeform.screenPoint(a, b, c), [x, y, z]));
  const x0 = Math.min(...corners.map((c) => c.x)) - 10, x1 = Math.max(...corners.map((c) => c.x)) + 10;
  const y0 = Math.min(...corners.map((c) => c.y)) - 10, y1 = Math.max(...corners.map((c) => c.y)) + 10;
  const boxDrag = async () => {
    await page.mouse.move(x0, y0);
    await page.mouse.down();
    await page.mouse.move((x0 + x1) / 2, (y0 + y1) / 2, { steps: 3 });
    await page.mouse.move(x1, y1, { steps: 3 });
    await page.mouse.up();
    await sleep(50);
  };
  const { P, camera } = await hook(() => ({ P: window.hdeform.positions(), camera: window.hdeform.camera() }));
  const N = P.length / 3;
  // Facing the camera: cos of the angle between the outward normal (the sphere is centred at 0) and the way to the camera.
  const facing = [];
  for (let v = 0; v < N; v++) {
    const p = [P[3 * v], P[3 * v + 1], P[3 * v + 2]];
    facing.push(dot(unit(p), unit(sub(camera.position, p))));
  }
  const sideCounts = (sel) => ({
    back: [...sel].filter((v) => facing[v] < -0.1).length,
    backAll: facing.filter((c) => c < -0.1).length,
    front: [...sel].filter((v) => facing[v] > 0.1).length,
    frontAll: facing.filter((c) => c > 0.1).length,
  });
  await boxDrag();
  const visible = region(await hook(() => window.hdeform.labels()));
  const c1 = sideCounts(visible);
  const depthMs = await hook(() => window.hdeform.depthPassMs);
  check(
    !(await hook(() => window.hdeform.xray)) && c1.back === 0 && c1.front === c1.frontAll && visible.size < 0.6 * N,
    `visible-only: a box around the sphere (front view) selects ${visible.size} of ${N}: ${c1.back} of the ${c1.backAll} on the far side, ${c1.front} of the ${c1.frontAll} facing the camera (depth pass ${depthMs.toFixed(1)} ms)`,
  );
  await shot(page, "visible-box-sphere");
  // The whole visible-only box select of 100K vertices, timed in the page (printed, not asserted).
  const timed = await hook(([a, b]) => {
    window.hdeform.select("none");
    const t = performance.now();
    window.hdeform.selectScreenRect(a, b, 0);
    return performance.now() - t;
  }, [{ x: x0 - vp.x, y: y0 - vp.y }, { x: x1 - vp.x, y: y1 - vp.y }]);
  log(`visible-only: the box select of ${N} vertices takes ${timed.toFixed(1)} ms in the page (depth pass ${(await hook(() => window.hdeform.depthPassMs)).toFixed(1)} ms)`);

  // A lasso around it: the same rule.
  await hook(() => window.hdeform.select("none"));
  await page.click('button[data-mode="lasso"]');
  const mx = (x0 + x1) / 2, my = (y0 + y1) / 2;
  await lassoDrag(page, star(mx, my, (x1 - x0) / 2 + 20, (x1 - x0) / 2 + 20, 12), sleep);
  const lassoed = region(await hook(() => window.hdeform.labels()));
  const c2 = sideCounts(lassoed);
  check(c2.back === 0 && c2.front === c2.frontAll, `visible-only: a lasso around the sphere selects ${lassoed.size}: ${c2.back} on the far side, ${c2.front} of the ${c2.frontAll} facing the camera`);
  await shot(page, "visible-lasso-sphere");

  // X-ray (Alt+Z): the box takes the far side too.
  await page.click('button[data-mode="box"]');
  await hook(() => window.hdeform.select("none"));
  await page.mouse.click(vp.x + 20, vp.y + vp.height / 2);
  await page.keyboard.press("Alt+z");
  await boxDrag();
  const all = region(await hook(() => window.hdeform.labels()));
  const c3 = sideCounts(all);
  check((await hook(() => window.hdeform.xray)) && all.size === N && c3.back === c3.backAll, `visible-only: with X-ray (Alt+Z) the same box selects ${all.size} of ${N} (far side ${c3.back} of ${c3.backAll})`);
  await shot(page, "visible-box-sphere-xray");

  // Numpad 5: orthographic (Blender's toggle). The picture's projection is orthographic, and the
  // tools see through it: a visible-only box takes exactly the half facing the view direction.
  await page.keyboard.press("Alt+z"); // X-ray off again
  await hook(() => window.hdeform.select("none"));
  await page.mouse.click(vp.x + 20, vp.y + vp.height / 2);
  const before = await view(page);
  await page.keyboard.press("Numpad5");
  await settle(page, sleep);
  const ortho = await hook(() => ({ on: window.hdeform.orthographic, P: window.hdeform.projectionMatrix() }));
  const after = await view(page);
  check(
    ortho.on && ortho.P[11] === 0 && ortho.P[15] === 1 && dot(before.dir, after.dir) > 0.999999,
    `orthographic: Numpad 5 draws an orthographic picture (P[11] ${ortho.P[11]}, P[15] ${ortho.P[15]}) looking the same way`,
  );
  await shot(page, "visible-ortho-sphere");
  const oc = [];
  for (const x of [bmin[0], bmax[0]]) for (const y of [bmin[1], bmax[1]]) for (const z of [bmin[2], bmax[2]]) oc.push(await hook(([a, b, c]) => window.hdeform.screenPoint(a, b, c), [x, y, z]));
  const ox0 = Math.min(...oc.map((c) => c.x)) - 10, ox1 = Math.max(...oc.map((c) => c.x)) + 10;
  const oy0 = Math.min(...oc.map((c) => c.y)) - 10, oy1 = Math.max(...oc.map((c) => c.y)) + 10;
  await page.mouse.move(ox0, oy0);
  await page.mouse.down();
  await page.mouse.move((ox0 + ox1) / 2, (oy0 + oy1) / 2, { steps: 3 });
  await page.mouse.move(ox1, oy1, { steps: 3 });
  await page.mouse.up();
  await sleep(50);
  const orthoSel = region(await hook(() => window.hdeform.labels()));
  // Facing an orthographic view: the outward normal against the view direction (every ray is parallel).
  const towards = after.dir.map((c) => -c);
  const oBack = [...orthoSel].filter((v) => dot(unit([P[3 * v], P[3 * v + 1], P[3 * v + 2]]), towards) < -0.1).length;
  const oFrontAll = facing.filter((_c, v) => dot(unit([P[3 * v], P[3 * v + 1], P[3 * v + 2]]), towards) > 0.1).length;
  const oFront = [...orthoSel].filter((v) => dot(unit([P[3 * v], P[3 * v + 1], P[3 * v + 2]]), towards) > 0.1).length;
  check(
    oBack === 0 && oFront === oFrontAll && orthoSel.size < 0.6 * N,
    `orthographic: a visible-only box around the sphere selects ${orthoSel.size} of ${N}: ${oBack} on the far side, ${oFront} of the ${oFrontAll} facing the view`,
  );
  await page.keyboard.press("Numpad5");
  await settle(page, sleep);
  const persp = await hook(() => ({ on: window.hdeform.orthographic, P: window.hdeform.projectionMatrix() }));
  check(!persp.on && persp.P[11] === -1 && persp.P[15] === 0, `orthographic: Numpad 5 again goes back to perspective (P[11] ${persp.P[11]}, P[15] ${persp.P[15]})`);
  await page.close();
}

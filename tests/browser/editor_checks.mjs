// The editor as people who know Blender / the three.js editor expect it (issue 12), driven with
// real mouse and keyboard events in headless Chromium against the real server (e2e.mjs runs
// these first, on sessions of their own):
//   layout — the empty state says what to do; the error banner and a long upload name do not
//     move the canvas; the upload label is cleared when a mesh opens;
//   view — the default 3/4 view shows all three gizmo arrows; F frames the handle (the orbit
//     target moves to it), Home / Reset view frame everything;
//   keys — W / E / R switch the gizmo (also entering Move), not while typing in a field; ? shows
//     the shortcuts; Esc and a right click cancel a drag back to its start, and the server
//     agrees (its shape is the pre-drag one); X keeps a drag to the x axis;
//   numbers — a typed-in translation moves the handle; the onboarding hint ticks off its steps
//     and goes once a handle moved;
//   failures — an update the server refuses snaps the gizmo back to the last confirmed pose;
//   β — the number box and the slider agree, sliding previews live (several SetBeta calls, at
//     most one in flight) and ends on the slider's value;
//   measures — emptied when another mesh opens; the energy legend has its title; the sweep
//     chart is on screen at 1400×860 without scrolling;
//   watchers — a watch page shows the editor's version, the frame's solve time and β;
//   several editors (needs a server with GrabHandles; skipped with a message otherwise) — two
//     editors drag different handles at once and both moves are kept; a drag of a handle the
//     other holds is refused with the holder's name; a watcher lists both names.

import { readFileSync } from "node:fs";

/** Page helpers shared with e2e.mjs. */
export async function editorChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle, positions, maxDiff }) {
  const W = 1400, H = 860;
  const page = await context.newPage();
  watchPage(page, "editor-ux");
  await page.setViewportSize({ width: W, height: H });
  await page.goto(base);
  await page.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const canvasBox = () => page.locator("#viewport canvas").boundingBox();
  const same = (a, b) => a && b && Math.abs(a.x - b.x) < 0.5 && Math.abs(a.y - b.y) < 0.5 && Math.abs(a.width - b.width) < 0.5 && Math.abs(a.height - b.height) < 0.5;

  // ---- layout: empty state, banner overlay, long upload name ------------------------------------
  const empty = (await page.textContent("#placeholder")) ?? "";
  check(/No mesh open/.test(empty) && /Upload/.test(empty) && (await page.isVisible("#placeholder")), "empty state says what to do before a mesh is open");
  const box0 = await canvasBox();
  const top0 = (await page.locator("#topbar").boundingBox()).height;
  const longName = `a-very-long-file-name-that-would-wrap-the-top-bar-${"x".repeat(80)}.obj`;
  await page.setInputFiles("#upload-input", { name: longName, mimeType: "text/plain", buffer: Buffer.from("not a mesh\n") });
  await page.waitForSelector("#banner:not(.hidden)", { timeout: 30_000 });
  const box1 = await canvasBox();
  const top1 = (await page.locator("#topbar").boundingBox()).height;
  check(same(box0, box1) && top0 === top1, `the error banner and a long upload name move neither the canvas (${JSON.stringify(box0)} → ${JSON.stringify(box1)}) nor the top bar (${top0} → ${top1} px)`);
  await shot(page, "ux-01-banner-overlay");
  await page.click("#banner-close");
  await page.selectOption("#library", "cactus");
  await page.click("#open-library");
  await waitLoaded(page, "editor-ux");
  check((await page.textContent("#upload-label")) === "", "the upload label is cleared when a mesh opens");
  check(same(await canvasBox(), box0), "opening a mesh does not move the canvas");

  // ---- regions (test hook), Apply; the onboarding hint ticks steps off ---------------------------
  check(await page.isVisible("#hint"), `onboarding hint shown after opening: "${await page.textContent("#hint")}"`);
  const [bmin, bmax] = await hook(() => window.hdeform.bbox());
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const h = bmax[up] - bmin[up];
  const slab = (from, to, extra = () => {}) => {
    const lo = bmin.map((v) => v - 1), hi = bmax.map((v) => v + 1);
    lo[up] = bmin[up] + from * h;
    hi[up] = bmin[up] + to * h;
    extra(lo, hi);
    return [lo, hi];
  };
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  const hint1 = (await page.innerHTML("#hint")) ?? "";
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01));
  // Handle 2: a side slab half-way up (an arm of the cactus), for the several-editor checks.
  const side = up === 2 ? 0 : 0;
  const n2 = await hook(([a, b]) => window.hdeform.selectBox(a, b, 2), slab(0.45, 0.65, (lo) => (lo[side] = bmax[side] - 0.25 * (bmax[side] - bmin[side]))));
  check(n2 > 0, `a second handle region (${n2} vertices)`);
  // Handle 3: one vertex, drawn as a marker (a vertex colour alone would hardly show).
  const lone = await hook(([u, lo, hi]) => {
    const L = window.hdeform.labels(), R = window.hdeform.restPositions();
    for (let v = 0; v < L.length; v++) if (L[v] === -1 && R[3 * v + u] > lo && R[3 * v + u] < hi) return [R[3 * v], R[3 * v + 1], R[3 * v + 2]];
    return null;
  }, [up, bmin[up] + 0.3 * h, bmin[up] + 0.35 * h]);
  const e = 1e-6;
  const nLone = await hook(([p, e]) => window.hdeform.selectBox(p.map((x) => x - e), p.map((x) => x + e), 3), [lone, e]);
  await sleep(100);
  const markers = await hook(() => window.hdeform.markerCount);
  check(nLone >= 1 && markers === nLone, `a single-vertex handle is drawn as a marker (${markers} marker(s) for ${nLone} vertex)`);
  // Hover feedback: Vertex mode marks the vertex a click would take; Brush shows its ring.
  const midPoint = await hook(([x, y, z]) => window.hdeform.screenPoint(x, y, z), bmin.map((a, k) => (k === up ? a + 0.3 * h : (a + bmax[k]) / 2)));
  await page.click('button[data-mode="vertex"]');
  await page.mouse.move(midPoint.x, midPoint.y);
  await page.mouse.move(midPoint.x + 2, midPoint.y + 1);
  await page.waitForFunction(() => window.hdeform.hoverVertex >= 0, null, { timeout: 5000 }).catch(() => {});
  check((await hook(() => window.hdeform.hoverVertex)) >= 0, `Vertex mode: the vertex under the cursor is marked (${await hook(() => window.hdeform.hoverVertex)})`);
  await page.click('button[data-mode="brush"]');
  await page.mouse.move(midPoint.x, midPoint.y);
  await page.mouse.move(midPoint.x + 1, midPoint.y + 2);
  await page.waitForFunction(() => window.hdeform.brushRing.visible, null, { timeout: 5000 }).catch(() => {});
  const ring = await hook(() => window.hdeform.brushRing);
  check(ring.visible && Math.abs(ring.radius - ring.expected) < 1e-9, `Brush mode: a ring of the brush's radius under the cursor (${ring.radius.toFixed(4)})`);
  await shot(page, "ux-01b-brush-ring-and-markers");
  await page.click("#apply");
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page);
  const hint2 = (await page.innerHTML("#hint")) ?? "";
  check(/step done/.test(hint1) && (hint2.match(/step done/g) ?? []).length === 3 && /done">✓ <b>Apply/.test(hint2) && (await page.isVisible("#hint")), "the hint ticks off 1 fixed, 2 handle and, after Apply, 3 Apply");

  // ---- the default view: all three arrows grabbable ----------------------------------------------
  await page.click('button[data-mode="move"]');
  await sleep(200);
  const arrowOf = (axis) =>
    hook((ax) => {
      const c = window.hdeform.gizmoScreenPoint(), a = window.hdeform.gizmoScreenPoint(ax);
      const len = Math.hypot(a.x - c.x, a.y - c.y);
      return { x: (a.x - c.x) / len, y: (a.y - c.y) / len, len, at: a };
    }, axis);
  const arrows = { x: await arrowOf("x"), y: await arrowOf("y"), z: await arrowOf("z") };
  const minLen = Math.min(arrows.x.len, arrows.y.len, arrows.z.len);
  const cam = await hook(() => window.hdeform.camera());
  check(minLen > 25, `default 3/4 view: every gizmo arrow is at least 25 px long on screen (x ${arrows.x.len.toFixed(0)}, y ${arrows.y.len.toFixed(0)}, z ${arrows.z.len.toFixed(0)}; camera up ${cam.up})`);
  // Move and Scale use the same (model) axes: the scale gizmo's z arrow is the move gizmo's.
  await page.keyboard.press("r");
  const zScale = await arrowOf("z");
  await page.keyboard.press("w");
  check(Math.abs(zScale.x - arrows.z.x) < 1e-3 && Math.abs(zScale.y - arrows.z.y) < 1e-3, "Scale and Move show the same axes (world = the model's axes)");
  await shot(page, "ux-02-default-view");

  // ---- keys ---------------------------------------------------------------------------------------
  await page.keyboard.press("e");
  const afterE = await hook(() => [window.hdeform.gizmoMode, window.hdeform.mode]);
  await page.keyboard.press("r");
  const afterR = await hook(() => window.hdeform.gizmoMode);
  await page.click("#display-name");
  await page.keyboard.press("w");
  const whileTyping = await hook(() => window.hdeform.gizmoMode);
  await page.keyboard.press("Escape");
  await page.locator("#display-name").blur();
  await page.click("#view-reset"); // focus away from the field, onto a button
  await page.keyboard.press("w");
  const afterW = await hook(() => window.hdeform.gizmoMode);
  check(afterE[0] === "rotate" && afterE[1] === "move" && afterR === "scale" && whileTyping === "scale" && afterW === "translate", `W / E / R switch the gizmo (${afterE}, ${afterR}, ${afterW}); a "w" typed into the name field does not (${whileTyping})`);
  check((await page.inputValue("#display-name")).includes("w"), "the w went into the name field");
  await page.fill("#display-name", "Ux Tester");
  await page.keyboard.press("Tab");
  await page.keyboard.press("?");
  const helpShown = await page.isVisible("#shortcuts");
  await shot(page, "ux-03-shortcuts");
  await page.keyboard.press("Escape");
  check(helpShown && !(await page.isVisible("#shortcuts")), "? shows the shortcuts overlay, Esc hides it");

  // Esc cancels a drag: the handle goes back and the server agrees.
  const t0 = await hook(() => window.hdeform.handleTransforms()[0].translation);
  const p0 = await positions(page);
  const horiz = arrows.x.len >= arrows.y.len ? ["x", arrows.x] : ["y", arrows.y];
  const dragStart = async (axis, dir, dist, pg = page) => {
    const p = await pg.evaluate((a) => window.hdeform.gizmoScreenPoint(a), axis);
    await pg.mouse.move(p.x, p.y);
    await sleep(50);
    await pg.mouse.down();
    for (let i = 1; i <= 8; i++) {
      await pg.mouse.move(p.x + (dir.x * dist * i) / 8, p.y + (dir.y * dist * i) / 8);
      await sleep(40);
    }
    return p;
  };
  await dragStart(horiz[0], horiz[1], 120);
  const moved = await hook(() => window.hdeform.handleTransforms()[0].translation);
  await page.keyboard.press("Escape");
  await page.mouse.up();
  await waitIdle(page);
  const t1 = await hook(() => window.hdeform.handleTransforms()[0].translation);
  const serverAfterEsc = await hook(() => window.hdeform.serverPositions());
  const d = (a, b) => Math.hypot(a.x - b.x, a.y - b.y, a.z - b.z);
  check(d(moved, t0) > 1e-3 && d(t1, t0) < 1e-9 && maxDiff(serverAfterEsc, p0) < 1e-5 && maxDiff(await positions(page), p0) < 1e-5, `Esc cancels a drag: the handle and the server's shape are back where the drag began (moved ${d(moved, t0).toFixed(3)}, back to ${d(t1, t0).toExponential(1)})`);
  // A right click cancels too.
  await dragStart(horiz[0], horiz[1], 100);
  const cur = await page.evaluate(() => window.hdeform.gizmoScreenPoint());
  await page.mouse.down({ button: "right" });
  await page.mouse.up({ button: "right" });
  await page.mouse.up();
  await waitIdle(page);
  const t2 = await hook(() => window.hdeform.handleTransforms()[0].translation);
  check(d(t2, t0) < 1e-9 && !(await hook(() => window.hdeform.gizmoDragging)), `a right click cancels a drag (${d(t2, t0).toExponential(1)} from the start; gizmo at ${cur.x.toFixed(0)},${cur.y.toFixed(0)})`);
  // X keeps a free (centre) drag to the x axis.
  const c = await page.evaluate(() => window.hdeform.gizmoScreenPoint());
  await page.mouse.move(c.x, c.y);
  await page.mouse.down();
  await page.mouse.move(c.x + 10, c.y - 10, { steps: 2 });
  await page.keyboard.press("x");
  for (let i = 1; i <= 6; i++) {
    await page.mouse.move(c.x + 10 + 12 * i, c.y - 10 - 9 * i);
    await sleep(40);
  }
  await page.mouse.up();
  await waitIdle(page);
  const t3 = await hook(() => window.hdeform.handleTransforms()[0].translation);
  check(Math.abs(t3.x - t0.x) > 1e-3 && Math.abs(t3.y - t0.y) < 1e-9 && Math.abs(t3.z - t0.z) < 1e-9, `X during a drag keeps it to the x axis (Δ = ${(t3.x - t0.x).toFixed(3)}, ${(t3.y - t0.y).toExponential(1)}, ${(t3.z - t0.z).toExponential(1)})`);
  const hint3 = await page.isVisible("#hint");
  check(!hint3, "the onboarding hint is gone once a handle moved");

  // ---- camera: F frames the handle, Home everything ------------------------------------------------
  await page.keyboard.press("f");
  const camF = await hook(() => window.hdeform.camera());
  const handleCentre = await hook(() => {
    const L = window.hdeform.labels(), P = window.hdeform.positions();
    const c = [0, 0, 0];
    let n = 0, mn = [Infinity, Infinity, Infinity], mx = [-Infinity, -Infinity, -Infinity];
    L.forEach((l, v) => {
      if (l !== 1) return;
      n++;
      for (let k = 0; k < 3; k++) { mn[k] = Math.min(mn[k], P[3 * v + k]); mx[k] = Math.max(mx[k], P[3 * v + k]); }
    });
    return n ? mn.map((a, k) => (a + mx[k]) / 2) : c;
  });
  const dist3 = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
  const diag = dist3(bmin, bmax);
  check(dist3(camF.target, handleCentre) < 1e-3 * diag, `F frames the active handle: the orbit target is its centre (${dist3(camF.target, handleCentre).toExponential(1)} off)`);
  await page.keyboard.press("Home");
  const camH = await hook(() => window.hdeform.camera());
  // Everything as it is now: the deformed shape and the gizmo (viewport/content_box.ts), all on screen.
  const [cmin, cmax] = await hook(() => window.hdeform.contentBox());
  const centre = cmin.map((a, k) => (a + cmax[k]) / 2);
  const offHome = await hook(() => window.hdeform.offScreen());
  check(dist3(camH.target, centre) < 1e-3 * diag && offHome.vertices === 0 && offHome.gizmo === 0, `Home frames everything: the orbit target is the centre of the current shape and gizmo, none of them off screen (${JSON.stringify(offHome)})`);
  await page.click("#view-frame");
  check(dist3((await hook(() => window.hdeform.camera())).target, handleCentre) < 1e-3 * diag, "the Frame selection button does what F does");
  await page.click("#view-reset");

  // Zoom to cursor: the point under the cursor stays under it while the wheel zooms.
  const cbox = await canvasBox();
  const cursor = { x: cbox.x + cbox.width / 2 + 160, y: cbox.y + cbox.height / 2 + 90 };
  const under = await hook(([x, y]) => window.hdeform.pointOnTargetPlane(x, y), [cursor.x, cursor.y]);
  const dist0 = dist3((await hook(() => window.hdeform.camera())).position, (await hook(() => window.hdeform.camera())).target);
  await page.mouse.move(cursor.x, cursor.y);
  await page.mouse.wheel(0, -300);
  await sleep(300);
  const underAfter = await hook(([x, y, z]) => window.hdeform.screenPoint(x, y, z), under);
  const camZ = await hook(() => window.hdeform.camera());
  check(dist3(camZ.position, camZ.target) < 0.95 * dist0 && Math.hypot(underAfter.x - cursor.x, underAfter.y - cursor.y) < 3, `the wheel zooms to the cursor (the point under it moved ${Math.hypot(underAfter.x - cursor.x, underAfter.y - cursor.y).toFixed(1)} px; distance ${dist0.toFixed(3)} → ${dist3(camZ.position, camZ.target).toFixed(3)})`);
  await page.click("#view-reset");

  // Q: world / local axes (also the Axes select).
  await page.keyboard.press("q");
  const spaceQ = [await hook(() => window.hdeform.gizmoSpace), await page.inputValue("#gizmo-space")];
  await page.keyboard.press("q");
  check(spaceQ.join() === "local,local" && (await hook(() => window.hdeform.gizmoSpace)) === "world", `Q toggles the gizmo between world and local axes (${spaceQ})`);

  // Ctrl held during a drag snaps the move to the grid.
  const grid = Number(await page.inputValue("#snap-grid"));
  await page.keyboard.down("Control");
  await dragStart(horiz[0], horiz[1], 77);
  await page.mouse.up();
  await page.keyboard.up("Control");
  await waitIdle(page);
  const snapped = await hook(() => window.hdeform.gizmoPose().position);
  const axisIndex = { x: 0, y: 1, z: 2 }[horiz[0]];
  const q = snapped[axisIndex] / grid;
  check(grid > 0 && Math.abs(q - Math.round(q)) < 1e-6, `Ctrl while dragging snaps the move to the ${grid} grid (${horiz[0]} = ${snapped[axisIndex]})`);

  // ---- typed-in values ----------------------------------------------------------------------------
  const typed = Number((t3.x + 0.05 * diag).toFixed(4));
  await page.fill("#tf-tx", String(typed));
  await page.keyboard.press("Enter");
  await waitIdle(page);
  const t4 = await hook(() => window.hdeform.handleTransforms()[0].translation);
  const shown4 = await positions(page);
  const server4 = await hook(() => window.hdeform.serverPositions());
  check(Math.abs(t4.x - typed) < 1e-9 && maxDiff(shown4, server4) === 0 && maxDiff(shown4, p0) > 1e-3, `a typed-in x translation (${typed}) moves the handle and the server solves it`);
  await page.fill("#tf-rz", "30");
  await page.keyboard.press("Enter");
  await waitIdle(page);
  const rot = await hook(() => window.hdeform.handleTransforms()[0].rotation);
  const wantRot = { w: Math.cos(Math.PI / 12), z: Math.sin(Math.PI / 12) };
  check(Math.abs(rot.w - wantRot.w) < 1e-9 && Math.abs(rot.z - wantRot.z) < 1e-9 && Math.abs(rot.x) < 1e-12 && Math.abs(rot.y) < 1e-12 && maxDiff(await positions(page), await hook(() => window.hdeform.serverPositions())) === 0, `a typed-in rotation of 30° about z is the handle's rotation (w ${rot.w.toFixed(6)}, z ${rot.z.toFixed(6)}) and is solved`);
  await shot(page, "ux-04-typed-values");
  await page.fill("#tf-rz", "0");
  await page.keyboard.press("Enter");
  await waitIdle(page);

  // ---- a refused update snaps the gizmo back ---------------------------------------------------------
  const confirmedBefore = await hook(() => window.hdeform.handleTransforms()[0].translation);
  const shapeBefore = await positions(page);
  await page.route("**/hdeform.v1.Deformation/UpdateHandles", (route) =>
    route.fulfill({ status: 200, headers: { "content-type": "application/grpc-web+proto", "grpc-status": "5", "grpc-message": "session gone (test)" }, body: "" }),
  );
  await dragStart(horiz[0], horiz[1], 90);
  await page.mouse.up();
  await page.waitForFunction(() => /rejected/.test(window.hdeform.lastError), null, { timeout: 10_000 }).catch(() => {});
  await waitIdle(page);
  await sleep(200);
  const tFail = await hook(() => window.hdeform.handleTransforms()[0].translation);
  const gizmoFail = await hook(() => window.hdeform.gizmoPose().position);
  const pivot = await hook(() => {
    const t = window.hdeform.handleTransforms()[0];
    return [t.pivot.x + t.translation.x, t.pivot.y + t.translation.y, t.pivot.z + t.translation.z];
  });
  const err = await hook(() => window.hdeform.lastError);
  check(
    d(tFail, confirmedBefore) < 1e-9 && dist3(gizmoFail, pivot) < 1e-9 && maxDiff(await positions(page), shapeBefore) === 0 && /rejected/.test(err),
    `a refused update puts the gizmo back on the pose the server confirmed ("${err}"; ${d(tFail, confirmedBefore).toExponential(1)} off)`,
  );
  await shot(page, "ux-05-refused-update");
  await page.unroute("**/hdeform.v1.Deformation/UpdateHandles");
  await page.click("#banner-close");

  // ---- β: number box, live preview ---------------------------------------------------------------------
  let betaCalls = 0;
  const countBeta = (r) => {
    if (/Deformation\/SetBeta/.test(r.url())) betaCalls++;
  };
  page.on("request", countBeta);
  const slider = await page.locator("#beta").boundingBox();
  await page.mouse.move(slider.x + 4, slider.y + slider.height / 2);
  await page.mouse.down();
  for (let i = 1; i <= 10; i++) {
    await page.mouse.move(slider.x + 4 + (i * (slider.width * 0.4)) / 10, slider.y + slider.height / 2);
    await sleep(60);
  }
  await page.mouse.up();
  await page.waitForFunction(() => !window.hdeform.busy && !/β/.test(window.hdeform.status), null, { timeout: 30_000 }).catch(() => {});
  await waitIdle(page);
  await sleep(300);
  const sliderValue = Number(await page.inputValue("#beta"));
  const numValue = Number(await page.inputValue("#beta-num"));
  const serverBeta = await hook(() => window.hdeform.serverBeta());
  page.off("request", countBeta);
  check(betaCalls >= 2 && sliderValue > 0.1 && Math.abs(numValue - sliderValue) < 1e-9 && Math.abs(serverBeta - sliderValue) < 1e-9, `β previews live while sliding (${betaCalls} SetBeta calls) and ends on the slider's value (slider ${sliderValue}, box ${numValue}, server ${serverBeta})`);
  await page.fill("#beta-num", "0.25");
  await page.keyboard.press("Enter");
  await page.waitForFunction(() => Math.abs(Number(document.querySelector("#beta").value) - 0.25) < 1e-9, null, { timeout: 5000 }).catch(() => {});
  await waitIdle(page);
  await sleep(300);
  check(Number(await page.inputValue("#beta")) === 0.25 && Math.abs((await hook(() => window.hdeform.serverBeta())) - 0.25) < 1e-9, "a β typed into the number box moves the slider and is sent");
  const rawTip = (await page.locator("label:has(#beta-raw)").getAttribute("title")) ?? "";
  check(/area/i.test(rawTip) && /model/i.test(rawTip), "the raw-units box's tooltip explains raw vs area units");

  // ---- energy legend, sweep chart on screen at 1400×860 --------------------------------------------------
  await page.selectOption("#energy-map", "linear");
  await waitIdle(page);
  const legendTitle = (await page.textContent("#legend-title")) ?? "";
  check((await page.isVisible("#legend")) && /‖r/.test(legendTitle) && /units²/.test(legendTitle), `the energy legend has a title with units: "${legendTitle}"`);
  await page.click("#sweep");
  await page.waitForFunction(() => window.hdeform.sweepRows > 0, null, { timeout: 60_000 });
  const chart = await page.locator("#chart").boundingBox();
  const scrolled = await page.evaluate(() => document.querySelector("#panel").scrollTop);
  check(chart && chart.y >= 0 && chart.y + chart.height <= H && scrolled === 0, `the sweep chart is on screen at ${W}×${H} without scrolling (y ${chart?.y.toFixed(0)}–${(chart?.y + chart?.height).toFixed(0)})`);
  await shot(page, "ux-06-energy-sweep-1400x860");
  await page.selectOption("#energy-map", "off");
  await waitIdle(page);

  // ---- a watcher: same version, solve time and β -------------------------------------------------------------
  const watchLink = await hook(() => window.hdeform.shareLink(true));
  const watcher = await context.newPage();
  watchPage(watcher, "ux-watch");
  await watcher.goto(watchLink);
  await waitLoaded(watcher, "ux watcher");
  await page.bringToFront();
  for (const sign of [1, -1]) {
    await dragStart(horiz[0], horiz[1], sign * 60);
    await page.mouse.up();
    await waitIdle(page);
  }
  const vEditor = await hook(() => window.hdeform.version);
  await watcher.waitForFunction((v) => window.hdeform.version >= v, vEditor, { timeout: 15_000 }).catch(() => {});
  await sleep(500);
  const vWatch = await watcher.evaluate(() => window.hdeform.version);
  const statusE = await hook(() => window.hdeform.status);
  const statusW = await watcher.evaluate(() => window.hdeform.status);
  const vOf = (s) => /version (\d+)/.exec(s)?.[1];
  check(vWatch === vEditor && vOf(statusW) === vOf(statusE), `the watcher's status line shows the editor's version (${vOf(statusW)} vs ${vOf(statusE)}; hook ${vWatch} vs ${vEditor})`);
  const solveW = (await watcher.textContent("#m-solve")) ?? "";
  const betaW = (await watcher.textContent("#m-beta")) ?? "";
  const betaE = (await page.textContent("#m-beta")) ?? "";
  check(/ms$/.test(solveW) && !/^0\.0 ms$/.test(solveW) && betaW === betaE && betaW !== "–", `the watcher shows the frame's solve time (${solveW}) and β (${betaW}, editor ${betaE})`);
  await shot(watcher, "ux-07-watcher");

  // ---- measures emptied on another mesh -----------------------------------------------------------------------
  const before = (await page.textContent("#m-e")) ?? "";
  // A mesh without the benchmark's ★ (nothing solves on it until regions are applied).
  const other = await page.evaluate(() => [...document.querySelectorAll("#library option")].find((o) => !o.textContent.includes("★") && o.value !== "cactus")?.value);
  await page.selectOption("#library", other);
  const prevName = await hook(() => window.hdeform.sessionName);
  await page.click("#open-library");
  await page.waitForFunction((p) => window.hdeform.loaded && window.hdeform.sessionName !== p, prevName, { timeout: 60_000 });
  const after = await Promise.all(["#m-e", "#m-flips", "#m-solve"].map((s) => page.textContent(s)));
  check(before !== "–" && after.every((t) => t === "–"), `the Measures table is emptied when another mesh (${other}) opens (${before} → ${after.join(", ")})`);
  // ---- ★ models open with the benchmark's regions in one click -----------------------------------------------
  const sel = readFileSync(new URL("../../data/botsch-sorkine/cactus.sel", import.meta.url), "utf8").split("\n").filter((l) => /^\d$/.test(l.trim()));
  const want = { fixed: sel.filter((l) => l.trim() === "0").length, handle: sel.filter((l) => l.trim() === "2").length };
  await page.selectOption("#library", "cactus");
  const prev = await hook(() => window.hdeform.sessionName);
  await page.click("#open-benchmark");
  await page.waitForFunction((p) => window.hdeform.sessionName !== p && window.hdeform.constraintsApplied, prev, { timeout: 60_000 });
  await waitIdle(page);
  const got = await hook(() => {
    const L = window.hdeform.labels();
    return { fixed: L.filter((l) => l === 0).length, handle: L.filter((l) => l === 1).length };
  });
  check(got.fixed === want.fixed && got.handle === want.handle && (await hook(() => window.hdeform.mode)) === "move", `Open ★ regions: the cactus opens with the benchmark's regions applied (fixed ${got.fixed}/${want.fixed}, handle ${got.handle}/${want.handle}), ready to move`);
  await shot(page, "ux-08-benchmark-regions");
  // Delete clears the region being assigned (here: Fixed), in a selection mode.
  await page.click('button[data-mode="box"]');
  await page.selectOption("#label-select", "0");
  await page.mouse.move(5, 300); // off any field
  await page.keyboard.press("Delete");
  const fixedLeft = await hook(() => window.hdeform.labels().filter((l) => l === 0).length);
  check(fixedLeft === 0 && /not applied/.test((await page.textContent("#region-counts")) ?? ""), `Delete clears the region being assigned (fixed ${want.fixed} → ${fixedLeft}, "not applied")`);
  await watcher.close();
  await page.close();
  return { watchLink };
}

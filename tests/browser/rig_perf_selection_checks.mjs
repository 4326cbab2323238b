// Export rig (issue 39 item 1), the perf overlay and selection habits (issue 37), in real pages
// against the real server (e2e.mjs runs them after the finished-editor checks; `--only rig`,
// `--only perf`, `--only selection` run one group):
//   rig — on the cactus with a moved handle and a 2-key timeline, "Export rig" (real clicks)
//     downloads SESSIONID-rig.glb that the Khronos validator passes with 0 errors and 0 warnings,
//     with a skin, the timeline's animation, JOINTS_1 with 8 influences, the server's z-up node
//     once (not wrapped again by the page; none for y-up); the report panel shows, per pose
//     (current, then each key time), ExportRig's own max / rms as % of the diagonal; a sheared
//     stretch shows the server's FAILED_PRECONDITION message; a watch page has no button;
//   perf — a 100,000-vertex tube uploaded through the page, P shows the overlay (frames/s,
//     update→frame latency, bytes/frame, page cost per frame), the Perf button hides it; a real
//     gizmo drag: the page's median cost per applied frame (decode + buffers + normals) is
//     printed against the ≤ 4 ms goal (not asserted: a time bound in a functional suite on a
//     shared machine would be noise);
//   selection — real box drags: a drag selects, Shift+drag adds, Ctrl+drag removes; All / None /
//     Invert / Grow / Shrink by button and by key (A, Alt+A, I, +, −) change the region's count as
//     they should and leave the other region alone.
import { readFileSync } from "node:fs";

/** A GLB's JSON chunk. */
function glbJson(bytes) {
  const b = Buffer.from(bytes);
  if (b.readUInt32LE(0) !== 0x46546c67) throw new Error("not a GLB");
  return JSON.parse(b.subarray(20, 20 + b.readUInt32LE(12)).toString("utf8"));
}

/** rig/rig_report.ts's percentOfDiagonal, for the check (the page must show exactly this). */
function percentOfDiagonal(f) {
  if (!Number.isFinite(f)) return "–";
  if (f === 0) return "0";
  const p = f * 100;
  return Math.abs(p) >= 1e-3 && Math.abs(p) < 1e5 ? String(Number(p.toPrecision(3))) : p.toExponential(2);
}

async function openCactus(context, base, name, { watchPage, waitLoaded }) {
  const page = await context.newPage();
  watchPage(page, name);
  await page.setViewportSize({ width: 1400, height: 860 });
  await page.goto(base);
  await page.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await page.selectOption("#library", "cactus");
  await page.click("#open-library");
  await waitLoaded(page, name);
  return page;
}

/** Model-space slabs along the model's up axis (the cactus is z-up). */
export async function slabs(page) {
  const [bmin, bmax] = await page.evaluate(() => window.hdeform.bbox());
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const h = bmax[up] - bmin[up];
  const slab = (from, to) => {
    const lo = bmin.map((v) => v - 1), hi = bmax.map((v) => v + 1);
    lo[up] = bmin[up] + from * h;
    hi[up] = bmin[up] + to * h;
    return [lo, hi];
  };
  return { slab, up, h };
}

export async function rigExportChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle, requireViewer }) {
  const page = await openCactus(context, base, "rig-ria", { watchPage, waitLoaded });
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const { slab, up, h } = await slabs(page);
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.85, 1.01));
  await page.click("#apply");
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page);
  const name = await hook(() => window.hdeform.sessionName);
  const id = name.replace(/^sessions\//, "");
  // A moved and turned handle (the current pose) and a timeline: rest at 0 s, the move at 1 s.
  const axis = ["x", "y", "z"][up];
  const s = Math.sin(Math.PI / 12), c = Math.cos(Math.PI / 12); // 30° about x
  const moved = { translation: { x: 0, y: 0, z: 0, [axis]: 0.15 * h }, rotation: { w: c, x: s, y: 0, z: 0 } };
  const set = await hook(([n, t]) => window.hdeform.call("updateHandles", { name: n, transforms: [t] }), [name, moved]);
  const tl = await hook(([n, t]) => window.hdeform.call("setTimeline", { name: n, timeline: { keys: [{ timeS: 0, transforms: [{}] }, { timeS: 1, transforms: [t] }] } }), [name, moved]);
  check(set.code === "OK" && tl.code === "OK", `rig: handle 0 moved and turned, a 2-key timeline (${set.code} ${set.message}; ${tl.code} ${tl.message})`);
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 2, null, { timeout: 10_000 }).catch(() => {});
  await waitIdle(page);
  check(await page.isVisible("#tl-rig"), "rig: the timeline strip has Export rig");

  const validator = requireViewer("gltf-validator");
  for (const [influences, upAxis] of [[4, "z"], [8, "y"]]) {
    await page.selectOption("#export-up", upAxis);
    await page.selectOption("#tl-rig-influences", String(influences));
    await page.waitForFunction(() => !document.querySelector("#tl-rig").disabled, null, { timeout: 10_000 });
    const t0 = Date.now();
    const [download] = await Promise.all([page.waitForEvent("download", { timeout: 60_000 }), page.click("#tl-rig")]);
    const bytes = readFileSync(await download.path());
    const ms = Date.now() - t0;
    const report = await validator.validateBytes(new Uint8Array(bytes));
    const { numErrors, numWarnings } = report.issues;
    const msgs = report.issues.messages.filter((m) => m.severity <= 1).map((m) => `${m.code} ${m.pointer ?? ""}`);
    const json = glbJson(bytes);
    const prim = json.meshes?.[0]?.primitives?.[0]?.attributes ?? {};
    const upNodes = (json.nodes ?? []).filter((n) => n.rotation && Math.abs(n.rotation[0] + Math.SQRT1_2) < 1e-6 && Math.abs(n.rotation[3] - Math.SQRT1_2) < 1e-6 && n.rotation[1] === 0 && n.rotation[2] === 0);
    check(
      download.suggestedFilename() === `${id}-rig.glb` && numErrors === 0 && numWarnings === 0 && (json.skins?.length ?? 0) >= 1 && (json.animations?.length ?? 0) === 1 &&
        "JOINTS_0" in prim && "WEIGHTS_0" in prim && ("JOINTS_1" in prim) === (influences === 8) && upNodes.length === (upAxis === "z" ? 1 : 0),
      `rig (${influences} influences, ${upAxis}-up): ${download.suggestedFilename()} ${(bytes.length / 1024).toFixed(0)} KiB in ${ms} ms: validator ${numErrors} errors, ${numWarnings} warnings${msgs.length ? ` (${msgs.slice(0, 4).join("; ")})` : ""}; skins ${json.skins?.length ?? 0} (${json.skins?.[0]?.joints?.length} joints), animations ${json.animations?.length ?? 0}, attributes ${Object.keys(prim).join(" ")}, z-up nodes ${upNodes.length}`,
    );
    // The panel shows the report of the server's first chunk: compared with ExportRig called again.
    await page.waitForSelector("#rig-report:not(.hidden)", { timeout: 10_000 });
    const shown = await page.$$eval("#rig-report-rows tr", (trs) => trs.map((tr) => [...tr.children].map((td) => td.textContent)));
    const server = await hook(([n, u]) => window.hdeform.exportRigReport(n, u), [influences, upAxis]);
    const want = (server?.poses ?? []).map((p) => [p.current ? "current" : `${p.timeS.toFixed(3)} s`, percentOfDiagonal(p.max), percentOfDiagonal(p.rms)]);
    check(
      server !== null && server.poses.length === 3 && JSON.stringify(shown) === JSON.stringify(want) && server.influences === influences,
      `rig: the panel shows ExportRig's report, % of the diagonal (${server?.bboxDiagonal?.toFixed(3)}): ${JSON.stringify(shown)} (server ${JSON.stringify(server?.poses?.map((p) => [p.current, p.timeS, p.max, p.rms]))})`,
    );
    const note = (await page.textContent("#tl-note")) ?? "";
    check(note.includes(`${id}-rig.glb`) && want.every(([, max]) => note.includes(`max ${max}`)), `rig: the strip says "${note}"`);
    await shot(page, `rig-report-${influences}-${upAxis}`);
  }

  // A sheared stretch cannot be a joint's TRS: the server's FAILED_PRECONDITION message shows.
  const sheared = await hook((n) => window.hdeform.call("updateHandles", { name: n, transforms: [{ scale: { case: "stretch", value: { m: [1, 0.3, 0, 0.3, 1, 0, 0, 0, 1] } } }] }), name);
  await waitIdle(page);
  const serverRefusal = await hook(() => window.hdeform.exportRigReport(4, "z").then(() => "", (e) => e.rawMessage ?? e.message));
  await page.click("#tl-rig");
  await page.waitForFunction(() => document.querySelector("#tl-note").classList.contains("err"), null, { timeout: 30_000 }).catch(() => {});
  const refusal = (await page.textContent("#tl-note")) ?? "";
  check(
    sheared.code === "OK" && serverRefusal !== "" && refusal.includes(serverRefusal) && /FailedPrecondition/.test(refusal) && (await page.isHidden("#rig-report")),
    `rig: a sheared stretch (${sheared.code} ${sheared.message}) is refused with the server's message: "${refusal}"`,
  );
  await shot(page, "rig-refused");

  // A watch page has no Export rig (ExportRig needs the edit token).
  const watchLink = await hook(() => window.hdeform.shareLink(true));
  const watcher = await context.newPage();
  watchPage(watcher, "rig-watcher");
  await watcher.goto(watchLink);
  await waitLoaded(watcher, "rig-watcher");
  check((await watcher.isHidden("#tl-rig")) && (await watcher.isHidden("#tl-rig-influences")), "rig: a watch page has no Export rig");
  await watcher.close();
  await page.close();
}

/** An open tube, rings × around vertices, as OFF (bench/wan/chromium_drag.mjs's mesh). */
function tubeOff(rings, around, height = 3, radius = 0.5) {
  const lines = ["OFF", `${rings * around} ${2 * around * (rings - 1)} 0`];
  for (let r = 0; r < rings; r++)
    for (let a = 0; a < around; a++) {
      const t = (2 * Math.PI * a) / around;
      lines.push(`${(radius * Math.cos(t)).toFixed(6)} ${(radius * Math.sin(t)).toFixed(6)} ${((height * r) / (rings - 1)).toFixed(6)}`);
    }
  for (let r = 0; r + 1 < rings; r++)
    for (let a = 0; a < around; a++) {
      const v = (rr, aa) => rr * around + (aa % around);
      lines.push(`3 ${v(r, a)} ${v(r, a + 1)} ${v(r + 1, a + 1)}`, `3 ${v(r, a)} ${v(r + 1, a + 1)} ${v(r + 1, a)}`);
    }
  return Buffer.from(lines.join("\n") + "\n");
}

export async function perfChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle }) {
  const page = await context.newPage();
  watchPage(page, "perf-paz");
  // A smaller canvas: software GL's draw (not part of the measured cost) then leaves the CPU to the page.
  await page.setViewportSize({ width: 640, height: 480 });
  await page.goto(base);
  await page.waitForSelector("#upload-input", { state: "attached", timeout: 30_000 });
  const rings = 250, around = 400, height = 3;
  const t0 = Date.now();
  await page.setInputFiles("#upload-input", { name: "tube-100k.off", mimeType: "text/plain", buffer: tubeOff(rings, around, height) });
  await page.waitForFunction(() => window.hdeform && window.hdeform.loaded && window.hdeform.sessionName !== "", null, { timeout: 180_000 });
  const n = await page.evaluate(() => window.hdeform.labels().length);
  log(`perf: ${n} vertices open in ${Date.now() - t0} ms`);
  await page.evaluate(([h]) => window.hdeform.selectBox([-1, -1, -0.01], [1, 1, 0.1 * h], 0), [height]);
  await page.evaluate(([h]) => window.hdeform.selectBox([-1, -1, 0.9 * h], [1, 1, 1.01 * h], 1), [height]);
  await page.evaluate(() => window.hdeform.applyConstraints()); // the side panel is a closed drawer at 640 px
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 180_000 });
  await waitIdle(page);
  // P shows the overlay, the Perf button hides it, P again shows it.
  await page.mouse.click(5, 300); // the side panel's edge would take keys into a field: focus the page
  await page.keyboard.press("p");
  const shownByKey = await page.evaluate(() => window.hdeform.perfShown);
  await page.evaluate(() => document.querySelector("#perf-toggle").click()); // in the drawer
  const hiddenByButton = !(await page.evaluate(() => window.hdeform.perfShown)) && (await page.isHidden("#perf"));
  await page.keyboard.press("p");
  check(shownByKey && hiddenByButton && (await page.isVisible("#perf")), `perf: P shows the overlay, its button hides it (${shownByKey}, ${hiddenByButton})`);

  await page.evaluate(() => window.hdeform.setMode("move"));
  await sleep(300);
  const p = await page.evaluate(() => window.hdeform.gizmoScreenPoint("x"));
  await page.evaluate(() => window.hdeform.perfReset());
  await page.mouse.move(p.x, p.y);
  await page.mouse.down();
  const start = Date.now();
  let moves = 0;
  while (Date.now() - start < 5000) {
    const s = (Date.now() - start) / 1000;
    await page.mouse.move(p.x + 80 * Math.sin((2 * Math.PI * s) / 3), p.y);
    moves++;
    const next = start + (moves * 1000) / 60;
    if (next > Date.now()) await sleep(next - Date.now());
  }
  // The overlay counts the frames of its last 2 s; on a loaded host the answer to the drag's
  // last moves can come later than that, so read it once one of this page's frames is in the window.
  await page
    .waitForFunction(
      () => {
        const s = window.hdeform.perfSummary();
        return s.frames > 0 && s.latencyMedianMs !== null && /update→frame\s+[\d.]+ ms/.test(window.hdeform.perfText());
      },
      null,
      { timeout: 60_000, polling: 50 },
    )
    .catch(() => log("perf: no frame of this page's drag was applied within 60 s of its end"));
  const [during, text] = await page.evaluate(() => [window.hdeform.perfSummary(), window.hdeform.perfText()]);
  await page.mouse.up();
  await waitIdle(page);
  await shot(page, "perf-overlay-100k");
  const costs = await page.evaluate(() => window.hdeform.perfCosts());
  log(`perf: 100K drag — ${costs.count} frames applied in 5 s; page cost per applied frame median ${costs.median?.toFixed(2)} ms, p90 ${costs.p90?.toFixed(2)} ms (decode median ${costs.decodeMedian?.toFixed(2)} ms; all: ${costs.costs.map((c, i) => `${c.toFixed(1)}/${costs.decodes[i].toFixed(1)}`).join(" ")}); overlay while dragging:\n${text}`);
  // Measured and printed, not asserted: a functional suite on a shared 2-core machine cannot
  // hold a time bound (speed is Google Benchmark's job); the goal is ≤ 4 ms on a quiet host.
  check(costs.count >= 2 && costs.median !== null && costs.median > 0, `perf: frames were applied and timed: ${costs.count} frames, page cost median ${costs.median?.toFixed(2)} ms (goal ≤ 4 ms on a quiet host: ${costs.median !== null && costs.median <= 4 ? "met" : "not met here"}), p90 ${costs.p90?.toFixed(2)} ms`);
  check(
    during.framesPerS > 0 && during.latencyMedianMs !== null && during.latencyMedianMs > 0 && during.bytesPerFrame > 0 &&
      /frames applied\/s\s+\d/.test(text) && /update→frame\s+[\d.]+ ms/.test(text) && /bytes\/frame\s+[\d.]+ (KiB|MiB|B)/.test(text) && /page cost\/frame\s+[\d.]+ ms/.test(text),
    `perf: the overlay shows frames/s ${during.framesPerS.toFixed(1)}, update→frame ${during.latencyMedianMs?.toFixed(1)} ms, ${(during.bytesPerFrame / 1024).toFixed(1)} KiB/frame, cost ${during.costMedianMs?.toFixed(2)} ms`,
  );
  await page.close();
}

export async function selectionChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded }) {
  const page = await openCactus(context, base, "select-sam", { watchPage, waitLoaded });
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const { slab } = await slabs(page);
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01)); // handle 0: the other region
  const n = (await hook(() => window.hdeform.labels())).length;
  const count = () => hook(() => window.hdeform.regionCount(0));
  const handleCount = () => hook(() => window.hdeform.regionCount(1));
  await page.click('button[data-mode="box"]');
  await page.selectOption("#label-select", "0");
  const vp = await page.locator("#viewport canvas").boundingBox();
  const cx = vp.x + vp.width / 2, cy = vp.y + vp.height / 2;
  const drag = async (x0, y0, x1, y1, modifier) => {
    if (modifier) await page.keyboard.down(modifier);
    await page.mouse.move(x0, y0);
    await page.mouse.down();
    await page.mouse.move((x0 + x1) / 2, (y0 + y1) / 2, { steps: 3 });
    await page.mouse.move(x1, y1, { steps: 3 });
    await page.mouse.up();
    if (modifier) await page.keyboard.up(modifier);
    await sleep(50);
  };
  await drag(cx - 150, cy - 200, cx, cy + 250);
  const c1 = await count();
  await drag(cx - 10, cy - 200, cx + 150, cy + 250, "Shift");
  const c2 = await count();
  await drag(cx - 100, cy - 100, cx + 100, cy + 100, "Control");
  const c3 = await count();
  const labels3 = await hook(() => window.hdeform.labels());
  const other = await handleCount(); // the commands leave it alone (a box drag takes vertices from it)
  check(c1 > 0 && c2 > c1 && c3 < c2 && c3 > 0, `selection: a box drag selects ${c1}, Shift+drag adds (${c2}), Ctrl+drag removes (${c3})`);
  await shot(page, "select-box-modifiers");

  // Buttons, then keys (the canvas has the focus after a click on it; the mode stays Box).
  const setOf = (labels) => new Set(labels.flatMap((l, v) => (l === 0 ? [v] : [])));
  const run = async (how, button, key) => {
    const before = await count();
    const labelsBefore = await hook(() => window.hdeform.labels());
    if (how === "button") await page.click(`#select-${button}`);
    else await page.keyboard.press(key);
    await sleep(30);
    const after = await count();
    const labelsAfter = await hook(() => window.hdeform.labels());
    return { before, after, was: setOf(labelsBefore), now: setOf(labelsAfter), unlabelledBefore: labelsBefore.filter((l) => l === -1).length };
  };
  for (const how of ["button", "key"]) {
    // Back to the Ctrl+drag result for each round.
    await hook((l) => {
      window.hdeform.select("none");
      const ids = [];
      l.forEach((x, v) => x === 0 && ids.push(v));
      return window.hdeform.selectIds(ids, 0);
    }, labels3);
    await page.mouse.move(vp.x + 5, vp.y + 5);
    const grow = await run(how, "grow", "+");
    const grownOk = grow.after > grow.before && [...grow.was].every((v) => grow.now.has(v));
    const shrink = await run(how, "shrink", "-");
    const shrunkOk = shrink.after < shrink.before && [...shrink.now].every((v) => shrink.was.has(v));
    const invert = await run(how, "invert", "i");
    const invertOk = invert.after === invert.unlabelledBefore && [...invert.was].every((v) => !invert.now.has(v));
    const all = await run(how, "all", "a");
    const allOk = all.after === n - (await handleCount());
    const none = await run(how, "none", "Alt+a");
    check(
      grownOk && shrunkOk && invertOk && allOk && none.after === 0 && (await handleCount()) === other,
      `selection by ${how}: grow ${grow.before} → ${grow.after}, shrink ${shrink.before} → ${shrink.after}, invert ${invert.before} → ${invert.after} (${invert.unlabelledBefore} were free), all ${all.before} → ${all.after} (of ${n}, handle 0 keeps ${await handleCount()} of ${other}), none ${none.before} → ${none.after}`,
    );
  }
  // The shortcuts list names them.
  await page.keyboard.press("?");
  const help = (await page.textContent("#shortcuts-list")) ?? "";
  check(/Alt\+A/.test(help) && /invert/.test(help) && /grow \/ shrink/.test(help) && /Shift\+drag/.test(help) && /Ctrl\+drag/.test(help) && /perf overlay/.test(help), "selection: the ? list has A / Alt+A, I, + / −, Shift / Ctrl+drag and P");
  await shot(page, "select-shortcuts");
  await page.close();
}

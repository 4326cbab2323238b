// The timeline strip (issue 13, the viewer's part) in real pages with real mouse and keyboard
// against the real server:
//   keys — three keys set with K at three playhead times (ruler clicks), each with another pose
//     (a gizmo drag, typed-in values): GetTimeline has them, times and transforms;
//   scrub — dragging the playhead to a mid time makes the session's transforms PoseAt(t);
//     a click a few px from a key snaps onto it;
//   live — a second editor sees the keys on join and a new key live; Delete removes it for both;
//   export — the downloaded SESSIONID-animation.glb passes the Khronos glTF validator (0 errors;
//     warnings reported), energies off and on;
//   mixer — three.js's AnimationMixer on that GLB: at sample times the morphed positions equal the
//     server's exact frame of PoseAt(t_k) (UpdateHandles), in between the linear blend of the
//     two neighbouring samples;
//   play — Play shows the animation (two canvas shots differ), Stop returns to the live mesh;
//   clear — a second editor's new constraints ask before dropping the keys, then empty the strip on
//     both pages, with a note; his Ctrl+Z brings the keys back, Ctrl+Shift+Z drops them again;
//   bad input — fps 500 and 721 frames (> --max-animation-frames 600) show the server's message;
//   key edits (issue 37) — the selected key's marker dragged with the mouse to a new time (one
//     SetTimeline, one TIMELINE step, the other keys untouched), Esc mid-drag (nothing changes), a
//     drop onto another key (refused, with the message), Ctrl+C / Ctrl+V (the copied pose keyed
//     at the playhead, also over a key there), Backspace, and a watch page refusing them.
// Screenshots `timeline-*.png`. Against a server without GetTimeline: SKIP, nothing checked.
import { readFileSync } from "node:fs";

// The strip redraws its markers (innerHTML) on every timeline event, so a marker found a moment
// ago may be detached when it is measured (boundingBox → null): measure until one holds still.
async function keyMarkerBox(page, index) {
  const marker = page.locator(`.tl-key[data-index="${index}"]`);
  for (let tries = 0; tries < 100; tries++) {
    const box = await marker.boundingBox({ timeout: 2_000 }).catch(() => null);
    if (box) return box;
    await new Promise((r) => setTimeout(r, 20));
  }
  throw new Error(`the timeline's key marker ${index} is not on screen`);
}

export async function timelineChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle, positions, maxDiff, requireViewer }) {
  const page = await context.newPage();
  watchPage(page, "timeline");
  await page.setViewportSize({ width: 1400, height: 860 });
  await page.goto(base);
  await page.fill("#display-name", "Tia");
  await page.press("#display-name", "Tab");
  await page.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await page.selectOption("#library", "cactus");
  await page.click("#open-library");
  await waitLoaded(page, "timeline");
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const name = await hook(() => window.hdeform.sessionName);
  const id = name.replace(/^sessions\//, "");
  const probe = await hook((n) => window.hdeform.call("getTimeline", { name: n }), name);
  if (/unimplemented/i.test(probe.code)) {
    log(`SKIP timeline: this hdeform-server has no GetTimeline (${probe.code}: ${probe.message})`);
    await page.close();
    return false;
  }
  const tl = () => hook(() => window.hdeform.timeline());
  const unfocus = () => page.click("#panel h3 >> nth=0");
  const rulerClick = async (t, p = page, dx = 0) => {
    const r = await p.evaluate((tt) => window.hdeform.rulerPoint(tt), t);
    await p.mouse.click(r.x + dx, r.y + 6); // below the key markers: the ruler itself
  };
  const settle = async (p = page) => {
    await p.waitForFunction(() => !window.hdeform.timeline().scrubbing, null, { timeout: 15_000 });
    await waitIdle(p);
  };
  // Transforms compared as numbers; a quaternion and its negative are the same rotation.
  const tfDiff = (a, b) => {
    if (!a || !b || a.length !== b.length) return Infinity;
    let d = 0;
    a.forEach((x, h) => {
      const y = b[h];
      const qd = Math.min(maxDiff(x.rotation, y.rotation), maxDiff(x.rotation, y.rotation.map((v) => -v)));
      d = Math.max(d, maxDiff(x.translation, y.translation), qd, maxDiff(x.stretch, y.stretch));
    });
    return d;
  };

  // Regions: fixed bottom, handle 1 the top, handle 2 a side slab.
  const [bmin, bmax] = await hook(() => window.hdeform.bbox());
  const diag = Math.hypot(...bmax.map((v, k) => v - bmin[k]));
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const h = bmax[up] - bmin[up];
  const slab = (from, to, side) => {
    const lo = bmin.map((v) => v - 1), hi = bmax.map((v) => v + 1);
    lo[up] = bmin[up] + from * h;
    hi[up] = bmin[up] + to * h;
    if (side) lo[0] = bmax[0] - 0.25 * (bmax[0] - bmin[0]);
    return [lo, hi];
  };
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01));
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 2), slab(0.45, 0.65, true));
  await page.click("#apply");
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page);
  await page.click('button[data-mode="move"]');
  await sleep(200);

  const strip = await page.locator("#timeline").boundingBox();
  const canvas = await page.locator("#viewport canvas").boundingBox();
  check(
    strip && canvas && Math.abs(strip.y + strip.height - (canvas.y + canvas.height)) < 1.5 && strip.height < 80 && (await page.isVisible("#tl-setkey")),
    `the strip runs along the bottom of the canvas (${strip?.height.toFixed(0)} px high, canvas ${canvas?.width.toFixed(0)}×${canvas?.height.toFixed(0)})`,
  );
  const rows = await page.$$eval("#shortcuts-list tr", (trs) => trs.map((tr) => [tr.querySelector("kbd")?.textContent, tr.querySelector("td")?.textContent]));
  check(rows.some(([k, what]) => k === "K" && /set a key/.test(what)), "the ? overlay lists K (set a key)");

  // ---- three keys ------------------------------------------------------------------------------
  const dragArrow = async (px, axis = "x") => {
    const c = await hook(() => window.hdeform.gizmoScreenPoint());
    const a = await hook((ax) => window.hdeform.gizmoScreenPoint(ax), axis);
    const len = Math.hypot(a.x - c.x, a.y - c.y);
    await page.mouse.move(a.x, a.y);
    await sleep(50);
    await page.mouse.down();
    for (let i = 1; i <= 8; i++) {
      await page.mouse.move(a.x + ((a.x - c.x) / len) * px * (i / 8), a.y + ((a.y - c.y) / len) * px * (i / 8));
      await sleep(40);
    }
    await page.mouse.up();
    await waitIdle(page);
  };
  const keyed = []; // { time, transforms } as the session had them when K was pressed
  const setKeyWithK = async (what) => {
    const before = (await tl()).keys.length;
    const session = await hook(() => window.hdeform.sessionTransforms());
    const t = (await tl()).playhead;
    await page.keyboard.press("k");
    await page.waitForFunction((n) => window.hdeform.timeline().keys.length > n, before, { timeout: 10_000 }).catch(() => {});
    keyed.push({ time: t, transforms: session, what });
  };
  await rulerClick(0);
  await settle();
  await setKeyWithK("rest");
  await rulerClick(1);
  await settle();
  await dragArrow(60); // (a click on the ruler now would pose the handles at key 1 again)
  await setKeyWithK("handle 1 dragged along x");
  await rulerClick(2);
  await settle();
  // Typed-in values: handle 1 up and turned, then handle 2 dragged.
  await page.fill("#tf-tz", "0.25");
  await page.keyboard.press("Enter");
  await page.fill("#tf-rx", "30");
  await page.keyboard.press("Enter");
  await page.waitForFunction(async () => Math.abs((await window.hdeform.sessionTransforms())[0].rotation[1]) > 0.1, null, { timeout: 10_000, polling: 200 }).catch(() => {});
  await waitIdle(page);
  await page.selectOption("#active-handle", "2");
  await sleep(200);
  await dragArrow(-50, "y");
  await page.selectOption("#active-handle", "1");
  await unfocus();
  await setKeyWithK("handle 1 typed (z 0.25, 30° about x), handle 2 dragged");
  await shot(page, "timeline-01-three-keys");
  const server = await hook(() => window.hdeform.serverTimeline());
  const times = server.keys.map((k) => k.time);
  const tDiffs = keyed.map((k, i) => Math.abs((times[i] ?? Infinity) - k.time));
  const trDiffs = keyed.map((k, i) => tfDiff(server.keys[i]?.transforms, k.transforms));
  const distinct = Math.min(tfDiff(keyed[0].transforms, keyed[1].transforms), tfDiff(keyed[1].transforms, keyed[2].transforms));
  check(
    server.keys.length === 3 && Math.max(...tDiffs) === 0 && Math.abs(times[1] - 1) < 0.02 && Math.abs(times[2] - 2) < 0.02 && times[0] === 0 && server.author === "Tia",
    `K three times: GetTimeline has 3 keys at ${JSON.stringify(times)} s (the playhead's times), set by ${server.author}`,
  );
  check(Math.max(...trDiffs) < 1e-9 && distinct > 1e-3, `…each with the session's transforms when K was pressed (max |Δ| ${Math.max(...trDiffs).toExponential(1)}; poses differ by ≥ ${distinct.toFixed(3)})`);
  check(
    (await page.$$eval(".tl-key", (els) => els.length)) === 3 && JSON.stringify((await tl()).keys) === JSON.stringify(times),
    "the strip shows the 3 keys as markers",
  );

  // ---- scrub --------------------------------------------------------------------------------------
  const from = await hook(() => window.hdeform.rulerPoint(0.3));
  const to = await hook(() => window.hdeform.rulerPoint(1.5));
  const posesBefore = (await tl()).posesApplied;
  const stepsBefore = (await hook(() => window.hdeform.history())).length;
  await page.mouse.move(from.x, from.y + 6);
  await page.mouse.down();
  for (let i = 1; i <= 12; i++) {
    await page.mouse.move(from.x + ((to.x - from.x) * i) / 12, from.y + 6);
    await sleep(40);
  }
  await page.mouse.up();
  await settle();
  const mid = (await tl()).playhead;
  const [atMid, sess, shown, solved] = [
    await hook((t) => window.hdeform.poseAt(t), mid),
    await hook(() => window.hdeform.sessionTransforms()),
    await positions(page),
    await hook(() => window.hdeform.serverPositions()),
  ];
  const applied = (await tl()).posesApplied - posesBefore;
  await sleep(300); // the step event
  const newSteps = (await hook(() => window.hdeform.history())).slice(0, (await hook(() => window.hdeform.history())).length - stepsBefore);
  check(
    Math.abs(mid - 1.5) < 0.02 && tfDiff(atMid, sess) < 1e-9 && tfDiff(atMid, keyed[1].transforms) > 1e-3 && tfDiff(atMid, keyed[2].transforms) > 1e-3,
    `scrubbed to ${mid} s (${applied} poses applied on the way): the session's transforms are PoseAt(${mid}) (max |Δ| ${tfDiff(atMid, sess).toExponential(1)}), between keys 2 and 3`,
  );
  check(maxDiff(shown, solved) < 1e-6, `…and the page shows the server's shape of that pose (max |Δ| ${maxDiff(shown, solved).toExponential(1)})`);
  check(newSteps.length === 1 && newSteps[0].kind === "MOVE" && newSteps[0].author === "Tia", `…as one history step (${newSteps.map((s) => `${s.kind} "${s.summary}"`).join(", ")})`);
  await shot(page, "timeline-02-scrubbed");
  await rulerClick(1, page, 3); // 3 px right of key 2: snaps onto it
  await settle();
  const snapped = await tl();
  check(snapped.playhead === times[1] && snapped.selected === 1, `a click 3 px from key 2 snaps the playhead onto it (${snapped.playhead} s) and selects its marker`);
  // A scrub may start on a key's marker (issue 37: the marker used to swallow the press): from
  // key 3's marker back to 1.6 s.
  const mk = await keyMarkerBox(page, 2);
  const [mx, my] = [mk.x + mk.width / 2, mk.y + mk.height / 2];
  const toB = await hook(() => window.hdeform.rulerPoint(1.6));
  await page.mouse.move(mx, my);
  await page.mouse.down();
  for (let i = 1; i <= 10; i++) {
    await page.mouse.move(mx + ((toB.x - mx) * i) / 10, my);
    await sleep(40);
  }
  await page.mouse.up();
  await settle();
  const fromKey = await tl();
  const [atB, sessB] = [await hook((t) => window.hdeform.poseAt(t), fromKey.playhead), await hook(() => window.hdeform.sessionTransforms())];
  check(
    Math.abs(fromKey.playhead - 1.6) < 0.02 && tfDiff(atB, sessB) < 1e-9 && tfDiff(atB, keyed[2].transforms) > 1e-3,
    `a scrub that starts on key 3's marker moves the playhead to ${fromKey.playhead} s and poses the session there (max |Δ| ${tfDiff(atB, sessB).toExponential(1)})`,
  );
  await shot(page, "timeline-02b-scrub-from-key");

  // ---- a second editor: keys on join, a new key live, Delete ------------------------------------------
  const bob = await context.newPage();
  watchPage(bob, "timeline-bob");
  await bob.setViewportSize({ width: 1100, height: 760 });
  await bob.goto(await hook(() => window.hdeform.shareLink(false)));
  await waitLoaded(bob, "timeline-bob");
  await bob.waitForFunction((n) => window.hdeform.timeline().keys.length === n, 3, { timeout: 10_000 }).catch(() => {});
  check(JSON.stringify((await bob.evaluate(() => window.hdeform.timeline())).keys) === JSON.stringify(times), "a second editor's page shows the 3 keys on opening");
  await rulerClick(3);
  await settle();
  await setKeyWithK("at 3 s");
  const live = await bob.waitForFunction(() => window.hdeform.timeline().keys.length === 4, null, { timeout: 10_000 }).then(() => true, () => false);
  check(live, `Tia's 4th key appears on Bob's strip live (${JSON.stringify((await bob.evaluate(() => window.hdeform.timeline())).keys)})`);
  await shot(bob, "timeline-03-bob-sees-key");
  // Select the marker with the mouse, Delete with the strip focused.
  const marker = await keyMarkerBox(page, 3);
  await page.mouse.click(marker.x + marker.width / 2, marker.y + marker.height / 2);
  await settle();
  const sel = await tl();
  await page.keyboard.press("Delete");
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).catch(() => {});
  const bobGone = await bob.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).then(() => true, () => false);
  const afterDelete = await hook(() => window.hdeform.serverTimeline());
  check(sel.selected === 3 && afterDelete.keys.length === 3 && bobGone && (await hook(() => window.hdeform.labels().length)) > 0, `a click on the 4th marker selects it; Delete removes it (server: ${afterDelete.keys.length} keys; Bob's strip too; the regions stay)`);

  // ---- export: the Khronos glTF validator, energies off and on -----------------------------------------
  const validator = requireViewer("gltf-validator");
  const exportGlb = async (what) => {
    const [download] = await Promise.all([page.waitForEvent("download", { timeout: 60_000 }), page.click("#tl-export")]);
    const bytes = readFileSync(await download.path());
    const report = await validator.validateBytes(new Uint8Array(bytes));
    const { numErrors, numWarnings, numInfos } = report.issues;
    const warnings = report.issues.messages.filter((m) => m.severity === 1).map((m) => `${m.code} ${m.pointer ?? ""}`);
    check(
      download.suggestedFilename() === `${id}-animation.glb` && numErrors === 0 && bytes.length > 1000,
      `Export (${what}) downloads ${download.suggestedFilename()} (${(bytes.length / 1024).toFixed(0)} KiB): glTF validator ${numErrors} errors, ${numWarnings} warnings${warnings.length ? ` (${[...new Set(warnings)].slice(0, 4).join("; ")})` : ""}, ${numInfos} infos`,
    );
    if (numErrors > 0) log(JSON.stringify(report.issues.messages.filter((m) => m.severity === 0).slice(0, 5)));
    return bytes;
  };
  const glb = await exportGlb("energies off");
  await page.selectOption("#energy-map", "linear");
  await waitIdle(page);
  const glbE = await exportGlb("energies on");
  const withColours = await hook(([b]) => window.hdeform.sampleAnimation(b, [0]), [glbE.toString("base64")]);
  check(withColours.colours && !(await hook(([b]) => window.hdeform.sampleAnimation(b, [0]), [glb.toString("base64")])).colours, "…the energies export has COLOR_0, the other none");
  await page.selectOption("#energy-map", "off");
  await waitIdle(page);

  // ---- three.js AnimationMixer vs the server's frames ---------------------------------------------------
  const b64 = glb.toString("base64");
  const info = await hook(([b]) => window.hdeform.sampleAnimation(b, []), [b64]);
  const ct = info.clipTimes;
  const offset = ct[0] === 0 ? times[0] : 0; // clip time 0 = the first key's time
  const K = ct.length;
  const picks = [0, 1, Math.floor(K / 3), Math.floor(K / 2), K - 2, K - 1];
  const between = [[1, 0.5], [Math.floor(K / 2), 0.3], [K - 2, 0.75]];
  const sampleTimes = [...picks.map((k) => ct[k]), ...between.map(([k, a]) => ct[k] + a * (ct[k + 1] - ct[k]))];
  const mixed = await hook(([b, ts]) => window.hdeform.sampleAnimation(b, ts), [b64, sampleTimes]);
  const frames = new Map();
  const frameOf = async (k) => {
    if (!frames.has(k)) frames.set(k, await hook((t) => window.hdeform.exactFrameAt(t), offset + ct[k]));
    return frames.get(k);
  };
  let worstSample = 0, worstBetween = 0, oneHot = true;
  const perSample = [];
  for (let i = 0; i < picks.length; i++) {
    const k = picks[i];
    const d = maxDiff(mixed.samples[i].positions, await frameOf(k)) / diag;
    perSample.push(d.toExponential(1));
    worstSample = Math.max(worstSample, d);
    const w = mixed.samples[i].influences;
    const want = w.map((_, j) => (j === k - 1 ? 1 : 0)); // frame 0 is the base mesh: no target
    if (maxDiff(w, want) > 1e-6) oneHot = false;
  }
  for (let i = 0; i < between.length; i++) {
    const [k, a] = between[i];
    const [p0, p1] = [await frameOf(k), await frameOf(k + 1)];
    const blend = p0.map((v, j) => (1 - a) * v + a * p1[j]);
    worstBetween = Math.max(worstBetween, maxDiff(mixed.samples[picks.length + i].positions, blend) / diag);
  }
  check(
    K >= 2 && info.targets === K - 1 && Math.abs(info.duration - (times[2] - times[0])) < 1e-6 && oneHot,
    `the GLB: ${K} samples (${info.targets} morph targets + the base mesh), ${info.duration.toFixed(3)} s, weights one-hot at the sample times`,
  );
  check(
    worstSample < 1e-5,
    `AnimationMixer.setTime at ${picks.length} sample times (${picks.map((k) => (offset + ct[k]).toFixed(3)).join(", ")} s): base + Σ influence × target = the server's exact frame of PoseAt(t) (max |Δ| ${worstSample.toExponential(2)} × bbox diagonal; each: ${perSample.join(", ")})`,
  );
  check(worstBetween < 1e-5, `…at ${between.length} in-between times: the linear blend of the two neighbouring samples (max |Δ| ${worstBetween.toExponential(2)} × bbox diagonal)`);
  await waitIdle(page);

  // ---- Play / Stop ----------------------------------------------------------------------------------------
  await page.click("#tl-play");
  await page.waitForFunction(() => window.hdeform.timeline().playing, null, { timeout: 60_000 }).catch(() => {});
  const canvasShot = () => page.locator("#viewport canvas").screenshot();
  await sleep(300);
  const t1 = (await tl()).playTime;
  const s1 = await canvasShot();
  await sleep(700);
  const t2 = (await tl()).playTime;
  const s2 = await canvasShot();
  await shot(page, "timeline-04-playing");
  const playing = await tl();
  check(playing.playing && !playing.liveMeshShown && t1 !== t2 && !s1.equals(s2) && (await page.textContent("#tl-play")) === "Stop", `Play: the animation plays in place of the live mesh (time ${t1?.toFixed(2)} → ${t2?.toFixed(2)} s, playhead ${playing.playhead.toFixed(2)}; two canvas shots differ)`);
  await page.click("#tl-play");
  await sleep(300);
  const stopped = await tl();
  const liveShape = await positions(page);
  const serverShape = await hook(() => window.hdeform.serverPositions());
  check(!stopped.playing && stopped.liveMeshShown && (await page.textContent("#tl-play")) === "Play" && maxDiff(liveShape, serverShape) < 1e-6, "Stop returns to the live mesh (shown again, the server's current shape)");
  await shot(page, "timeline-05-stopped");

  // ---- Bob's new constraints: asked first (Tia's keys), then the strip clears on both pages; his Ctrl+Z
  // brings the keys back, Ctrl+Shift+Z drops them again ---------------------------------------------------------
  const dialogs = [];
  bob.on("dialog", (d) => {
    dialogs.push(d.message());
    void d.accept();
  });
  await bob.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 2), slab(0.35, 0.65, true));
  await bob.click("#apply");
  await waitIdle(bob);
  const cleared = await page.waitForFunction(() => window.hdeform.timeline().keys.length === 0, null, { timeout: 10_000 }).then(() => true, () => false);
  const bobCleared = await bob.waitForFunction(() => window.hdeform.timeline().keys.length === 0, null, { timeout: 10_000 }).then(() => true, () => false);
  const notes = [(await tl()).note, await bob.evaluate(() => window.hdeform.timeline().note)];
  check(dialogs.length === 1 && /3 key/.test(dialogs[0]) && /Undo brings them back/.test(dialogs[0]), `Bob's Apply asks before dropping Tia's keys ("${(dialogs[0] ?? "no dialog").split("\n")[0]}")`);
  check(cleared && bobCleared && notes.every((n) => /cleared/.test(n) && /constraints/.test(n)), `new constraints clear the strip on both pages, with a note ("${notes[0]}")`);
  await shot(bob, "timeline-06-cleared");
  await bob.keyboard.press("Control+z");
  const keysBack = await page.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).then(() => true, () => false);
  const bobKeysBack = await bob.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).then(() => true, () => false);
  const bobError = await bob.evaluate(() => window.hdeform.lastError);
  check(keysBack && bobKeysBack, `Bob's Ctrl+Z undoes his constraints and brings Tia's 3 keys back on both pages${keysBack ? "" : ` (Bob's page: "${bobError}")`}`);
  await bob.keyboard.press("Control+Shift+z");
  const clearedAgain = await page.waitForFunction(() => window.hdeform.timeline().keys.length === 0, null, { timeout: 10_000 }).then(() => true, () => false);
  check(clearedAgain && dialogs.length === 1, "Ctrl+Shift+Z redoes them (the keys go again, nothing asked: they were Bob's to drop once)");
  await waitIdle(page);
  await bob.close();

  // ---- bad input: the server's message inline -------------------------------------------------------------------
  await page.click('button[data-mode="move"]');
  await rulerClick(0);
  await settle();
  await page.keyboard.press("k");
  await rulerClick(4.9);
  await settle();
  await page.keyboard.press("k");
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 2, null, { timeout: 10_000 }).catch(() => {});
  await page.fill("#tl-fps", "500");
  await page.click("#tl-export");
  await page.waitForFunction(() => /failed/.test(window.hdeform.timeline().note), null, { timeout: 15_000 }).catch(() => {});
  const fpsNote = (await tl()).note;
  const fpsShown = await page.isVisible("#tl-note");
  check(/fps/.test(fpsNote) && /InvalidArgument/.test(fpsNote) && fpsShown, `fps 500: the strip shows the server's message ("${fpsNote}")`);
  await rulerClick(6.5);
  await settle();
  await page.keyboard.press("k");
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).catch(() => {});
  await page.fill("#tl-fps", "120");
  await page.click("#tl-play");
  await page.waitForFunction(() => /failed/.test(window.hdeform.timeline().note), null, { timeout: 15_000 }).catch(() => {});
  const framesNote = (await tl()).note;
  check(/ResourceExhausted/.test(framesNote) && /max-animation-frames/.test(framesNote) && !(await tl()).playing, `${(await tl()).keys.at(-1)} s at 120 fps (> 600 frames): Play shows the server's message ("${framesNote}")`);
  await shot(page, "timeline-07-too-many-frames");
  await page.fill("#tl-fps", "24");
  await keyEditChecks({ page, context, log, check, sleep, shot, watchPage, waitLoaded, settle, rulerClick, tfDiff });
  await page.close();
  return true;
}

// Issue 37: keys moved by dragging their marker, copied and pasted, on the timeline the checks
// above leave (3 keys). Every gesture is the real mouse and keyboard; the server's GetTimeline
// and the History panel are the judges.
async function keyEditChecks({ page, context, log, check, sleep, shot, watchPage, waitLoaded, settle, rulerClick, tfDiff }) {
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const tl = () => hook(() => window.hdeform.timeline());
  const state = await tl();
  // The hooks these checks read: missing ones are a failure, not a reason to skip.
  const missing = ["keyDragTime", "copiedFrom"].filter((k) => !(k in state));
  check(missing.length === 0, `the test hook has timeline().keyDragTime and .copiedFrom${missing.length ? ` (missing: ${missing.join(", ")})` : ""}`);
  if (missing.length) return;
  const server = () => hook(() => window.hdeform.serverTimeline());
  const steps = async () => (await hook(() => window.hdeform.history())).length;
  const newSteps = async (before) => {
    await sleep(400); // the step event
    const all = await hook(() => window.hdeform.history());
    return all.slice(0, all.length - before);
  };
  const sameKeys = (a, b) => a.keys.length === b.keys.length && a.keys.every((k, i) => k.time === b.keys[i].time && tfDiff(k.transforms, b.keys[i].transforms) === 0 && k.beta === b.keys[i].beta);
  const clickMarker = async (index, p = page) => {
    const m = await keyMarkerBox(p, index);
    await p.mouse.click(m.x + m.width / 2, m.y + m.height / 2);
    await settle(p);
  };
  // Press the marker's centre and move in steps to x (the callback runs before the release).
  const dragMarker = async (index, x, { steps: n = 10, before } = {}) => {
    const m = await keyMarkerBox(page, index);
    const [mx, my] = [m.x + m.width / 2, m.y + m.height / 2];
    await page.mouse.move(mx, my);
    await page.mouse.down();
    for (let i = 1; i <= n; i++) {
      await page.mouse.move(mx + ((x - mx) * i) / n, my);
      await sleep(30);
    }
    const during = before ? await before() : undefined;
    await page.mouse.up();
    return during;
  };
  const secondsPerPx = await hook(() => 1 / (window.hdeform.rulerPoint(1).x - window.hdeform.rulerPoint(0).x));

  // ---- drag key 2 to 3 s: one SetTimeline, one step ----------------------------------------------------
  const start = await server();
  check(start.keys.length === 3, `key edits start from 3 keys (${JSON.stringify(start.keys.map((k) => k.time))} s)`);
  await clickMarker(1); // a click selects (and scrubs to it); dragging the selected key moves it
  const from = start.keys[1].time;
  const target = 3;
  const to = await hook((t) => window.hdeform.rulerPoint(t), target);
  let stepsBefore = await steps();
  const during = await dragMarker(1, to.x, {
    before: async () => {
      await shot(page, "timeline-08-key-drag");
      return { tl: await tl(), time: await page.textContent("#tl-time") };
    },
  });
  await page.waitForFunction((f) => !window.hdeform.timeline().keys.includes(f), from, { timeout: 10_000 }).catch(() => {});
  await page.waitForFunction(() => /moved/.test(window.hdeform.timeline().note), null, { timeout: 10_000 }).catch(() => {});
  const moved = await server();
  const added = await newSteps(stepsBefore);
  const mk = moved.keys[1];
  check(
    (await tl()).selected === 1 && during.tl.keyDragTime !== null && Math.abs(during.tl.keyDragTime - target) <= secondsPerPx && /→/.test(during.time) && during.tl.keys[1] === from,
    `dragging the selected key's marker shows its new time ("${during.time}") while the list is unchanged`,
  );
  check(
    moved.keys.length === 3 && Math.abs(mk.time - target) <= secondsPerPx && tfDiff(mk.transforms, start.keys[1].transforms) === 0 && mk.beta === start.keys[1].beta,
    `…on release GetTimeline has key 2 at ${mk?.time} s (wanted ${target} ± ${secondsPerPx.toFixed(4)} s, one pixel), its pose unchanged`,
  );
  check(
    [0, 2].every((i) => moved.keys[i].time === start.keys[i].time && tfDiff(moved.keys[i].transforms, start.keys[i].transforms) === 0),
    "…the other keys are unchanged (times and transforms)",
  );
  const movedNote = (await tl()).note;
  check(
    added.length === 1 && added[0].kind === "TIMELINE" && /Key moved from/.test(movedNote),
    `…as one history step (${added.map((s) => `${s.kind} "${s.summary}"`).join(", ")}); the strip says "${movedNote}"`,
  );

  // ---- Esc mid-drag: nothing changes --------------------------------------------------------------------
  const markerX = (await keyMarkerBox(page, 1)).x;
  const towards = await hook(() => window.hdeform.rulerPoint(1.5));
  stepsBefore = await steps();
  const escaped = await dragMarker(1, towards.x, {
    before: async () => {
      const mid = (await tl()).keyDragTime;
      await page.keyboard.press("Escape");
      await sleep(50);
      return { mid, after: (await tl()).keyDragTime };
    },
  });
  await sleep(300);
  const afterEsc = await server();
  const escSteps = await newSteps(stepsBefore);
  check(
    escaped.mid !== null && escaped.after === null && sameKeys(afterEsc, moved) && escSteps.length === 0 && Math.abs((await keyMarkerBox(page, 1)).x - markerX) < 0.5,
    `Esc during a key drag (at ${escaped.mid} s) cancels it: the marker back at ${mk.time} s, GetTimeline unchanged, no history step`,
  );

  // ---- a drop onto another key: refused, the key back where it was -------------------------------------------
  const onto = await keyMarkerBox(page, 2);
  stepsBefore = await steps();
  await dragMarker(1, onto.x + onto.width / 2);
  await page.waitForFunction(() => /not moved/.test(window.hdeform.timeline().note), null, { timeout: 5_000 }).catch(() => {});
  const refusedNote = (await tl()).note;
  await shot(page, "timeline-09-drop-refused");
  const afterRefusal = await server();
  check(
    /not moved/.test(refusedNote) && refusedNote.includes(moved.keys[2].time.toFixed(3)) && (await page.getAttribute("#tl-note", "class")).includes("err") && sameKeys(afterRefusal, moved) && (await newSteps(stepsBefore)).length === 0 && JSON.stringify((await tl()).keys) === JSON.stringify(moved.keys.map((k) => k.time)),
    `a drop onto key 3 is refused ("${refusedNote}"): GetTimeline unchanged, no step, the marker back`,
  );

  // ---- Ctrl+C / Ctrl+V -------------------------------------------------------------------------------------------
  await clickMarker(2);
  await page.keyboard.press("Control+c");
  const copiedFrom = (await tl()).copiedFrom;
  await rulerClick(2);
  await settle();
  const pasteAt = (await tl()).playhead;
  stepsBefore = await steps();
  await page.keyboard.press("Control+v");
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 4, null, { timeout: 10_000 }).catch(() => {});
  const pasted = await server();
  const pk = pasted.keys.find((k) => k.time === pasteAt);
  const pasteSteps = await newSteps(stepsBefore);
  check(
    copiedFrom === moved.keys[2].time && pasted.keys.length === 4 && pk && tfDiff(pk.transforms, moved.keys[2].transforms) === 0 && pk.beta === moved.keys[2].beta && pasteSteps.length === 1,
    `Ctrl+C on key 3 (${copiedFrom} s), Ctrl+V at the playhead (${pasteAt} s): a 4th key there with the same pose (${pasteSteps.length} step)`,
  );
  check(
    moved.keys.every((k) => pasted.keys.some((p) => p.time === k.time && tfDiff(p.transforms, k.transforms) === 0)),
    "…the other keys are unchanged",
  );
  await shot(page, "timeline-10-pasted");
  // Pasting over a key replaces it, as setting a key does: key 1's pose onto the pasted key.
  await clickMarker(0);
  await page.keyboard.press("Control+c");
  await clickMarker(1); // the pasted key (the playhead goes to its exact time)
  await page.keyboard.press("Control+v");
  await page.waitForFunction(() => /Pasted the key from 0/.test(window.hdeform.timeline().note), null, { timeout: 10_000 }).catch(() => {});
  const replaced = await server();
  const rk = replaced.keys.find((k) => k.time === pasteAt);
  check(
    replaced.keys.length === 4 && rk && tfDiff(rk.transforms, pasted.keys[0].transforms) === 0,
    `Ctrl+V onto a key's time replaces it (still 4 keys; the key at ${pasteAt} s now holds key 1's pose)`,
  );
  // Backspace (the strip focused) deletes the selected key.
  await page.keyboard.press("Backspace");
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).catch(() => {});
  const afterDelete = await server();
  check(afterDelete.keys.length === 3 && !afterDelete.keys.some((k) => k.time === pasteAt), `Backspace deletes the selected key (${afterDelete.keys.length} keys left)`);

  // ---- a watch page refuses them --------------------------------------------------------------------------------
  const watcher = await context.newPage();
  watchPage(watcher, "timeline-watch");
  await watcher.setViewportSize({ width: 1100, height: 760 });
  await watcher.goto(await hook(() => window.hdeform.shareLink(true)));
  await waitLoaded(watcher, "timeline-watch");
  await watcher.waitForFunction(() => window.hdeform.timeline().keys.length === 3, null, { timeout: 10_000 }).catch(() => {});
  await clickMarker(1, watcher);
  const wSel = (await watcher.evaluate(() => window.hdeform.timeline())).selected;
  await watcher.keyboard.press("Control+c");
  const wCopy = await watcher.evaluate(() => window.hdeform.timeline());
  await watcher.keyboard.press("Control+v");
  await sleep(200);
  const wPaste = (await watcher.evaluate(() => window.hdeform.timeline())).note;
  // Dragging the selected marker scrubs there (a local playhead), it moves no key.
  const wm = await keyMarkerBox(watcher, 1);
  const wTo = await watcher.evaluate(() => window.hdeform.rulerPoint(0.5));
  await watcher.mouse.move(wm.x + wm.width / 2, wm.y + wm.height / 2);
  await watcher.mouse.down();
  for (let i = 1; i <= 8; i++) {
    await watcher.mouse.move(wm.x + wm.width / 2 + ((wTo.x - wm.x - wm.width / 2) * i) / 8, wm.y + wm.height / 2);
    await sleep(30);
  }
  await watcher.mouse.up();
  await sleep(300);
  const wAfter = await watcher.evaluate(() => window.hdeform.timeline());
  check(
    wSel === 1 && wCopy.copiedFrom === null && /Watch-only/.test(wCopy.note) && /Watch-only/.test(wPaste) && sameKeys(await server(), afterDelete) && wAfter.keyDragTime === null && Math.abs(wAfter.playhead - 0.5) < 0.05,
    `a watch page refuses Ctrl+C / Ctrl+V ("${wPaste}"), and a drag of its selected marker only moves its playhead (${wAfter.playhead} s): the timeline unchanged`,
  );
  await shot(watcher, "timeline-11-watch-refuses");
  await watcher.close();
  // ---- a key's own easing: the selected key's segment eases, the timeline's others stay --------------------
  // Smoothstep maps u = 0.25 to 0.15625, and every part of a transform is interpolated in u:
  // eased PoseAt(t₀ + 0.25 Δ) must be linear PoseAt(t₀ + 0.15625 Δ).
  // Three keys that move every handle up (the edits above left equal poses), set through the API.
  const handles = (await server()).keys[0].transforms.length;
  const rise = (z) => Array.from({ length: handles }, () => ({ translation: { x: 0, y: 0, z } }));
  const setUp = await hook(
    ([n, h]) => window.hdeform.call("setTimeline", { name: n, clientId: "timeline-check", timeline: { keys: h.map((z, i) => ({ timeS: i, transforms: z })) } }),
    [await hook(() => window.hdeform.sessionName), [rise(0), rise(0.3), rise(0.6)]],
  );
  await page.waitForFunction(() => window.hdeform.timeline().keys.length === 3 && window.hdeform.timeline().keys[2] === 2, null, { timeout: 10_000 }).catch(() => {});
  const before = await server();
  check(setUp.code === "OK" && before.keys.length === 3, `a timeline of three rising keys is set for the easing check (${setUp.code} ${setUp.message})`);
  const seg = 1;
  const at = (u) => before.keys[seg].time + u * (before.keys[seg + 1].time - before.keys[seg].time);
  const linearAt = await hook((t) => window.hdeform.poseAt(t), at(0.15625));
  const linearQuarter = await hook((t) => window.hdeform.poseAt(t), at(0.25));
  await clickMarker(seg);
  const easeBefore = await steps();
  const keyEasingEnabled = await page.isEnabled("#tl-key-easing");
  await page.selectOption("#tl-key-easing", "1"); // smoothstep
  await page.waitForFunction((i) => window.hdeform.timeline().keyEasings?.[i] === 1, seg, { timeout: 10_000 }).catch(() => {});
  const eased = await server();
  const easedQuarter = await hook((t) => window.hdeform.poseAt(t), at(0.25));
  const easeSteps = await newSteps(easeBefore);
  const others = eased.keys.every((k, i) => i === seg || k.easing === before.keys[i].easing);
  const off = tfDiff(easedQuarter, linearAt);
  const apart = tfDiff(linearQuarter, linearAt);
  check(
    keyEasingEnabled && apart > 1e-3 && off < 1e-9 && eased.keys[seg].easing === 1 && others && easeSteps.length === 1 && easeSteps[0].kind === "TIMELINE",
    `"key: smoothstep" on key ${seg} eases its segment only: PoseAt at u = 0.25 is ${off.toExponential(1)} from the linear pose at u = 0.15625 (the linear quarter is ${apart.toFixed(3)} away), key easings ${JSON.stringify(eased.keys.map((k) => k.easing))}, ${easeSteps.length} step`,
  );
  await clickMarker(eased.keys.length - 1);
  check(await page.isDisabled("#tl-key-easing"), "the last key's easing is disabled (it starts no segment)");
  await shot(page, "timeline-10b-key-easing");

  log(`key edits: one pixel is ${secondsPerPx.toFixed(4)} s on this ruler`);
}

// The viewer as a finished editor (issue 37), in real pages against the real server (e2e.mjs runs
// these after the editor checks, on sessions of their own):
//   test hook — the production bundle (web-viewer/dist) has none of window.hdeform's code and its
//     page works without it (served by a server of its own); the tests' build has it;
//   no mesh — Apply constraints and Sweep β say "open a mesh first"; the banner lies over the
//     canvas only: every top-bar control stays visible and clickable (Open works under it);
//   numbers — the β box shows 0.99 and a β another client set (0.9875) whole, the threshold box
//     3.57e-25 whole (not scrolled, not cut);
//   share link — copying it puts the link on the clipboard and no token in the status line;
//   presence — after opening another mesh the list holds this session's people only;
//   view token as `#edit=` — the page asks the server what the token may do and opens watch-only,
//     saying so (an amber notice, not a PermissionDenied error); no edit is sent; the address
//     becomes the watch link; the server lists the page as a viewer; the probe changed nothing;
//   no mesh, more — Clear, Clear all, Reset transforms and a snapshot's Save say "open a mesh first";
//   first steps — marking both regions does not tick Apply; Apply does;
//   noise — an undeformed pose's E reads 0, its sweep charts flat at 0, a 3.57e-25 threshold paints
//     no noise; the energy legend's title is whole; History has no scroll box of its own and an
//     empty one says why; handles are numbered from 0 as in the server's messages;
//   settings — after another mesh opens: energy map off, threshold and "Assign to" reset, no frame
//     sizes of the old session in the status line;
//   camera — a shared session opened already deformed, Home, Frame all and a reload frame the
//     deformed shape and the gizmo (no vertex off screen);
//   GLB up axis — the z-up cactus downloads with a root node rotating +z to +y, its BIN chunk
//     GetMesh's byte for byte; y-up downloads GetMesh's bytes;
//   layout — at 1400×860, 1024×700 and 900×600 the top bar's controls lie inside it without
//     overlapping, Share / Watch links stay, the name is whole, the presence list, status line and
//     view buttons do not overlap; at 900 the side panel is a drawer (screenshots layout-*.png).
import { readdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { slabs } from "./rig_perf_selection_checks.mjs";

/** The text of every script vite emitted into `dist`. */
function bundleText(dist) {
  const dir = join(dist, "assets");
  return readdirSync(dir)
    .filter((f) => f.endsWith(".js"))
    .map((f) => readFileSync(join(dir, f), "utf8"))
    .join("\n");
}

/** The input's text is cut: it scrolls (Chromium scrolls a text control's inner editor). */
const clipped = (page, selector) =>
  page.evaluate((s) => {
    const el = document.querySelector(s);
    el.scrollLeft = 10_000;
    const cut = el.scrollLeft > 0;
    el.scrollLeft = 0;
    return cut;
  }, selector);

/** Top-bar controls that something else covers at their centre. */
const coveredTopBarControls = (page) =>
  page.evaluate(() => {
    const covered = [];
    for (const el of document.querySelectorAll("#topbar button, #topbar select, #topbar input:not([type=file]), #topbar label.button")) {
      const r = el.getBoundingClientRect();
      if (r.width === 0 || r.height === 0) continue; // hidden
      const hit = document.elementFromPoint(r.x + r.width / 2, r.y + r.height / 2);
      if (!hit || !(el === hit || el.contains(hit))) covered.push(el.id || el.textContent.trim());
    }
    return covered;
  });

const personTexts = (page) => page.$$eval("#presence .person", (els) => els.map((e) => e.textContent.trim()));

/** A GLB's JSON (parsed) and its chunks after the JSON one (the BIN chunk: header, data, padding). */
function glbParts(bytes) {
  const b = Buffer.from(bytes);
  if (b.readUInt32LE(0) !== 0x46546c67 || b.readUInt32LE(8) !== b.length) throw new Error("not a GLB, or a wrong length");
  const jsonLength = b.readUInt32LE(12);
  return { json: JSON.parse(b.subarray(20, 20 + jsonLength).toString("utf8")), rest: b.subarray(20 + jsonLength), aligned: jsonLength % 4 === 0 && b.length % 4 === 0 };
}

/** Rectangles intersect (by more than half a pixel). */
const overlap = (a, b) => a && b && a.x + a.width - 0.5 > b.x && b.x + b.width - 0.5 > a.x && a.y + a.height - 0.5 > b.y && b.y + b.height - 0.5 > a.y;

/** The top bar at this window size: its visible controls, whether each lies inside it, and the pairs that overlap. */
const topBarLayout = (page) =>
  page.evaluate(() => {
    const bar = document.querySelector("#topbar").getBoundingClientRect();
    const els = [...document.querySelectorAll("#topbar .brand, #topbar button, #topbar select, #topbar input:not([type=file]), #topbar label.button, #topbar progress, #session-label, #upload-label, #watch-badge")];
    const items = els
      .map((el) => ({ id: el.id || el.textContent.trim(), r: el.getBoundingClientRect().toJSON(), visible: getComputedStyle(el).visibility !== "hidden" }))
      .filter((i) => i.visible && i.r.width > 0 && i.r.height > 0);
    const outside = items.filter((i) => i.r.x < bar.x - 0.5 || i.r.right > Math.min(bar.right, window.innerWidth) + 0.5 || i.r.y < bar.y - 0.5 || i.r.bottom > bar.bottom + 0.5).map((i) => i.id);
    const pairs = [];
    for (let a = 0; a < items.length; a++)
      for (let b = a + 1; b < items.length; b++) {
        const [p, q] = [items[a].r, items[b].r];
        if (p.x + p.width - 0.5 > q.x && q.x + q.width - 0.5 > p.x && p.y + p.height - 0.5 > q.y && q.y + q.height - 0.5 > p.y) pairs.push(`${items[a].id} × ${items[b].id}`);
      }
    const covered = items.filter((i) => {
      const hit = document.elementFromPoint(i.r.x + i.r.width / 2, i.r.y + i.r.height / 2);
      const el = document.getElementById(i.id);
      return el && !(hit === el || el.contains(hit));
    }).map((i) => i.id);
    return { ids: items.map((i) => i.id), outside, pairs, covered, barHeight: bar.height, scrollWidth: document.documentElement.scrollWidth, innerWidth: window.innerWidth };
  });

export async function finishedEditorChecks({ context, base, prodBase, prodDist, testDist, log, check, sleep, shot, watchPage, waitLoaded, waitIdle, artifacts }) {
  // ---- the test hook is in the tests' build only ---------------------------------------------------
  const markers = ["window.hdeform=", "workerDecodeRecycled", "serverPositions", "gizmoScreenPoint", "selectBox"];
  const prodJs = bundleText(prodDist);
  const testJs = bundleText(testDist);
  const inProd = markers.filter((m) => prodJs.includes(m));
  check(
    inProd.length === 0 && markers.every((m) => testJs.includes(m)),
    `the production bundle has none of the test hook's code (${inProd.length ? `found ${inProd.join(", ")}` : markers.join(", ")}), the tests' build has it`,
  );
  const prod = await context.newPage();
  watchPage(prod, "production");
  await prod.goto(prodBase);
  await prod.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await prod.selectOption("#library", "cactus");
  await prod.click("#open-library");
  const prodOpened = await prod
    .waitForFunction(() => /sessions\//.test(document.querySelector("#session-label").textContent) && document.querySelector("#placeholder").classList.contains("hidden"), null, { timeout: 60_000 })
    .then(() => true, () => false);
  const prodHook = await prod.evaluate(() => typeof window.hdeform);
  check(
    prodOpened && prodHook === "undefined" && (await prod.isHidden("#banner")),
    `the production page opens the cactus without a test hook (window.hdeform: ${prodHook}; "${await prod.textContent("#session-label")}")`,
  );
  await prod.close();

  // ---- no mesh yet: Apply and Sweep say so; the banner leaves the top bar usable ------------------
  const page = await context.newPage();
  watchPage(page, "finish-pia");
  await page.setViewportSize({ width: 1400, height: 860 });
  await page.goto(base);
  await page.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await page.fill("#display-name", "Pia");
  await page.press("#display-name", "Tab");
  const hook = (fn, arg) => page.evaluate(fn, arg);
  const bannerText = async () => ((await page.isVisible("#banner")) ? ((await page.textContent("#banner-text")) ?? "") : "");
  for (const button of ["#apply", "#sweep", "#clear-label", "#clear-all", "#reset-handles", "#snapshot-save"]) {
    await page.click(button);
    const said = await page
      .waitForFunction(() => /open a mesh first/i.test(document.querySelector("#banner-text").textContent) && !document.querySelector("#banner").classList.contains("hidden"), null, { timeout: 5000 })
      .then(() => true, () => false);
    check(said, `${button} with no mesh open says "${await bannerText()}"`);
    if (await page.isVisible("#banner")) await page.click("#banner-close");
  }
  // An error banner (a rejected upload) over the empty page.
  await page.setInputFiles("#upload-input", { name: "broken.obj", mimeType: "text/plain", buffer: Buffer.from("not a mesh\n") });
  await page.waitForSelector("#banner:not(.hidden)", { timeout: 30_000 });
  const covered = await coveredTopBarControls(page);
  const [bannerBox, viewportBox, topBox] = await Promise.all(["#banner", "#viewport", "#topbar"].map((s) => page.locator(s).boundingBox()));
  check(
    covered.length === 0 && bannerBox.y >= topBox.y + topBox.height - 0.5 && bannerBox.x >= viewportBox.x - 0.5 && bannerBox.x + bannerBox.width <= viewportBox.x + viewportBox.width + 0.5,
    `the banner lies over the canvas only (banner ${JSON.stringify(bannerBox)}, top bar bottom ${topBox.y + topBox.height}); top-bar controls covered: ${covered.length ? covered.join(", ") : "none"}`,
  );
  await shot(page, "finish-01-banner-below-top-bar");
  // Real clicks on the top bar while the banner shows (a covered control times out).
  const openedUnder = await page
    .selectOption("#library", "cactus", { timeout: 5000 })
    .then(() => page.click("#open-library", { timeout: 5000 }))
    .then(() => true, () => false);
  check(openedUnder, "the top bar's Open works while the banner shows");
  if (!openedUnder) {
    await page.click("#banner-close");
    await page.selectOption("#library", "cactus");
    await page.click("#open-library");
  }
  await waitLoaded(page, "finish-pia");
  check((await bannerText()) === "", "opening a mesh clears the open-a-mesh-first notice");

  // ---- β and threshold boxes show their values whole ----------------------------------------------
  const { slab, up, h } = await slabs(page);
  // A new session: History is empty and says so (not the after-a-restart note).
  await page.waitForSelector("#history-list li.empty", { timeout: 10_000 }).catch(() => {});
  const emptyNew = ((await page.textContent("#history-list")) ?? "").trim();
  check(/No changes yet/.test(emptyNew), `a new session's empty History says "${emptyNew}"`);
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01));
  // Both regions marked, not applied: steps 1 and 2 ticked, Apply not.
  const ticked = () => page.$$eval("#hint .step.done", (els) => els.map((e) => e.textContent.trim()));
  const beforeApply = await ticked();
  check(beforeApply.length === 2 && !beforeApply.some((t) => /Apply/.test(t)), `before Apply the first-steps hint ticks only the marking: ${JSON.stringify(beforeApply)}`);
  await page.click("#apply");
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page);
  const afterApply = await ticked();
  check(afterApply.length === 3 && afterApply.some((t) => /Apply/.test(t)), `after Apply it ticks Apply too: ${JSON.stringify(afterApply)}`);
  // One numbering: the panel says "Handle 0", as the History's "moved handle 0" and the server's messages.
  const labelsShown = await page.$$eval("#label-select option, #active-handle option", (os) => os.map((o) => o.textContent));
  const countsShown = (await page.textContent("#region-counts")) ?? "";
  check(labelsShown.includes("Handle 0") && !labelsShown.includes("Handle 1") && /handle 0: \d+/.test(countsShown), `handles are numbered from 0 in the panel: ${JSON.stringify(labelsShown)}, "${countsShown}"`);
  // Noise is 0: the undeformed pose's E (≈ 1e-27 from the solver) reads 0, and its sweep is flat at 0.
  const raw = await hook(() => window.hdeform.measures());
  const shownE = await page.textContent("#m-e");
  check(shownE === "0" && (await page.textContent("#m-iso")) === "0", `the undeformed pose's E reads "${shownE}" (the solver's ${raw?.e}), E_iso,n "${await page.textContent("#m-iso")}"`);
  await page.click("#sweep");
  await page.waitForFunction(() => window.hdeform.sweepRows > 0, null, { timeout: 60_000 });
  const range = await hook(() => window.hdeform.sweepRange());
  check(range[0] === 0 && range[1] === 1, `a sweep of the undeformed pose charts flat at 0: y axis ${JSON.stringify(range)}`);
  await page.locator("#chart").screenshot({ path: `${artifacts}/finish-02a-flat-sweep.png` });
  // History: no scroll box inside the scrolling panel.
  const historyBox = await page.evaluate(() => {
    const s = getComputedStyle(document.querySelector("#history-list"));
    return { overflowY: s.overflowY, maxHeight: s.maxHeight };
  });
  check(historyBox.overflowY === "visible" && historyBox.maxHeight === "none", `the History list does not scroll inside the panel (${JSON.stringify(historyBox)})`);
  await page.fill("#beta-num", "0.99");
  await page.press("#beta-num", "Tab");
  for (let t = Date.now(); Date.now() - t < 30_000 && Math.abs((await hook(() => window.hdeform.serverBeta())) - 0.99) > 1e-12; ) await sleep(200);
  await waitIdle(page);
  const betaShown = await page.inputValue("#beta-num");
  check(betaShown === "0.99" && !(await clipped(page, "#beta-num")), `β 0.99: the box shows "${betaShown}", whole (not cut to "0.9")`);
  // Another client's β, finer than the slider's steps, comes in through the watch stream.
  const name1 = await hook(() => window.hdeform.sessionName);
  const other = await hook(([n, cv]) => window.hdeform.call("setBeta", { name: n, beta: { value: 0.9875 }, expectedConfigVersion: cv }), [name1, await hook(() => window.hdeform.configVersion)]);
  const finer = await page
    .waitForFunction(() => document.querySelector("#beta-num").value === "0.9875", null, { timeout: 15_000 })
    .then(() => true, () => false);
  check(other.code === "OK" && finer && !(await clipped(page, "#beta-num")), `β 0.9875 set elsewhere: the box shows "${await page.inputValue("#beta-num")}", whole (SetBeta ${other.code})`);
  await page.selectOption("#energy-map", "truncated");
  await waitIdle(page);
  await sleep(300);
  const defaultTrunc = await page.inputValue("#energy-trunc");
  check(defaultTrunc !== "" && !(await clipped(page, "#energy-trunc")), `the threshold box's default "${defaultTrunc}" is shown whole`);
  await page.fill("#energy-trunc", "3.57e-25");
  const trunc = await page.inputValue("#energy-trunc");
  check(trunc === "3.57e-25" && !(await clipped(page, "#energy-trunc")), `threshold 3.57e-25: the box shows "${trunc}", whole (not cut to "3.57e-2")`);
  await shot(page, "finish-02-number-boxes");
  // A threshold far below the noise floor paints no noise: every free triangle has the ramp's 0 colour.
  await sleep(300);
  const colours = await hook(() => Array.from(window.hdeform.displayColours()));
  const counts = new Map();
  for (let k = 0; k < colours.length; k += 3) {
    const key = colours.slice(k, k + 3).map((v) => v.toFixed(3)).join(",");
    counts.set(key, (counts.get(key) ?? 0) + 1);
  }
  // The region colours (fixed, handle 0) and the ramp's bottom: nothing else.
  const vertexCount = (await hook(() => window.hdeform.labels())).length;
  check(counts.size <= 3 && colours.length / 3 > vertexCount, `threshold 3.57e-25 on an undeformed pose: the split display has ${counts.size} distinct colours (regions and the ramp's 0), no noise streaks`);
  const legendCut = await page.evaluate(() => {
    const t = document.querySelector("#legend-title");
    const p = document.querySelector("#panel").getBoundingClientRect();
    const r = t.getBoundingClientRect();
    return { scroll: t.scrollWidth, client: t.clientWidth, right: r.right, panelRight: p.right, text: t.textContent };
  });
  check(legendCut.scroll <= legendCut.client && legendCut.right <= legendCut.panelRight, `the energy legend's title is whole ("${legendCut.text}", ${legendCut.scroll} ≤ ${legendCut.client} px)`);

  // ---- Share link: on the clipboard, never in the status line ---------------------------------------
  await context.grantPermissions(["clipboard-read", "clipboard-write"], { origin: new URL(base).origin });
  await page.bringToFront();
  const tok = await hook(() => window.hdeform.tokens());
  for (const [button, watch] of [["#copy-share", false], ["#copy-watch", true]]) {
    await page.evaluate(() => navigator.clipboard.writeText(""));
    await page.click(button);
    const said = watch ? /watch link copied/i : /share link copied/i;
    await page.waitForFunction((re) => new RegExp(re, "i").test(document.querySelector("#status").textContent), said.source, { timeout: 5000 }).catch(() => {});
    const status = (await page.textContent("#status")) ?? "";
    const clip = await page.evaluate(() => navigator.clipboard.readText()).catch((e) => `(clipboard: ${e.message})`);
    const link = await hook((w) => window.hdeform.shareLink(w), watch);
    check(
      said.test(status) && !status.includes(tok.edit) && !status.includes(tok.view) && clip === link,
      `${button}: the link is on the clipboard (${clip === link}), the status line says "${status}" (a token in it: ${status.includes(tok.edit) || status.includes(tok.view)})`,
    );
  }

  // ---- camera: a session opened already deformed is framed as it is now ------------------------------
  // Handle 0 (the top tenth) lifted by 1.2 × the height through the API: a framing of the rest
  // shape leaves it, and its gizmo, off screen.
  const lift = [0, 0, 0];
  lift[up] = 1.2 * h;
  const lifted = await hook(([n, t]) => window.hdeform.call("updateHandles", { name: n, transforms: [{ translation: { x: t[0], y: t[1], z: t[2] } }] }), [name1, lift]);
  const rex = await context.newPage();
  watchPage(rex, "finish-rex");
  await rex.setViewportSize({ width: 1400, height: 860 });
  await rex.goto(await hook(() => window.hdeform.shareLink(false)));
  await waitLoaded(rex, "finish-rex");
  await waitIdle(rex);
  const off = () => rex.evaluate(() => window.hdeform.offScreen());
  const onOpen = await off();
  check(lifted.code === "OK" && onOpen.vertices === 0 && onOpen.gizmo === 0 && onOpen.gizmoShown, `a shared session opened already deformed frames the deformed shape and the gizmo (off screen: ${JSON.stringify(onOpen)}; UpdateHandles ${lifted.code})`);
  await shot(rex, "finish-05-opened-deformed");
  const canvasBox = await rex.locator("#viewport canvas").boundingBox();
  const zoomIn = async () => {
    await rex.mouse.move(canvasBox.x + canvasBox.width * 0.3, canvasBox.y + canvasBox.height * 0.7);
    for (let i = 0; i < 6; i++) await rex.mouse.wheel(0, -300);
    await sleep(200);
    return (await off()).vertices;
  };
  const zoomed = await zoomIn();
  await rex.keyboard.press("Home");
  await sleep(200);
  const afterHome = await off();
  const zoomed2 = await zoomIn();
  await rex.click("#view-all");
  await sleep(200);
  const afterAll = await off();
  check(zoomed > 0 && zoomed2 > 0 && afterHome.vertices === 0 && afterHome.gizmo === 0 && afterAll.vertices === 0 && afterAll.gizmo === 0, `Home and Frame all frame it all again after zooming in (${zoomed} vertices off screen → Home ${JSON.stringify(afterHome)}, Frame all ${JSON.stringify(afterAll)})`);
  await rex.reload();
  await waitLoaded(rex, "finish-rex reloaded");
  await waitIdle(rex);
  const afterReload = await off();
  check(afterReload.vertices === 0 && afterReload.gizmo === 0, `…and so does a reload (${JSON.stringify(afterReload)})`);
  await rex.close();
  await page.bringToFront();
  await page.keyboard.press("Home");
  await sleep(200);
  const piaHome = await page.evaluate(() => window.hdeform.offScreen());
  check(piaHome.vertices === 0, `Home on the page that saw the move live frames it too (${JSON.stringify(piaHome)})`);

  // ---- GLB downloads carry the model's up axis ------------------------------------------------------
  const upDefault = await page.inputValue("#export-up");
  const downloadGlb = async () => {
    const [dl] = await Promise.all([page.waitForEvent("download", { timeout: 30_000 }), page.click("#dl-glb")]);
    return readFileSync(await dl.path());
  };
  const serverGlb = Buffer.from(await hook(() => window.hdeform.meshGlb()), "base64");
  const server = glbParts(serverGlb);
  const zGlb = glbParts(await downloadGlb());
  const root = zGlb.json.nodes[zGlb.json.scenes[zGlb.json.scene ?? 0].nodes[0]];
  const q = root.rotation ?? [];
  check(
    upDefault === "z" &&
      Math.abs(q[0] + Math.SQRT1_2) < 1e-12 && q[1] === 0 && q[2] === 0 && Math.abs(q[3] - Math.SQRT1_2) < 1e-12 &&
      JSON.stringify(root.children) === JSON.stringify(server.json.scenes[server.json.scene ?? 0].nodes) &&
      zGlb.rest.equals(server.rest) && zGlb.aligned,
    `the z-up cactus downloads (export up "${upDefault}", the viewer's) with a root node rotating +z to +y (${JSON.stringify(q)}) over GetMesh's roots, its BIN chunk GetMesh's byte for byte (${zGlb.rest.length} bytes), 4-byte aligned`,
  );
  await page.selectOption("#export-up", "y");
  const yGlb = await downloadGlb();
  check(yGlb.equals(serverGlb), `y-up downloads GetMesh's GLB as it is (${yGlb.length} bytes)`);
  await page.selectOption("#export-up", "z");

  // ---- presence: after a switch of session, only the new session's people ---------------------------
  const quinn = await context.newPage();
  watchPage(quinn, "finish-quinn");
  await quinn.goto(await hook(() => window.hdeform.shareLink(false)));
  await waitLoaded(quinn, "finish-quinn");
  await quinn.fill("#display-name", "Quinn");
  await quinn.press("#display-name", "Tab");
  const bothListed = await page
    .waitForFunction(() => [...document.querySelectorAll("#presence .person")].some((e) => /Quinn/.test(e.textContent)), null, { timeout: 15_000 })
    .then(() => true, () => false);
  check(bothListed, `Pia's presence list shows Quinn: ${JSON.stringify(await personTexts(page))}`);
  const otherMesh = await page.$$eval("#library option", (os) => os.map((o) => o.value).find((v) => v && v !== "cactus"));
  await page.bringToFront();
  // Settings of this mesh that must not carry over: the truncated energy map at 3.57e-25 (still on),
  // "Assign to" a second handle, frame sizes in the status line.
  await page.selectOption("#label-select", "1");
  await page.click("#new-handle");
  const settingsBefore = { energy: await page.inputValue("#energy-map"), trunc: await page.inputValue("#energy-trunc"), assign: await page.inputValue("#label-select"), status: (await page.textContent("#status")) ?? "" };
  await page.selectOption("#library", otherMesh);
  await page.click("#open-library");
  await page.waitForFunction((n) => window.hdeform.loaded && window.hdeform.sessionName !== n, name1, { timeout: 60_000 });
  await waitIdle(page);
  // The new session's presence (Pia alone) comes with its watch stream.
  const onlyPia = await page
    .waitForFunction(() => {
      const t = [...document.querySelectorAll("#presence .person")].map((e) => e.textContent);
      return t.length === 1 && /Pia/.test(t[0]);
    }, null, { timeout: 15_000 })
    .then(() => true, () => false);
  const people = await personTexts(page);
  check(onlyPia && !people.some((t) => /Quinn/.test(t)), `after opening ${otherMesh} the presence list holds this session's people only: ${JSON.stringify(people)}`);
  const settingsAfter = {
    energy: await page.inputValue("#energy-map"),
    truncShown: await page.isVisible("#energy-trunc"),
    trunc: await page.inputValue("#energy-trunc"),
    assign: await page.inputValue("#label-select"),
    offered: await page.$$eval("#label-select option", (os) => os.map((o) => o.textContent)),
    status: (await page.textContent("#status")) ?? "",
  };
  check(
    settingsBefore.energy === "truncated" && settingsBefore.assign === "2" && /frames:/.test(settingsBefore.status) &&
      settingsAfter.energy === "off" && !settingsAfter.truncShown && settingsAfter.trunc !== settingsBefore.trunc && settingsAfter.assign === "0" &&
      JSON.stringify(settingsAfter.offered) === JSON.stringify(["Fixed", "Handle 0", "Erase"]) && !/frames:/.test(settingsAfter.status),
    `the previous mesh's settings do not carry over (before ${JSON.stringify(settingsBefore)}; after ${JSON.stringify(settingsAfter)})`,
  );
  await shot(page, "finish-03-presence-after-switch");
  await quinn.close();

  // ---- the view token in `#edit=`: watch-only, and the page says so -------------------------------------
  const name2 = await hook(() => window.hdeform.sessionName);
  const tok2 = await hook(() => window.hdeform.tokens());
  const v0 = await hook(() => window.hdeform.version);
  const steps0 = (await hook(() => window.hdeform.history())).length;
  const vera = await context.newPage();
  watchPage(vera, "finish-vera");
  await vera.setViewportSize({ width: 1400, height: 860 });
  // Every call the page makes, by method: the view token's calls, and the one probe.
  const veraCalls = [];
  vera.on("request", (r) => {
    const m = /\/hdeform\.v1\.Deformation\/(\w+)/.exec(r.url());
    if (m) veraCalls.push(m[1]);
  });
  const reads = new Set(["GetSession", "GetMesh", "WatchSession", "ListHistory", "ListSnapshots", "GetHandleWeights", "GetTimeline", "PoseAt", "ListMeshes"]);
  await vera.goto(`${base}?session=${encodeURIComponent(name2)}#edit=${tok2.view}`);
  await waitLoaded(vera, "finish-vera");
  await vera.fill("#display-name", "Vera");
  await vera.press("#display-name", "Tab");
  const veraBanner = (await vera.isVisible("#banner")) ? ((await vera.textContent("#banner-text")) ?? "") : "";
  const amber = await vera.evaluate(() => document.querySelector("#banner").classList.contains("notice"));
  check(
    (await vera.evaluate(() => window.hdeform.watchOnly)) &&
      !(await vera.isVisible("#tools")) &&
      !(await vera.isVisible("#sweep")) &&
      !(await vera.isVisible("#copy-share")) &&
      (await vera.isVisible("#watch-badge")),
    "a link with the view token as #edit= opens watch-only (no tools, no Sweep, no Share link; the watch badge)",
  );
  check(/view token/i.test(veraBanner) && /watch-only/i.test(veraBanner) && amber && !/PermissionDenied/i.test(veraBanner), `it says so, as a notice: "${veraBanner}"`);
  const probes = veraCalls.filter((m) => m === "ReleaseHandles").length;
  check(probes === 1, `the page asked the server what its token may do (one ReleaseHandles for a throwaway client: ${probes})`);
  const addr = new URL(vera.url());
  const frag = new URLSearchParams(addr.hash.slice(1));
  check(
    addr.searchParams.get("watch") === "1" && [...frag.keys()].join() === "view" && frag.get("view") === tok2.view,
    `the address became the watch link (${addr.search}, fragment keys ${[...frag.keys()].join()})`,
  );
  // Editor keys do nothing on a watch page (W: Move, Ctrl+Z: undo); nothing is refused.
  await vera.mouse.move(500, 400);
  await vera.keyboard.press("w");
  await vera.keyboard.press("Control+z");
  await sleep(1000);
  const veraErr = await vera.evaluate(() => window.hdeform.lastError);
  const edits = veraCalls.filter((m) => m !== "ReleaseHandles" && !reads.has(m));
  check(edits.length === 0 && !/PermissionDenied/i.test(veraErr), `no edit was sent (calls: ${[...new Set(veraCalls)].join(", ")}; banner "${veraErr}")`);
  const veraViewer = await page
    .waitForFunction(() => [...document.querySelectorAll("#presence .person")].some((e) => /Vera/.test(e.textContent) && e.getAttribute("title") === "viewer"), null, { timeout: 15_000 })
    .then(() => true, () => false);
  check(veraViewer, `the server lists Vera as a viewer: ${JSON.stringify(await personTexts(page))}`);
  const v1 = await hook(() => window.hdeform.version);
  const steps1 = (await hook(() => window.hdeform.history())).length;
  check(v1 === v0 && steps1 === steps0, `the probe changed nothing (version ${v0} → ${v1}, history steps ${steps0} → ${steps1})`);
  await shot(vera, "finish-04-view-token-as-edit");
  await vera.reload();
  await waitLoaded(vera, "finish-vera reloaded");
  check(
    (await vera.evaluate(() => window.hdeform.watchOnly)) && (await vera.evaluate(() => window.hdeform.lastError)) === "",
    "a reload of it opens watch-only at once (the watch link), without the notice",
  );

  // ---- narrow layouts: 1400×860, 1024×700, 900×600 --------------------------------------------------
  await page.bringToFront();
  await page.fill("#display-name", "Alice Martin");
  await page.press("#display-name", "Tab");
  await page.waitForFunction(() => document.querySelectorAll("#presence .person").length >= 2, null, { timeout: 15_000 }).catch(() => {});
  for (const [w, hgt] of [[1400, 860], [1024, 700], [900, 600]]) {
    await page.setViewportSize({ width: w, height: hgt });
    await sleep(500);
    const bar = await topBarLayout(page);
    check(
      bar.outside.length === 0 && bar.pairs.length === 0 && bar.covered.length === 0 && bar.ids.includes("copy-share") && bar.ids.includes("copy-watch") && bar.ids.includes("display-name") && bar.scrollWidth <= bar.innerWidth && bar.barHeight <= 41,
      `${w}×${hgt}: the top bar's ${bar.ids.length} controls lie inside it (${bar.barHeight} px high), none overlap or is covered, Share / Watch links there (outside: ${bar.outside.join(", ") || "none"}; overlapping: ${bar.pairs.join(", ") || "none"}; covered: ${bar.covered.join(", ") || "none"})`,
    );
    const nameWhole = !(await clipped(page, "#display-name")) && (await page.inputValue("#display-name")) === "Alice Martin";
    check(nameWhole, `${w}×${hgt}: the name field shows "Alice Martin" whole`);
    const corner = await page.evaluate(() => {
      const box = (el) => (el && el.getBoundingClientRect().width > 0 ? el.getBoundingClientRect().toJSON() : null);
      return {
        chips: [...document.querySelectorAll("#presence .person")].map(box),
        status: box(document.querySelector("#status")),
        viewbar: box(document.querySelector("#viewbar")),
        strip: box(document.querySelector("#timeline")),
        hint: box(document.querySelector("#hint")),
        canvas: box(document.querySelector("#viewport")),
      };
    });
    const clash = [
      ...corner.chips.flatMap((c, i) => [overlap(c, corner.status) && `chip ${i} × status`, overlap(c, corner.viewbar) && `chip ${i} × view buttons`, overlap(c, corner.strip) && `chip ${i} × timeline`]),
      overlap(corner.status, corner.viewbar) && "status × view buttons",
      overlap(corner.status, corner.strip) && "status × timeline",
    ].filter(Boolean);
    const hintBox = corner.hint;
    if (hintBox) clash.push(...(hintBox.x < corner.canvas.x - 0.5 || hintBox.x + hintBox.width > corner.canvas.x + corner.canvas.width + 0.5 ? ["the first-steps hint is cut"] : []));
    check(corner.chips.length >= 2 && corner.status && clash.length === 0, `${w}×${hgt}: ${corner.chips.length} presence chips, the status line and the view buttons do not overlap, the first-steps hint is whole (${clash.join(", ") || "none"})`);
    const canvasW = (await page.locator("#viewport canvas").boundingBox()).width;
    const panelShown = await page.isVisible("#panel");
    if (w <= 960) {
      check(!panelShown && canvasW >= w - 1 && (await page.isVisible("#panel-toggle")), `${w}×${hgt}: the side panel is folded away (a drawer behind "Panels"), the canvas ${canvasW} px wide`);
      await page.click("#panel-toggle");
      await sleep(300);
      const canvasOpen = (await page.locator("#viewport canvas").boundingBox()).width;
      const panelBox = await page.locator("#panel").boundingBox();
      check((await page.isVisible("#panel")) && canvasOpen === canvasW && panelBox.x + panelBox.width <= w + 0.5, `${w}×${hgt}: "Panels" opens the drawer over the canvas (which keeps ${canvasOpen} px)`);
      await shot(page, `layout-${w}x${hgt}-panel`);
      await page.click("#panel-toggle");
      await page.click("#files-toggle");
      await sleep(200);
      const menu = await page.locator("#dl-glb").boundingBox().catch(() => null);
      check(menu && (await page.isVisible("#dl-glb")) && menu.x >= 0 && menu.x + menu.width <= w, `${w}×${hgt}: the downloads are in the Files menu`);
      await shot(page, `layout-${w}x${hgt}-files`);
      await page.keyboard.press("Escape");
    } else {
      check(panelShown && canvasW >= w - 330, `${w}×${hgt}: the side panel is shown, the canvas ${canvasW} px wide`);
    }
    await shot(page, `layout-${w}x${hgt}`);
  }
  await page.setViewportSize({ width: 1400, height: 860 });
  await vera.close();
  await page.close();
  log("finished-editor checks done");
}

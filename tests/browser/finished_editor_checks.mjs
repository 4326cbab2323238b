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
//     becomes the watch link; the server lists the page as a viewer; the probe changed nothing.
import { readdirSync, readFileSync } from "node:fs";
import { join } from "node:path";

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

export async function finishedEditorChecks({ context, base, prodBase, prodDist, testDist, log, check, sleep, shot, watchPage, waitLoaded, waitIdle }) {
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
  for (const button of ["#apply", "#sweep"]) {
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
  const [bmin, bmax] = await hook(() => window.hdeform.bbox());
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const h = bmax[up] - bmin[up];
  const slab = (from, to) => {
    const lo = bmin.map((v) => v - 1), hi = bmax.map((v) => v + 1);
    lo[up] = bmin[up] + from * h;
    hi[up] = bmin[up] + to * h;
    return [lo, hi];
  };
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  await hook(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01));
  await page.click("#apply");
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page);
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
  await page.selectOption("#energy-map", "off");

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
  await vera.close();
  await page.close();
  log("finished-editor checks done");
}

// End-to-end test of the web viewer in real headless Chromium (Debian's /usr/bin/chromium,
// driven by playwright-core; no browser downloads) against a real hdeform-server.
//
//   node e2e.mjs --server PATH/hdeform-server --viewer PATH/web-viewer --artifacts DIR
//     [--web-root DIR]        the page under test: a `vite build --mode test` (window.hdeform);
//                             default web-viewer/dist-test (npm run build:test)
//     [--prod-web-root DIR]   the production build (no hook), default web-viewer/dist
//
// Flow: open the cactus from the library; select a fixed region (bottom) and a handle (top)
// through the page's test hook (window.hdeform.selectBox — the same assign() path the
// brush / box tools use); Apply constraints with a real click; switch to Move with a real
// click and drag the TransformControls gizmo with real mouse events; check the mesh moved
// (handle moved, fixed region still) and the measures changed; open the share link in a
// second page and compare positions; drag again and check the second page follows live
// (WatchSession); open the watch-only link (no editing tools); the display is indexed, and
// split into 3 corners per triangle while the energy map is on; reopen the editor with
// ?encoding=float32, quantized, meshopt and meshopt-delta and drag on each: it ends on exactly the shape
// GetMesh returns (the drag's last frame is float32); upload a broken file and
// check the error banner; upload a glTF split at a seam and check that regions picked in its
// base GLB are accepted and shown where they were picked (base_ids / base_constraints);
// check the gateway's 413 for an oversized body.
//
// Access and durability (docs/viewer.md "Links and tokens", "Reconnecting"): the server runs
// with a temporary --state-dir. Share links carry the edit token only in the URL fragment,
// watch links only the view token; a watch page whose `watch` parameter is removed still
// has no editing tools and its own API calls are refused (PERMISSION_DENIED); a page with
// no token (or a wrong one) cannot open the session; no request the pages make carries a
// token in its URL, and every session call carries `authorization`. A reload of the editor
// keeps the session and can still edit. The server is killed (SIGKILL) and started again on
// the same ports and state: the open pages reconnect by themselves, show the same version
// and shape, and a further drag works; an edit whose call fails with UNAVAILABLE is sent
// again after the reconnect (once: a second failure is reported). A session deleted for
// real is reported as deleted.
import { spawn } from "node:child_process";
import { mkdirSync, mkdtempSync, rmSync, writeFileSync } from "node:fs";
import http from "node:http";
import { createRequire } from "node:module";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";
import { pathToFileURL } from "node:url";
import { editorChecks } from "./editor_checks.mjs";
import { severalEditorsChecks } from "./several_editors_checks.mjs";
import { historyChecks } from "./history_checks.mjs";
import { weightsChecks } from "./weights_checks.mjs";
import { timelineChecks } from "./timeline_checks.mjs";
import { finishedEditorChecks } from "./finished_editor_checks.mjs";
import { repairChecks } from "./repair_checks.mjs";
import { perfChecks, rigExportChecks, selectionChecks } from "./rig_perf_selection_checks.mjs";
import { lassoChecks, orientationChecks, visibleOnlyChecks } from "./orientation_lasso_checks.mjs";

/**
 * A flat 7×5 grid (x = 0.5 i, y = 0.5 j) as GLB in two vertex blocks that both carry the
 * seam column i = 3 (tests/service/test_gltf_ids.cpp builds the same mesh): 40 vertices, of
 * which the server welds 5 pairs.
 */
function seamGridGlb() {
  const L = (i, j) => 4 * j + i;
  const R = (i, j) => 20 + 4 * j + (i - 3);
  const pos = new Float32Array(40 * 3);
  for (let j = 0; j < 5; j++) {
    for (let i = 0; i <= 3; i++) pos.set([0.5 * i, 0.5 * j, 0], 3 * L(i, j));
    for (let i = 3; i <= 6; i++) pos.set([0.5 * i, 0.5 * j, 0], 3 * R(i, j));
  }
  const idx = [];
  for (const [i0, i1, id] of [[0, 3, L], [3, 6, R]])
    for (let j = 0; j < 4; j++)
      for (let i = i0; i < i1; i++) idx.push(id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j), id(i + 1, j + 1), id(i, j + 1));
  const indices = new Uint32Array(idx);
  const bin = Buffer.concat([Buffer.from(pos.buffer), Buffer.from(indices.buffer)]);
  const gltf = {
    asset: { version: "2.0" },
    buffers: [{ byteLength: bin.length }],
    bufferViews: [
      { buffer: 0, byteOffset: 0, byteLength: pos.byteLength, target: 34962 },
      { buffer: 0, byteOffset: pos.byteLength, byteLength: indices.byteLength, target: 34963 },
    ],
    accessors: [
      { bufferView: 0, componentType: 5126, count: 40, type: "VEC3", min: [0, 0, 0], max: [3, 2, 0] },
      { bufferView: 1, componentType: 5125, count: indices.length, type: "SCALAR" },
    ],
    meshes: [{ primitives: [{ attributes: { POSITION: 0 }, indices: 1 }] }],
    nodes: [{ mesh: 0 }],
    scenes: [{ nodes: [0] }],
    scene: 0,
  };
  let json = Buffer.from(JSON.stringify(gltf));
  json = Buffer.concat([json, Buffer.alloc((4 - (json.length % 4)) % 4, 0x20)]);
  const header = Buffer.alloc(12);
  header.writeUInt32LE(0x46546c67, 0);
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(12 + 8 + json.length + 8 + bin.length, 8);
  const chunk = (type, data) => {
    const h = Buffer.alloc(8);
    h.writeUInt32LE(data.length, 0);
    h.writeUInt32LE(type, 4);
    return Buffer.concat([h, data]);
  };
  return Buffer.concat([header, chunk(0x4e4f534a, json), chunk(0x004e4942, bin)]);
}

const args = Object.fromEntries(
  process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith("--") ? [...acc, [a.slice(2), all[i + 1]]] : acc), []),
);
const serverBin = args.server ?? process.env.HDEFORM_SERVER;
const viewerDir = resolve(args.viewer ?? process.env.HDEFORM_VIEWER ?? "web-viewer");
const artifacts = resolve(args.artifacts ?? process.env.HDEFORM_ARTIFACTS ?? "test-artifacts");
const chromiumPath = args.chromium ?? process.env.HDEFORM_CHROMIUM ?? "/usr/bin/chromium";
// The pages under test need the test hook: the tests' build. The production build is checked
// for its absence (finished_editor_checks.mjs).
const webRoot = resolve(args["web-root"] ?? join(viewerDir, "dist-test"));
const prodWebRoot = resolve(args["prod-web-root"] ?? join(viewerDir, "dist"));
if (!serverBin) throw new Error("--server PATH/hdeform-server is required");
mkdirSync(artifacts, { recursive: true });

const require = createRequire(join(viewerDir, "package.json"));
const { chromium } = require("playwright-core");

const log = (...a) => console.log(`[e2e ${new Date().toISOString().slice(11, 23)}]`, ...a);
let failures = 0;
// CI shows only the head and tail of a long log: the summary repeats what failed.
const failed = [];
function check(cond, what) {
  if (cond) log(`ok   ${what}`);
  else {
    failures++;
    failed.push(what);
    log(`FAIL ${what}`);
  }
  return cond;
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
class StopHere {}

// ---- server ---------------------------------------------------------------------------------
// Durable sessions go to a temporary --state-dir (never the user's ~/.local/share/hdeform);
// the restart in step 10 reuses it, and the ports.
const stateDir = mkdtempSync(join(tmpdir(), "hdeform-e2e-state-"));
function startServer({ grpcPort = 0, httpPort = 0, tag = "server", root = webRoot, durable = true } = {}) {
  const extra = process.env.HDEFORM_SERVER_ARGS ? process.env.HDEFORM_SERVER_ARGS.split(" ").filter(Boolean) : [];
  const proc = spawn(
    serverBin,
    // --web-root: the viewer under test (by default a server serves its own source tree's).
    ["--port", String(grpcPort), "--http-port", String(httpPort), ...(durable ? ["--state-dir", stateDir] : ["--no-state"]), "--web-root", root, ...extra],
    { stdio: ["ignore", "pipe", "pipe"] },
  );
  const output = [];
  const port = new Promise((resolvePort, reject) => {
    const timer = setTimeout(() => reject(new Error(`no HTTP port printed within 60 s:\n${output.join("")}`)), 60_000);
    const onData = (buf) => {
      const text = buf.toString();
      output.push(text);
      process.stdout.write(`[${tag}] ${text}`);
      const all = output.join("");
      const m = /hdeform-server http on \S+:(\d+)/.exec(all) ?? /hdeform-gateway listening on \S+:(\d+)/.exec(all);
      const g = /hdeform-server listening on \S+:(\d+)/.exec(all);
      if (m) {
        clearTimeout(timer);
        resolvePort({ http: Number(m[1]), grpc: g ? Number(g[1]) : 0 });
      }
    };
    proc.stdout.on("data", onData);
    proc.stderr.on("data", onData);
    proc.on("exit", (code) => {
      clearTimeout(timer);
      reject(new Error(`hdeform-server exited (${code}) before listening:\n${output.join("")}`));
    });
  });
  return { proc, port };
}

function rawRequest(port, path, headers, body = "") {
  return new Promise((resolveReq, reject) => {
    const req = http.request({ host: "127.0.0.1", port, path, method: "POST", headers }, (res) => {
      let data = "";
      res.on("data", (d) => (data += d));
      res.on("end", () => resolveReq({ status: res.statusCode, body: data }));
    });
    req.on("error", reject);
    req.end(body);
  });
}

// ---- helpers in the page ----------------------------------------------------------------------
async function waitLoaded(page, what) {
  await page.waitForFunction(() => window.hdeform && window.hdeform.loaded, null, { timeout: 60_000 });
  log(`${what}: loaded ${await page.evaluate(() => window.hdeform.sessionName)}`);
}
async function waitIdle(page) {
  await page.waitForFunction(() => !window.hdeform.busy, null, { timeout: 30_000 });
  await sleep(100);
  await page.waitForFunction(() => !window.hdeform.busy, null, { timeout: 30_000 });
}
const positions = (page) => page.evaluate(() => window.hdeform.positions());
function maxDiff(a, b) {
  if (a.length !== b.length) return Infinity;
  let m = 0;
  for (let i = 0; i < a.length; i++) m = Math.max(m, Math.abs(a[i] - b[i]));
  return m;
}
async function waitSame(page, ref, what, tol = 1e-4) {
  const t0 = Date.now();
  let d = Infinity;
  while (Date.now() - t0 < 15_000) {
    d = maxDiff(await positions(page), ref);
    if (d <= tol) break;
    await sleep(200);
  }
  return check(d <= tol, `${what} (max |Δ| = ${d.toExponential(2)})`);
}
/** Fraction of canvas pixels that differ from the background: the canvas is not blank. */
async function nonBackgroundFraction(page) {
  return page.evaluate(() => {
    const src = document.querySelector("#viewport canvas");
    const c = document.createElement("canvas");
    c.width = 200;
    c.height = 150;
    const ctx = c.getContext("2d");
    ctx.drawImage(src, 0, 0, c.width, c.height);
    const d = ctx.getImageData(0, 0, c.width, c.height).data;
    const bg = [d[0], d[1], d[2]];
    let differ = 0;
    for (let i = 0; i < d.length; i += 4) {
      if (Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]) > 24) differ++;
    }
    return differ / (c.width * c.height);
  });
}
/** Screen direction of a gizmo arrow (unit vector) and its on-screen length. */
async function arrow(page, axis) {
  const [c, a] = await page.evaluate((ax) => [window.hdeform.gizmoScreenPoint(), window.hdeform.gizmoScreenPoint(ax)], axis);
  const len = Math.hypot(a.x - c.x, a.y - c.y);
  return { x: (a.x - c.x) / len, y: (a.y - c.y) / len, len, axis };
}
/**
 * The gizmo's arrows by how they look on screen: `up` (the most vertical one) and
 * `horizontal` (the longer of the other two). The axes are the model's: for a z-up model
 * (the cactus) up is z.
 */
async function arrowsOnScreen(page) {
  const all = [await arrow(page, "x"), await arrow(page, "y"), await arrow(page, "z")];
  const upArrow = all.reduce((a, b) => (Math.abs(b.y) * b.len > Math.abs(a.y) * a.len ? b : a));
  const rest = all.filter((a) => a !== upArrow);
  return { up: upArrow, horizontal: rest[0].len >= rest[1].len ? rest[0] : rest[1] };
}
/** The URL's fragment as parameters (`#edit=…&view=…`). */
const fragmentOf = (url) => new URLSearchParams(new URL(url).hash.replace(/^#/, ""));
/** True when any of the tokens appears in the URL outside its fragment (what a server sees). */
function tokenOutsideFragment(url, tokens) {
  const u = new URL(url);
  u.hash = "";
  const sent = u.toString();
  return tokens.some((t) => t && sent.includes(t));
}
async function dragGizmo(page, axis, dx, dy, steps = 12) {
  const p = await page.evaluate((a) => window.hdeform.gizmoScreenPoint(a), axis);
  if (!p) throw new Error("the gizmo is not attached");
  await page.mouse.move(p.x, p.y);
  await sleep(50);
  await page.mouse.down();
  for (let i = 1; i <= steps; i++) {
    await page.mouse.move(p.x + (dx * i) / steps, p.y + (dy * i) / steps);
    await sleep(40); // a few animation frames: updates are coalesced, one in flight
  }
  await page.mouse.up();
  const t = Date.now();
  await waitIdle(page);
  if (Date.now() - t > 2000) log(`(the page was busy for ${Date.now() - t} ms after the drag)`);
}

// ---- the test -----------------------------------------------------------------------------------
let { proc: server, port: portPromise } = startServer();
const userDataDir = mkdtempSync(join(tmpdir(), "hdeform-chromium-"));
let context;
const t00 = Date.now();
try {
  const ports = await portPromise;
  const port = ports.http;
  const base = `http://127.0.0.1:${port}/`;
  log(`server HTTP at ${base}`);

  const tooBig = await rawRequest(port, "/upload?filename=huge.obj", { "Content-Length": String(1e12) });
  check(tooBig.status === 413 && /limit/.test(tooBig.body), `oversized body → HTTP 413 (${tooBig.status}: ${tooBig.body.trim()})`);

  context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: chromiumPath,
    headless: true,
    viewport: { width: 1280, height: 800 },
    args: [
      "--no-sandbox",
      "--disable-gpu",
      "--disable-quic",
      "--no-first-run",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
    ],
  });
  const consoleLines = [];
  const pageNames = new Map();
  const watchPage = (page, name) => {
    pageNames.set(page, name);
    page.on("console", (m) => consoleLines.push(`[${name}] ${m.type()}: ${m.text()}`));
    page.on("pageerror", (e) => consoleLines.push(`[${name}] pageerror: ${e.message}`));
  };
  // Every request the pages make: no token may travel in a URL (they live in fragments),
  // and every call that names a session must carry `authorization`.
  const requests = [];
  context.on("request", (r) => {
    let name = "?";
    try {
      name = pageNames.get(r.frame().page()) ?? "?";
    } catch {
      /* a worker's request */
    }
    requests.push({ page: name, url: r.url(), auth: r.headers()["authorization"] ?? "" });
  });
  context.on("requestfinished", (r) => {
    const t = r.timing();
    if (t.responseEnd > 1500 && !/WatchSession/.test(r.url())) log(`(slow request ${r.url().replace(/^.*\//, "")}: ${JSON.stringify(t)})`);
  });
  const shot = (page, name) => page.screenshot({ path: join(artifacts, `${name}.png`) });

  // 0. The editor's usability checks (editor_checks.mjs) and several editors in one session
  // (several_editors_checks.mjs), history and the weight preview, on sessions of their own.
  // `--only editor` stops after them.
  const helpers = { context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle, positions, maxDiff, artifacts, requireViewer: require };
  // `--only history` runs just the history checks (history_checks.mjs), `--only weights` just
  // the weight preview's (weights_checks.mjs), `--only timeline` the timeline strip's
  // (timeline_checks.mjs), `--only finished` issue 37's (finished_editor_checks.mjs), `--only repair`
  // repair on upload (repair_checks.mjs); `--only rig`, `--only perf`, `--only selection` one
  // group of rig_perf_selection_checks.mjs; `--only orientation` the view helper, keypad views,
  // grid, lasso and visible-only selection (orientation_lasso_checks.mjs).
  const only = args.only;
  const groups = ["editor", "history", "weights", "timeline", "finished", "repair", "rig", "perf", "selection", "orientation"];
  if (only !== undefined && !groups.includes(only)) throw new Error(`--only ${only}: one of ${groups.join(", ")}`);
  if (only === undefined || only === "editor") {
    await editorChecks(helpers);
    await severalEditorsChecks(helpers);
  }
  if (only === undefined || only === "editor" || only === "history") await historyChecks(helpers);
  if (only === undefined || only === "editor" || only === "weights") await weightsChecks(helpers);
  if (only === undefined || only === "editor" || only === "timeline") await timelineChecks(helpers);
  if (only === undefined || only === "editor" || only === "finished") {
    // The production build, served by a server of its own (in-memory sessions).
    const prodServer = startServer({ tag: "server-prod", root: prodWebRoot, durable: false });
    try {
      const prodBase = `http://127.0.0.1:${(await prodServer.port).http}/`;
      await finishedEditorChecks({ ...helpers, prodBase, prodDist: prodWebRoot, testDist: webRoot });
    } finally {
      prodServer.proc.kill("SIGTERM");
    }
  }
  if (only === undefined || only === "editor" || only === "repair") await repairChecks(helpers);
  if (only === undefined || only === "editor" || only === "rig") await rigExportChecks(helpers);
  if (only === undefined || only === "editor" || only === "selection") await selectionChecks(helpers);
  if (only === undefined || only === "editor" || only === "perf") await perfChecks(helpers);
  if (only === undefined || only === "editor" || only === "orientation") {
    await orientationChecks(helpers);
    await lassoChecks(helpers);
    await visibleOnlyChecks(helpers);
  }
  if (only !== undefined) throw new StopHere();

  // 1. Open the cactus from the library.
  const page1 = context.pages()[0] ?? (await context.newPage());
  watchPage(page1, "editor");
  await page1.goto(base);
  await page1.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await page1.selectOption("#library", "cactus");
  await page1.click("#open-library");
  await waitLoaded(page1, "editor");
  await sleep(300);
  const filled = await nonBackgroundFraction(page1);
  check(filled > 0.02, `the canvas shows the mesh (${(filled * 100).toFixed(1)} % of pixels drawn)`);
  await shot(page1, "01-cactus-loaded");
  const tok = await page1.evaluate(() => window.hdeform.tokens());
  const cactusName = await page1.evaluate(() => window.hdeform.sessionName);
  check(tok.edit.length >= 32 && tok.view.length >= 32 && tok.edit !== tok.view, "the new session came with an edit and a view token");
  const addr1 = page1.url();
  check(
    fragmentOf(addr1).get("edit") === tok.edit && fragmentOf(addr1).get("view") === tok.view && !tokenOutsideFragment(addr1, [tok.edit, tok.view]),
    "the editor's address holds its tokens in the fragment only (so a reload can reopen it)",
  );

  // 2. Regions: fixed at the bottom, handle at the top (test hook → the UI's assign()).
  const [bmin, bmax] = await page1.evaluate(() => window.hdeform.bbox());
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const h = bmax[up] - bmin[up];
  const lo = [...bmin].map((v) => v - 1);
  const hi = [...bmax].map((v) => v + 1);
  const fixedMax = [...hi];
  fixedMax[up] = bmin[up] + 0.1 * h;
  const handleMin = [...lo];
  handleMin[up] = bmax[up] - 0.1 * h;
  const countLabel = (label) => page1.evaluate((l) => window.hdeform.labels().filter((x) => x === l).length, label);
  // Fixed: a real screen-rectangle drag in Box mode around the bottom 10 % of the model.
  await page1.click('button[data-mode="box"]');
  await page1.selectOption("#label-select", "0");
  const corners = [];
  for (const x of [bmin[0], bmax[0]])
    for (const y of [bmin[1], up === 1 ? fixedMax[1] : bmax[1]])
      for (const z of [bmin[2], up === 2 ? fixedMax[2] : bmax[2]])
        corners.push(await page1.evaluate(([a, b, c]) => window.hdeform.screenPoint(a, b, c), [x, y, z]));
  const x0 = Math.min(...corners.map((c) => c.x)) - 4, x1 = Math.max(...corners.map((c) => c.x)) + 4;
  const y0 = Math.min(...corners.map((c) => c.y)) - 4, y1 = Math.max(...corners.map((c) => c.y)) + 4;
  await page1.mouse.move(x0, y0);
  await page1.mouse.down();
  await page1.mouse.move((x0 + x1) / 2, (y0 + y1) / 2, { steps: 3 });
  await page1.mouse.move(x1, y1, { steps: 3 });
  await page1.mouse.up();
  const nFixed = await countLabel(0);
  const fixedTooHigh = await page1.evaluate(
    ([upAxis, limit]) => {
      const L = window.hdeform.labels(), R = window.hdeform.restPositions();
      return L.filter((l, v) => l === 0 && R[3 * v + upAxis] > limit).length;
    },
    // The default view looks down about 30°, so the rectangle around the bottom slab also
    // takes the front of the trunk above it (Box takes the visible vertices; X-ray is off).
    [up, bmin[up] + 0.4 * h],
  );
  check(nFixed > 10 && fixedTooHigh === 0, `box select (real mouse drag) marked ${nFixed} fixed vertices, all near the bottom`);
  // Handle: the page's test hook (model-space box → the same assign() the tools use).
  const nHandle = await page1.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 1), [handleMin, hi]);
  check(nHandle > 10, `selected ${nHandle} handle vertices`);
  // Vertex mode: a real click on the middle of the trunk adds one fixed vertex; Erase removes it.
  await page1.click('button[data-mode="vertex"]');
  const mid = [(bmin[0] + bmax[0]) / 2, (bmin[1] + bmax[1]) / 2, (bmin[2] + bmax[2]) / 2];
  mid[up] = bmin[up] + 0.35 * h;
  const midScreen = await page1.evaluate(([a, b, c]) => window.hdeform.screenPoint(a, b, c), mid);
  await page1.mouse.click(midScreen.x, midScreen.y);
  const afterClick = await countLabel(0);
  await page1.selectOption("#label-select", "-1");
  await page1.mouse.click(midScreen.x, midScreen.y);
  const afterErase = await countLabel(0);
  check(afterClick === nFixed + 1 && afterErase === nFixed, `vertex click adds one vertex (${nFixed} → ${afterClick}) and Erase removes it (${afterErase})`);
  // Brush mode: a real stroke paints several vertices; an Erase stroke over it removes them.
  await page1.click('button[data-mode="brush"]');
  const stroke = async () => {
    await page1.mouse.move(midScreen.x, midScreen.y - 6);
    await page1.mouse.down();
    await page1.mouse.move(midScreen.x, midScreen.y + 6, { steps: 4 });
    await page1.mouse.up();
  };
  await page1.selectOption("#label-select", "0");
  await stroke();
  const afterBrush = await countLabel(0);
  await page1.selectOption("#label-select", "-1");
  await stroke();
  const afterBrushErase = await countLabel(0);
  check(afterBrush > nFixed + 3 && afterBrushErase === nFixed, `brush stroke paints ${afterBrush - nFixed} vertices; an Erase stroke removes them`);
  await page1.selectOption("#label-select", "0");
  await page1.click("#apply");
  await page1.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page1);
  const labels = await page1.evaluate(() => window.hdeform.labels());
  const rest = await page1.evaluate(() => window.hdeform.restPositions());
  const m0 = await page1.evaluate(() => window.hdeform.measures());
  const p0 = await positions(page1);
  check(m0 !== null, `measures shown after applying constraints (E = ${m0?.e})`);
  await shot(page1, "02-regions");

  // 3. Drag the gizmo with real mouse events.
  await page1.click('button[data-mode="move"]');
  await sleep(200);
  const g = await page1.evaluate(() => window.hdeform.gizmoScreenPoint());
  check(g !== null, `gizmo attached at (${g?.x.toFixed(0)}, ${g?.y.toFixed(0)})`);
  // Grab the horizontal arrow that is longest on screen and pull along it.
  const dir = (await arrowsOnScreen(page1)).horizontal;
  const axis = dir.axis;
  log(`dragging the ${axis} arrow (${dir.len.toFixed(0)} px from the centre)`);
  await dragGizmo(page1, axis, 140 * dir.x, 140 * dir.y);
  const p1 = await positions(page1);
  const m1 = await page1.evaluate(() => window.hdeform.measures());
  let handleMove = 0;
  let fixedMove = 0;
  for (let v = 0; v < labels.length; v++) {
    const d = Math.hypot(p1[3 * v] - rest[3 * v], p1[3 * v + 1] - rest[3 * v + 1], p1[3 * v + 2] - rest[3 * v + 2]);
    if (labels[v] === 1) handleMove = Math.max(handleMove, d);
    if (labels[v] === 0) fixedMove = Math.max(fixedMove, d);
  }
  const diag = Math.hypot(bmax[0] - bmin[0], bmax[1] - bmin[1], bmax[2] - bmin[2]);
  check(handleMove > 0.02 * diag, `the handle moved (${handleMove.toFixed(4)}, diagonal ${diag.toFixed(3)})`);
  check(fixedMove < 1e-4 * diag, `the fixed region stayed (${fixedMove.toExponential(2)})`);
  check(maxDiff(p0, p1) > 0, "the mesh moved");
  check(m1 && m0 && m1.e !== m0.e && m1.e > 0, `measures changed (E ${m0?.e} → ${m1?.e}, E_iso,n ${m1?.eIsoN})`);
  const measuresText = await page1.textContent("#m-e");
  check(measuresText && measuresText !== "–", `measures panel shows E = ${measuresText}`);
  await shot(page1, "03-after-drag");
  // The display is indexed while the energy map is off: each vertex drawn once.
  const drawnIndexed = await page1.evaluate(() => window.hdeform.displayVertices);
  check(drawnIndexed === labels.length, `indexed display draws ${drawnIndexed} vertices (the mesh has ${labels.length}); status "${await page1.evaluate(() => window.hdeform.status)}"`);

  // 4. The share link opens the same session with the same positions.
  const share = await page1.evaluate(() => window.hdeform.shareLink(false));
  log(`share link: ${share.replace(/[0-9a-f]{16,}/g, (t) => `${t.slice(0, 6)}…`)}`);
  check(
    new URL(share).searchParams.get("session") === cactusName && fragmentOf(share).get("edit") === tok.edit && !tokenOutsideFragment(share, [tok.edit, tok.view]),
    "the share link names the session in its query and carries the edit token only in its fragment",
  );
  const page2 = await context.newPage();
  watchPage(page2, "share");
  await page2.goto(share);
  await waitLoaded(page2, "share link");
  await waitSame(page2, p1, "the share link shows the same positions");
  await shot(page2, "04-share-link");
  check(!(await page2.evaluate(() => window.hdeform.watchOnly)) && (await page2.isVisible("#tools")), "the share link opens an editor (tools shown)");

  // 4b. Reload the editor: the address's fragment reopens the same session, still editable
  // (the next step drags on the reloaded page).
  const vBeforeReload = await page1.evaluate(() => window.hdeform.version);
  await page1.reload();
  await waitLoaded(page1, "editor after reload");
  check(
    (await page1.evaluate(() => window.hdeform.sessionName)) === cactusName &&
      !(await page1.evaluate(() => window.hdeform.watchOnly)) &&
      (await page1.evaluate(() => window.hdeform.version)) >= vBeforeReload,
    "reload keeps the session, as an editor",
  );
  await waitIdle(page1);
  await waitSame(page1, p1, "the reloaded editor shows the same shape");

  // 5. Live: another drag on page 1 reaches page 2 through WatchSession.
  await page1.bringToFront();
  const ay = (await arrowsOnScreen(page1)).up;
  await dragGizmo(page1, ay.axis, 70 * ay.x, 70 * ay.y);
  const p2 = await positions(page1);
  check(maxDiff(p1, p2) > 1e-3 && (await page1.evaluate(() => window.hdeform.lastError)) === "", "the reloaded editor's drag moved the mesh again");
  await waitSame(page2, p2, "the second viewer followed the edit live");
  await shot(page2, "05-live-follow");

  // 6. Watch-only link: no editing tools, same shape.
  const watchLink = await page1.evaluate(() => window.hdeform.shareLink(true));
  check(
    new URL(watchLink).searchParams.get("watch") === "1" &&
      fragmentOf(watchLink).get("view") === tok.view &&
      [...fragmentOf(watchLink).keys()].join() === "view" &&
      !watchLink.includes(tok.edit) &&
      !tokenOutsideFragment(watchLink, [tok.view]),
    "the watch link carries only the view token, in its fragment",
  );
  const page3 = await context.newPage();
  watchPage(page3, "watch");
  await page3.goto(watchLink);
  await waitLoaded(page3, "watch link");
  check(!(await page3.isVisible("#tools")), "watch-only page hides the editing tools");
  check(!(await page3.isVisible("#upload-input + progress")) && !(await page3.isVisible("#open-library")), "watch-only page hides open/upload");
  await waitSame(page3, p2, "the watch-only page shows the same positions");
  await shot(page3, "06-watch-only");

  // 6b. The watch link without `watch=1`: the view token alone still gives a watch-only page,
  // and an edit sent from that page's own API (its headers: the view token) is refused.
  const page4 = await context.newPage();
  watchPage(page4, "no-watch-param");
  const noWatch = new URL(watchLink);
  noWatch.searchParams.delete("watch");
  await page4.goto(noWatch.toString());
  await waitLoaded(page4, "watch link without watch=1");
  const noTools =
    (await page4.evaluate(() => window.hdeform.watchOnly)) &&
    !(await page4.isVisible("#tools")) &&
    !(await page4.isVisible("#sweep")) &&
    !(await page4.isVisible("#copy-share")) &&
    (await page4.evaluate(() => window.hdeform.gizmoScreenPoint())) === null;
  check(noTools, "a view-token page without watch=1 still has no editing tools");
  const transforms = await page1.evaluate(() => window.hdeform.handleTransforms());
  const deniedMove = await page4.evaluate(([name, t]) => window.hdeform.call("updateHandles", { name, transforms: t }), [cactusName, transforms]);
  const deniedBeta = await page4.evaluate((name) => window.hdeform.call("setBeta", { name, beta: { value: 0.3 } }), cactusName);
  const read = await page4.evaluate((name) => window.hdeform.call("getSession", { name }), cactusName);
  check(
    deniedMove.code === "PermissionDenied" && deniedBeta.code === "PermissionDenied" && read.code === "OK",
    `edits from the view-token page are refused (UpdateHandles ${deniedMove.code}, SetBeta ${deniedBeta.code}: "${deniedMove.message}"); GetSession ${read.code}`,
  );

  // 7. Energy colour map and sweep chart render (no errors).
  await page1.bringToFront();
  await page1.selectOption("#energy-map", "linear");
  await waitIdle(page1);
  await sleep(300);
  check(await page1.isVisible("#legend"), "energy legend shown");
  // Energy map on: three corners per triangle, so per-triangle colours are exact.
  const drawnSplit = await page1.evaluate(() => window.hdeform.displayVertices);
  check(drawnSplit > labels.length && drawnSplit % 3 === 0, `with the energy map the display draws ${drawnSplit} vertices (3 per triangle)`);
  await page1.click("#sweep");
  await page1.waitForFunction(() => document.querySelector("#sweep").textContent === "Sweep β", null, { timeout: 120_000 });
  check((await page1.evaluate(() => window.hdeform.lastError)) === "", "sweep and energies without errors");
  check((await page1.evaluate(() => window.hdeform.sweepRows)) >= 5, "sweep returned rows for the chart");
  await shot(page1, "07-energy-sweep");
  // The watch page measures from frames (a measuring Sweep needs the edit token): the energy
  // map's frame reached it.
  const m2 = await page1.evaluate(() => window.hdeform.measures());
  await page3
    .waitForFunction((e) => window.hdeform.measures() !== null && window.hdeform.measures().e === e, m2?.e, { timeout: 15_000 })
    .catch(() => {});
  const m3 = await page3.evaluate(() => window.hdeform.measures());
  check(m3 && m2 && Math.abs(m3.e - m2.e) <= 1e-9 * Math.max(1, Math.abs(m2.e)), `the watch-only page shows the same measures (E ${m3?.e} vs ${m2?.e})`);
  await page1.locator("#chart").scrollIntoViewIfNeeded();
  await page1.locator("#chart").screenshot({ path: join(artifacts, "07b-sweep-chart.png") });

  // 7c. Each frame encoding (?encoding=…): drag frames come encoded, the frame that ends the
  // drag as float32 (exactAsFloat32), so the page ends on the server's exact shape (GetMesh).
  await page1.selectOption("#energy-map", "off");
  await waitIdle(page1);
  check((await page1.evaluate(() => window.hdeform.displayVertices)) === labels.length, "energy map off: the display is indexed again");
  const editorLink = await page1.evaluate(() => window.hdeform.shareLink(false));
  for (const [i, encoding] of ["float32", "quantized", "meshopt", "meshopt-delta"].entries()) {
    const url = new URL(editorLink);
    url.searchParams.set("encoding", encoding);
    await page1.goto(url.toString());
    await waitLoaded(page1, `editor ?encoding=${encoding}`);
    await waitIdle(page1);
    await page1.click('button[data-mode="move"]');
    await sleep(200);
    const before = await positions(page1);
    // The longer horizontal arrow (the up arrow's tip may be off the canvas), back and forth.
    const a = (await arrowsOnScreen(page1)).horizontal;
    const hAxis = a.axis;
    const sign = i % 2 === 0 ? -1 : 1;
    await dragGizmo(page1, hAxis, sign * 60 * a.x, sign * 60 * a.y);
    const shown = await positions(page1);
    const exact = await page1.evaluate(() => window.hdeform.serverPositions());
    const sizes = await page1.evaluate(() => window.hdeform.status);
    check(
      maxDiff(before, shown) > 1e-3 && maxDiff(shown, exact) === 0 && (await page1.evaluate(() => window.hdeform.lastError)) === "",
      `?encoding=${encoding}: the drag ends on the server's exact shape (max |Δ| = ${maxDiff(shown, exact).toExponential(2)}; status "${sizes}")`,
    );
    if (encoding !== "float32") check(sizes.includes(`${encoding} `), `?encoding=${encoding}: drag frames came ${encoding}`);
  }
  // 7d. The decode worker writes a frame into the arrays of one the page handed back
  // (frame_decoder.ts): the same values as into fresh arrays, every entry written.
  {
    const { MeshoptEncoder } = await import(pathToFileURL(join(viewerDir, "node_modules/meshoptimizer/meshopt_encoder.js")).href);
    await MeshoptEncoder.ready;
    const n = 300;
    const packed = (t) => {
      const q = new Uint8Array(8 * n);
      const v = new DataView(q.buffer);
      for (let i = 0; i < n; i++) {
        for (let k = 0; k < 3; k++) v.setUint16(8 * i + 2 * k, Math.round(32767 * (1 + Math.sin(0.1 * i + k + t))), true);
        v.setInt8(8 * i + 6, Math.round(100 * Math.sin(0.2 * i + t)));
        v.setInt8(8 * i + 7, Math.round(-100 * Math.cos(0.3 * i - t)));
      }
      return Array.from(MeshoptEncoder.encodeVertexBuffer(q, n, 8));
    };
    const box = [[-1, -2, 0], [1, 2, 3]];
    const r = await page1.evaluate(([a, b, bx, count]) => window.hdeform.workerDecodeRecycled(a, b, bx, count), [packed(0), packed(1.5), box, n]);
    check(
      r.recycled[0].length === 3 * n && JSON.stringify(r.recycled) === JSON.stringify(r.fresh),
      "the decode worker's frame in handed-back arrays equals the fresh decode",
    );
  }

  // 8. A bad upload shows its error in the banner.
  await page1.setInputFiles("#upload-input", {
    name: "broken.obj",
    mimeType: "text/plain",
    buffer: Buffer.from("this is not a mesh\nf 1 2 99\n"),
  });
  await page1.waitForSelector("#banner:not(.hidden)", { timeout: 30_000 });
  const banner = await page1.textContent("#banner-text");
  check(/upload|rejected|invalid|parse|mesh/i.test(banner ?? ""), `bad upload shows an error: "${banner}"`);
  await shot(page1, "08-bad-upload");

  // 8b. A good upload (OFF from the repository's data) opens a new session.
  const before = await page1.evaluate(() => window.hdeform.sessionName);
  await page1.evaluate(() => document.querySelector("#banner-close").click());
  await page1.setInputFiles("#upload-input", resolve(viewerDir, "../data/models/knight.off"));
  await page1.waitForFunction((b) => window.hdeform.loaded && window.hdeform.sessionName !== b && window.hdeform.meshName !== "", before, { timeout: 60_000 });
  check((await page1.evaluate(() => window.hdeform.lastError)) === "", `upload of knight.off opened ${await page1.evaluate(() => window.hdeform.sessionName)}`);
  await shot(page1, "08b-upload-knight");

  // 8c. A glTF upload whose vertices are split at a seam (40 GLB vertices, 35 welded): the
  // viewer's selections are base-GLB ids (base_ids), and the regions it shows after Apply
  // come from Session.base_constraints. Column x = 3 has base ids 23, 27, …, 39 — beyond
  // the 35 engine vertices, so they only resolve through the weld map.
  const before8c = await page1.evaluate(() => window.hdeform.sessionName);
  await page1.setInputFiles("#upload-input", { name: "seam-grid.glb", mimeType: "model/gltf-binary", buffer: seamGridGlb() });
  await page1.waitForFunction((b) => window.hdeform.loaded && window.hdeform.sessionName !== b, before8c, { timeout: 60_000 });
  const nBase = await page1.evaluate(() => window.hdeform.labels().length);
  check(nBase === 40, `seam glTF upload: the viewer holds the 40 base-GLB vertices (${nBase})`);
  const nF = await page1.evaluate(() => window.hdeform.selectBox([-0.1, -0.1, -1], [0.1, 2.1, 1], 0));
  const nH = await page1.evaluate(() => window.hdeform.selectBox([2.9, -0.1, -1], [3.1, 2.1, 1], 1));
  const nSeam = await page1.evaluate(() => window.hdeform.selectBox([1.4, 0.9, -1], [1.6, 1.1, 1], 2));
  check(nF === 5 && nH === 5 && nSeam === 2, `seam glTF: selected 5 fixed, 5 handle and the 2 copies of a seam vertex (${nF}, ${nH}, ${nSeam})`);
  await page1.evaluate(() => window.hdeform.applyConstraints());
  await page1.waitForFunction(() => window.hdeform.constraintsApplied || window.hdeform.lastError !== "", null, { timeout: 60_000 });
  const err8c = await page1.evaluate(() => window.hdeform.lastError);
  check(err8c === "", `seam glTF: constraints by base ids accepted${err8c ? ` (${err8c})` : ""}`);
  const seamLabels = await page1.evaluate(() => window.hdeform.labels());
  const seamRest = await page1.evaluate(() => window.hdeform.restPositions());
  let labelsOk = true;
  for (let v = 0; v < seamLabels.length; v++) {
    const x = seamRest[3 * v], y = seamRest[3 * v + 1];
    const want = x === 0 ? 0 : x === 3 ? 1 : x === 1.5 && y === 1 ? 2 : -1;
    if (seamLabels[v] !== want) labelsOk = false;
  }
  check(labelsOk, "seam glTF: the regions adopted from the server (base_constraints) sit on the selected base vertices");
  // Grow crosses the seam (selection/commands.ts welds coincident copies): handle 2's region
  // emptied, then the left block's (1, 1) alone grown once takes its 6 neighbours on the welded
  // grid, among them (1.5, 1) and (1.5, 1.5) with both copies each: 4 vertices at x = 1.5, 9 in
  // all (a grow by triangle edges alone stops at the left copies: 2 and 7).
  await page1.selectOption("#label-select", "2");
  const grown = await page1.evaluate(() => {
    window.hdeform.select("none");
    const seed = window.hdeform.selectBox([0.9, 0.9, -1], [1.1, 1.1, 1], 2);
    window.hdeform.select("grow");
    const l = window.hdeform.labels(), r = window.hdeform.restPositions();
    let all = 0, atSeam = 0;
    l.forEach((x, v) => {
      if (x !== 2) return;
      all++;
      if (r[3 * v] === 1.5) atSeam++;
    });
    return { seed, all, atSeam };
  });
  check(grown.seed === 1 && grown.all === 9 && grown.atSeam === 4, `seam glTF: Grow crosses the seam (from ${grown.seed} vertex: ${grown.all} in the region, ${grown.atSeam} at the seam; want 9 and 4)`);
  await shot(page1, "08c-seam-gltf");

  // 9. Links that cannot open the session: a plain error, not a blank page.
  const bannerOf = async (url) => {
    await page4.goto("about:blank");
    await page4.goto(url);
    await page4.waitForSelector("#banner:not(.hidden)", { timeout: 30_000 });
    return (await page4.textContent("#banner-text")) ?? "";
  };
  const noToken = await bannerOf(`${base}?session=${encodeURIComponent(cactusName)}`);
  check(/no access token/i.test(noToken) && !(await page4.evaluate(() => window.hdeform.loaded)), `a link without a token cannot open the session: "${noToken}"`);
  const wrongToken = await bannerOf(`${base}?session=${encodeURIComponent(cactusName)}#edit=${"0".repeat(64)}`);
  check(/does not open/i.test(wrongToken) && !(await page4.evaluate(() => window.hdeform.loaded)), `a link with a wrong token cannot open the session: "${wrongToken}"`);
  const missing = await bannerOf(`${base}?session=sessions/does-not-exist#view=${"0".repeat(64)}`);
  check(/does-not-exist|not found|NotFound/i.test(missing), `unknown session link shows an error: "${missing}"`);
  await shot(page4, "09-missing-session");
  await page4.close();

  // 9b. A real deletion (from the editor's own API, with its edit token) ends the page's
  // session: the `deleted` event, then NOT_FOUND on the re-read.
  const seamName = await page1.evaluate(() => window.hdeform.sessionName);
  const del = await page1.evaluate((name) => window.hdeform.call("deleteSession", { name }), seamName);
  const gone = await page1
    .waitForFunction(() => window.hdeform.connection === "gone" && /was deleted/.test(window.hdeform.lastError), null, { timeout: 15_000 })
    .then(() => true, () => false);
  check(del.code === "OK" && gone, `a deleted session shows "${await page1.evaluate(() => window.hdeform.lastError)}"`);

  // 10. Durable restart: the share-link editor (page 2, constrained and moved) and the watch
  // page stay open while the server is killed and started again on the same ports and state.
  await page2.bringToFront();
  await waitIdle(page2);
  await sleep(1200); // moves are saved within 100 ms, history steps within a second
  const vKill = await page2.evaluate(() => window.hdeform.version);
  const pKill = await positions(page2);
  const stepsOf = (page) => page.evaluate(() => JSON.stringify(window.hdeform.history().map((s) => [s.id, s.kind, s.summary, s.undone])));
  const hKill = await stepsOf(page2);
  const tKill = Date.now();
  server.kill("SIGKILL");
  await new Promise((r) => (server.exitCode !== null || server.signalCode !== null ? r() : server.once("exit", r)));
  const sawReconnecting = await page2
    .waitForFunction(() => /reconnecting/.test(window.hdeform.status) && window.hdeform.connection === "reconnecting", null, { timeout: 10_000 })
    .then(() => true, () => false);
  check(sawReconnecting, `after kill -9 the editor's status line says "${await page2.evaluate(() => window.hdeform.status)}"`);
  await shot(page2, "10-reconnecting");
  ({ proc: server, port: portPromise } = startServer({ grpcPort: ports.grpc, httpPort: ports.http, tag: "server#2" }));
  const ports2 = await portPromise;
  const tUp = Date.now();
  check(ports2.http === port, `server started again on the same ports (${ports2.grpc}, ${ports2.http}) ${tUp - tKill} ms after the kill`);
  const back = (page) =>
    page
      .waitForFunction(() => window.hdeform.connection === "connected" && window.hdeform.reconnects >= 1, null, { timeout: 30_000 })
      .then(() => true, () => false);
  const back2 = await back(page2);
  check(back2, `the editor reconnected by itself ${Date.now() - tUp} ms after the restart (no reload)`);
  const err10 = await page2.evaluate(() => window.hdeform.lastError);
  check(err10 === "", `no banner after the reconnect${err10 ? ` (${err10})` : ""}`);
  const v10 = await page2.evaluate(() => window.hdeform.version);
  check(v10 === vKill, `the session came back with the same version (${v10}, was ${vKill})`);
  await waitSame(page2, pKill, "the editor shows the same pose after the restart");
  // The history is stored with the session (within the flush window the sleep above waits
  // out): the History list after the restart is the one before the kill.
  const historyBack = await page2
    .waitForFunction((h) => JSON.stringify(window.hdeform.history().map((s) => [s.id, s.kind, s.summary, s.undone])) === h && window.hdeform.history().length > 0, hKill, { timeout: 10_000 })
    .then(() => true, () => false);
  check(historyBack, `the History after the restart is the one before the kill (${JSON.parse(hKill).length} steps; now ${await stepsOf(page2)})`);
  check(await back(page3), "the watch page reconnected too");
  await waitSame(page3, pKill, "the watch page shows the same pose after the restart");
  // A horizontal arrow (the up arrow's tip may be under the top bar after step 5's lift).
  const dir2 = (await arrowsOnScreen(page2)).horizontal;
  const axis2 = dir2.axis;
  await dragGizmo(page2, axis2, -80 * dir2.x, -80 * dir2.y, 5);
  const p10 = await positions(page2);
  const v10b = await page2.evaluate(() => window.hdeform.version);
  check(maxDiff(p10, pKill) > 1e-3 && v10b > vKill && (await page2.evaluate(() => window.hdeform.lastError)) === "", `a drag after the restart works (version ${vKill} → ${v10b})`);
  await waitSame(page3, p10, "the watch page follows the drag after the restart");
  await shot(page2, "10b-after-restart");

  // 11. Retry policy: an UpdateHandles answered with HTTP 503 (UNAVAILABLE) makes the page
  // reconnect and send the edit once more; a SetBeta that fails twice is reported.
  let failUpdates = 1;
  await page2.route("**/hdeform.v1.Deformation/UpdateHandles", (route) =>
    failUpdates-- > 0 ? route.fulfill({ status: 503, contentType: "text/plain", body: "unavailable (test)" }) : route.continue(),
  );
  const r11 = await page2.evaluate(() => window.hdeform.reconnects);
  await dragGizmo(page2, axis2, 50 * dir2.x, 50 * dir2.y, 5);
  const p11 = await positions(page2);
  const r11b = await page2.evaluate(() => window.hdeform.reconnects);
  const err11 = await page2.evaluate(() => window.hdeform.lastError);
  check(failUpdates < 0 && r11b === r11 + 1 && err11 === "" && maxDiff(p11, p10) > 1e-3, `a handle update refused with 503 was sent again after a reconnect (reconnects ${r11} → ${r11b}${err11 ? `, banner ${err11}` : ""})`);
  await waitSame(page3, p11, "the retried edit reached the server (the watch page follows)");
  await page2.unroute("**/hdeform.v1.Deformation/UpdateHandles");
  let failBeta = 2;
  await page2.route("**/hdeform.v1.Deformation/SetBeta", (route) =>
    failBeta-- > 0 ? route.fulfill({ status: 503, contentType: "text/plain", body: "unavailable (test)" }) : route.continue(),
  );
  await page2.evaluate(() => {
    const b = document.querySelector("#beta");
    b.value = "0.4";
    b.dispatchEvent(new Event("change"));
  });
  const betaErr = await page2
    .waitForFunction(() => /β rejected/.test(window.hdeform.lastError) && window.hdeform.connection === "connected", null, { timeout: 15_000 })
    .then(() => page2.evaluate(() => window.hdeform.lastError), () => "");
  check(failBeta <= 0 && betaErr !== "", `an edit failing again after the reconnect is reported, not retried again ("${betaErr}")`);
  await page2.unroute("**/hdeform.v1.Deformation/SetBeta");

  // 12. No token ever left a page in a URL; every session call carried one.
  const tokensSeen = await Promise.all([page1, page2, page3].map((p) => p.evaluate(() => window.hdeform.tokens())));
  const allTokens = [tok.edit, tok.view, ...tokensSeen.flatMap((t) => [t.edit, t.view])];
  const leaked = requests.filter((r) => tokenOutsideFragment(r.url, allTokens));
  check(leaked.length === 0, `no request URL carries a token (${requests.length} requests${leaked.length ? `; e.g. ${leaked[0].url}` : ""})`);
  const calls = requests.filter((r) => /\/hdeform\.v1\.Deformation\/(?!ListMeshes)/.test(r.url) && r.page !== "no-watch-param");
  const bare = calls.filter((r) => !/^Bearer \S+$/.test(r.auth));
  check(calls.length > 20 && bare.length === 0, `every session call of the pages carried authorization: Bearer (${calls.length} calls${bare.length ? `; without: ${bare[0].url}` : ""})`);

  // 13. Lost server for good: the status line says reconnecting at once, the banner follows.
  server.kill("SIGTERM");
  await page2.evaluate(() => document.querySelector("#banner-close").click());
  await page2.waitForFunction(() => /reconnecting/.test(window.hdeform.status), null, { timeout: 10_000 }).then(
    () => check(true, "stopped server: the status line says reconnecting"),
    () => check(false, "stopped server: the status line says reconnecting"),
  );
  await page2.waitForFunction(() => /lost|connection|reconnect/i.test(window.hdeform.lastError), null, { timeout: 30_000 }).then(
    () => check(true, "lost server shows an error banner"),
    () => check(false, "lost server shows an error banner"),
  );
  await shot(page2, "13-lost-server");

  writeFileSync(join(artifacts, "console.log"), consoleLines.join("\n") + "\n");
} catch (err) {
  if (err instanceof StopHere) log(`--only ${args.only}: stopping after the ${args.only} checks`);
  else {
    failures++;
    failed.push(`exception: ${err.message ?? err}`);
    log(`FAIL exception: ${err.stack ?? err}`);
  }
} finally {
  if (context) await context.close().catch(() => {});
  rmSync(userDataDir, { recursive: true, force: true });
  if (server.exitCode === null && server.signalCode === null) {
    server.kill("SIGTERM");
    await Promise.race([new Promise((r) => server.once("exit", r)), sleep(5000)]);
    if (server.exitCode === null && server.signalCode === null) server.kill("SIGKILL");
  }
  rmSync(stateDir, { recursive: true, force: true });
}
log(`${failures === 0 ? "PASSED" : `${failures} check(s) FAILED; screenshots in ${artifacts}`} (${((Date.now() - t00) / 1000).toFixed(1)} s)`);
for (const what of failed) log(`FAILED: ${what}`);
process.exit(failures === 0 ? 0 : 1);

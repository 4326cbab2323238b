// The viewer in real headless Chromium (Debian's, software GL: SwiftShader) dragging a large
// mesh, one run per frame encoding: how many frames per second the page applies while the
// mouse drags the gizmo at ≈ 60 Hz for a while (issue 11: "84K mesh in headless Chromium").
// Not a CI test: it reports. Results and method: docs/benchmarks.md "WAN bench (issue 11)".
//
//   node bench/wan/chromium_drag.mjs --server build/server/hdeform-server [--viewer web-viewer]
//        [--chromium /usr/bin/chromium] [--rings 300 --around 280] [--seconds 10]
//        [--encodings float32,quantized,meshopt,meshopt-delta]
//
// The mesh is an open tube of rings × around vertices (default 84,000), written as OFF and
// uploaded through the page; the bottom tenth is fixed, the top tenth is the handle.
import { spawn } from "node:child_process";
import { existsSync, mkdtempSync, rmSync, writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";
import { pathToFileURL } from "node:url";

const args = Object.fromEntries(
  process.argv.slice(2).reduce((a, v, i, all) => (v.startsWith("--") ? [...a, [v.slice(2), all[i + 1]]] : a), []),
);
const serverBin = args.server;
if (!serverBin) throw new Error("--server PATH/hdeform-server is required");
const viewerDir = resolve(args.viewer ?? "web-viewer");
const chromiumPath = args.chromium ?? "/usr/bin/chromium";
const rings = Number(args.rings ?? 300), around = Number(args.around ?? 280);
const seconds = Number(args.seconds ?? 10);
const encodings = (args.encodings ?? "float32,quantized,meshopt,meshopt-delta").split(",");
const decodes = Number(args.decodes ?? 40); // decodes of one frame by the worker alone (0: none)
const require = createRequire(join(viewerDir, "package.json"));
const { chromium } = require("playwright-core");
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const log = (...a) => console.log(`[chromium-drag ${new Date().toISOString().slice(11, 19)}]`, ...a);

// ---- the tube -------------------------------------------------------------------------------
const work = mkdtempSync(join(tmpdir(), "hdeform-chromium-drag-"));
const height = 3, radius = 0.5;
const lines = [`OFF`, `${rings * around} ${2 * around * (rings - 1)} 0`];
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
const meshPath = join(work, `tube-${rings * around}.off`);
writeFileSync(meshPath, lines.join("\n") + "\n");

// ---- server and browser ---------------------------------------------------------------------
// The page with its test hook (window.hdeform): `npm run build:test` → VIEWER/dist-test.
const webRoot = resolve(args["web-root"] ?? join(viewerDir, "dist-test"));
if (!existsSync(join(webRoot, "index.html"))) {
  console.error(`chromium_drag: no ${webRoot}/index.html: run \`npm run build:test\` in ${viewerDir} (or pass --web-root)`);
  process.exit(2);
}
const server = spawn(serverBin, ["--port", "0", "--http-port", "0", "--no-state", "--web-root", webRoot], {
  stdio: ["ignore", "pipe", "pipe"],
});
const httpPort = await new Promise((ok, fail) => {
  let out = "";
  const timer = setTimeout(() => fail(new Error(`no HTTP port within 60 s:\n${out}`)), 60_000);
  const on = (b) => {
    out += b.toString();
    const m = /hdeform-server http on \S+:(\d+)/.exec(out);
    if (m) clearTimeout(timer), ok(Number(m[1]));
  };
  server.stdout.on("data", on);
  server.stderr.on("data", on);
});
const context = await chromium.launchPersistentContext(join(work, "profile"), {
  executablePath: chromiumPath,
  headless: true,
  viewport: { width: 1280, height: 800 },
  args: ["--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
});

const rows = [];
try {
  for (const encoding of encodings) {
    const page = await context.newPage();
    page.on("pageerror", (e) => log(`pageerror: ${e.message}`));
    await page.goto(`http://127.0.0.1:${httpPort}/?encoding=${encoding}`);
    await page.waitForSelector("#upload-input", { state: "attached", timeout: 30_000 });
    const t0 = Date.now();
    await page.setInputFiles("#upload-input", meshPath);
    await page.waitForFunction(() => window.hdeform && window.hdeform.loaded && window.hdeform.sessionName !== "", null, { timeout: 180_000 });
    const openMs = Date.now() - t0;
    const nFixed = await page.evaluate(([h]) => window.hdeform.selectBox([-1, -1, -0.01], [1, 1, 0.1 * h], 0), [height]);
    const nHandle = await page.evaluate(([h]) => window.hdeform.selectBox([-1, -1, 0.9 * h], [1, 1, 1.01 * h], 1), [height]);
    await page.evaluate(() => window.hdeform.applyConstraints());
    await page.waitForFunction(() => window.hdeform.constraintsApplied || window.hdeform.lastError !== "", null, { timeout: 180_000 });
    await page.waitForFunction(() => !window.hdeform.busy, null, { timeout: 60_000 });
    await page.click('button[data-mode="move"]');
    await sleep(300);
    const vertices = await page.evaluate(() => window.hdeform.labels().length);
    const displayed = await page.evaluate(() => window.hdeform.displayVertices);
    // Drag the gizmo's x arrow back and forth at ≈ 60 mouse moves a second.
    const p = await page.evaluate(() => window.hdeform.gizmoScreenPoint("x"));
    if (!p) throw new Error("the gizmo is not attached");
    await page.mouse.move(p.x, p.y);
    await page.mouse.down();
    // Animation frames the page gets while dragging: with software GL each one renders the mesh.
    await page.evaluate(() => {
      window.__rafCount = 0;
      const tick = () => { window.__rafCount++; requestAnimationFrame(tick); };
      requestAnimationFrame(tick);
    });
    const r0 = await page.evaluate(() => window.__rafCount);
    const f0 = await page.evaluate(() => window.hdeform.framesApplied);
    const start = Date.now();
    let moves = 0;
    while (Date.now() - start < seconds * 1000) {
      const s = (Date.now() - start) / 1000;
      await page.mouse.move(p.x + 80 * Math.sin(2 * Math.PI * s / 3), p.y);
      moves++;
      const next = start + (moves * 1000) / 60;
      if (next > Date.now()) await sleep(next - Date.now());
    }
    const f1 = await page.evaluate(() => window.hdeform.framesApplied);
    const r1 = await page.evaluate(() => window.__rafCount);
    const elapsed = (Date.now() - start) / 1000;
    await page.mouse.up();
    await page.waitForFunction(() => !window.hdeform.busy, null, { timeout: 60_000 }).catch(() => {});
    const status = await page.evaluate(() => window.hdeform.status);
    const error = await page.evaluate(() => window.hdeform.lastError);
    // The decode worker's own time per frame (float32 frames decode on the main thread: none).
    const workerMs = (await page.evaluate(() => window.hdeform.workerDecodeMs())).sort((a, b) => a - b);
    const pct = (q) => (workerMs.length ? +workerMs[Math.min(workerMs.length - 1, Math.floor(q * workerMs.length))].toFixed(2) : null);
    const row = {
      encoding, vertices, displayed, fixed: nFixed, handle: nHandle, open_ms: openMs,
      mouse_moves_per_s: +(moves / elapsed).toFixed(1),
      frames_per_s: +((f1 - f0) / elapsed).toFixed(1),
      animation_frames_per_s: +((r1 - r0) / elapsed).toFixed(1),
      worker_decode_p50_ms: pct(0.5), worker_decode_p90_ms: pct(0.9), worker_decodes: workerMs.length,
      status, error,
    };
    rows.push(row);
    log(JSON.stringify(row));
    await page.close();
  }
  // ---- the decode worker alone: one MESHOPT frame of the tube (positions quantized in its
  // box, the tube's outward normals octahedral) decoded `decodes` times, one after another,
  // by a decode worker of the page's own code, with no session open and nothing rendering.
  if (decodes > 0) {
    const { MeshoptEncoder } = await import(pathToFileURL(join(viewerDir, "node_modules/meshoptimizer/meshopt_encoder.js")).href);
    await MeshoptEncoder.ready;
    const n = rings * around;
    const q = new Uint8Array(8 * n);
    const view = new DataView(q.buffer);
    for (let r = 0; r < rings; r++)
      for (let a = 0; a < around; a++) {
        const i = r * around + a, t = (2 * Math.PI * a) / around, c = Math.cos(t), s = Math.sin(t);
        view.setUint16(8 * i, Math.round(((c + 1) / 2) * 65535), true);
        view.setUint16(8 * i + 2, Math.round(((s + 1) / 2) * 65535), true);
        view.setUint16(8 * i + 4, Math.round((r / (rings - 1)) * 65535), true);
        view.setInt8(8 * i + 6, Math.round((c / (Math.abs(c) + Math.abs(s))) * 127));
        view.setInt8(8 * i + 7, Math.round((s / (Math.abs(c) + Math.abs(s))) * 127));
      }
    const packed = MeshoptEncoder.encodeVertexBuffer(q, n, 8);
    const page = await context.newPage();
    await page.goto(`http://127.0.0.1:${httpPort}/`);
    await page.waitForFunction(() => window.hdeform, null, { timeout: 30_000 });
    await sleep(1000);
    const box = [[-radius, -radius, 0], [radius, radius, height]];
    const { fresh, recycled } = await page.evaluate(([v, b, count, k]) => window.hdeform.workerDecodeTimes(v, b, count, k), [Array.from(packed), box, n, decodes]);
    const at = (ms, f) => {
      const sorted = [...ms].sort((a, b) => a - b);
      return +sorted[Math.min(sorted.length - 1, Math.floor(f * sorted.length))].toFixed(2);
    };
    // The first decode also builds the normals' table: left out of the medians.
    rows.idle = {
      vertices: n, bytes: packed.byteLength, first_ms: +fresh[0].toFixed(2), decodes,
      fresh_median_ms: at(fresh.slice(1), 0.5), fresh_p90_ms: at(fresh.slice(1), 0.9),
      recycled_median_ms: at(recycled, 0.5), recycled_p90_ms: at(recycled, 0.9),
    };
    log(JSON.stringify({ worker_decode_alone: rows.idle }));
    await page.close();
  }
} finally {
  await context.close().catch(() => {});
  server.kill();
  rmSync(work, { recursive: true, force: true });
}
console.log("| encoding | vertices (displayed) | mouse moves/s | animation frames/s | frames applied/s | worker decode p50 / p90 ms | status after the drag |");
console.log("|---|---|---|---|---|---|---|");
for (const r of rows)
  console.log(`| ${r.encoding} | ${r.vertices} (${r.displayed}) | ${r.mouse_moves_per_s} | ${r.animation_frames_per_s} | ${r.frames_per_s} | ${r.worker_decode_p50_ms ?? "—"} / ${r.worker_decode_p90_ms ?? "—"} | ${r.status}${r.error ? ` — error: ${r.error}` : ""} |`);
if (rows.idle) {
  const w = rows.idle;
  console.log(`\nworker decode alone (MESHOPT, ${w.vertices} vertices, ${w.bytes} bytes, ${w.decodes} decodes each): first ${w.first_ms} ms; ` +
    `fresh arrays median ${w.fresh_median_ms} / p90 ${w.fresh_p90_ms} ms; arrays handed back (as the page does) median ${w.recycled_median_ms} / p90 ${w.recycled_p90_ms} ms`);
}

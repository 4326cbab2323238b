// Repair on upload (docs/api.md "Repair", the viewer's part), in a real page against the real
// server: a file refused for inconsistent orientation offers no repair; a bowtie (two triangles
// touching at one vertex) is refused as "non-manifold vertex" with a "Repair and open" button
// in the error banner; the button uploads the same file again with `repair=0` (no new file
// pick), the session opens with the split vertex's copy (6 vertices) and an amber notice lists
// what the repair changed. Screenshots `repair-*.png`.

const bowtie = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv -1 0 0\nv 0 -1 0\nf 1 2 3\nf 1 4 5\n";
// Two triangles sharing edge 2–3 in the same direction: not repairable.
const flipped = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 3 4\n";

export async function repairChecks({ context, base, log, check, shot, watchPage }) {
  const page = await context.newPage();
  watchPage(page, "repair");
  const uploads = [];
  page.on("request", (r) => {
    if (/\/upload\?/.test(r.url())) uploads.push(r.url());
  });
  await page.goto(base);
  await page.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  const bannerState = () =>
    page.evaluate(() => ({
      shown: !document.querySelector("#banner").classList.contains("hidden"),
      notice: document.querySelector("#banner").classList.contains("notice"),
      text: document.querySelector("#banner-text").textContent ?? "",
      action: document.querySelector("#banner-action").classList.contains("hidden") ? "" : document.querySelector("#banner-action").textContent,
    }));
  /** Waits until the banner shows text matching `re` (the same banner may show an older message first). */
  const bannerSays = (re) =>
    page
      .waitForFunction(
        (src) => !document.querySelector("#banner").classList.contains("hidden") && new RegExp(src).test(document.querySelector("#banner-text").textContent ?? ""),
        re.source,
        { timeout: 30_000 },
      )
      .then(() => true, () => false);

  // Not repairable: the refusal has no button.
  await page.setInputFiles("#upload-input", { name: "flipped.obj", mimeType: "text/plain", buffer: Buffer.from(flipped) });
  const saidFlipped = await bannerSays(/inconsistent orientation/);
  const flippedBanner = await bannerState();
  check(saidFlipped && flippedBanner.action === "", `inconsistent orientation: refused without a repair button (${JSON.stringify(flippedBanner)})`);

  // A bowtie: refused, with "Repair and open".
  await page.setInputFiles("#upload-input", { name: "bowtie.obj", mimeType: "text/plain", buffer: Buffer.from(bowtie) });
  const saidBowtie = await bannerSays(/non-manifold vertex/);
  const button = page.locator("#banner-action");
  const offered = await button.waitFor({ state: "visible", timeout: 30_000 }).then(() => true, () => false);
  const refused = await bannerState();
  check(
    saidBowtie && offered && refused.action === "Repair and open" && !refused.notice && /^Upload rejected \(HTTP 400\): non-manifold vertex/.test(refused.text),
    `bowtie upload: refused with the server's message and "Repair and open" (${JSON.stringify(refused)})`,
  );
  await shot(page, "repair-01-refused");
  if (!offered) {
    await page.close();
    return;
  }

  // The button: the same file again, repaired; the session opens and the notice says what changed.
  await button.click({ timeout: 10_000 });
  const opened = await page
    .waitForFunction(() => window.hdeform.loaded && window.hdeform.sessionName !== "", null, { timeout: 60_000 })
    .then(() => true, () => false);
  const n = opened ? await page.evaluate(() => window.hdeform.labels().length) : -1;
  check(opened && n === 6, `Repair and open: the bowtie opened with 6 vertices (the split vertex's copy added) (loaded ${opened}, ${n} vertices)`);
  if (opened) log(`repair: loaded ${await page.evaluate(() => window.hdeform.sessionName)}`);
  const noticed = await bannerSays(/^Repaired: split 1 non-manifold vertex/);
  const repaired = await bannerState();
  check(noticed && repaired.notice && repaired.action === "", `after the repair an amber notice lists the changes: "${repaired.text}"`);
  check(
    uploads.length === 3 && !/[?&]repair=/.test(uploads[1]) && /[?&]repair=0(&|$)/.test(uploads[2]) && /filename=bowtie\.obj/.test(uploads[2]),
    `the retry uploads bowtie.obj again with repair=0 (${uploads.map((u) => u.replace(/^.*\/upload\?/, "").replace(/&session_id=\w+/, "")).join(" | ")})`,
  );
  await shot(page, "repair-02-repaired");
  await page.close();
}

// Several editors in one session (issue 12, part C), in real pages with real mouse events:
// Alice and Bob open the same session (Bob through Alice's share link) and drag DIFFERENT
// handles at the same time: the server ends with both moves. Then Alice holds handle 1 and
// Bob tries to drag it: his drag is refused, his page names Alice, and nothing of his is sent.
// A third page, a watcher (view token), lists both names live. Needs a server with GrabHandles:
// against one without, the checks are skipped with a message saying so.

export async function severalEditorsChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle }) {
  const alice = await context.newPage();
  watchPage(alice, "alice");
  await alice.setViewportSize({ width: 1100, height: 760 });
  await alice.goto(base);
  // Names through the name field in the top bar (remembered per browser profile: localStorage).
  await alice.fill("#display-name", "Alice");
  await alice.press("#display-name", "Tab");
  await alice.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await alice.selectOption("#library", "cactus");
  await alice.click("#open-library");
  await waitLoaded(alice, "alice");
  const name = await alice.evaluate(() => window.hdeform.sessionName);
  const grab = await alice.evaluate((n) => window.hdeform.call("grabHandles", { name: n, client: { clientId: "probe" }, handles: [] }), name);
  if (grab.code === "Unimplemented" || grab.code === "UNIMPLEMENTED") {
    log(`SKIP several editors: this hdeform-server has no GrabHandles (${grab.code}: ${grab.message}); the client code is in place, the checks need the server side ("service: several editors")`);
    await alice.close();
    return false;
  }
  // Regions: fixed bottom, handle 1 the top, handle 2 a side slab half-way up.
  const [bmin, bmax] = await alice.evaluate(() => window.hdeform.bbox());
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const h = bmax[up] - bmin[up];
  const slab = (from, to, side) => {
    const lo = bmin.map((v) => v - 1), hi = bmax.map((v) => v + 1);
    lo[up] = bmin[up] + from * h;
    hi[up] = bmin[up] + to * h;
    if (side) lo[0] = bmax[0] - 0.25 * (bmax[0] - bmin[0]);
    return [lo, hi];
  };
  await alice.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  await alice.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01));
  await alice.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 2), slab(0.45, 0.65, true));
  await alice.click("#apply");
  await alice.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(alice);
  await alice.click('button[data-mode="move"]');

  const bob = await context.newPage();
  watchPage(bob, "bob");
  await bob.setViewportSize({ width: 1100, height: 760 });
  await bob.goto(await alice.evaluate(() => window.hdeform.shareLink(false)));
  await waitLoaded(bob, "bob");
  await bob.fill("#display-name", "Bob");
  await bob.press("#display-name", "Tab");
  await waitIdle(bob);
  const watcher = await context.newPage();
  watchPage(watcher, "watcher-3");
  await watcher.setViewportSize({ width: 1100, height: 760 });
  await watcher.goto(await alice.evaluate(() => window.hdeform.shareLink(true)));
  await waitLoaded(watcher, "watcher");
  await watcher.fill("#display-name", "Carol");
  await watcher.press("#display-name", "Tab");
  const names = (p) => p.evaluate(() => window.hdeform.presence().map((x) => x.name).sort().join(","));
  const seesBoth = await watcher
    .waitForFunction(() => {
      const p = window.hdeform.presence();
      const by = (n) => p.find((x) => x.name === n);
      return by("Alice")?.editor && by("Bob")?.editor && by("Carol") && !by("Carol").editor;
    }, null, { timeout: 15_000 })
    .then(() => true, () => false);
  check(seesBoth, `the watcher's presence lists both editors and itself as a viewer (${await names(watcher)})`);
  check(/Alice/.test((await watcher.textContent("#presence")) ?? "") && /Bob/.test((await watcher.textContent("#presence")) ?? ""), "…and shows their names on screen");
  await shot(watcher, "multi-01-watcher-presence");

  // Handle 1 for Alice, handle 2 for Bob; both drag at the same time.
  await alice.evaluate(() => window.hdeform.setActiveHandle(1));
  await bob.evaluate(() => window.hdeform.setActiveHandle(2));
  await bob.click('button[data-mode="move"]');
  await sleep(200);
  const start = async (page) => {
    const c = await page.evaluate(() => window.hdeform.gizmoScreenPoint());
    const a = await page.evaluate(() => window.hdeform.gizmoScreenPoint("x"));
    const len = Math.hypot(a.x - c.x, a.y - c.y);
    const dir = { x: (a.x - c.x) / len, y: (a.y - c.y) / len };
    await page.mouse.move(a.x, a.y);
    await sleep(50);
    await page.mouse.down();
    return { a, dir };
  };
  const step = (page, s, i, dist = 60) => page.mouse.move(s.a.x + (s.dir.x * dist * i) / 8, s.a.y + (s.dir.y * dist * i) / 8);
  await alice.bringToFront();
  const sa = await start(alice);
  const sb = await start(bob);
  for (let i = 1; i <= 8; i++) {
    await step(alice, sa, i);
    await step(bob, sb, i);
    await sleep(60);
  }
  // While both hold their handles, each page shows the other's handle in the holder's colour.
  await shot(alice, "multi-02-alice-dragging-handle1");
  await shot(bob, "multi-02-bob-dragging-handle2");
  await alice.mouse.up();
  await bob.mouse.up();
  await waitIdle(alice);
  await waitIdle(bob);
  await sleep(500);
  const server = await alice.evaluate(() => window.hdeform.serverTranslations());
  const moved = (t) => Math.hypot(...t) > 1e-3;
  check(server.length === 2 && moved(server[0]) && moved(server[1]), `two editors dragging different handles at once: both moves kept (server: ${JSON.stringify(server.map((t) => t.map((v) => +v.toFixed(3))))})`);
  const bobSees = await bob.evaluate(() => window.hdeform.handleTransforms().map((t) => [t.translation.x, t.translation.y, t.translation.z]));
  const near = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]) < 1e-6;
  check(bobSees.length === 2 && near(bobSees[0], server[0]) && near(bobSees[1], server[1]), "Bob's page has Alice's handle where the server has it (Frame.transforms)");

  // The same handle: Alice holds handle 1, Bob's drag of it is refused with her name.
  await bob.evaluate(() => window.hdeform.setActiveHandle(1));
  await sleep(200);
  const sa2 = await start(alice);
  for (let i = 1; i <= 4; i++) {
    await step(alice, sa2, i, 40);
    await sleep(60);
  }
  // Alice holds still for longer than the 5 s lease: her page grabs again every 2 s, so she
  // still holds the handle when Bob tries.
  await sleep(6000);
  await bob.waitForFunction(() => window.hdeform.presence().some((p) => p.name === "Alice" && p.held.includes(0)), null, { timeout: 10_000 }).catch(() => {});
  const bobBefore = await bob.evaluate(() => window.hdeform.handleTransforms()[0].translation);
  let bobUpdates = 0;
  const countUpdates = (r) => {
    if (/Deformation\/UpdateHandles/.test(r.url())) bobUpdates++;
  };
  bob.on("request", countUpdates);
  const sb2 = await start(bob);
  for (let i = 1; i <= 4; i++) {
    await step(bob, sb2, i, 40);
    await sleep(60);
  }
  await bob.mouse.up();
  await bob.waitForFunction(() => /being moved by/.test(window.hdeform.lastError), null, { timeout: 10_000 }).catch(() => {});
  const refused = await bob.evaluate(() => window.hdeform.lastError);
  await sleep(300);
  bob.off("request", countUpdates);
  await shot(bob, "multi-03-bob-refused");
  await alice.mouse.up();
  await waitIdle(alice);
  await sleep(300);
  const bobAfter = await bob.evaluate(() => window.hdeform.handleTransforms()[0].translation);
  const aliceFinal = await alice.evaluate(() => window.hdeform.serverTranslations());
  check(/Handle 0 is being moved by Alice/.test(refused) && bobUpdates === 0, `Bob's drag of the handle Alice holds is refused: "${refused}" (${bobUpdates} updates sent)`);
  check(
    Math.hypot(aliceFinal[0][0] - bobAfter.x, aliceFinal[0][1] - bobAfter.y, aliceFinal[0][2] - bobAfter.z) < 1e-6,
    `…his page ends on Alice's pose of it, not his own (before ${bobBefore.x.toFixed(3)}, after ${bobAfter.x.toFixed(3)}, server ${aliceFinal[0][0].toFixed(3)})`,
  );
  await shot(alice, "multi-04-alice-after");

  // A stale β change: Bob's live stream is held back (a WatchSession that never answers; his
  // name change restarts the stream), so he has not seen Alice's β when he sets his own. The
  // server refuses his (expected_config_version); his page says so and reloads the session.
  await bob.route("**/hdeform.v1.Deformation/WatchSession", () => {}); // never answered
  await bob.fill("#display-name", "Bob2");
  await bob.press("#display-name", "Tab");
  await sleep(300);
  const cvBob = await bob.evaluate(() => window.hdeform.configVersion);
  await alice.fill("#beta-num", "0.3");
  await alice.press("#beta-num", "Enter");
  await alice.waitForFunction((v) => window.hdeform.configVersion > v, cvBob, { timeout: 15_000 }).catch(() => {});
  await waitIdle(alice);
  await bob.fill("#beta-num", "0.6");
  await bob.press("#beta-num", "Enter");
  await bob.waitForFunction(() => /not applied/.test(window.hdeform.lastError), null, { timeout: 15_000 }).catch(() => {});
  const conflict = await bob.evaluate(() => window.hdeform.lastError);
  await bob.waitForFunction(() => Math.abs(Number(document.querySelector("#beta").value) - 0.3) < 1e-9, null, { timeout: 10_000 }).catch(() => {});
  const bobBeta = Number(await bob.inputValue("#beta"));
  const serverBeta = await alice.evaluate(() => window.hdeform.serverBeta());
  check(/someone else changed/.test(conflict) && Math.abs(serverBeta - 0.3) < 1e-9 && Math.abs(bobBeta - 0.3) < 1e-9, `a β change made on a stale config version is refused, said so, and the page reloads Alice's β (${bobBeta}; server ${serverBeta}): "${conflict.slice(0, 90)}…"`);
  await shot(bob, "multi-05-bob-stale-beta");
  await bob.unroute("**/hdeform.v1.Deformation/WatchSession");
  for (const p of [watcher, bob, alice]) await p.close();
  return true;
}

// History and snapshots in a real page with real mouse and keyboard (issue 13, the viewer's
// part): a drag, Ctrl+Z puts the mesh and the gizmo back at the rest pose (as the server has
// it, GetSession), Ctrl+Shift+Z brings the move back; Ctrl+Y with nothing to redo and a click
// on a step that cannot be undone show the server's refusal and change nothing; the History
// panel lists the MOVE, UNDO and REDO steps with the author's name; a snapshot "A" is saved,
// the handle moved again, "A" restored (the pose is A's again) and deleted. Screenshots
// `history-*.png`. Against a server without ListHistory it prints SKIP and checks nothing.

export async function historyChecks({ context, base, log, check, sleep, shot, watchPage, waitLoaded, waitIdle, positions, maxDiff }) {
  const page = await context.newPage();
  watchPage(page, "history");
  await page.setViewportSize({ width: 1280, height: 860 });
  await page.goto(base);
  await page.fill("#display-name", "Hana");
  await page.press("#display-name", "Tab");
  await page.waitForSelector('#library option[value="cactus"]', { state: "attached", timeout: 30_000 });
  await page.selectOption("#library", "cactus");
  await page.click("#open-library");
  await waitLoaded(page, "history");
  const name = await page.evaluate(() => window.hdeform.sessionName);
  const probe = await page.evaluate((n) => window.hdeform.call("listHistory", { name: n }), name);
  if (probe.code === "Unimplemented" || probe.code === "UNIMPLEMENTED") {
    log(`SKIP history: this hdeform-server has no ListHistory (${probe.code}: ${probe.message})`);
    await page.close();
    return false;
  }
  // Fixed: the bottom 10 %; handle 1: the top 10 %.
  const [bmin, bmax] = await page.evaluate(() => window.hdeform.bbox());
  const up = bmax[2] - bmin[2] >= bmax[1] - bmin[1] ? 2 : 1;
  const slab = (from, to) => {
    const lo = bmin.map((v) => v - 1), hi = bmax.map((v) => v + 1);
    lo[up] = bmin[up] + from * (bmax[up] - bmin[up]);
    hi[up] = bmin[up] + to * (bmax[up] - bmin[up]);
    return [lo, hi];
  };
  await page.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 0), slab(-0.01, 0.1));
  await page.evaluate(([a, b]) => window.hdeform.selectBox(a, b, 1), slab(0.9, 1.01));
  await page.click("#apply");
  await page.waitForFunction(() => window.hdeform.constraintsApplied && window.hdeform.framesApplied > 0, null, { timeout: 60_000 });
  await waitIdle(page);
  await page.click('button[data-mode="move"]');
  await sleep(200);

  const server = () => page.evaluate(() => window.hdeform.serverTranslations());
  const gizmo = () => page.evaluate(() => window.hdeform.handleTransforms().map((t) => [t.translation.x, t.translation.y, t.translation.z]));
  const dist = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
  const fmt = (t) => JSON.stringify(t.map((v) => +v.toFixed(3)));
  // Real mouse: along the x arrow (the hook only says where it is on screen).
  const drag = async (px) => {
    const c = await page.evaluate(() => window.hdeform.gizmoScreenPoint());
    const a = await page.evaluate(() => window.hdeform.gizmoScreenPoint("x"));
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
  // The page shows the server's pose and shape: gizmo = GetSession transforms, mesh = GetMesh.
  const settlesOn = async (want, what) => {
    let g = [], s = [], dShape = Infinity;
    const t0 = Date.now();
    while (Date.now() - t0 < 10_000) {
      [g, s] = [await gizmo(), await server()];
      if (dist(g[0], want) < 1e-6 && dist(s[0], want) < 1e-6) {
        dShape = maxDiff(await positions(page), await page.evaluate(() => window.hdeform.serverPositions()));
        if (dShape < 1e-4) break;
      }
      await sleep(150);
    }
    return check(
      dist(g[0], want) < 1e-6 && dist(s[0], want) < 1e-6 && dShape < 1e-4,
      `${what}: server ${fmt(s[0] ?? [])}, gizmo ${fmt(g[0] ?? [])}, want ${fmt(want)}; mesh vs GetMesh max |Δ| ${dShape.toExponential(2)}`,
    );
  };

  const rest = await positions(page);
  const zero = [0, 0, 0];
  const movesBefore = (await page.evaluate(() => window.hdeform.history())).filter((s) => s.kind === "MOVE").length;
  await drag(70);
  const moved = (await server())[0];
  check(dist(moved, zero) > 1e-3, `a real drag moved handle 1 (server ${fmt(moved)})`);
  const movedShape = await positions(page);
  // One drag, one step: the page releases the handle only after the drag's last update was
  // answered (the server ends the drag's step at the release).
  await page.waitForFunction((n) => window.hdeform.history().filter((s) => s.kind === "MOVE").length > n, movesBefore, { timeout: 5000 }).catch(() => {});
  await sleep(300);
  const movesAfter = (await page.evaluate(() => window.hdeform.history())).filter((s) => s.kind === "MOVE").length;
  check(movesAfter === movesBefore + 1, `the drag is one MOVE step in the History panel (${movesBefore} → ${movesAfter})`);

  // The drag's mousedown was on the canvas: no field has the focus, so the keys are shortcuts.
  await page.keyboard.press("Control+z");
  await settlesOn(zero, "Ctrl+Z: handle 1 back at rest");
  check(maxDiff(await positions(page), rest) < 1e-4, "…and the mesh at its rest shape");
  await shot(page, "history-01-undone");
  await page.keyboard.press("Control+Shift+z");
  await settlesOn(moved, "Ctrl+Shift+Z: the move is back");
  check(maxDiff(await positions(page), movedShape) < 1e-4, "…and the mesh as after the drag");

  // Nothing to redo: the server's FAILED_PRECONDITION in the banner, nothing else.
  const versionBefore = await page.evaluate(() => window.hdeform.version);
  await page.keyboard.press("Control+y");
  await page.waitForFunction(() => /Redo/.test(window.hdeform.lastError), null, { timeout: 5000 }).catch(() => {});
  const nothing = await page.evaluate(() => window.hdeform.lastError);
  check(/FailedPrecondition/i.test(nothing), `Ctrl+Y with nothing to redo: the server's answer shown ("${nothing}")`);
  check(dist((await server())[0], moved) < 1e-9 && (await page.evaluate(() => window.hdeform.version)) === versionBefore, "…and nothing changed");

  // The History panel: the steps with the author's name, newest first.
  await page.waitForFunction(() => {
    const k = window.hdeform.history().map((s) => s.kind);
    return k[0] === "REDO" && k[1] === "UNDO" && k.includes("MOVE") && k.includes("CONSTRAINTS");
  }, null, { timeout: 10_000 }).catch(() => {});
  const steps = await page.evaluate(() => window.hdeform.history());
  const kinds = steps.map((s) => s.kind);
  const move = steps.find((s) => s.kind === "MOVE");
  check(kinds[0] === "REDO" && kinds[1] === "UNDO" && !!move && steps[0].target === move.id && steps[1].target === move.id, `the History panel lists REDO, UNDO (of the MOVE), MOVE, … newest first (${kinds.join(", ")})`);
  check(steps.slice(0, 3).every((s) => s.author === "Hana") && !move.undone, "…each by Hana; the redone MOVE is not greyed");
  const listText = (await page.textContent("#history-list")) ?? "";
  check(/Hana/.test(listText) && listText.includes(move.summary), `…on screen: the author and the summaries ("${move.summary}")`);

  // A step that cannot be undone: the constraints, since the move changed the transforms after
  // them. A click on it shows the server's refusal (ABORTED, naming the later step).
  const constraints = steps.find((s) => s.kind === "CONSTRAINTS");
  await page.click(`#history-list li[data-step="${constraints.id}"]`);
  await page.waitForFunction(() => /Undo/.test(window.hdeform.lastError), null, { timeout: 5000 }).catch(() => {});
  const refused = await page.evaluate(() => window.hdeform.lastError);
  check(/Aborted/i.test(refused), `a click on the CONSTRAINTS step: refused with the server's message ("${refused}")`);
  check(dist((await server())[0], moved) < 1e-9 && dist((await gizmo())[0], moved) < 1e-9, "…and the pose is unchanged");
  await shot(page, "history-02-panel-refused");

  // Snapshots: save "A", move, restore "A", delete it.
  await page.fill("#snapshot-name", "A");
  await page.click("#snapshot-save");
  await page.waitForFunction(() => window.hdeform.snapshotNames().includes("A"), null, { timeout: 5000 }).catch(() => {});
  check((await page.textContent("#snapshot-list"))?.includes("Hana"), "snapshot A is listed, with its author");
  await drag(-50);
  const other = (await server())[0];
  check(dist(other, moved) > 1e-3, `the handle moved again after saving A (server ${fmt(other)})`);
  await page.click('#snapshot-list li[data-name="A"] button[data-act="restore"]');
  await settlesOn(moved, "Restore A: the pose is A's");
  await page.waitForFunction(() => window.hdeform.history()[0]?.kind === "RESTORE", null, { timeout: 5000 }).catch(() => {});
  check((await page.evaluate(() => window.hdeform.history()[0]?.kind)) === "RESTORE", "…and the History panel shows the RESTORE step");
  await shot(page, "history-03-restored");
  // Delete asks first: the first click only asks (nothing deleted), Cancel keeps it, and the
  // confirming click deletes.
  const deletes = () => page.evaluate(() => window.hdeform.history().filter((s) => s.kind === "SNAPSHOT_DELETE").length);
  const deletes0 = await deletes();
  await page.click('#snapshot-list li[data-name="A"] button[data-act="delete"]');
  await sleep(500);
  const asking = ((await page.textContent('#snapshot-list li[data-name="A"]')) ?? "").trim();
  check(
    (await page.evaluate(() => window.hdeform.snapshotNames())).includes("A") && (await deletes()) === deletes0 && /Delete it\?/.test(asking) && (await page.isVisible('#snapshot-list button[data-act="confirm-delete"]')),
    `Delete asks first, and deletes nothing yet: "${asking}"`,
  );
  await shot(page, "history-03b-delete-asks");
  await page.click('#snapshot-list li[data-name="A"] button[data-act="cancel"]');
  await sleep(300);
  check((await page.isVisible('#snapshot-list li[data-name="A"] button[data-act="restore"]')) && (await deletes()) === deletes0, "Cancel keeps the snapshot");
  await page.click('#snapshot-list li[data-name="A"] button[data-act="delete"]');
  await page.click('#snapshot-list li[data-name="A"] button[data-act="confirm-delete"]');
  await page.waitForFunction(() => !window.hdeform.snapshotNames().includes("A"), null, { timeout: 5000 }).catch(() => {});
  // The list the page shows is the server's ListSnapshots answer after the delete.
  const left = await page.evaluate(() => window.hdeform.snapshotNames());
  check(!left.includes("A") && !((await page.textContent("#snapshot-list")) ?? "").includes("Restore"), `snapshot A deleted (listed: [${left}])`);
  await page.close();
  return true;
}

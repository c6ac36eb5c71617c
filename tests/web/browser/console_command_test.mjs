// Commands from the console in a real browser (issue 28): Debian's chromium driven by
// puppeteer-core, against fleetgw-serve, mosquitto and a real `fleetgw run` on a simulated bike.
//   node console_command_test.mjs SPEC_JSON
// SPEC: {url, operator: {name, password}, viewer: {name, password}, vehicle, screenshots,
//        markers: [{id, lat, lon, state}], clicks (default 2: unlock then lock, alternating)}
// Checks: the map screenshot has each bike's colour at its marker and the plain background
// elsewhere; an operator's clicks on the vehicle page each end in `succeeded` on screen (the
// click-to-succeeded times are printed as JSON); a viewer sees no command button and the same
// POST answers 403; a POST without the CSRF token answers 403. Exit 0 when all hold.
import puppeteer from 'puppeteer-core';

const spec = JSON.parse(process.argv[2]);
const fail = (why) => { throw new Error(why); };
const problems = [];
// Colours of maps.js, and the plain background of style.css (no tiles).
const COLOURS = { parked: [0x2b, 0x8a, 0x3e], riding: [0x19, 0x71, 0xc2], alarm: [0xe0, 0x31, 0x31],
  low_battery: [0xf0, 0x8c, 0x00], offline: [0x86, 0x8e, 0x96] };
const BACKGROUND = [0xde, 0xe2, 0xe6];

const browser = await puppeteer.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
});

function watch(page, expected) {
  page.setDefaultTimeout(30000);
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('console', (m) => {
    if (m.type() === 'error' && !m.text().startsWith('Failed to load resource')) {
      problems.push(`console: ${m.text()}`);
    }
  });
  page.on('response', (r) => {
    const ok = r.status() < 400 || (r.status() === 401 && r.url().endsWith('/api/session')) ||
      expected.has(r.status());
    if (!ok) problems.push(`HTTP ${r.status()} for ${r.url()}`);
  });
}

async function login(page, who) {
  await page.goto(spec.url, { waitUntil: 'load' });
  await page.waitForSelector('#login-form', { visible: true });
  await page.type('#login-name', who.name);
  await page.type('#login-password', who.password);
  await page.click('#login-submit');
  await page.waitForSelector('#top:not([hidden])');
}

// Pixels of a PNG (base64) at the given points, decoded by the browser itself on a blank page
// (no CSP there): [[r, g, b], ...].
async function pixels(png, points) {
  const blank = await browser.newPage();
  try {
    return await blank.evaluate(async (data, pts) => {
      const img = new Image();
      img.src = `data:image/png;base64,${data}`;
      await img.decode();
      const canvas = document.createElement('canvas');
      canvas.width = img.width;
      canvas.height = img.height;
      const g = canvas.getContext('2d');
      g.drawImage(img, 0, 0);
      return pts.map(([x, y]) => [...g.getImageData(Math.round(x), Math.round(y), 1, 1).data.slice(0, 3)]);
    }, png, points);
  } finally {
    await blank.close();
  }
}

const near = (a, b, tol) => a.every((v, i) => Math.abs(v - b[i]) <= tol);

let exitCode = 0;
try {
  // --- the operator: the map, pixel by pixel ------------------------------------------------
  const op = await browser.newPage();
  await op.setViewport({ width: 1000, height: 700 });
  const opExpected = new Set();
  watch(op, opExpected);
  await login(op, spec.operator);
  await op.waitForFunction((n) => document.querySelectorAll('#map path[data-vehicle]').length === n,
    {}, spec.markers.length);
  const mapEl = await op.$('#map');
  const box = await mapEl.boundingBox();
  const centres = await op.$$eval('#map path[data-vehicle]', (paths) => paths.map((p) => {
    const r = p.getBoundingClientRect();
    return { id: p.getAttribute('data-vehicle'), x: r.x + r.width / 2, y: r.y + r.height / 2 };
  }));
  const shot = await mapEl.screenshot({ encoding: 'base64', path: undefined });
  await mapEl.screenshot({ path: `${spec.screenshots}/console-command-map.png` });
  const points = centres.map((c) => [c.x - box.x, c.y - box.y]);
  points.push([5, box.height - 30]); // a corner away from every bike: the plain background
  const seen = await pixels(shot, points);
  centres.forEach((c, i) => {
    const m = spec.markers.find((v) => v.id === c.id) ?? fail(`unexpected marker ${c.id}`);
    // fillOpacity .95 over the background.
    const want = COLOURS[m.state].map((v, k) => 0.95 * v + 0.05 * BACKGROUND[k]);
    if (!near(seen[i], want, 24)) fail(`${c.id}: pixel ${seen[i]} at its marker, expected ~${want.map(Math.round)}`);
  });
  if (!near(seen[seen.length - 1], BACKGROUND, 6)) fail(`background pixel ${seen[seen.length - 1]}`);

  // --- the operator: clicks on the vehicle page, each to `succeeded` on screen --------------
  await op.goto(`${spec.url}/#vehicle/${encodeURIComponent(spec.vehicle)}`);
  await op.waitForSelector('#v-buttons button.cmd[data-action="lock"]', { visible: true });
  // FLEETGW_CONSOLE_LOCK_KIND=seat (bench): the vehicle page's one-lock buttons instead of the
  // whole vehicle's, which drive every lock of the bike one after the other.
  const lockKind = process.env.FLEETGW_CONSOLE_LOCK_KIND || '';
  if (lockKind) await op.select('#v-lock-kind', lockKind);
  const button = (action) => (lockKind ? `#v-one-lock button.cmd-one[data-action="${action}"]`
    : `#v-buttons button.cmd[data-action="${action}"]`);
  const times = [];
  const bikeTimes = [];
  // Where the time goes, per click (all clocks are this machine's): click to the server's
  // signing (issued_at_us), signing to the bike's result stored by the server (result_at_us;
  // the bike's own duration_ms inside it), stored to shown on the page.
  const split = { click_to_issued_ms: [], issued_to_stored_ms: [], stored_to_shown_ms: [] };
  const clicks = spec.clicks ?? 2;
  for (let i = 0; i < clicks; i += 1) {
    const action = i % 2 === 0 ? 'unlock' : 'lock';
    const before = await op.$eval('#v-last-result', (e) => e.dataset.command || '');
    const t0 = Date.now();
    // Found and pressed in one turn of the page: a handle kept across a live re-render of the
    // vehicle page would be detached.
    await op.waitForFunction((sel) => {
      const b = document.querySelector(sel);
      if (!b || b.disabled) return false;
      b.click();
      return true;
    }, {}, button(action));
    const handle = await op.waitForFunction((prev) => {
      const e = document.getElementById('v-last-result');
      const r = e.dataset.result;
      return e.dataset.command && e.dataset.command !== prev && r && r !== 'pending'
        ? `${r}|${Date.now()}` : null;
    }, { polling: 'mutation', timeout: 30000 }, before);
    const [result, shownAt] = (await handle.jsonValue()).split('|');
    times.push(Number(shownAt) - t0);
    // The bike's own time for it (receipt to result), to tell the console's share apart.
    const id = await op.$eval('#v-last-result', (e) => e.dataset.command);
    const c = await op.evaluate(async (cid) => (await (await fetch(
      `/api/commands?ids=${encodeURIComponent(cid)}`)).json()).commands[0], id);
    bikeTimes.push(c.duration_ms);
    split.click_to_issued_ms.push(Math.round(c.issued_at_us / 1000 - t0));
    split.issued_to_stored_ms.push(Math.round((c.result_at_us - c.issued_at_us) / 1000));
    split.stored_to_shown_ms.push(Math.round(Number(shownAt) - c.result_at_us / 1000));
    if (result !== 'succeeded') {
      fail(`${action}: ${result}: ${await op.$eval('#v-last-result', (e) => e.textContent)}`);
    }
  }
  // The history names who sent it.
  await op.waitForFunction((name) => [...document.querySelectorAll('#v-console-commands tbody tr')]
    .some((r) => r.children[2].textContent === name && r.dataset.result === 'succeeded'),
  {}, spec.operator.name);
  await op.screenshot({ path: `${spec.screenshots}/console-command-vehicle.png` });

  // --- a POST without the CSRF token is refused ---------------------------------------------
  opExpected.add(403);
  const noCsrf = await op.evaluate(async (v) => (await fetch(`/api/vehicles/${encodeURIComponent(v)}/commands`,
    { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: '{"action":"unlock"}' })).status,
  spec.vehicle);
  if (noCsrf !== 403) fail(`POST without CSRF token: ${noCsrf}`);

  // --- a viewer: no buttons, and 403 from the API -------------------------------------------
  const ctx = await browser.createBrowserContext();
  const viewer = await ctx.newPage();
  watch(viewer, new Set([403]));
  await login(viewer, spec.viewer);
  await viewer.goto(`${spec.url}/#vehicle/${encodeURIComponent(spec.vehicle)}`);
  await viewer.waitForFunction((id) => document.getElementById('v-title').textContent === id, {}, spec.vehicle);
  if (await viewer.$('button.cmd')) fail('a viewer sees command buttons');
  if (await viewer.$('#bulk:not([hidden])')) fail('a viewer sees the bulk command bar');
  const asViewer = await viewer.evaluate(async (v) => {
    const s = await (await fetch('/api/session')).json();
    return (await fetch(`/api/vehicles/${encodeURIComponent(v)}/commands`, { method: 'POST',
      headers: { 'Content-Type': 'application/json', 'X-CSRF-Token': s.csrf_token },
      body: '{"action":"unlock"}' })).status;
  }, spec.vehicle);
  if (asViewer !== 403) fail(`a viewer's POST: ${asViewer}`);

  if (problems.length) fail(problems.join('\n'));
  console.log(JSON.stringify({ click_to_result_ms: times, bike_duration_ms: bikeTimes,
    lock_kind: lockKind || 'whole vehicle', ...split }));
} catch (e) {
  console.error(`console command test failed: ${e.message}`);
  if (problems.length) console.error(problems.join('\n'));
  exitCode = 1;
} finally {
  await browser.close();
}
process.exitCode = exitCode;

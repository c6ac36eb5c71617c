// The console in a real browser (issue 28): Debian's chromium driven by puppeteer-core.
//   node console_test.mjs SPEC_JSON
// SPEC: {url, name, password, screenshots (dir), vehicles: [{id, lat, lon, state}],
//        xss_id, ack_vehicle}
// Logs in, checks every bike is drawn where it is (relative positions on the map) in its
// state's colour, that a vehicle id holding markup shows as text and runs nothing, that no
// Content-Security-Policy violation or script error happens, and acknowledges the alarm of
// `ack_vehicle` from the alarm feed. Exit 0 when all hold, 1 with the reason otherwise.
import puppeteer from 'puppeteer-core';

const spec = JSON.parse(process.argv[2]);
const problems = [];
const fail = (why) => { throw new Error(why); };

const browser = await puppeteer.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  // Root in CI: chromium's sandbox needs user namespaces it may not have there.
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
});
try {
  const page = await browser.newPage();
  page.setDefaultTimeout(15000);
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  // Errors (a CSP violation is one) count; failed loads are reported with their URL below,
  // the console's own line for them says less. The only expected refusal: /api/session before
  // the login.
  page.on('console', (m) => {
    if (m.type() === 'error' && !m.text().startsWith('Failed to load resource')) {
      problems.push(`console: ${m.text()}`);
    }
  });
  page.on('response', (r) => {
    if (r.status() >= 400 && !(r.status() === 401 && r.url().endsWith('/api/session'))) {
      problems.push(`HTTP ${r.status()} for ${r.url()}`);
    }
  });
  await page.setViewport({ width: 1000, height: 700 });
  await page.goto(spec.url, { waitUntil: 'load' });

  await page.waitForSelector('#login-form', { visible: true });
  await page.type('#login-name', spec.name);
  await page.type('#login-password', spec.password);
  await page.click('#login-submit');

  // The map: one marker per vehicle with a position, each in its state.
  await page.waitForFunction((n) => document.querySelectorAll('#map path[data-vehicle]').length === n,
    {}, spec.vehicles.length);
  const markers = await page.$$eval('#map path[data-vehicle]', (paths) => paths.map((p) => {
    const r = p.getBoundingClientRect();
    return { id: p.getAttribute('data-vehicle'), state: p.getAttribute('data-state'),
      fill: p.getAttribute('fill'), x: r.x + r.width / 2, y: r.y + r.height / 2 };
  }));
  const box = await page.$eval('#map', (m) => { const r = m.getBoundingClientRect(); return { x: r.x, y: r.y, w: r.width, h: r.height }; });
  const byId = new Map(markers.map((m) => [m.id, m]));
  for (const v of spec.vehicles) {
    const m = byId.get(v.id) ?? fail(`no marker for ${v.id}`);
    if (m.state !== v.state) fail(`${v.id}: drawn as ${m.state}, expected ${v.state}`);
    if (m.x < box.x || m.x > box.x + box.w || m.y < box.y || m.y > box.y + box.h) {
      fail(`${v.id}: marker outside the map (${m.x}, ${m.y})`);
    }
  }
  // Positions: east is right, north is up, in proportion (Web Mercator is locally linear).
  const [a, b] = [spec.vehicles[0], spec.vehicles[1]];
  const ma = byId.get(a.id);
  const mb = byId.get(b.id);
  const pxPerDegLon = (mb.x - ma.x) / (b.lon - a.lon);
  for (const v of spec.vehicles) {
    const m = byId.get(v.id);
    const expectX = ma.x + (v.lon - a.lon) * pxPerDegLon;
    if (Math.abs(m.x - expectX) > 3) fail(`${v.id}: x ${m.x}, expected ${expectX}`);
    for (const w of spec.vehicles) {
      const n = byId.get(w.id);
      if (v.lat > w.lat + 1e-6 && !(m.y < n.y)) fail(`${v.id} is north of ${w.id} but drawn below`);
    }
  }
  const colours = new Set(markers.map((m) => m.fill));
  if (colours.size < new Set(spec.vehicles.map((v) => v.state)).size) {
    fail(`states share colours: ${[...colours].join(', ')}`);
  }
  await page.screenshot({ path: `${spec.screenshots}/console-map.png` });

  // The list: the markup-bearing id is a row whose text is exactly that id.
  await page.goto(`${spec.url}/#list`);
  await page.waitForSelector('#fleet-table tbody tr', { visible: true });
  const listed = await page.$$eval('#fleet-table tbody tr td:nth-child(2)', (tds) => tds.map((t) => t.textContent));
  if (!listed.includes(spec.xss_id)) fail(`the id ${spec.xss_id} is not shown as text: ${listed}`);
  await page.type('#f-search', 'script');
  const filtered = await page.$$eval('#fleet-table tbody tr', (rows) => rows.length);
  if (filtered !== 1) fail(`search 'script' shows ${filtered} rows, expected 1`);

  // The vehicle page of that id.
  await page.goto(`${spec.url}/#vehicle/${encodeURIComponent(spec.xss_id)}`);
  await page.waitForFunction((id) => document.getElementById('v-title').textContent === id, {}, spec.xss_id);
  await page.screenshot({ path: `${spec.screenshots}/console-vehicle.png` });

  // The alarm feed: acknowledge the alarm of ack_vehicle.
  await page.goto(`${spec.url}/#alarms`);
  const row = `#alarm-table tbody tr`;
  await page.waitForSelector(`${row} button.ack`, { visible: true });
  const clicked = await page.$$eval(row, (rows, vehicle) => {
    for (const r of rows) {
      if (r.children[1].textContent === vehicle) {
        const button = r.querySelector('button.ack');
        if (button) { button.click(); return true; }
      }
    }
    return false;
  }, spec.ack_vehicle);
  if (!clicked) fail(`no acknowledge button for ${spec.ack_vehicle}`);
  await page.waitForFunction((vehicle, name) => [...document.querySelectorAll('#alarm-table tbody tr')]
    .some((r) => r.children[1].textContent === vehicle && r.lastElementChild.textContent.startsWith(name)),
  {}, spec.ack_vehicle, spec.name);

  const executed = await page.evaluate(() => window.__xss);
  if (executed !== undefined) fail(`injected markup ran (window.__xss = ${executed})`);
  if (await page.$('main script, main img')) fail('injected markup became elements');
  if (problems.length) fail(problems.join('\n'));
  console.log('console: all checks passed');
} catch (e) {
  console.error(`console test failed: ${e.message}`);
  if (problems.length) console.error(problems.join('\n'));
  process.exitCode = 1;
} finally {
  await browser.close();
}

// Issue 28's "Done when" in one browser run (web_story_test.cc starts the stack): Debian's
// chromium driven by puppeteer-core.
//   node console_story_test.mjs SPEC_JSON
// SPEC: {url, operator: {name, password}, admin: {name, password}, vehicle, vehicles: [ids],
//        revocation_file, zones_file, zone: {id}, want_alarm (a file to create when
//        the feed is watched), screenshots (a directory)}
// Steps, each waiting for a condition (no fixed sleep):
//  1. the operator logs in and sees every bike on the map;
//  2. clicks the real bike's marker, then Lock on its page: `succeeded` on screen;
//  3. watches the alarm feed, the theft alarm arrives live, Acknowledge: acknowledged by them;
//  4. the admin (own browser context) previews the GeoJSON on the zones page and publishes it;
//     the zone is drawn on the fleet map (its path, and its tint in the map's pixels);
//  5. the admin uploads the root's revocation list on the admin page: shown in force;
//  6. the operator clicks Lock again: the bike's `rejected · revoked ...` on screen.
// Screenshots: console-map.png, console-vehicle.png, console-alarms.png, console-zones.png,
// console-admin.png, console-revoked.png. Prints {"step_ms": {...}} and exits 0 when all hold.
import fs from 'node:fs';
import puppeteer from 'puppeteer-core';

const spec = JSON.parse(process.argv[2]);
const fail = (why) => { throw new Error(why); };
const problems = [];
const steps = {};
const t0 = Date.now();
let doing = 'start';
const step = (name) => { steps[name] = Date.now() - t0; doing = `after ${name}`; };
const BACKGROUND = [0xde, 0xe2, 0xe6];
const NO_PARKING = [0x70, 0x48, 0xe8]; // zones.js ZONE_COLOURS.no_parking, fill opacity .2

const browser = await puppeteer.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'],
});

function watch(page) {
  page.setDefaultTimeout(30000);
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
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
}

async function login(page, who) {
  await page.goto(spec.url, { waitUntil: 'load' });
  await page.waitForSelector('#login-form', { visible: true });
  await page.type('#login-name', who.name);
  await page.type('#login-password', who.password);
  await page.click('#login-submit');
  await page.waitForSelector('#top:not([hidden])');
}

async function pixel(png, x, y) {
  const blank = await browser.newPage();
  try {
    return await blank.evaluate(async (data, px, py) => {
      const img = new Image();
      img.src = `data:image/png;base64,${data}`;
      await img.decode();
      const canvas = document.createElement('canvas');
      canvas.width = img.width;
      canvas.height = img.height;
      const g = canvas.getContext('2d');
      g.drawImage(img, 0, 0);
      return [...g.getImageData(Math.round(px), Math.round(py), 1, 1).data.slice(0, 3)];
    }, png, x, y);
  } finally {
    await blank.close();
  }
}

// The bike's answer line once it holds a new command's final result.
async function clickAndWait(page, action) {
  const before = await page.$eval('#v-last-result', (e) => e.dataset.command || '');
  // Found and clicked in one turn of the page: the vehicle page re-renders on every live
  // update (another bike's telemetry included), and a handle kept across one is detached.
  await page.waitForFunction((sel) => {
    const b = document.querySelector(sel);
    if (!b || b.disabled) return false;
    b.click();
    return true;
  }, {}, `#v-buttons button.cmd[data-action="${action}"]`);
  const handle = await page.waitForFunction((prev) => {
    const e = document.getElementById('v-last-result');
    const r = e.dataset.result;
    return e.dataset.command && e.dataset.command !== prev && r && r !== 'pending'
      ? [r, e.textContent] : null;
  }, { polling: 'mutation', timeout: 30000 }, before);
  return handle.jsonValue();
}

let exitCode = 0;
try {
  // 1. The fleet on the map. --------------------------------------------------------------
  const op = await browser.newPage();
  await op.setViewport({ width: 1000, height: 700 });
  watch(op);
  await login(op, spec.operator);
  await op.waitForFunction((ids) => ids.every((id) => document.querySelector(
    `#map path[data-vehicle="${CSS.escape(id)}"]`)), {}, spec.vehicles);
  await op.screenshot({ path: `${spec.screenshots}/console-map.png` });
  step('map');

  // 2. Lock with a click: marker -> vehicle page -> Lock -> `succeeded`. ------------------
  await op.click(`#map path[data-vehicle="${spec.vehicle}"]`);
  await op.waitForFunction((id) => document.getElementById('v-title').textContent === id, {}, spec.vehicle);
  await op.waitForSelector('#v-buttons button.cmd[data-action="lock"]', { visible: true });
  const [locked, lockedText] = await clickAndWait(op, 'lock');
  if (locked !== 'succeeded') fail(`lock: ${lockedText}`);
  await op.screenshot({ path: `${spec.screenshots}/console-vehicle.png` });
  step('locked');

  // 3. The theft alarm arrives in the feed, live; acknowledged with a click. ---------------
  await op.goto(`${spec.url}/#alarms`);
  await op.waitForSelector('#alarms-view:not([hidden])');
  fs.writeFileSync(spec.want_alarm, '');
  // The feed re-renders on every change event: find the row and click its button in one go
  // (a handle kept across a re-render would be detached).
  await op.waitForFunction((id) => {
    const row = [...document.querySelectorAll('#alarm-table tbody tr')]
      .find((r) => r.children[1].textContent === id && r.querySelector('button.ack:not([disabled])'));
    if (row) row.querySelector('button.ack').click();
    return Boolean(row);
  }, { timeout: 60000 }, spec.alarm_vehicle || spec.vehicle);
  await op.waitForFunction((id, name) => [...document.querySelectorAll('#alarm-table tbody tr')]
    .some((r) => r.children[1].textContent === id && r.children[5].textContent.startsWith(name)),
  {}, spec.alarm_vehicle || spec.vehicle, spec.operator.name);
  await op.screenshot({ path: `${spec.screenshots}/console-alarms.png` });
  step('alarm_acknowledged');

  // 4. The admin publishes a zone: previewed, published, drawn on the fleet map. ----------
  const ctx = await browser.createBrowserContext();
  const admin = await ctx.newPage();
  await admin.setViewport({ width: 1000, height: 900 });
  watch(admin);
  await login(admin, spec.admin);
  await admin.waitForSelector('#nav-admin:not([hidden])');
  await admin.click('#nav-zones');
  await admin.waitForSelector('#zone-upload:not([hidden])');
  await (await admin.$('#zone-file')).uploadFile(spec.zones_file);
  await admin.waitForSelector(`#zone-map path[data-zone="${spec.zone.id}"]`);
  await admin.waitForSelector('#zone-publish:not([disabled])');
  await admin.click('#zone-publish');
  await admin.waitForFunction(() => document.getElementById('zone-result').textContent.startsWith('Published version'));
  await admin.screenshot({ path: `${spec.screenshots}/console-zones.png` });
  await admin.click('#nav-map');
  await admin.waitForSelector(`#map path[data-zone="${spec.zone.id}"]`);
  // The zone's tint where it is on the map (the plain background under a 20 % fill).
  const mapEl = await admin.$('#map');
  const box = await mapEl.boundingBox();
  const at = await admin.$eval(`#map path[data-zone="${spec.zone.id}"]`, (p) => {
    const r = p.getBoundingClientRect();
    return { x: r.x + r.width / 2, y: r.y + r.height / 2 };
  });
  if (at.x < box.x || at.x > box.x + box.width || at.y < box.y || at.y > box.y + box.height) {
    fail(`the zone's centre (${at.x}, ${at.y}) is outside the map ${JSON.stringify(box)}`);
  }
  const tint = await pixel(await mapEl.screenshot({ encoding: 'base64' }), at.x - box.x, at.y - box.y);
  const want = NO_PARKING.map((v, k) => 0.2 * v + 0.8 * BACKGROUND[k]);
  if (!tint.every((v, k) => Math.abs(v - want[k]) <= 12)) {
    fail(`zone pixel ${tint}, expected ~${want.map(Math.round)}`);
  }
  step('zone_published');

  // 5. The admin uploads the root's revocation list. ---------------------------------------
  await admin.click('#nav-admin');
  await admin.waitForSelector('#admin-view:not([hidden])');
  await (await admin.$('#rev-file')).uploadFile(spec.revocation_file);
  await admin.click('#rev-upload');
  await admin.waitForSelector('#rev-table tbody tr[data-root="root-1"][data-version="1"]');
  const said = await admin.$eval('#rev-result', (e) => e.textContent);
  if (!said.includes('serials 7')) fail(`revocation upload: ${said}`);
  await admin.screenshot({ path: `${spec.screenshots}/console-admin.png`, fullPage: true });
  step('revocation_published');

  // 6. The bike refuses the revoked key: shown on the operator's screen. -------------------
  await op.goto(`${spec.url}/#vehicle/${encodeURIComponent(spec.vehicle)}`);
  await op.waitForSelector('#v-buttons button.cmd[data-action="lock"]', { visible: true });
  // The retained list reaches the bike within moments of the upload; a command that raced it
  // would be answered `succeeded`, so the operator tries again, as a person would.
  let refused = null;
  for (let i = 0; i < 5 && !refused; i += 1) {
    const [r, text] = await clickAndWait(op, 'lock');
    if (r === 'rejected') refused = text;
    else if (r !== 'succeeded') fail(`lock after the revocation: ${text}`);
  }
  if (!refused || !refused.startsWith('rejected · revoked')) fail(`not refused as revoked: ${refused}`);
  await op.screenshot({ path: `${spec.screenshots}/console-revoked.png` });
  step('refused_revoked');

  if (problems.length) fail(problems.join('\n'));
  console.log(JSON.stringify({ step_ms: steps }));
} catch (e) {
  console.error(`console story test failed (${doing}): ${e.message}`);
  if (problems.length) console.error(problems.join('\n'));
  exitCode = 1;
} finally {
  await browser.close();
}
process.exitCode = exitCode;

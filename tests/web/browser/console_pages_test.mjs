// The vehicle page and the campaign page in a real browser (issues 28/29): Debian's chromium
// driven by puppeteer-core against fleetgw-serve with rows in the ingest's tables.
//   node console_pages_test.mjs SPEC_JSON
// SPEC: {url, name, password, screenshots, vehicle, ride, ride_samples, limit_vehicle, campaign,
//        campaign_version, hostile_campaign}
// Checks: a vehicle id and a ride id holding markup show as text and run nothing; the ride's
// track is drawn on the map with every sample's point and its speed, power and SOC plot has a
// point per sample; the speed limit in force and why are shown; the campaign page lists the
// campaigns (a hostile id as text), opens one with its vehicles, plots the signal (a line per
// vehicle) and tabulates it; the CSV link downloads the samples. No CSP violation, script error
// or failed request. Exit 0 when all hold.
import puppeteer from 'puppeteer-core';

const spec = JSON.parse(process.argv[2]);
const problems = [];
const fail = (why) => { throw new Error(why); };

const browser = await puppeteer.launch({ executablePath: '/usr/bin/chromium', headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'] });
let exitCode = 0;
try {
  const page = await browser.newPage();
  page.setDefaultTimeout(15000);
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('console', (m) => {
    if (m.type() === 'error' && !m.text().startsWith('Failed to load resource')) problems.push(`console: ${m.text()}`);
  });
  page.on('response', (r) => {
    if (r.status() >= 400 && !(r.status() === 401 && r.url().endsWith('/api/session'))) {
      problems.push(`HTTP ${r.status()} for ${r.url()}`);
    }
  });
  page.on('dialog', (d) => { problems.push(`dialog: ${d.message()}`); d.dismiss(); });
  await page.setViewport({ width: 1000, height: 900 });
  await page.goto(spec.url, { waitUntil: 'load' });
  await page.waitForSelector('#login-form', { visible: true });
  await page.type('#login-name', spec.name);
  await page.type('#login-password', spec.password);
  await page.click('#login-submit');
  await page.waitForSelector('#top:not([hidden])');

  // --- the vehicle page of the hostile bike: its ride's track and plot ----------------------
  await page.goto(`${spec.url}/#vehicle/${encodeURIComponent(spec.vehicle)}`);
  await page.waitForFunction((id) => document.getElementById('v-title').textContent === id, {}, spec.vehicle);
  const rideButton = await page.waitForSelector('#v-rides button.ride-show');
  if (await page.$eval('#v-rides button.ride-show', (b) => b.dataset.ride) !== spec.ride) fail('ride id not shown as it is');
  await rideButton.click();
  await page.waitForFunction((n) => {
    const t = document.querySelector('#v-map path.ride-selected');
    return t && Number(t.getAttribute('data-points')) === n;
  }, {}, spec.ride_samples);
  // The drawn track's path has a vertex per sample (Leaflet's SVG path: M x y L x y ...).
  const vertices = await page.$eval('#v-map path.ride-selected', (p) => (p.getAttribute('d').match(/[ML]/g) || []).length);
  if (vertices < 2) fail(`ride track drawn with ${vertices} vertices`);
  const series = await page.$$eval('#v-ride-plot polyline', (ls) => ls.map((l) => ({
    series: l.dataset.series, points: l.getAttribute('points').trim().split(/\s+/).length,
    declared: Number(l.dataset.points) })));
  for (const name of ['speed_kmh', 'power_w', 'soc_pct']) {
    const s = series.find((x) => x.series === name) ?? fail(`no ${name} line in the plot`);
    if (s.points !== spec.ride_samples || s.declared !== spec.ride_samples) {
      fail(`${name}: ${s.points} points plotted, expected ${spec.ride_samples}`);
    }
  }
  const rideTitle = await page.$eval('#v-ride-title', (e) => e.textContent);
  if (!rideTitle.includes(spec.ride)) fail(`ride title ${rideTitle}`);
  if (await page.$('#v-title script, #v-rides img, #v-ride-title img')) fail('markup from the data became elements');
  await page.screenshot({ path: `${spec.screenshots}/console-vehicle-ride.png`, fullPage: true });

  // --- the speed limit in force and why (another bike) --------------------------------------
  await page.goto(`${spec.url}/#vehicle/${encodeURIComponent(spec.limit_vehicle)}`);
  await page.waitForFunction((id) => document.getElementById('v-title').textContent === id, {}, spec.limit_vehicle);
  const limit = await page.$eval('#v-speed-limit', (e) => e.textContent);
  const why = await page.$eval('#v-speed-limit-why', (e) => e.textContent);
  if (limit !== '12 km/h') fail(`speed limit shown: ${limit}`);
  for (const want of ['operator cap (speed_limit 20 km/h) by olga', 'slow zone Old <b>Town</b> (12 km/h)']) {
    if (!why.includes(want)) fail(`why: "${why}" lacks "${want}"`);
  }
  if (await page.$('#v-speed-limit-why b')) fail('a zone name became markup');

  // --- the campaign page ----------------------------------------------------------------------
  await page.goto(`${spec.url}/#campaigns`);
  await page.waitForSelector('#campaign-table tbody tr');
  const ids = await page.$$eval('#campaign-table tbody tr', (rs) => rs.map((r) => r.children[0].textContent));
  if (!ids.includes(spec.campaign) || !ids.includes(spec.hostile_campaign)) fail(`campaigns listed: ${JSON.stringify(ids)}`);
  await page.click(`#campaign-table tbody tr[data-version="${spec.campaign_version}"] button.campaign-open`);
  await page.waitForFunction(() => document.querySelectorAll('#campaign-plot polyline').length === 2);
  const vehicles = await page.$$eval('#campaign-vehicles tbody tr', (rs) => rs.map((r) => r.children[0].textContent));
  if (vehicles.length !== 2 || !vehicles.includes(spec.vehicle)) fail(`campaign vehicles: ${JSON.stringify(vehicles)}`);
  const lines = await page.$$eval('#campaign-plot polyline', (ls) => ls.map((l) => Number(l.dataset.points)));
  if (lines.some((n) => n !== 10)) fail(`campaign plot lines: ${lines}`);
  const rows = await page.$$eval('#campaign-samples tbody tr', (rs) => rs.length);
  if (rows !== 20) fail(`campaign samples table: ${rows} rows`);
  const csv = await page.evaluate(async () => {
    const r = await fetch(document.getElementById('campaign-csv').getAttribute('href'));
    return { status: r.status, text: await r.text() };
  });
  if (csv.status !== 200 || csv.text.split('\r\n').filter(Boolean).length !== 21) fail(`CSV: ${csv.status} ${csv.text.slice(0, 200)}`);
  await page.screenshot({ path: `${spec.screenshots}/console-campaign.png`, fullPage: true });

  if (await page.evaluate(() => window.__xss !== undefined)) fail('injected script ran');
  if (problems.length) fail(problems.join('\n'));
  console.log('console pages: ok');
} catch (e) {
  console.error(`console pages test failed: ${e.message}`);
  if (problems.length) console.error(problems.join('\n'));
  exitCode = 1;
} finally {
  await browser.close();
}
process.exitCode = exitCode;

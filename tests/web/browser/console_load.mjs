// The console's first load (issue 28's figure): log in, then time from navigating to the
// console to every bike drawn on the map, and the bytes the browser received.
//   node console_load.mjs '{"url": ..., "name": ..., "password": ..., "vehicles": N}'
// Prints {"vehicles", "map_drawn_ms", "bytes"}. Used by bench/console-load.sh.
import puppeteer from 'puppeteer-core';

const spec = JSON.parse(process.argv[2]);
const browser = await puppeteer.launch({ executablePath: '/usr/bin/chromium', headless: true,
  args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'] });
try {
  const page = await browser.newPage();
  page.setDefaultTimeout(120000);
  await page.setViewport({ width: 1280, height: 800 });
  // Log in through the API so the measured load is the console's own (session cookie set).
  await page.goto(`${spec.url}/`, { waitUntil: 'load' });
  await page.evaluate(async (n, p) => {
    await fetch('/api/login', { method: 'POST', headers: { 'Content-Type': 'application/json' },
      body: JSON.stringify({ name: n, password: p }) });
  }, spec.name, spec.password);
  const cdp = await page.createCDPSession();
  await cdp.send('Network.enable');
  await cdp.send('Network.setCacheDisabled', { cacheDisabled: true });
  let bytes = 0;
  cdp.on('Network.loadingFinished', (e) => { bytes += e.encodedDataLength; });
  const t0 = Date.now();
  // A new document (the query makes it one; a hash change alone would not reload).
  await page.goto(`${spec.url}/?first-load#map`, { waitUntil: 'domcontentloaded' });
  try {
    // SVG markers (one element each), or the canvas renderer's count of bikes drawn (maps.js sets
    // #map's data-drawn once the canvas has drawn them).
    await page.waitForFunction((n) => document.querySelectorAll('#map path[data-vehicle]').length >= n ||
      Number(document.getElementById('map').dataset.drawn || 0) >= n, { polling: 50 }, spec.vehicles);
  } catch (e) {
    const drawn = await page.evaluate(() => ({ markers: document.querySelectorAll('#map path[data-vehicle]').length,
      canvas: document.getElementById('map').dataset.drawn,
      paths: document.querySelectorAll('#map path').length, status: document.getElementById('status-line').textContent,
      login: !document.getElementById('login-view').hidden }));
    throw new Error(`${e.message}: ${JSON.stringify(drawn)}`);
  }
  const ms = Date.now() - t0;
  // Where the time went (ms from navigation start): the document ready, the fleet list's request
  // sent and its last byte received.
  const parts = await page.evaluate(() => {
    const nav = performance.getEntriesByType('navigation')[0];
    const fleet = performance.getEntriesByType('resource').find((e) => e.name.includes('/api/fleet'));
    return { dom_ready_ms: Math.round(nav.domContentLoadedEventEnd),
      fleet_request_ms: fleet ? Math.round(fleet.requestStart) : null,
      fleet_received_ms: fleet ? Math.round(fleet.responseEnd) : null };
  });
  console.log(JSON.stringify({ vehicles: spec.vehicles, map_drawn_ms: ms, bytes, ...parts }));
} finally {
  await browser.close();
}

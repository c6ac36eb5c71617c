// Zones (issue 28): the bundle in force drawn on the fleet map for everyone, and the admin's
// zones page -- upload GeoJSON or a GBFS geofencing_zones.json, preview it on the map (the
// server checks it as the bikes will and answers with the zones or the refusal naming the field
// and place), publish it (the server signs it under its delegation, publishes it retained on
// the fleet's bundle topic and records it). Text from files and the server goes through el()
// (textContent) only; Leaflet tooltips get DOM nodes.
import { el, when, jsonCall } from './dom.js';

// Zone colours by kind: outlines and a light fill, so bikes stay visible on top.
export const ZONE_COLOURS = {
  operating_area: '#2f9e44', slow: '#f59f00', no_ride: '#c92a2a', no_parking: '#7048e8',
  no_start: '#d6336c', rules: '#1c7ed6', unknown: '#495057',
};

let session = null; // {name, role, csrf_token}, from app.js's `fleet-session` event
let fleetLayer = null; // zones in force on the fleet map
let pageMap = null;
let pageLayer = null;
let uploaded = null; // the document previewed (parsed JSON)

// JSON in and out with the session's CSRF token on state-changing requests (dom.js).
const call = (path, opts) => jsonCall(path, opts, session && session.csrf_token);

function zoneTooltip(p) {
  const what = p.kind === 'slow' ? `slow, ${p.speed_limit_kmh} km/h`
    : p.kind === 'rules' ? (p.rule || 'rules') : p.kind.replaceAll('_', ' ');
  return el('span', {}, el('strong', {}, p.name || p.id), el('br'), what);
}

// A GeoJSON layer of zones; each polygon's path carries data-zone and data-kind (tests, CSS).
function zoneLayer(geojson) {
  const layer = L.geoJSON(geojson, {
    interactive: true,
    style: (f) => {
      const c = ZONE_COLOURS[f.properties.kind] || ZONE_COLOURS.unknown;
      return { color: c, weight: 2, fillColor: c, fillOpacity: 0.2, className: 'zone' };
    },
    onEachFeature: (f, l) => {
      l.bindTooltip(zoneTooltip(f.properties));
      l.on('add', () => {
        const path = l.getElement();
        if (path) {
          path.setAttribute('data-zone', f.properties.id);
          path.setAttribute('data-kind', f.properties.kind);
        }
      });
    },
  });
  return layer;
}

function drawOn(map, previous, geojson) {
  if (previous) previous.remove();
  const layer = zoneLayer(geojson).addTo(map);
  layer.bringToBack();
  return layer;
}

// The bundle in force on the fleet map (under the bikes) and on the zones page.
async function loadInForce(fleetMap) {
  const z = await call('/api/zones');
  if (fleetMap) fleetLayer = drawOn(fleetMap, fleetLayer, z.geojson);
  const info = document.getElementById('zone-in-force');
  info.dataset.version = z.version ?? '';
  info.textContent = z.version === null ? 'No zone bundle published yet.'
    : `In force: version ${z.version}, ${z.zones} zones, published by ${z.published_by} ${when(z.published_at_us)}.`;
  return z;
}

function ensurePageMap() {
  if (pageMap) { pageMap.invalidateSize(); return; }
  pageMap = L.map('zone-map', { attributionControl: false, zoomSnap: 0.25 });
  pageMap.setView([48.137, 11.575], 12);
}

function fit(layer) {
  const b = layer.getBounds();
  if (b.isValid()) pageMap.fitBounds(b, { padding: [20, 20], maxZoom: 16 });
}

function showResult(text, ok) {
  const line = document.getElementById('zone-result');
  line.textContent = text;
  line.dataset.state = ok ? 'ok' : 'error';
}

async function onFile(ev) {
  const file = ev.target.files[0];
  document.getElementById('zone-publish').disabled = true;
  uploaded = null;
  if (!file) return;
  let doc;
  try {
    doc = JSON.parse(await file.text());
  } catch (e) {
    showResult(`${file.name}: not JSON (${e.message})`, false);
    return;
  }
  try {
    const p = await call('/api/zones/preview', { method: 'POST', body: doc });
    ensurePageMap();
    pageLayer = drawOn(pageMap, pageLayer, p.geojson);
    fit(pageLayer);
    const notes = p.notes.length ? ` Notes: ${p.notes.join('; ')}` : '';
    showResult(`Preview of ${file.name} (${p.format}): ${p.zones} zones, ${p.vertices} vertices; `
      + `publishing makes it version ${p.next_version}.${notes}`, true);
    uploaded = doc;
    document.getElementById('zone-publish').disabled = false;
  } catch (e) {
    showResult(`${file.name}: ${e.message}`, false);
  }
}

async function onPublish() {
  if (!uploaded) return;
  const button = document.getElementById('zone-publish');
  button.disabled = true;
  try {
    const r = await call('/api/zones/publish', { method: 'POST', body: uploaded });
    showResult(`Published version ${r.version} (${r.zones} zones) on ${r.topic}, signed by ${r.key_id}.`, true);
    uploaded = null;
    await refresh();
  } catch (e) {
    showResult(`Not published: ${e.message}`, false);
    button.disabled = false;
  }
}

let fleetMapRef = null;

async function refresh() {
  const z = await loadInForce(fleetMapRef);
  if (location.hash === '#zones') {
    ensurePageMap();
    pageLayer = drawOn(pageMap, pageLayer, z.geojson);
    fit(pageLayer);
  }
}

function onRoute() {
  if (location.hash !== '#zones' || !session) return;
  const admin = session.role === 'admin';
  document.getElementById('zone-upload').hidden = !admin;
  ensurePageMap();
  refresh().catch((e) => showResult(e.message, false));
}

document.addEventListener('fleet-session', (ev) => {
  session = ev.detail.session;
  fleetMapRef = ev.detail.map || null;
  document.getElementById('nav-zones').hidden = false;
  loadInForce(fleetMapRef).catch(() => {});
  onRoute();
});
window.addEventListener('hashchange', onRoute);
document.getElementById('zone-file').addEventListener('change', (ev) => { onFile(ev).catch(() => {}); });
document.getElementById('zone-publish').addEventListener('click', () => { onPublish().catch(() => {}); });

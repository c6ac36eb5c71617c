// The operator console: plain ES module, no build step. Every piece of data from the server is
// untrusted (vehicle ids, details, names come from the bikes and the bus): it reaches the page
// only through textContent or attribute values, never through innerHTML, and Leaflet tooltips
// get DOM nodes, not strings (Leaflet would parse a string as HTML).
import { el, clear, ago, when, fmt } from './dom.js';
import { FleetMap, STATES } from './maps.js';
import { Commands, resultText } from './commands.js';
import { VehiclePage, shortKind, shortTransition, locksText } from './vehicle.js';
import { CampaignPage } from './campaigns.js';

const app = {
  session: null, // {name, role, csrf_token}
  config: null,
  fleet: [],
  alarms: [],
  fleetEtag: null, // the ETag of app.fleet: the next fetch answers 304 when nothing changed
  fleetMap: null,
  vehiclePage: null, // vehicle.js
  campaignPage: null, // campaigns.js
  events: null,
  view: '',
  selected: new Set(), // vehicle ids ticked in the list (commands to several bikes)
  commands: null,
  listStale: true, // the list's table is built when it is shown, not on every fleet update
};

// The list shows at most this many rows (a search or filter narrows it): 10,000 rows of DOM
// cost more than the map.
const LIST_ROWS = 1000;

const ROLE_RANK = { viewer: 0, operator: 1, admin: 2 };
const can = (role) => app.session && ROLE_RANK[app.session.role] >= ROLE_RANK[role];

class ApiError extends Error {
  constructor(status, message) { super(message); this.status = status; }
}

async function api(path, { method = 'GET', body, headers: extra = {}, raw = false } = {}) {
  const headers = { ...extra };
  if (method !== 'GET') {
    headers['Content-Type'] = 'application/json';
    if (app.session) headers['X-CSRF-Token'] = app.session.csrf_token;
  }
  const res = await fetch(path, {
    method, headers, credentials: 'same-origin',
    body: method === 'GET' ? undefined : JSON.stringify(body ?? {}),
  });
  if (raw && res.status === 304) return res;
  let data = null;
  try { data = await res.json(); } catch { data = null; }
  if (res.status === 401 && path !== '/api/login') {
    showLogin();
    throw new ApiError(401, 'login required');
  }
  if (!res.ok) throw new ApiError(res.status, (data && data.error) || res.statusText);
  if (raw) return { status: res.status, etag: res.headers.get('ETag'), data };
  return data;
}

function status(text) { document.getElementById('status-line').textContent = text; }

// --- login -------------------------------------------------------------------------------
function showLogin() {
  app.session = null;
  if (app.events) { app.events.close(); app.events = null; }
  document.getElementById('top').hidden = true;
  for (const s of document.querySelectorAll('main > section')) s.hidden = s.id !== 'login-view';
  document.getElementById('login-name').focus();
}

async function onLogin(ev) {
  ev.preventDefault();
  const error = document.getElementById('login-error');
  error.textContent = '';
  const button = document.getElementById('login-submit');
  button.disabled = true;
  try {
    app.session = await api('/api/login', {
      method: 'POST',
      body: {
        name: document.getElementById('login-name').value,
        password: document.getElementById('login-password').value,
      },
    });
    document.getElementById('login-password').value = '';
    await start();
  } catch (e) {
    error.textContent = e.status === 429 ? 'Too many failed attempts: wait and try again.'
      : e.status === 401 ? 'Wrong name or password.' : `Login failed: ${e.message}`;
  } finally {
    button.disabled = false;
  }
}

async function onLogout() {
  try { await api('/api/logout', { method: 'POST' }); } catch { /* the session is gone anyway */ }
  showLogin();
}

// --- data and live updates -----------------------------------------------------------------
// The compact list (GET /api/fleet?view=compact: arrays in the order of `fields`) as the
// objects the map and the list use. The browser keeps no copy (no-store): the console sends the
// ETag it has and a 304 keeps app.fleet as it is.
function fleetObjects(compact) {
  const f = Object.fromEntries(compact.fields.map((name, i) => [name, i]));
  return compact.vehicles.map((r) => ({
    id: r[f.id], lat: r[f.lat], lon: r[f.lon], state: r[f.state], soc_pct: r[f.soc_pct],
    speed_kmh: r[f.speed_kmh], last_seen_us: r[f.last_seen_us],
    locks: (r[f.locks] || []).map(([kind, name]) => ({ kind, name })),
    alarms: { active: r[f.alarms_active], unacked: r[f.alarms_unacked] },
  }));
}

function fetchFleet() {
  const headers = app.fleetEtag ? { 'If-None-Match': app.fleetEtag } : {};
  return api('/api/fleet?view=compact', { headers, raw: true });
}

// pending: a fetchFleet() already under way (the first load asks for the list at once).
async function loadFleet(pending = null) {
  const r = await (pending || fetchFleet());
  if (r.status !== 304) {
    app.fleet = fleetObjects(r.data);
    app.fleetEtag = r.etag;
    if (app.fleetMap) app.fleetMap.update(app.fleet);
    app.listStale = true;
    if (app.view === 'list') renderList();
  }
  status(`${app.fleet.length} vehicles · updated ${new Date().toLocaleTimeString()}`);
}

async function loadAlarms() {
  app.alarms = (await api('/api/alarms?limit=200')).alarms;
  renderAlarms();
}

function debounce(fn, ms) {
  let t = null;
  return () => { clearTimeout(t); t = setTimeout(() => fn().catch(() => {}), ms); };
}

function listen() {
  // Server-sent events say *that* something changed; the data comes from the API as usual.
  const fleetChanged = debounce(async () => {
    await loadFleet();
    if (app.view === 'vehicle') await app.vehiclePage.render(currentVehicleId());
  }, 300);
  const alarmsChanged = debounce(loadAlarms, 300);
  // A command result: the commands this page waits for, at once (no debounce: the operator is
  // watching), and the vehicle page's history.
  const commandsChanged = async () => {
    await app.commands.refresh();
    if (app.view === 'vehicle') await app.vehiclePage.loadHistory(currentVehicleId());
  };
  app.events = new EventSource('/api/events');
  app.events.addEventListener('commands', () => commandsChanged().catch(() => {}));
  app.events.addEventListener('fleet', fleetChanged);
  app.events.addEventListener('alarms', alarmsChanged);
  app.events.onerror = () => status('live updates interrupted: retrying');
}

// --- list ------------------------------------------------------------------------------------
function passesFilters(v) {
  const q = document.getElementById('f-search').value.trim().toLowerCase();
  const st = document.getElementById('f-state').value;
  const bat = document.getElementById('f-battery').value;
  const seen = document.getElementById('f-seen').value;
  if (q && !v.id.toLowerCase().includes(q)) return false;
  if (st && v.state !== st) return false;
  if (bat && !(v.soc_pct !== null && v.soc_pct < Number(bat))) return false;
  if (seen) {
    const limit = Number(seen);
    const age = v.last_seen_us ? (Date.now() * 1000 - v.last_seen_us) / 1e6 : Infinity;
    if (limit > 0 && age > limit) return false;
    if (limit < 0 && age < -limit) return false;
  }
  return true;
}

function stateCell(state) {
  return el('td', {}, el('span', { className: `dot s-${state}` }, STATES[state] || state));
}

function pickCell(v) {
  const box = el('input', { type: 'checkbox', 'aria-label': `select ${v.id}` });
  box.checked = app.selected.has(v.id);
  box.addEventListener('click', (ev) => ev.stopPropagation());
  box.addEventListener('change', () => {
    if (box.checked) app.selected.add(v.id); else app.selected.delete(v.id);
    renderBulk();
  });
  return el('td', { className: 'pick' }, box);
}

function renderBulk() {
  const on = Boolean(app.commands.enabled());
  document.getElementById('bulk').hidden = !on;
  document.getElementById('pick-all').hidden = !on;
  document.getElementById('bulk-count').textContent = `${app.selected.size} selected`;
}

// Several bikes: one line per bike, updated as the results come.
function bulkSent(out) {
  const line = document.getElementById('bulk-result');
  if (out.error) { line.textContent = out.error; return; }
  const state = new Map(out.commands.map((c) => [c.vehicle_id, c.error || 'sent']));
  const show = () => {
    line.textContent = [...state].map(([v, r]) => `${v}: ${r}`).join(' · ');
  };
  for (const c of out.commands) {
    if (!c.command_id || c.error) continue;
    app.commands.watch(c.command_id, (cmd) => { state.set(c.vehicle_id, resultText(cmd)); show(); });
  }
  show();
}

function renderList() {
  app.listStale = false;
  const body = document.querySelector('#fleet-table tbody');
  clear(body);
  const picking = Boolean(app.commands.enabled());
  let n = 0;
  for (const v of app.fleet) {
    if (!passesFilters(v)) continue;
    n += 1;
    if (n > LIST_ROWS) continue; // counted, not drawn
    const row = el('tr', { className: 'link', dataset: { vehicle: v.id } },
      picking ? pickCell(v) : el('td', { className: 'pick' }),
      el('td', { className: 'wrap' }, v.id),
      stateCell(v.state),
      el('td', {}, v.soc_pct === null ? '–' : `${v.soc_pct} %`),
      el('td', {}, v.speed_kmh === null ? '–' : `${fmt(v.speed_kmh)} km/h`),
      el('td', {}, locksText(v.locks)),
      el('td', {}, v.alarms.active ? `${v.alarms.active} (${v.alarms.unacked} new)` : ''),
      el('td', {}, ago(v.last_seen_us)));
    row.addEventListener('click', () => { location.hash = `#vehicle/${encodeURIComponent(v.id)}`; });
    body.append(row);
  }
  document.getElementById('list-count').textContent = n > LIST_ROWS
    ? `${n} of ${app.fleet.length} vehicles match; the first ${LIST_ROWS} shown (search or filter to narrow)`
    : `${n} of ${app.fleet.length} vehicles`;
  renderBulk();
}

// --- alarms ----------------------------------------------------------------------------------
function ackCell(alarm, onDone) {
  const cell = ackOnly(alarm, onDone);
  if (alarm.resolved_by) {
    cell.append(el('div', { className: 'muted' },
      `resolved by ${alarm.resolved_by}, ${when(alarm.resolved_at_us)}`));
  } else if (alarm.transition === 'ALARM_TRANSITION_RAISED' && can('operator')) {
    const button = el('button', { type: 'button', className: 'resolve',
      dataset: { alarm: alarm.id } }, 'Resolve');
    button.addEventListener('click', async () => {
      button.disabled = true;
      try {
        await api(`/api/alarms/${encodeURIComponent(alarm.id)}/resolve`, { method: 'POST' });
        await onDone();
      } catch (e) {
        button.disabled = false;
        status(`resolve failed: ${e.message}`);
      }
    });
    cell.append(' ', button);
  }
  return cell;
}

function ackOnly(alarm, onDone) {
  if (alarm.acked_by) return el('td', {}, `${alarm.acked_by}, ${when(alarm.acked_at_us)}`);
  if (alarm.transition !== 'ALARM_TRANSITION_RAISED') return el('td', {}, '');
  if (!can('operator')) return el('td', { className: 'muted' }, 'not yet');
  const button = el('button', { type: 'button', className: 'ack', dataset: { alarm: alarm.id } },
    'Acknowledge');
  button.addEventListener('click', async () => {
    button.disabled = true;
    try {
      await api(`/api/alarms/${encodeURIComponent(alarm.id)}/ack`, { method: 'POST' });
      await onDone();
    } catch (e) {
      button.disabled = false;
      status(`acknowledge failed: ${e.message}`);
    }
  });
  return el('td', {}, button);
}

function renderAlarms() {
  const unackedOnly = document.getElementById('f-unacked').checked;
  const body = document.querySelector('#alarm-table tbody');
  clear(body);
  let open = 0;
  for (const a of app.alarms) {
    const pending = a.active && !a.acked_by;
    if (pending) open += 1;
    if (unackedOnly && !pending) continue;
    const vehicle = el('a', { href: `#vehicle/${encodeURIComponent(a.vehicle_id)}` }, a.vehicle_id);
    body.append(el('tr', { dataset: { alarm: a.id } },
      el('td', {}, when(a.at_us || a.created_at_us)),
      el('td', { className: 'wrap' }, vehicle),
      el('td', {}, shortKind(a.kind)),
      el('td', {}, shortTransition(a.transition) + (a.active ? ' (active)' : '')),
      el('td', { className: 'wrap' }, a.detail),
      ackCell(a, loadAlarms)));
  }
  const badge = document.getElementById('alarm-count');
  badge.hidden = open === 0;
  badge.textContent = String(open);
}

// --- vehicle page (vehicle.js) ---------------------------------------------------------------
function currentVehicleId() {
  return location.hash.startsWith('#vehicle/')
    ? decodeURIComponent(location.hash.slice('#vehicle/'.length)) : '';
}

// --- routing ---------------------------------------------------------------------------------
async function route() {
  if (!app.session) return;
  const hash = location.hash || '#map';
  const view = hash.startsWith('#vehicle/') ? 'vehicle' : hash.slice(1);
  app.view = ['map', 'list', 'alarms', 'vehicle', 'zones', 'admin', 'campaigns'].includes(view)
    ? view : 'map';
  for (const s of document.querySelectorAll('main > section')) {
    s.hidden = s.id !== `${app.view}-view`;
  }
  for (const a of document.querySelectorAll('header nav a')) {
    a.classList.toggle('active', a.id === `nav-${app.view}`);
  }
  if (app.view === 'map') app.fleetMap.resize();
  if (app.view === 'list' && app.listStale) renderList();
  if (app.view !== 'vehicle') app.vehiclePage.reset();
  if (app.view === 'vehicle') await app.vehiclePage.render(currentVehicleId());
  if (app.view === 'campaigns') await app.campaignPage.show();
}

async function start() {
  document.getElementById('top').hidden = false;
  document.getElementById('who').textContent = `${app.session.name} (${app.session.role})`;
  // The fleet list is the biggest answer: asked for now, in parallel with the configuration.
  const firstFleet = fetchFleet();
  firstFleet.catch(() => {}); // awaited below; a failure is reported there
  app.config = await api('/api/config');
  if (!app.commands) {
    app.commands = new Commands({ api, can, status, config: () => app.config });
  }
  if (!app.vehiclePage) {
    app.vehiclePage = new VehiclePage({ api, can, status, config: () => app.config,
      commands: () => app.commands, ackCell, currentId: currentVehicleId });
  }
  app.vehiclePage.reset();
  if (!app.campaignPage) app.campaignPage = new CampaignPage({ api, status });
  app.commands.renderButtons(document.getElementById('bulk-buttons'), () => [...app.selected],
    bulkSent);
  if (!app.fleetMap) {
    app.fleetMap = new FleetMap('map', app.config, (id) => {
      location.hash = `#vehicle/${encodeURIComponent(id)}`;
    });
    const legend = document.getElementById('legend');
    for (const [state, name] of Object.entries(STATES)) {
      if (state !== 'unknown') legend.append(el('li', { className: `s-${state}` }, name));
    }
  }
  // zones.js and admin.js (issue 28) take the session and the fleet map from here.
  document.dispatchEvent(new CustomEvent('fleet-session',
    { detail: { session: app.session, map: app.fleetMap.map } }));
  await route();
  await Promise.all([loadFleet(firstFleet), loadAlarms()]);
  app.fleetMap.fit();
  listen();
}

async function boot() {
  document.getElementById('login-form').addEventListener('submit', onLogin);
  document.getElementById('logout').addEventListener('click', onLogout);
  for (const id of ['f-search', 'f-state', 'f-battery', 'f-seen']) {
    document.getElementById(id).addEventListener('input', renderList);
  }
  document.getElementById('f-unacked').addEventListener('change', renderAlarms);
  document.getElementById('pick-all').addEventListener('change', (ev) => {
    for (const v of app.fleet) {
      if (!passesFilters(v)) continue;
      if (ev.target.checked) app.selected.add(v.id); else app.selected.delete(v.id);
    }
    renderList();
  });
  window.addEventListener('hashchange', () => route().catch(() => {}));
  try {
    app.session = await api('/api/session');
    await start();
  } catch {
    showLogin();
  }
}

boot();

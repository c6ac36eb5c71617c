// The operator console: plain ES module, no build step. Every piece of data from the server is
// untrusted (vehicle ids, details, names come from the bikes and the bus): it reaches the page
// only through textContent or attribute values, never through innerHTML, and Leaflet tooltips
// get DOM nodes, not strings (Leaflet would parse a string as HTML).
import { el, clear, ago, when, fmt } from './dom.js';
import { FleetMap, VehicleMap, STATES } from './maps.js';
import { Commands, resultText, renderHistory } from './commands.js';

const app = {
  session: null, // {name, role, csrf_token}
  config: null,
  fleet: [],
  alarms: [],
  fleetMap: null,
  vehicleMap: null,
  events: null,
  view: '',
  selected: new Set(), // vehicle ids ticked in the list (commands to several bikes)
  buttonsFor: null, // the vehicle whose command buttons are on the page
  commands: null,
};

const ROLE_RANK = { viewer: 0, operator: 1, admin: 2 };
const can = (role) => app.session && ROLE_RANK[app.session.role] >= ROLE_RANK[role];

class ApiError extends Error {
  constructor(status, message) { super(message); this.status = status; }
}

async function api(path, { method = 'GET', body } = {}) {
  const headers = {};
  if (method !== 'GET') {
    headers['Content-Type'] = 'application/json';
    if (app.session) headers['X-CSRF-Token'] = app.session.csrf_token;
  }
  const res = await fetch(path, {
    method, headers, credentials: 'same-origin',
    body: method === 'GET' ? undefined : JSON.stringify(body ?? {}),
  });
  let data = null;
  try { data = await res.json(); } catch { data = null; }
  if (res.status === 401 && path !== '/api/login') {
    showLogin();
    throw new ApiError(401, 'login required');
  }
  if (!res.ok) throw new ApiError(res.status, (data && data.error) || res.statusText);
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
async function loadFleet() {
  app.fleet = (await api('/api/fleet')).vehicles;
  if (app.fleetMap) app.fleetMap.update(app.fleet);
  renderList();
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
    if (app.view === 'vehicle') await renderVehicle(currentVehicleId());
  }, 300);
  const alarmsChanged = debounce(loadAlarms, 300);
  // A command result: the commands this page waits for, at once (no debounce: the operator is
  // watching), and the vehicle page's history.
  const commandsChanged = async () => {
    await app.commands.refresh();
    if (app.view === 'vehicle') await loadHistory(currentVehicleId());
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

function locksText(locks) {
  return (locks || []).map((l) => `${l.kind || 'lock'}: ${l.name || l.state}`).join(', ');
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
  const body = document.querySelector('#fleet-table tbody');
  clear(body);
  const picking = Boolean(app.commands.enabled());
  let n = 0;
  for (const v of app.fleet) {
    if (!passesFilters(v)) continue;
    n += 1;
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
  document.getElementById('list-count').textContent = `${n} of ${app.fleet.length} vehicles`;
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

const shortKind = (k) => (k || '').replace(/^ALARM_KIND_/, '').toLowerCase().replaceAll('_', ' ');
const shortTransition = (t) => (t || '').replace(/^ALARM_TRANSITION_/, '').toLowerCase();

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

// --- vehicle page ----------------------------------------------------------------------------
function currentVehicleId() {
  return decodeURIComponent(location.hash.slice('#vehicle/'.length));
}

function fact(dl, name, value) {
  dl.append(el('dt', {}, name), el('dd', {}, value ?? '–'));
}

async function renderVehicle(id) {
  let v;
  try {
    v = await api(`/api/vehicles/${encodeURIComponent(id)}`);
  } catch (e) {
    document.getElementById('v-title').textContent = `${id}: ${e.message}`;
    return;
  }
  document.getElementById('v-title').textContent = v.id;
  const dl = document.getElementById('v-facts');
  clear(dl);
  fact(dl, 'State', STATES[v.state] || v.state);
  fact(dl, 'Online', v.online ? 'yes' : 'no');
  fact(dl, 'Battery', v.soc_pct === null ? null : `${v.soc_pct} %`);
  fact(dl, 'Range', v.range_m === null ? null : `${fmt(v.range_m / 1000)} km`);
  fact(dl, 'Speed', v.speed_kmh === null ? null : `${fmt(v.speed_kmh)} km/h`);
  fact(dl, 'Position', v.lat === null ? null : `${v.lat.toFixed(5)}, ${v.lon.toFixed(5)}`);
  // What the bike reports of itself (the ingest's vehicle_state, when it has these columns),
  // else what the console derives from the event tables.
  const rep = v.reported || {};
  const locks = Array.isArray(rep.locks) && rep.locks.length ? rep.locks.map((l) =>
    `${l.kind || l.lock_kind || 'lock'}: ${l.state_name || l.name || l.state}`).join(', ')
    : locksText(v.locks);
  fact(dl, 'Locks', locks || null);
  if (rep.speed_limit_dkmh !== undefined && rep.speed_limit_dkmh !== null) {
    fact(dl, 'Speed limit in force', `${fmt(rep.speed_limit_dkmh / 10)} km/h`);
  }
  if (rep.assist_name) fact(dl, 'Assist', rep.assist_name);
  if (rep.bus_state) fact(dl, 'Bus', String(rep.bus_state).replace(/^BUS_STATE_/, '').toLowerCase());
  if (Array.isArray(rep.faults)) {
    fact(dl, 'Active faults', rep.faults.map((f) => (typeof f === 'string' ? f
      : f.name || f.code)).join(', ') || 'none');
  }
  const active = Array.isArray(rep.active_alarms) ? rep.active_alarms.map(shortKind)
    : v.alarms.kinds.map(shortKind);
  fact(dl, 'Active alarms', active.join(', ') || 'none');
  fact(dl, 'Last seen', ago(v.last_seen_us));
  if (v.status) {
    fact(dl, 'Connection', v.status.connection);
    fact(dl, 'Firmware', v.status.firmware_version);
    fact(dl, 'Outbox', v.status.outbox_depth === null ? null : String(v.status.outbox_depth));
  }
  if (!app.vehicleMap) app.vehicleMap = new VehicleMap('v-map', app.config);
  app.vehicleMap.show(v);

  const alarms = document.querySelector('#v-alarms tbody');
  clear(alarms);
  for (const a of v.alarm_history) {
    alarms.append(el('tr', { dataset: { alarm: a.id } }, el('td', {}, when(a.at_us || a.created_at_us)),
      el('td', {}, shortKind(a.kind)), el('td', {}, shortTransition(a.transition)),
      el('td', { className: 'wrap' }, a.detail), ackCell(a, () => renderVehicle(id))));
  }
  const rides = document.querySelector('#v-rides tbody');
  clear(rides);
  for (const r of v.rides) {
    const km = r.distance_odo_m ?? r.distance_gnss_m;
    rides.append(el('tr', {}, el('td', {}, when(r.started_at_us)), el('td', {}, when(r.ended_at_us)),
      el('td', {}, km === null ? '–' : `${fmt(km / 1000)} km`),
      el('td', {}, r.max_speed_dkmh === null ? '–' : `${fmt(r.max_speed_dkmh / 10)} km/h`),
      el('td', {}, `${r.soc_start_pct ?? '–'} → ${r.soc_end_pct ?? '–'} %`)));
  }
  const faults = document.querySelector('#v-faults tbody');
  clear(faults);
  for (const f of v.faults) {
    faults.append(el('tr', {}, el('td', {}, f.node), el('td', { className: 'wrap' }, f.name),
      el('td', {}, f.severity.replace(/^FAULT_SEVERITY_/, '').toLowerCase()), el('td', {}, f.kind),
      el('td', {}, when(f.last_seen_us))));
  }
  if (app.buttonsFor !== v.id) {
    app.buttonsFor = v.id;
    const last = document.getElementById('v-last-result');
    last.textContent = '';
    delete last.dataset.result;
    app.commands.renderButtons(document.getElementById('v-buttons'), () => [v.id],
      (out) => vehicleSent(v.id, out));
  }
  renderHistory(document.querySelector('#v-console-commands tbody'), v.console_commands || []);
  const commands = document.querySelector('#v-commands tbody');
  clear(commands);
  for (const c of v.commands) {
    commands.append(el('tr', {}, el('td', {}, when(c.received_at_us)), el('td', {}, c.action),
      el('td', {}, c.key_id), el('td', {}, c.result ?? 'pending'),
      el('td', { className: 'wrap' }, c.reason ?? '')));
  }
}

// The vehicle page's answer line: the command's result as soon as the bike sends it.
function vehicleSent(id, out) {
  const last = document.getElementById('v-last-result');
  const one = out.commands && out.commands[0];
  if (out.error || !one || one.error) {
    last.dataset.result = 'failed';
    last.textContent = out.error || (one && one.error) || 'not sent';
    return;
  }
  last.dataset.result = 'pending';
  last.dataset.command = one.command_id;
  last.textContent = 'sent, waiting for the bike';
  app.commands.watch(one.command_id, (c) => {
    if (last.dataset.command !== c.command_id) return;
    last.dataset.result = c.result || 'pending';
    last.textContent = resultText(c);
  });
  loadHistory(id).catch(() => {});
}

async function loadHistory(id) {
  if (!id) return;
  const r = await api(`/api/commands?vehicle=${encodeURIComponent(id)}&limit=50`);
  if (currentVehicleId() !== id) return;
  renderHistory(document.querySelector('#v-console-commands tbody'), r.commands);
}

// --- routing ---------------------------------------------------------------------------------
async function route() {
  if (!app.session) return;
  const hash = location.hash || '#map';
  const view = hash.startsWith('#vehicle/') ? 'vehicle' : hash.slice(1);
  app.view = ['map', 'list', 'alarms', 'vehicle'].includes(view) ? view : 'map';
  for (const s of document.querySelectorAll('main > section')) {
    s.hidden = s.id !== `${app.view}-view`;
  }
  for (const a of document.querySelectorAll('header nav a')) {
    a.classList.toggle('active', a.id === `nav-${app.view}`);
  }
  if (app.view === 'map') app.fleetMap.resize();
  if (app.view !== 'vehicle') app.buttonsFor = null;
  if (app.view === 'vehicle') await renderVehicle(currentVehicleId());
}

async function start() {
  document.getElementById('top').hidden = false;
  document.getElementById('who').textContent = `${app.session.name} (${app.session.role})`;
  app.config = await api('/api/config');
  app.buttonsFor = null;
  if (!app.commands) {
    app.commands = new Commands({ api, can, status, config: () => app.config });
  }
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
  await route();
  await Promise.all([loadFleet(), loadAlarms()]);
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

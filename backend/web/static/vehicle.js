// The vehicle page (issue 28): state, locks, the speed limit in force and why, faults, alarms,
// rides with their track on the map and a ride's speed / power / SOC plot, commands with who
// sent each. Every string from the server is untrusted (vehicle ids, lock kinds, zone names and
// the bike's reasons come from the bikes and the bus): it reaches the page only through el()
// (textContent) or SVG text nodes, never as markup.
import { el, clear, ago, when, fmt } from './dom.js';
import { VehicleMap, STATES } from './maps.js';
import { resultText, renderHistory } from './commands.js';

export const shortKind = (k) => (k || '').replace(/^ALARM_KIND_/, '').toLowerCase().replaceAll('_', ' ');
export const shortTransition = (t) => (t || '').replace(/^ALARM_TRANSITION_/, '').toLowerCase();

export function locksText(locks) {
  return (locks || []).map((l) => `${l.kind || 'lock'}: ${l.name || l.state}`).join(', ');
}

// The lock kinds a bike is known to have (its reported state, else its lock events), else the
// protocol's default set (docs/simulator.md lock_kinds): for the one-lock command.
const DEFAULT_LOCK_KINDS = ['seat', 'frame', 'steering', 'battery', 'other'];

function fact(dl, name, value, id) {
  const dd = el('dd', id ? { id } : {}, value ?? '–');
  dl.append(el('dt', {}, name), dd);
  return dd;
}

// Why the limit in force is what it is: the operator's cap (and the bike's own one-line
// account of it), the slow zones it is in, else the MC's own limit.
export function speedLimitWhy(sl) {
  if (!sl) return null;
  const parts = [];
  if (sl.operator_cap) {
    const c = sl.operator_cap;
    parts.push(`operator cap (${c.command}) by ${c.operator}, ${when(c.at_us)}` +
      (c.limit_in_force ? ` — bike: ${c.limit_in_force}` : ''));
  }
  for (const z of sl.slow_zones || []) {
    parts.push(`slow zone ${z.zone_name || z.zone_id}` +
      (z.limit_kmh === null ? '' : ` (${z.limit_kmh} km/h)`) + ` since ${when(z.since_us)}`);
  }
  if (parts.length === 0) parts.push('no operator cap or slow zone known: the MC\'s own limit');
  return parts.join('; ');
}

// --- the ride plot: three panels (speed, power, SOC) over the ride's time, plain SVG ---------
const SVG = 'http://www.w3.org/2000/svg';
function svg(tag, attrs = {}, text) {
  const node = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, String(v));
  if (text !== undefined) node.textContent = String(text);
  return node;
}

const SERIES = [
  { key: 'speed_kmh', label: 'speed', unit: 'km/h', colour: '#1971c2' },
  { key: 'power_w', label: 'power', unit: 'W', colour: '#e8590c' },
  { key: 'soc_pct', label: 'SOC', unit: '%', colour: '#2b8a3e' },
];

export function drawRidePlot(box, ride) {
  clear(box);
  const fields = ride.fields;
  const rows = ride.samples;
  const t = fields.indexOf('t_us');
  if (rows.length === 0) {
    box.append(el('p', { className: 'muted' }, 'No telemetry samples in this ride.'));
    return;
  }
  const W = 640; const H = 110; const L = 56; const R = 8; const GAP = 18;
  const t0 = rows[0][t]; const t1 = rows[rows.length - 1][t];
  const span = Math.max(1, t1 - t0);
  const plot = svg('svg', { viewBox: `0 0 ${W} ${SERIES.length * (H + GAP) + 16}`,
    role: 'img', class: 'ride-plot', 'aria-label': 'speed, power and SOC over the ride' });
  SERIES.forEach((s, i) => {
    const col = fields.indexOf(s.key);
    const top = i * (H + GAP) + 4;
    const values = rows.filter((r) => r[col] !== null && r[col] !== undefined);
    let lo = Math.min(0, ...values.map((r) => r[col]));
    let hi = Math.max(...values.map((r) => r[col]), lo + 1);
    if (s.key === 'soc_pct') { lo = 0; hi = 100; }
    const x = (us) => L + ((us - t0) / span) * (W - L - R);
    const y = (v) => top + H - ((v - lo) / (hi - lo)) * H;
    plot.append(svg('rect', { x: L, y: top, width: W - L - R, height: H, fill: '#fff',
      stroke: '#dee2e6' }));
    plot.append(svg('text', { x: 4, y: top + 12, class: 'plot-label', fill: s.colour },
      `${s.label}`));
    plot.append(svg('text', { x: 4, y: top + 26, class: 'plot-tick' }, `${fmt(hi)} ${s.unit}`));
    plot.append(svg('text', { x: 4, y: top + H, class: 'plot-tick' }, `${fmt(lo)} ${s.unit}`));
    const points = values.map((r) => `${x(r[t]).toFixed(1)},${y(r[col]).toFixed(1)}`).join(' ');
    plot.append(svg('polyline', { points, fill: 'none', stroke: s.colour, 'stroke-width': 1.5,
      'data-series': s.key, 'data-points': values.length }));
  });
  const bottom = SERIES.length * (H + GAP) + 10;
  plot.append(svg('text', { x: L, y: bottom, class: 'plot-tick' }, when(t0)));
  plot.append(svg('text', { x: W - R, y: bottom, class: 'plot-tick', 'text-anchor': 'end' },
    when(t1)));
  box.append(plot);
  if (ride.samples_in_ride > rows.length) {
    box.append(el('p', { className: 'muted' },
      `${rows.length} of the ride's ${ride.samples_in_ride} samples shown (every ` +
      `${Math.ceil(ride.samples_in_ride / rows.length)}th).`));
  }
}

// ctx: {api, can, status, config(), commands(), ackCell(alarm, onDone), currentId()}
export class VehiclePage {
  constructor(ctx) {
    this.ctx = ctx;
    this.map = null;
    this.buttonsFor = null; // the vehicle whose command buttons are on the page
    this.rideShown = null;
  }

  reset() { this.buttonsFor = null; }

  async render(id) {
    const { api } = this.ctx;
    let v;
    try {
      v = await api(`/api/vehicles/${encodeURIComponent(id)}`);
    } catch (e) {
      document.getElementById('v-title').textContent = `${id}: ${e.message}`;
      return;
    }
    if (this.ctx.currentId() !== id) return; // navigated away meanwhile
    document.getElementById('v-title').textContent = v.id;
    this.facts(v);
    if (!this.map) this.map = new VehicleMap('v-map', this.ctx.config());
    this.map.show(v);
    if (this.rideShown && this.rideShown.vehicle === v.id) {
      this.map.showRide(this.rideShown.ride, this.rideShown.points);
    }
    this.alarms(v, id);
    this.rides(v);
    const faults = document.querySelector('#v-faults tbody');
    clear(faults);
    for (const f of v.faults) {
      faults.append(el('tr', {}, el('td', {}, f.node), el('td', { className: 'wrap' }, f.name),
        el('td', {}, f.severity.replace(/^FAULT_SEVERITY_/, '').toLowerCase()), el('td', {}, f.kind),
        el('td', {}, when(f.last_seen_us))));
    }
    if (this.buttonsFor !== v.id) {
      this.buttonsFor = v.id;
      const last = document.getElementById('v-last-result');
      last.textContent = '';
      delete last.dataset.result;
      this.ctx.commands().renderButtons(document.getElementById('v-buttons'), () => [v.id],
        (out) => this.sent(v.id, out));
      this.oneLock(v);
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

  facts(v) {
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
    const sl = v.speed_limit || {};
    const inForce = sl.in_force_kmh ?? (rep.speed_limit_dkmh == null ? null : rep.speed_limit_dkmh / 10);
    fact(dl, 'Speed limit in force', inForce === null ? 'not reported yet' : `${fmt(inForce)} km/h`,
      'v-speed-limit');
    fact(dl, 'Why', speedLimitWhy(v.speed_limit), 'v-speed-limit-why');
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
  }

  alarms(v, id) {
    const body = document.querySelector('#v-alarms tbody');
    clear(body);
    for (const a of v.alarm_history) {
      body.append(el('tr', { dataset: { alarm: a.id } }, el('td', {}, when(a.at_us || a.created_at_us)),
        el('td', {}, shortKind(a.kind)), el('td', {}, shortTransition(a.transition)),
        el('td', { className: 'wrap' }, a.detail), this.ctx.ackCell(a, () => this.render(id))));
    }
  }

  rides(v) {
    const body = document.querySelector('#v-rides tbody');
    clear(body);
    for (const r of v.rides) {
      const km = r.distance_odo_m ?? r.distance_gnss_m;
      const show = el('button', { type: 'button', className: 'ride-show',
        dataset: { ride: r.ride_id } }, 'Track and plot');
      show.addEventListener('click', () => this.showRide(v.id, r.ride_id)
        .catch((e) => this.ctx.status(`ride: ${e.message}`)));
      body.append(el('tr', { dataset: { ride: r.ride_id } }, el('td', {}, when(r.started_at_us)),
        el('td', {}, when(r.ended_at_us)),
        el('td', {}, km === null ? '–' : `${fmt(km / 1000)} km`),
        el('td', {}, r.max_speed_dkmh === null ? '–' : `${fmt(r.max_speed_dkmh / 10)} km/h`),
        el('td', {}, `${r.soc_start_pct ?? '–'} → ${r.soc_end_pct ?? '–'} %`), el('td', {}, show)));
    }
  }

  // A ride's full track on the map and its plot (GET /api/rides).
  async showRide(vehicleId, rideId) {
    const ride = await this.ctx.api(`/api/rides?vehicle=${encodeURIComponent(vehicleId)}` +
      `&ride=${encodeURIComponent(rideId)}`);
    const lat = ride.fields.indexOf('lat');
    const lon = ride.fields.indexOf('lon');
    const points = ride.samples.map((s) => [s[lat], s[lon]]);
    this.rideShown = { vehicle: vehicleId, ride: rideId, points };
    this.map.showRide(rideId, points);
    const title = document.getElementById('v-ride-title');
    title.textContent = `Ride ${rideId}, ${when(ride.ride.started_at_us)} to ${when(ride.ride.ended_at_us)}`;
    const box = document.getElementById('v-ride-plot');
    box.dataset.ride = rideId;
    drawRidePlot(box, ride);
  }

  // One lock at a time (lock_kind): a whole-vehicle command drives every lock one after the
  // other (seconds on a bike with five locks); a technician swapping a battery wants one.
  oneLock(v) {
    const box = document.getElementById('v-one-lock');
    clear(box);
    const cmds = this.ctx.commands();
    const c = this.ctx.config();
    if (!this.ctx.can('operator') || !c || !c.commands) return;
    const rep = v.reported || {};
    const known = [...new Set([...(Array.isArray(rep.locks) ? rep.locks : []), ...(v.locks || [])]
      .map((l) => l.kind || l.lock_kind).filter((k) => typeof k === 'string' && /^[a-z0-9_]{1,32}$/.test(k)))];
    const kinds = known.length ? known : DEFAULT_LOCK_KINDS;
    const select = el('select', { id: 'v-lock-kind', 'aria-label': 'which lock' },
      ...kinds.map((k) => el('option', { value: k }, k)));
    box.append(el('span', { className: 'muted' }, 'One lock:'), select);
    for (const action of ['lock', 'unlock']) {
      if (!cmds.allowed(action)) continue;
      const button = el('button', { type: 'button', className: 'cmd-one', dataset: { action } },
        action === 'lock' ? 'Lock it' : 'Unlock it');
      button.addEventListener('click', async () => {
        button.disabled = true;
        try {
          this.sent(v.id, await cmds.send([v.id], { action, lock_kind: select.value }));
        } catch (e) {
          this.ctx.status(`${action} ${select.value} failed: ${e.message}`);
          this.sent(v.id, { error: e.message });
        } finally {
          button.disabled = false;
        }
      });
      box.append(button);
    }
  }

  // The answer line: the command's result as soon as the bike's answer is pushed to the page.
  sent(id, out) {
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
    this.ctx.commands().watch(one.command_id, (c) => {
      if (last.dataset.command !== c.command_id) return;
      last.dataset.result = c.result || 'pending';
      last.textContent = resultText(c);
    });
    this.loadHistory(id).catch(() => {});
  }

  async loadHistory(id) {
    if (!id) return;
    const r = await this.ctx.api(`/api/commands?vehicle=${encodeURIComponent(id)}&limit=50`);
    if (this.ctx.currentId() !== id) return;
    renderHistory(document.querySelector('#v-console-commands tbody'), r.commands);
  }
}

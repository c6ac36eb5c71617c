// The campaign page (issue 29): the collection campaigns whose samples reached the database
// (the ingest's campaign_samples), per campaign the vehicles, sample counts and last sample, one
// signal's samples as a plot and a table, and the samples as CSV (the server writes it under the
// formula rule). Campaign ids, signals, vehicle ids and text values are untrusted: el() only.
import { el, clear, when, fmt } from './dom.js';

const SVG = 'http://www.w3.org/2000/svg';
function svg(tag, attrs = {}, text) {
  const node = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, String(v));
  if (text !== undefined) node.textContent = String(text);
  return node;
}

const COLOURS = ['#1971c2', '#e8590c', '#2b8a3e', '#9c36b5', '#c92a2a', '#0c8599'];
const TABLE_ROWS = 200;

function query(params) {
  return Object.entries(params).filter(([, v]) => v !== null && v !== undefined && v !== '')
    .map(([k, v]) => `${k}=${encodeURIComponent(v)}`).join('&');
}

// One signal's samples over time, a line per vehicle (at most six coloured; the rest grey).
export function drawSamplePlot(box, samples) {
  clear(box);
  const numeric = samples.filter((s) => typeof s[2] === 'number');
  if (numeric.length === 0) {
    box.append(el('p', { className: 'muted' }, 'No numeric samples to plot.'));
    return;
  }
  const W = 640; const H = 180; const L = 64; const R = 8; const T = 8;
  const t0 = Math.min(...numeric.map((s) => s[0]));
  const t1 = Math.max(...numeric.map((s) => s[0]));
  let lo = Math.min(...numeric.map((s) => s[2]));
  let hi = Math.max(...numeric.map((s) => s[2]));
  if (hi === lo) { hi += 1; lo -= 1; }
  const x = (us) => L + ((us - t0) / Math.max(1, t1 - t0)) * (W - L - R);
  const y = (v) => T + H - ((v - lo) / (hi - lo)) * H;
  const plot = svg('svg', { viewBox: `0 0 ${W} ${H + T + 24}`, role: 'img', class: 'campaign-plot',
    'aria-label': 'the signal over time, one line per vehicle' });
  plot.append(svg('rect', { x: L, y: T, width: W - L - R, height: H, fill: '#fff', stroke: '#dee2e6' }));
  plot.append(svg('text', { x: 4, y: T + 10, class: 'plot-tick' }, fmt(hi)));
  plot.append(svg('text', { x: 4, y: T + H, class: 'plot-tick' }, fmt(lo)));
  plot.append(svg('text', { x: L, y: T + H + 18, class: 'plot-tick' }, when(t0)));
  plot.append(svg('text', { x: W - R, y: T + H + 18, class: 'plot-tick', 'text-anchor': 'end' }, when(t1)));
  const byVehicle = new Map();
  for (const s of numeric) {
    if (!byVehicle.has(s[1])) byVehicle.set(s[1], []);
    byVehicle.get(s[1]).push(s);
  }
  let i = 0;
  for (const [vehicle, rows] of byVehicle) {
    const colour = COLOURS[i] || '#868e96';
    i += 1;
    const points = rows.map((s) => `${x(s[0]).toFixed(1)},${y(s[2]).toFixed(1)}`).join(' ');
    const line = svg('polyline', { points, fill: 'none', stroke: colour, 'stroke-width': 1.5,
      'data-points': rows.length });
    line.dataset.vehicle = vehicle;
    line.append(svg('title', {}, vehicle));
    plot.append(line);
    for (const s of rows.length <= 60 ? rows : []) {
      plot.append(svg('circle', { cx: x(s[0]).toFixed(1), cy: y(s[2]).toFixed(1), r: 2.5, fill: colour }));
    }
  }
  box.append(plot);
}

// ctx: {api, status}
export class CampaignPage {
  constructor(ctx) {
    this.ctx = ctx;
    this.selected = null; // {id, version}
  }

  async show() {
    const r = await this.ctx.api('/api/campaigns');
    const body = document.querySelector('#campaign-table tbody');
    clear(body);
    document.getElementById('campaign-none').textContent = !r.available
      ? 'This database has no campaign samples table yet (the ingest\'s migration 7).'
      : r.campaigns.length === 0 ? 'No campaign has delivered samples yet.' : '';
    for (const c of r.campaigns) {
      const open = el('button', { type: 'button', className: 'campaign-open',
        dataset: { campaign: c.id, version: String(c.version) } }, 'Open');
      open.addEventListener('click', () => this.open(c).catch((e) => this.ctx.status(`campaign: ${e.message}`)));
      body.append(el('tr', { dataset: { campaign: c.id, version: String(c.version) } },
        el('td', { className: 'wrap' }, c.id), el('td', {}, String(c.version)),
        el('td', {}, String(c.vehicles)), el('td', {}, String(c.samples)),
        el('td', { className: 'wrap' }, c.signals.join(', ')),
        el('td', {}, when(c.last_sample_us)), el('td', {}, open)));
    }
    if (this.selected) {
      const again = r.campaigns.find((c) => c.id === this.selected.id && c.version === this.selected.version);
      if (again) await this.open(again);
    }
  }

  async open(c) {
    this.selected = { id: c.id, version: c.version };
    const box = document.getElementById('campaign-detail');
    box.hidden = false;
    document.getElementById('campaign-title').textContent = `${c.id} · version ${c.version}`;
    const d = await this.ctx.api(`/api/campaigns/detail?${query({ id: c.id, version: c.version })}`);
    const body = document.querySelector('#campaign-vehicles tbody');
    clear(body);
    for (const v of d.vehicles) {
      const link = el('a', { href: `#vehicle/${encodeURIComponent(v.vehicle_id)}` }, v.vehicle_id);
      body.append(el('tr', { dataset: { vehicle: v.vehicle_id } }, el('td', { className: 'wrap' }, link),
        el('td', {}, String(v.samples)), el('td', {}, String(v.invalid)),
        el('td', {}, when(v.last_sample_us)), el('td', {}, when(v.last_received_us)),
        el('td', { className: 'wrap' }, v.signals.join(', '))));
    }
    const select = document.getElementById('campaign-signal');
    const keep = select.value;
    clear(select);
    for (const s of c.signals) select.append(el('option', { value: s }, s));
    if (c.signals.includes(keep)) select.value = keep;
    select.onchange = () => this.signal().catch((e) => this.ctx.status(`campaign: ${e.message}`));
    await this.signal();
  }

  async signal() {
    const { id, version } = this.selected;
    const signal = document.getElementById('campaign-signal').value;
    const csv = document.getElementById('campaign-csv');
    csv.setAttribute('href', `/api/campaigns/samples.csv?${query({ id, version })}`);
    const one = document.getElementById('campaign-csv-signal');
    one.setAttribute('href', `/api/campaigns/samples.csv?${query({ id, version, signal })}`);
    if (!signal) return;
    const r = await this.ctx.api(`/api/campaigns/samples?${query({ id, version, signal })}`);
    const plot = document.getElementById('campaign-plot');
    plot.dataset.signal = signal;
    drawSamplePlot(plot, r.samples);
    const body = document.querySelector('#campaign-samples tbody');
    clear(body);
    const newest = r.samples.slice(-TABLE_ROWS).reverse();
    for (const s of newest) {
      body.append(el('tr', {}, el('td', {}, when(s[0])), el('td', { className: 'wrap' }, s[1]),
        el('td', { className: 'wrap' }, s[2] === null ? (s[3] ?? '–') : String(s[2])),
        el('td', {}, s[4] ? 'invalid' : ''), el('td', {}, s[5] === null ? '' : when(s[5]))));
    }
    document.getElementById('campaign-samples-note').textContent =
      `${r.samples.length} samples${r.truncated ? ' (the first 5,000; the CSV has them all)' : ''}; ` +
      `the newest ${Math.min(TABLE_ROWS, r.samples.length)} listed.`;
  }
}

// Commands from the console (issue 28): buttons on the vehicle page and for the bikes selected
// in the list, the result shown live. The server signs and publishes; the page only asks. A
// viewer gets no buttons (and the server answers 403 anyway); without --broker/--signing-key
// the server has no commands and the page says so. Text from the server goes through el()
// (textContent) only.
import { el, clear, when } from './dom.js';

// What a button sends: the delegation's action name and its parameters.
const BUTTONS = [
  { label: 'Lock', action: 'lock', body: () => ({ action: 'lock' }) },
  { label: 'Unlock', action: 'unlock', body: () => ({ action: 'unlock' }) },
  { label: 'Set speed limit', action: 'speed_limit', needsKmh: true,
    body: (kmh) => ({ action: 'speed_limit', kmh }) },
  { label: 'Light on', action: 'headlight', body: () => ({ action: 'headlight', on: true }) },
  { label: 'Light off', action: 'headlight', body: () => ({ action: 'headlight', on: false }) },
  { label: 'Clear trip', action: 'clear_trip', body: () => ({ action: 'clear_trip' }) },
  { label: 'Power off', action: 'power_off', confirm: 'Power the bike off?',
    body: () => ({ action: 'power_off' }) },
];

const FINAL = new Set(['succeeded', 'failed', 'timeout', 'rejected', 'not_published', 'no_answer']);

export class Commands {
  // ctx: {api(path, opts), can(role), status(text), config()}
  constructor(ctx) {
    this.ctx = ctx;
    this.pending = new Map(); // command_id -> callback(command)
  }

  enabled() {
    const c = this.ctx.config();
    return this.ctx.can('operator') && c && c.commands;
  }

  allowed(action) {
    const c = this.ctx.config().commands;
    return !c.actions || c.actions.includes(action);
  }

  // The buttons of one vehicle (or, with ids(), of the selected ones) into `box`.
  renderButtons(box, ids, onSent) {
    clear(box);
    const c = this.ctx.config();
    if (!this.ctx.can('operator')) return; // viewers: nothing to press
    if (!c || !c.commands) {
      box.append(el('p', { className: 'muted' }, 'Commands are off on this server.'));
      return;
    }
    const kmh = el('input', { type: 'number', min: '1', max: '255', value: '20',
      id: `${box.id}-kmh`, className: 'kmh', 'aria-label': 'speed limit km/h' });
    for (const b of BUTTONS) {
      if (!this.allowed(b.action)) continue;
      const button = el('button', { type: 'button', className: 'cmd',
        dataset: { action: b.action, label: b.label } }, b.label);
      button.addEventListener('click', async () => {
        if (b.confirm && !window.confirm(b.confirm)) return;
        const vehicles = ids();
        if (vehicles.length === 0) { this.ctx.status('select one or more bikes first'); return; }
        const n = Number(kmh.value);
        if (b.needsKmh && !(Number.isInteger(n) && n >= 1 && n <= 255)) {
          this.ctx.status('speed limit: a whole number of km/h, 1 to 255');
          return;
        }
        button.disabled = true;
        try {
          await onSent(await this.send(vehicles, b.body(n)));
        } catch (e) {
          this.ctx.status(`${b.label} failed: ${e.message}`);
          onSent({ error: e.message });
        } finally {
          button.disabled = false;
        }
      });
      box.append(button);
      if (b.needsKmh) box.append(kmh, el('span', { className: 'muted' }, 'km/h'));
    }
  }

  // One vehicle: POST /api/vehicles/{id}/commands; several: POST /api/commands.
  async send(vehicles, body) {
    if (vehicles.length === 1) {
      const r = await this.ctx.api(`/api/vehicles/${encodeURIComponent(vehicles[0])}/commands`,
        { method: 'POST', body });
      return { commands: [{ vehicle_id: vehicles[0], command_id: r.command_id, status: 202 }] };
    }
    return this.ctx.api('/api/commands', { method: 'POST', body: { ...body, vehicles } });
  }

  // Called on the server's `commands` event: fetch the commands still waiting for a result.
  async refresh() {
    if (this.pending.size === 0) return;
    const ids = [...this.pending.keys()].join(',');
    const r = await this.ctx.api(`/api/commands?ids=${encodeURIComponent(ids)}&limit=500`);
    for (const c of r.commands) {
      const cb = this.pending.get(c.command_id);
      if (!cb) continue;
      cb(c);
      if (FINAL.has(c.result)) this.pending.delete(c.command_id);
    }
  }

  // Also asks once now: a fast answer (a refusal on the bike takes milliseconds) can reach the
  // server, and its `commands` event the page, before the POST's reply registered the watch;
  // waiting for the next event would leave "waiting for the bike" on screen for good.
  watch(commandId, cb) {
    this.pending.set(commandId, cb);
    this.refresh().catch(() => {});
  }
}

export function resultText(c) {
  if (!c.result) return 'sent, waiting for the bike';
  const parts = [c.result];
  if (c.reason) parts.push(c.reason);
  if (c.limit_in_force) parts.push(c.limit_in_force);
  return parts.join(' · ');
}

// The vehicle page's command history: who sent what, when, and the bike's answer.
export function renderHistory(tbody, commands) {
  clear(tbody);
  for (const c of commands) {
    tbody.append(el('tr', { dataset: { command: c.command_id, result: c.result || 'pending' } },
      el('td', {}, when(c.issued_at_us)),
      el('td', {}, c.params || c.action),
      el('td', {}, c.operator),
      el('td', { className: 'result' }, c.result || 'pending'),
      el('td', { className: 'wrap' }, [c.reason, c.limit_in_force, c.duration_ms === null ||
        c.duration_ms === undefined ? null : `${c.duration_ms} ms`].filter(Boolean).join(' · '))));
  }
}

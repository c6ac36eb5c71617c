// The admin page (issue 28): revocation lists (upload the file `fleetgw keys revoke` signed
// offline; the server verifies, publishes, stores and audits it), operator accounts (add with a
// role, change the role, reset the password, remove) and API tokens (create: shown once; list;
// revoke), and the latest audit rows. Admin-only: the link shows for admins, and the server
// answers 403 to anyone else whatever the page does. Text goes through el() (textContent) only.
import { el, clear, when, jsonCall } from './dom.js';

let session = null;

// JSON in and out with the session's CSRF token on state-changing requests (dom.js).
const call = (path, opts) => jsonCall(path, opts, session && session.csrf_token);

const $ = (id) => document.getElementById(id);
function say(id, text, ok) {
  $(id).textContent = text;
  $(id).dataset.state = ok ? 'ok' : 'error';
}
function button(label, className, onClick) {
  const b = el('button', { type: 'button', className }, label);
  b.addEventListener('click', async () => {
    b.disabled = true;
    try { await onClick(); } finally { b.disabled = false; }
  });
  return b;
}

// --- revocation lists ------------------------------------------------------------------------
function base64Of(buffer) {
  let s = '';
  const bytes = new Uint8Array(buffer);
  for (let i = 0; i < bytes.length; i += 1) s += String.fromCharCode(bytes[i]);
  return btoa(s);
}

async function loadRevocations() {
  const r = await call('/api/revocations');
  $('rev-roots').textContent = r.roots.length ? `Roots this server verifies: ${r.roots.join(', ')}`
    : 'No --root-key configured: lists cannot be verified.';
  const body = document.querySelector('#rev-table tbody');
  clear(body);
  for (const l of r.in_force) {
    body.append(el('tr', { dataset: { root: l.root_key_id, version: String(l.version) } },
      el('td', {}, l.root_key_id), el('td', {}, String(l.version)),
      el('td', { className: 'wrap' }, l.revoked_serials.join(', ') || '–'),
      el('td', { className: 'wrap' }, l.revoked_key_ids.join(', ') || '–'),
      el('td', {}, `${l.published_by} from ${l.address}, ${when(l.published_at_us)}`),
      el('td', {}, String(l.vehicles))));
  }
  const keys = document.querySelector('#keys-table tbody');
  clear(keys);
  for (const k of r.keys_seen) {
    keys.append(el('tr', {}, el('td', {}, k.key_id),
      el('td', {}, k.delegation_serial === null ? 'trusted key' : String(k.delegation_serial)),
      el('td', {}, String(k.commands)), el('td', {}, when(k.last_used_us)),
      el('td', {}, String(k.refused_revoked))));
  }
}

async function onRevocationUpload() {
  const file = $('rev-file').files[0];
  if (!file) { say('rev-result', 'Choose the file fleetgw keys revoke wrote.', false); return; }
  try {
    const r = await call('/api/revocations', { method: 'POST',
      body: { list_base64: base64Of(await file.arrayBuffer()) } });
    say('rev-result', `Version ${r.version} of root ${r.root_key_id} published to ${r.vehicles} `
      + `vehicles: serials ${r.revoked_serials.join(', ') || 'none'}, key ids `
      + `${r.revoked_key_ids.join(', ') || 'none'}.`, true);
  } catch (e) {
    say('rev-result', `Refused: ${e.message}`, false);
  }
  await loadRevocations();
}

async function onRepublish() {
  try {
    const r = await call('/api/revocations/republish', { method: 'POST' });
    say('rev-result', `Published again: ${r.republished.map((x) => `${x.list} to ${x.vehicles} vehicles`).join(', ') || 'nothing to publish'}.`, true);
  } catch (e) {
    say('rev-result', `Not published: ${e.message}`, false);
  }
}

// --- operators -------------------------------------------------------------------------------
const ROLES = ['viewer', 'operator', 'admin'];

function roleSelect(current) {
  const s = el('select', { 'aria-label': 'role' });
  for (const r of ROLES) {
    const o = el('option', { value: r }, r);
    if (r === current) o.selected = true;
    s.append(o);
  }
  return s;
}

async function loadOperators() {
  const r = await call('/api/operators');
  const body = document.querySelector('#ops-table tbody');
  clear(body);
  for (const o of r.operators) {
    const role = roleSelect(o.role);
    const pw = el('input', { type: 'password', placeholder: 'new password', maxlength: '1024',
      autocomplete: 'new-password', 'aria-label': `new password for ${o.name}` });
    const act = async (what, payload, done) => {
      try {
        await call(`/api/operators/${encodeURIComponent(o.name)}/${what}`, { method: 'POST', body: payload });
        say('ops-result', done, true);
      } catch (e) {
        say('ops-result', `${o.name}: ${e.message}`, false);
      }
      await loadOperators();
    };
    body.append(el('tr', { dataset: { operator: o.name } },
      el('td', {}, o.name), el('td', {}, role),
      el('td', {}, String(o.sessions)), el('td', {}, when(o.last_seen_us)),
      el('td', {},
        button('Set role', 'op-role', () => act('role', { role: role.value }, `${o.name} is now ${role.value}.`)),
        ' ', pw, ' ',
        button('Reset password', 'op-password', () => act('password', { password: pw.value },
          `${o.name}'s password was reset; their sessions ended.`)),
        ' ',
        button('Remove', 'op-remove', async () => {
          if (!window.confirm(`Remove ${o.name}?`)) return;
          await act('remove', {}, `${o.name} removed.`);
        }))));
  }
}

async function onAddOperator(ev) {
  ev.preventDefault();
  const name = $('op-name').value;
  try {
    await call('/api/operators', { method: 'POST',
      body: { name, role: $('op-role').value, password: $('op-password').value } });
    say('ops-result', `${name} added.`, true);
    $('op-password').value = '';
    $('op-name').value = '';
  } catch (e) {
    say('ops-result', `${name}: ${e.message}`, false);
  }
  await loadOperators();
}

// --- API tokens ------------------------------------------------------------------------------
async function loadTokens() {
  const r = await call('/api/tokens');
  const body = document.querySelector('#tok-table tbody');
  clear(body);
  for (const t of r.tokens) {
    const revoked = t.revoked_at_us !== null && t.revoked_at_us !== undefined;
    body.append(el('tr', { dataset: { token: String(t.id) } },
      el('td', {}, t.name), el('td', {}, t.role), el('td', {}, `${t.created_by}, ${when(t.created_at_us)}`),
      el('td', {}, when(t.last_used_us)),
      el('td', {}, revoked ? `revoked by ${t.revoked_by}, ${when(t.revoked_at_us)}`
        : button('Revoke', 'tok-revoke', async () => {
          try {
            await call(`/api/tokens/${t.id}/revoke`, { method: 'POST' });
            say('tok-result', `${t.name} revoked.`, true);
          } catch (e) {
            say('tok-result', `${t.name}: ${e.message}`, false);
          }
          await loadTokens();
        }))));
  }
}

async function onCreateToken(ev) {
  ev.preventDefault();
  try {
    const t = await call('/api/tokens', { method: 'POST',
      body: { name: $('tok-name').value, role: $('tok-role').value } });
    // Shown once: the server keeps only its hash.
    $('tok-shown').textContent = t.token;
    say('tok-result', `Token ${t.name} (${t.role}) created: copy it now, it is not shown again.`, true);
    $('tok-name').value = '';
  } catch (e) {
    say('tok-result', e.message, false);
  }
  await loadTokens();
}

async function loadAudit() {
  const r = await call('/api/audit');
  const body = document.querySelector('#audit-table tbody');
  clear(body);
  for (const a of r.audit.slice(0, 50)) {
    body.append(el('tr', {}, el('td', {}, when(a.at_us)), el('td', {}, a.operator ?? '–'),
      el('td', {}, a.address), el('td', {}, a.action), el('td', { className: 'wrap' }, a.target),
      el('td', {}, a.result), el('td', { className: 'wrap' }, a.detail)));
  }
}

async function onRoute() {
  if (location.hash !== '#admin' || !session || session.role !== 'admin') return;
  $('tok-shown').textContent = '';
  await Promise.all([loadRevocations(), loadOperators(), loadTokens(), loadAudit()]);
}

document.addEventListener('fleet-session', (ev) => {
  session = ev.detail.session;
  $('nav-admin').hidden = session.role !== 'admin';
  onRoute().catch(() => {});
});
window.addEventListener('hashchange', () => { onRoute().catch(() => {}); });
$('rev-upload').addEventListener('click', () => { onRevocationUpload().catch(() => {}); });
$('rev-republish').addEventListener('click', () => { onRepublish().catch(() => {}); });
$('op-form').addEventListener('submit', (ev) => { onAddOperator(ev).catch(() => {}); });
$('tok-form').addEventListener('submit', (ev) => { onCreateToken(ev).catch(() => {}); });

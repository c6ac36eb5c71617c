// DOM helpers of the console. el() sets text with textContent only: a string child becomes a
// text node, never markup, whatever it contains.
export function el(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(props)) {
    if (key === 'dataset') Object.assign(node.dataset, value);
    else if (key === 'className') node.className = value;
    else node.setAttribute(key, value);
  }
  for (const child of children) {
    if (child === null || child === undefined) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

export function clear(node) {
  while (node.firstChild) node.firstChild.remove();
}

export function fmt(x) {
  return Number(x).toLocaleString(undefined, { maximumFractionDigits: 1 });
}

// A time in µs since the epoch, as the operator's local date and time.
export function when(us) {
  if (us === null || us === undefined) return '–';
  return new Date(us / 1000).toLocaleString();
}

export function ago(us) {
  if (!us) return 'never';
  const s = Math.max(0, Math.round((Date.now() * 1000 - us) / 1e6));
  if (s < 60) return `${s} s ago`;
  if (s < 3600) return `${Math.round(s / 60)} min ago`;
  if (s < 86400) return `${Math.round(s / 3600)} h ago`;
  return `${Math.round(s / 86400)} d ago`;
}

// A JSON request to the console's API: the CSRF token on every state-changing request (the
// server refuses one without it), the server's `error` text as the thrown Error's message and
// the HTTP status as its `status`.
export async function jsonCall(path, { method = 'GET', body } = {}, csrfToken = null) {
  const headers = {};
  if (method !== 'GET') {
    headers['Content-Type'] = 'application/json';
    if (csrfToken) headers['X-CSRF-Token'] = csrfToken;
  }
  const res = await fetch(path, {
    method, headers, credentials: 'same-origin',
    body: method === 'GET' ? undefined : JSON.stringify(body ?? {}),
  });
  let data = null;
  try { data = await res.json(); } catch { data = null; }
  if (!res.ok) {
    const e = new Error((data && data.error) || res.statusText);
    e.status = res.status;
    throw e;
  }
  return data;
}

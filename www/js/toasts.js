// Non-blocking notices: errors that name the file and the reason, and short confirmations.
// Each notice has a close button; confirmations fade on their own (warnings after a while),
// errors stay until dismissed (or until there are too many, the oldest go first).

const MAX = 5;

/** Rewrites of notices about to be shown (amendNext): [{ prefix, detail }]. */
const amends = [];

/**
 * The next notice whose title starts with `prefix`, shown in this task, gets `detail` instead of
 * its own (a module that changed what another one is about to announce says so; forgotten at
 * the end of the task).
 */
export function amendNext(prefix, detail) {
  const a = { prefix, detail };
  amends.push(a);
  queueMicrotask(() => amends.includes(a) && amends.splice(amends.indexOf(a), 1));
}

/** Show a notice. kind: "error" | "warning" | "info"; `detail`: text or an element. Returns the element. */
export function notify(kind, title, detail = '') {
  const k = amends.findIndex((a) => title.startsWith(a.prefix));
  if (k >= 0) detail = amends.splice(k, 1)[0].detail;
  const host = document.getElementById('toasts');
  const el = document.createElement('div');
  el.className = `toast ${kind}`;
  el.setAttribute('role', kind === 'error' ? 'alert' : 'status');
  const text = document.createElement('div');
  text.className = 'toast-text';
  const t = document.createElement('strong');
  t.textContent = title;
  text.append(t);
  if (detail instanceof Node) text.append(detail);
  else if (detail) {
    const d = document.createElement('span');
    d.textContent = detail;
    text.append(d);
  }
  const close = document.createElement('button');
  close.type = 'button';
  close.className = 'toast-close';
  close.setAttribute('aria-label', 'Dismiss');
  close.textContent = '×';
  close.addEventListener('click', () => el.remove());
  el.append(text, close);
  host.append(el);
  while (host.children.length > MAX) host.firstElementChild.remove();
  if (kind === 'info') setTimeout(() => el.remove(), 4000);
  else if (kind === 'warning') setTimeout(() => el.remove(), 15000);
  return el;
}

/** The text of a thrown value: an Error's message, anything else as a string. */
export function message(e) {
  return e instanceof Error ? e.message : String(e);
}

/** An error notice for a file: "<file>: <reason>". */
export function fileError(fileName, err) {
  const reason = message(err);
  console.warn(`facemimic: ${fileName}: ${reason}`);
  return notify('error', `Could not load ${fileName}`, reason);
}

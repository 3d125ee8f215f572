// The output view's settings (size, background: the avatar's picture or a key colour) as a small
// form, shared by the main page's "Output view" panel and the call page's pop-out menu; changes
// go to the feed (www/js/output-feed.js), which keeps them in this browser and applies them to
// the open pop-outs at once.

import { OUTPUT_PRESETS, OUTPUT_MIN, OUTPUT_MAX } from './output-feed.js';

function el(tag, { ariaLabel, ...props } = {}, ...children) {
  const e = document.createElement(tag);
  Object.assign(e, props);
  if (ariaLabel) e.setAttribute('aria-label', ariaLabel);
  e.append(...children);
  return e;
}

/** The settings form for `feed`; ids start with `prefix`. */
export function settingsForm(feed, prefix) {
  const s = feed.settings;
  const form = el('div', { className: 'output-settings' });

  const size = el('select', { id: `${prefix}-size` });
  for (const p of OUTPUT_PRESETS) size.append(el('option', { value: p.id, textContent: p.label }));
  size.value = s.preset;
  form.append(el('div', { className: 'row' }, el('label', { htmlFor: size.id, textContent: 'Size' }), size));

  const side = (what, value) =>
    el('input', { type: 'number', id: `${prefix}-${what}`, min: OUTPUT_MIN, max: OUTPUT_MAX, step: 2, value, className: 'output-side', ariaLabel: `Custom ${what} (pixels)` });
  const w = side('width', s.width);
  const h = side('height', s.height);
  const custom = el('div', { className: 'row output-custom' }, el('span', { className: 'output-pad' }), w, el('span', { className: 'muted', textContent: '×' }), h, el('span', { className: 'muted', textContent: 'px' }));
  form.append(custom);

  const bg = el('fieldset', { className: 'segmented small output-bg' }, el('legend', { className: 'visually-hidden', textContent: 'Background' }));
  for (const [value, label, title] of [
    ['picture', 'Picture', "The avatar in its own picture (the target's backdrop), filling the frame"],
    ['key', 'Key colour', 'The face alone on a solid colour, for a chroma key filter (OBS)'],
  ]) {
    const input = el('input', { type: 'radio', name: `${prefix}-bg`, value, checked: s.background === value });
    bg.append(el('label', { title }, input, el('span', { textContent: label })));
  }
  const key = el('input', { type: 'color', id: `${prefix}-key`, value: s.key, className: 'output-key' });
  const keyText = el('output', { htmlFor: key.id, textContent: s.key });
  form.append(
    el('div', { className: 'row' }, el('label', { textContent: 'Background' }), bg),
    el('div', { className: 'row output-key-row' }, el('label', { htmlFor: key.id, textContent: 'Key colour' }), key, keyText),
  );

  const sync = () => {
    const now = feed.settings;
    custom.hidden = now.preset !== 'custom';
    w.value = now.width;
    h.value = now.height;
    key.disabled = now.background !== 'key';
    keyText.textContent = now.key;
    form.dataset.background = now.background;
  };
  const set = (change) => {
    feed.setSettings(change);
    sync();
  };
  size.addEventListener('change', () => set({ preset: size.value, width: feed.settings.width, height: feed.settings.height }));
  for (const input of [w, h]) input.addEventListener('change', () => set({ preset: 'custom', width: w.value, height: h.value }));
  bg.addEventListener('change', (e) => set({ background: e.target.value }));
  key.addEventListener('input', () => set({ key: key.value }));
  sync();
  return form;
}

/** The pop-out icon (a window with an arrow out of it). */
export const POPOUT_ICON = 'M9.5 2.5h4v4M13.5 2.5 8 8M11.5 9.5v3a1 1 0 0 1-1 1h-7a1 1 0 0 1-1-1v-7a1 1 0 0 1 1-1h3';

/**
 * The call page's "Pop out" button and its settings menu, appended to `host` (the avatar's
 * caption): `open()` opens the output view (in the click), `feed` holds the settings.
 */
export function popoutMenu(host, feed, open) {
  const wrap = el('span', { className: 'output-menu' });
  const button = el('button', { type: 'button', className: 'btn small output-open', title: 'Your avatar alone in a window of its own, for OBS (then Zoom, Meet, Discord)' });
  button.innerHTML = `<svg viewBox="0 0 16 16" aria-hidden="true"><path d="${POPOUT_ICON}"/></svg><span>Pop out</span>`;
  button.addEventListener('click', open);
  const details = el('details', { className: 'output-more' });
  const summary = el('summary', { className: 'btn small', title: 'Output view settings', ariaLabel: 'Output view settings' });
  summary.innerHTML = '<svg viewBox="0 0 16 16" aria-hidden="true"><path d="M4 6l4 4 4-4"/></svg>';
  details.append(summary, el('div', { className: 'output-pop' }, settingsForm(feed, 'call-output')));
  document.addEventListener('pointerdown', (e) => {
    if (details.open && !details.contains(e.target)) details.open = false;
  });
  wrap.append(button, details);
  host.append(wrap);
  const sync = () => button.classList.toggle('on', feed.open > 0);
  feed.onChange(sync);
  return button;
}

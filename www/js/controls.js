// The control panels: the inspector, the cloning settings (method, gain, constraint, the
// expressive method's region gains and style, follow-pose, mesh, fast raster, face only), the
// compare view (one canvas per method) and its target, reset, the transport's buttons and the
// space bar, and the menus listing the models on the stage. The method radios and the compare
// view's canvases are made from the package's `methods()` (app.methods), the core's one list.

import { Inspector } from './inspector.js';
import { styleTarget } from './cards.js';
import { activate, play, syncTransport, usableTrack } from './source-control.js';
import { app, fm, $, DEFAULTS, FACE_BG, REGIONS } from './page-state.js';

/** The method that has its own settings (region gains, style) on the panel. */
const EXPRESSIVE = 'expressive';

/** The panels' controls: the inspector, the cloning settings, the compare view, the transport,
 *  the source menu, the inspector's model menu and the space bar (play and pause). */
export function buildControls() {
  buildMethods();
  app.inspector = new Inspector(fm, {
    mean: $('inspect-mean'),
    mode: $('inspect-mode'),
    caption: $('inspect-mode-caption'),
    bars: $('inspect-bars'),
    info: $('inspect-info'),
    kind: $('inspect-kind'),
    sigma: $('inspect-sigma'),
    sigmaOut: $('inspect-sigma-out'),
  }, { background: FACE_BG });
  for (const id of ['inspect-mean', 'inspect-mode']) app.hidpi.watch($(id));
  for (const v of app.compareViews) app.hidpi.watch(v.canvas);

  $('method').addEventListener('change', (e) => {
    if (e.target.name === 'method') setMethod(e.target.value);
  });
  $('gain').addEventListener('input', () => setGain(Number($('gain').value)));
  for (const r of REGIONS) $(`gain-${r}`).addEventListener('input', () => setExpressive({ [r]: Number($(`gain-${r}`).value) }));
  $('style').addEventListener('input', () => setExpressive({ style: Number($('style').value) }));
  $('clamp').addEventListener('change', applyClamp);
  $('clamp-k').addEventListener('input', applyClamp);
  $('follow-pose').addEventListener('change', () => {
    app.settings.followPose = $('follow-pose').checked;
    app.cloner.setFollowPose(app.settings.followPose);
    app.dirty = true;
  });
  $('keep-whole').addEventListener('change', () => {
    app.settings.keepWhole = $('keep-whole').checked;
    app.dirty = true;
  });
  $('mesh').addEventListener('change', () => {
    app.settings.mesh = $('mesh').checked;
    app.dirty = true;
  });
  $('fast-raster').addEventListener('change', () => {
    app.settings.fast = $('fast-raster').checked;
    app.dirty = true;
  });
  $('face-only').addEventListener('change', () => setFaceOnly($('face-only').checked));
  $('compare-on').addEventListener('change', () => {
    $('compare').hidden = !$('compare-on').checked;
    app.dirty = true;
  });
  $('compare-target').addEventListener('change', () => {
    app.compareIndex = Number($('compare-target').value);
    app.dirty = true;
  });
  $('reset').addEventListener('click', reset);

  $('play').addEventListener('click', () => play(!(app.active === app.track && app.track.playing)));
  $('scrub').addEventListener('input', () => {
    if (!usableTrack()) return;
    if (app.active !== app.track) activate('track');
    app.track.pause();
    app.track.seek(Number($('scrub').value));
    app.dirty = true;
    syncTransport();
  });
  $('source-kind').addEventListener('change', () => {
    const kind = $('source-kind').value;
    activate(kind);
    if (kind === 'track') play(true);
  });

  $('inspect-model').addEventListener('change', () => {
    const v = $('inspect-model').value;
    if (v === 'source') app.inspector.show(app.source.model, app.source.info, 'source');
    else {
      const t = app.targets[Number(v)];
      if (t) app.inspector.show(t.model, t.info, 'target');
    }
  });

  document.addEventListener('keydown', (e) => {
    if (e.key !== ' ' && e.code !== 'Space') return;
    if (e.defaultPrevented || e.altKey || e.ctrlKey || e.metaKey) return;
    const t = e.target;
    // Space already means something on buttons, check boxes, menus and text fields.
    if (t instanceof HTMLElement) {
      const tag = t.tagName;
      const type = t.getAttribute('type');
      if (tag === 'BUTTON' || tag === 'SELECT' || tag === 'TEXTAREA' || tag === 'SUMMARY' || tag === 'A') return;
      if (tag === 'INPUT' && type !== 'range') return;
      if (t.isContentEditable) return;
    }
    if (!usableTrack()) return;
    e.preventDefault();
    play(!(app.active === app.track && app.track.playing));
  });

  applySettingsToCloner();
  syncControls();
}

/** The method radios and the compare view's canvases, one per method of the package's list. */
function buildMethods() {
  const radios = app.methods.map((m) => {
    const label = document.createElement('label');
    label.title = m.description;
    const input = document.createElement('input');
    Object.assign(input, { type: 'radio', name: 'method', value: m.name });
    const span = document.createElement('span');
    span.textContent = m.label;
    label.append(input, span);
    return label;
  });
  $('method').append(...radios);
  const grid = $('compare-grid');
  grid.style.setProperty('--n', String(app.methods.length));
  app.compareViews = app.methods.map((m) => {
    const fig = document.createElement('figure');
    fig.className = 'card';
    fig.title = `${m.label}: ${m.description}`;
    const canvas = document.createElement('canvas');
    canvas.id = `cmp-${m.name}`;
    canvas.className = 'face';
    canvas.setAttribute('aria-label', m.label);
    const cap = document.createElement('figcaption');
    const b = document.createElement('b');
    b.textContent = m.label;
    const span = document.createElement('span');
    span.textContent = m.description;
    cap.append(b, span);
    fig.append(canvas, cap);
    grid.append(fig);
    return { method: m.name, canvas };
  });
}

/** Targets as the face alone (the paper's view) or composited into their pictures. */
function setFaceOnly(on) {
  app.settings.faceOnly = on;
  for (const t of app.targets) styleTarget(t);
  app.dirty = true;
}

/** The cloning method (one of the package's methods). */
function setMethod(m) {
  if (!app.methods.some((x) => x.name === m)) return;
  app.settings.method = m;
  app.cloner.setMethod(m);
  showMethod();
  app.dirty = true;
}

/** The method's description under the radios; the expressive settings shown with that method. */
function showMethod() {
  const m = app.methods.find((x) => x.name === app.settings.method);
  $('method-note').textContent = m ? `${m.label}: ${m.description}.` : '';
  $('expressive-settings').hidden = app.settings.method !== EXPRESSIVE;
}

/** The expressive method's region gains and style (they also drive the compare view's column). */
function setExpressive(patch) {
  Object.assign(app.settings, patch);
  applyExpressive();
  syncExpressive();
  app.dirty = true;
}

function applyExpressive() {
  const s = app.settings;
  app.cloner.setRegionGains(s.mouth, s.eyes, s.brows);
  app.cloner.setStyle(s.style);
}

function syncExpressive() {
  const s = app.settings;
  for (const r of REGIONS) {
    $(`gain-${r}`).value = String(s[r]);
    $(`gain-${r}-out`).value = s[r].toFixed(2);
  }
  $('style').value = String(s.style);
  $('style-out').value = s.style.toFixed(2);
}

/** The cloning gain. */
function setGain(g) {
  app.settings.gain = g;
  $('gain-out').value = g.toFixed(2);
  app.cloner.setGain(g);
  app.dirty = true;
}

/** The constraint (+-k sigma, or none) from its controls. */
function applyClamp() {
  app.settings.clamp = $('clamp').checked;
  app.settings.k = Number($('clamp-k').value);
  $('clamp-k').disabled = !app.settings.clamp;
  $('clamp-out').value = `±${app.settings.k.toFixed(1)}σ`;
  app.cloner.setClamp(app.settings.clamp ? app.settings.k : null);
  app.dirty = true;
}

/** Every setting into the cloner. */
function applySettingsToCloner() {
  const s = app.settings;
  app.cloner.setMethod(s.method);
  app.cloner.setGain(s.gain);
  app.cloner.setClamp(s.clamp ? s.k : null);
  app.cloner.setFollowPose(s.followPose);
  applyExpressive();
}

/** The controls show the settings. */
function syncControls() {
  const s = app.settings;
  for (const r of document.querySelectorAll('input[name="method"]')) r.checked = r.value === s.method;
  $('gain').value = String(s.gain);
  $('gain-out').value = s.gain.toFixed(2);
  $('clamp').checked = s.clamp;
  $('clamp-k').value = String(s.k);
  $('clamp-k').disabled = !s.clamp;
  $('clamp-out').value = `±${s.k.toFixed(1)}σ`;
  $('follow-pose').checked = s.followPose;
  $('keep-whole').checked = s.keepWhole !== false;
  $('mesh').checked = s.mesh;
  $('fast-raster').checked = s.fast;
  $('face-only').checked = s.faceOnly;
  syncExpressive();
  showMethod();
}

/** The settings back to their defaults, the source to its reference face. */
function reset() {
  app.settings = { ...DEFAULTS };
  applySettingsToCloner();
  syncControls();
  setFaceOnly(app.settings.faceOnly);
  // The source back to its reference face: sliders at zero, mean pose.
  if (app.track) app.track.pause();
  app.params = app.source.model.baseParams();
  app.sliders = null;
  activate('sliders', { fresh: true });
  app.dirty = true;
}

/** The inspector's and the compare view's menus, from the models on the stage. */
export function refreshModelLists() {
  // Inspector menu.
  const ins = $('inspect-model');
  const opts = [['source', `Source · ${app.source.name}`], ...app.targets.map((t, i) => [String(i), `Target ${i + 1} · ${t.name}`])];
  ins.replaceChildren(...opts.map(([v, l]) => option(v, l)));
  const current = app.inspector?.model;
  const idx = app.targets.findIndex((t) => t.model === current);
  ins.value = idx >= 0 ? String(idx) : 'source';
  // Compare menu.
  const cmp = $('compare-target');
  cmp.replaceChildren(...app.targets.map((t, i) => option(String(i), t.name)));
  if (app.compareIndex >= app.targets.length) app.compareIndex = 0;
  cmp.value = String(app.compareIndex);
  cmp.disabled = app.targets.length === 0;
  $('compare-on').disabled = app.targets.length === 0;
  if (app.targets.length === 0) {
    $('compare-on').checked = false;
    $('compare').hidden = true;
  }
  document.body.dataset.targets = String(app.targets.length);
}

/** An `<option>` of a menu. */
function option(value, label) {
  const o = document.createElement('option');
  o.value = value;
  o.textContent = label;
  return o;
}

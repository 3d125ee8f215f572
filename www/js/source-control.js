// The page's sources, as the page drives them: the active source (the recorded track, the
// sliders, or a live source from tracking.js), the source menu, the track's transport (play,
// scrub, frame counter), and the sliders (one per source mode, in sigma units, labelled with the
// mode's share of the variance) that show whatever drives the source.

import { availableSources, createSource } from './sources.js';
import { pct } from './inspector.js';
import { app, fm, $ } from './page-state.js';

/** What the page offers every source (see js/sources.js). */
const sourceCtx = {
  wasm: fm,
  sourceModel: () => app.source.model,
  sourceInfo: () => app.source.info,
  // A bundled source model is not the person's own: live sources follow landmarks with it.
  sourceIsOwn: () => !app.source.bundled,
  createFace: () => app.enrol?.open(),
  currentParams: () => app.params ?? app.source.model.baseParams(),
  invalidate: () => {
    app.dirty = true;
  },
};

/** The recorded track, when it belongs to the current source model (else null). */
export function usableTrack() {
  return app.track && app.source?.bytesKey === app.trackKey ? app.track : null;
}

/** Make a source kind active. `fresh`: build a new instance even if one exists. */
export function activate(kind, { fresh = false } = {}) {
  let src;
  if (kind === 'track') src = usableTrack();
  else if (kind === 'sliders') {
    if (!app.sliders || fresh || app.active !== app.sliders) app.sliders = createSource('sliders', sourceCtx);
    src = app.sliders;
  } else src = createSource(kind, sourceCtx);
  if (!src) return;
  if (app.active && app.active !== src) app.active.stop();
  app.active = src;
  src.start();
  app.dirty = true;
  syncSourceMenu();
  syncTransport();
}

function syncSourceMenu() {
  const sel = $('source-kind');
  const kinds = availableSources(fm);
  const current = [...sel.options].map((o) => o.value).join();
  if (current !== kinds.map((k) => k.kind).join()) {
    sel.replaceChildren(
      ...kinds.map(({ kind, label }) => {
        const o = document.createElement('option');
        o.value = kind;
        o.textContent = label;
        return o;
      }),
    );
  }
  sel.value = app.active?.kind ?? '';
  sel.title = app.active === app.track && app.track.description ? app.track.description : '';
}

export function play(on) {
  if (!usableTrack()) return;
  if (on) {
    if (app.active !== app.track) activate('track');
    app.track.play();
  } else app.track.pause();
  app.dirty = true;
  syncTransport();
}

export function syncTransport() {
  const t = usableTrack();
  const btn = $('play');
  const playing = !!t && app.active === t && t.playing;
  btn.disabled = !t;
  btn.dataset.state = playing ? 'playing' : 'paused';
  btn.querySelector('.label').textContent = playing ? 'Pause' : 'Play';
  btn.classList.toggle('playing', playing);
  const scrub = $('scrub');
  scrub.disabled = !t;
  if (t) {
    scrub.max = String(t.frameCount - 1);
    if (document.activeElement !== scrub || playing) scrub.value = String(t.frame);
    $('frame-counter').value = `${t.frame + 1} / ${t.frameCount}`;
  } else $('frame-counter').value = '– / –';
  document.body.classList.toggle('on-track', !!t && app.active === t);
}

// Sliders: one per source mode, in sigma units, labelled with the mode's share of the variance.
const sliderEls = { shape: [], appearance: [] };

export function buildSliders() {
  const info = app.source.info;
  for (const [kind, host, count, sigma, share] of [
    ['shape', $('shape-sliders'), info.shapeModes, info.shapeSigma, info.shapeVarianceShare],
    ['appearance', $('app-sliders'), info.appearanceModes, info.appearanceSigma, info.appearanceVarianceShare],
  ]) {
    host.replaceChildren();
    sliderEls[kind] = [];
    for (let i = 0; i < count; i++) {
      const id = `p-${kind}-${i}`;
      const row = document.createElement('div');
      row.className = 'param';
      const label = document.createElement('label');
      label.htmlFor = id;
      label.innerHTML = `<span class="mode">${kind === 'shape' ? 'S' : 'A'}${i + 1}</span><span class="share">${pct(share[i])}</span>`;
      label.title = `${kind === 'shape' ? 'Shape' : 'Appearance'} mode ${i + 1}: ${pct(share[i])} of the variance, σ = ${fmt(sigma[i])}`;
      const input = document.createElement('input');
      input.type = 'range';
      input.id = id;
      input.min = '-3';
      input.max = '3';
      input.step = '0.01';
      input.value = '0';
      input.setAttribute('aria-label', `${kind === 'shape' ? 'Shape' : 'Appearance'} mode ${i + 1} (${pct(share[i])} of the variance), in standard deviations`);
      const out = document.createElement('output');
      out.htmlFor = id;
      out.value = '0.00σ';
      input.addEventListener('input', () => {
        const v = Number(input.value);
        out.value = `${v >= 0 ? '+' : ''}${v.toFixed(2)}σ`;
        if (app.active !== app.sliders) activate('sliders');
        app.sliders.set(kind, i, v * sigma[i]);
        app.dirty = true;
      });
      input.addEventListener('dblclick', () => {
        input.value = '0';
        input.dispatchEvent(new Event('input'));
      });
      row.append(label, input, out);
      host.append(row);
      sliderEls[kind].push({ input, out, sigma: sigma[i] });
    }
  }
  $('shape-count').textContent = `(${info.shapeModes} modes)`;
  $('app-count').textContent = `(${info.appearanceModes} modes)`;
}

/** Show the current source params on the sliders (skipping the one being dragged). */
export function syncSliders(p) {
  for (const kind of ['shape', 'appearance']) {
    const els = sliderEls[kind];
    const vals = p[kind];
    for (let i = 0; i < els.length; i++) {
      const { input, out, sigma } = els[i];
      if (document.activeElement === input && app.active === app.sliders) continue;
      const v = sigma > 0 ? vals[i] / sigma : 0;
      const clamped = Math.max(-3, Math.min(3, v));
      const str = clamped.toFixed(2);
      if (input.value !== str) input.value = str;
      const o = `${v >= 0 ? '+' : ''}${v.toFixed(2)}σ`;
      if (out.value !== o) out.value = o;
    }
  }
}

/** A number in three significant digits (whole above 100), or a dash. */
function fmt(x) {
  return Number.isFinite(x) ? (Math.abs(x) >= 100 ? x.toFixed(0) : x.toPrecision(3)) : '–';
}

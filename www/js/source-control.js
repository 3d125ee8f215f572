// The page's sources, as the page drives them: the active source (the recorded track, the
// sliders, or a live source from tracking.js), the source menu, the transport (play, scrub,
// counter: the track's, or the video's of a video source; none for the webcam or the sliders),
// and the sliders (one per source mode, in sigma units, labelled with the mode's share of the
// variance) that show whatever drives the source.

import { availableSources, createSource } from './sources.js';
import { pct } from './inspector.js';
import { amendNext } from './toasts.js';
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
  // A video source's transport changed (played, paused, moved on, seeked), or it let go of the
  // source it held.
  transportChanged: (src) => {
    if (app.active !== src) return;
    syncSourceMenu();
    syncTransport();
  },
  // A source that held the one before it (a dropped file that cannot be played) gives its place back.
  handBack: (from, to) => {
    if (app.active !== from) return;
    app.active = to;
    from.stop();
    app.dirty = true;
    syncSourceMenu();
    syncTransport();
  },
};

/** The recorded track, when it belongs to the current source model (else null). */
export function usableTrack() {
  return app.track && app.source?.bytesKey === app.trackKey ? app.track : null;
}

/**
 * Make a source kind active. `fresh`: build a new instance even if one exists (and the source
 * model may have changed).
 */
export function activate(kind, { fresh = false } = {}) {
  const old = app.active;
  // A live source (the webcam, a video file) outlives a change of the source model (a face made
  // in "Create a face", one of Your models, a model dropped on the source): it is made again for
  // the new model on the same camera picture or file, and the core's policy picks its tracker
  // (the AAM for the person's own model), instead of handing the source to the sliders.
  const keep = fresh && old?.keepsAcross?.(app.source.model);
  if (keep) kind = old.kind;
  let src;
  if (kind === 'track') src = usableTrack();
  else if (kind === 'sliders') {
    if (!app.sliders || fresh || app.active !== app.sliders) app.sliders = createSource('sliders', sourceCtx);
    src = app.sliders;
  } else src = createSource(kind, sourceCtx);
  if (!src) return;
  // A source may hold the one before it for a moment (a dropped video: tracking-flow.js).
  if (old && old !== src && !src.takeOver?.(old)) old.stop();
  app.active = src;
  src.start();
  if (keep) {
    const how = src.path === 'aam' ? "now fitted with this model's AAM" : 'following the face by its landmarks';
    amendNext('Source is now', `The ${old.label.toLowerCase()} goes on driving it, ${how}.`);
  }
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
  const shown = showing();
  if (sel.value !== (shown?.kind ?? '')) sel.value = shown?.kind ?? '';
  sel.title = shown === app.track && app.track.description ? app.track.description : '';
}

/** Plays or pauses the recorded track (making it the source); the video's are wired below. */
export function play(on) {
  if (!usableTrack()) return;
  if (on) {
    if (app.active !== app.track) activate('track');
    app.track.play();
  } else app.track.pause();
  app.dirty = true;
  syncTransport();
}

/**
 * The source the menu and the transport show: the active one, or while it holds the one before
 * it (a dropped video being tried: js/tracking-flow.js), that one, which still drives the face.
 */
function showing() {
  return app.active?.previous ?? app.active;
}

/** The shown video source's transport (`{ playing, time, duration, toggle(), seek(s) }`), or null. */
function videoTransport() {
  const a = showing();
  return a && a !== usableTrack() && typeof a.transport === 'function' ? a.transport() : null;
}

/** What the transport bar says when nothing of a track or a video drives the source. */
function transportNote(src) {
  if (!src) return '';
  if (src.kind === 'webcam') return 'Live from the webcam';
  if (src.kind === 'sliders') return 'Set by the sliders (Source parameters)';
  if (src.kind === 'video-file') return src.media?.still ? 'A photo: nothing to play' : src.haveFrame ? '' : 'Drop a video or a photo below';
  return '';
}

/** Seconds as m:ss.s. */
function clock(s) {
  const t = Math.max(0, s);
  return `${Math.floor(t / 60)}:${(t % 60).toFixed(1).padStart(4, '0')}`;
}

/**
 * The transport shows what drives the source: the recorded track's (Play, the scrubber over its
 * frames, "12 / 75"), a video's (the bundled clip's or a file's: Play / Pause, the scrubber over
 * its time, "0:01.2 / 0:03.0"), or, for the webcam and the sliders, none (a line says what
 * drives it instead).
 */
export function syncTransport() {
  wireTransport();
  const t = usableTrack();
  const onTrack = !!t && showing() === t;
  const v = onTrack ? null : videoTransport();
  const what = onTrack ? 'track' : v ? 'video' : 'none';
  const btn = $('play');
  const scrub = $('scrub');
  const counter = $('frame-counter');
  btn.closest('.transport').dataset.transport = what;
  for (const e of [btn, scrub.closest('.scrub'), counter]) e.hidden = what === 'none';
  const playing = onTrack ? t.playing : Boolean(v?.playing);
  btn.disabled = what === 'none';
  btn.dataset.state = playing ? 'playing' : 'paused';
  btn.querySelector('.label').textContent = playing ? 'Pause' : 'Play';
  btn.classList.toggle('playing', playing);
  btn.title = what === 'video' ? 'Play / pause the video (space)' : 'Play / pause the recorded track (space)';
  scrub.disabled = what === 'none' || (what === 'video' && v.duration === null);
  const still = document.activeElement === scrub && !playing; // being dragged
  if (onTrack) {
    scrub.step = '1';
    scrub.max = String(t.frameCount - 1);
    if (!still) scrub.value = String(t.frame);
    counter.value = `${t.frame + 1} / ${t.frameCount}`;
  } else if (v) {
    scrub.step = 'any';
    scrub.max = String(v.duration ?? 0);
    if (!still) scrub.value = String(v.time);
    counter.value = `${clock(v.time)} / ${v.duration === null ? '–' : clock(v.duration)}`;
  } else counter.value = '– / –';
  scrub.previousElementSibling.textContent = what === 'video' ? 'Video position' : 'Track position';
  const note = $('transport-note');
  const says = what === 'none' ? transportNote(showing()) : '';
  if (note.textContent !== says) note.textContent = says;
  note.hidden = !says;
  note.dataset.kind = showing()?.kind ?? '';
  document.body.classList.toggle('on-track', onTrack);
}

let wired = false;

/**
 * The transport bar's own listeners (once): its note, and, with a video as the source, Play and
 * the scrubber driving the video. They listen in the capture phase, so they come before the
 * track's listeners on the button and the scrubber themselves (js/controls.js), which then never
 * see an event meant for the video.
 */
function wireTransport() {
  if (wired) return;
  wired = true;
  const bar = $('play').closest('.transport');
  const note = document.createElement('span');
  note.id = 'transport-note';
  note.className = 'transport-note';
  note.hidden = true;
  bar.append(note);
  bar.addEventListener('click', (e) => {
    const v = e.target instanceof Element && e.target.closest('#play') ? videoTransport() : null;
    if (!v) return;
    e.stopPropagation();
    v.toggle();
    syncTransport();
  }, true);
  bar.addEventListener('input', (e) => {
    const v = e.target === $('scrub') ? videoTransport() : null;
    if (!v) return;
    e.stopPropagation();
    v.seek(Number(e.target.value));
    syncTransport();
  }, true);
  // Space is the video's Play too (where it means nothing else), as the button says.
  window.addEventListener('keydown', (e) => {
    if ((e.key !== ' ' && e.code !== 'Space') || e.defaultPrevented || e.altKey || e.ctrlKey || e.metaKey) return;
    const el = e.target instanceof HTMLElement ? e.target : null;
    if (el && (['BUTTON', 'SELECT', 'TEXTAREA', 'SUMMARY', 'A'].includes(el.tagName) || el.isContentEditable)) return;
    if (el?.tagName === 'INPUT' && el.getAttribute('type') !== 'range') return;
    const v = videoTransport();
    if (!v) return;
    e.preventDefault();
    v.toggle();
    syncTransport();
  }, true);
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

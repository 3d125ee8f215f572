// The main page's output views (www/js/output-feed.js): the "Output view" panel (the settings,
// an avatar to pop out and its button), each target card's pop-out button, and the feed the
// frame loop calls after each frame (app.js `render`).
//
// Output mode, for a browser source (OBS): `index.html?output=NAME` shows nothing but the
// output view of the target NAME (the first with `?output`), filling the page; `size=WxH`
// (e.g. 1280x720), `background=key` with `key=RRGGBB` (default 00ff00), `source=webcam` (or
// another of the source menu's kinds) set it up for this page only.

import { OutputFeed, headAnchor, copyContain, normaliseSettings, OUTPUT_PRESETS } from './output-feed.js';
import { outputView, outputRoot } from './output-view.js';
import { settingsForm } from './output-controls.js';
import { notify } from './toasts.js';
import { play } from './source-control.js';
import { app, $, FACE_BG } from './page-state.js';

/** The feed, the panel, and the list of avatars. */
export function wireOutput() {
  app.outputs = new OutputFeed({
    page: 'page',
    raster: () => (app.settings.fast ? 'scanline' : 'tiny-skia'),
    wake: () => {
      app.dirty = true;
    },
  });
  $('output-settings').append(settingsForm(app.outputs, 'output'));
  $('output-open').addEventListener('click', () => openOutput(app.targets[Number($('output-target').value)]));
  app.outputs.onChange(showOpen);
  refreshOutputTargets();
  if (query.has('output')) startOutputMode();
}

const query = new URLSearchParams(location.search);
/** Output mode: `{ want, view, attached }`. */
let inPage = null;

function startOutputMode() {
  document.documentElement.classList.add('fm-output-mode');
  document.body.classList.add('fm-output-mode');
  const size = /^(\d+)x(\d+)$/i.exec(query.get('size') || '');
  const id = size ? `${Number(size[1])}x${Number(size[2])}` : '1280x720';
  const key = /^#?([0-9a-f]{6})$/i.exec(query.get('key') || '');
  // For this page only (not kept): the settings of the pop-outs stay as they were.
  app.outputs.settings = normaliseSettings({
    preset: OUTPUT_PRESETS.some((p) => p.id === id) ? id : 'custom',
    width: size?.[1],
    height: size?.[2],
    background: query.get('background') === 'key' || key ? 'key' : 'picture',
    key: key ? `#${key[1]}` : undefined,
  });
  inPage = { want: query.get('output'), view: outputView(outputRoot(document)), attached: false };
  window.facemimicOutput = inPage.view; // for the tests, as in a pop-out
}

/** At the first frame (the default targets are on the stage): the output mode's avatar. */
function attachInPage() {
  inPage.attached = true;
  const want = inPage.want;
  const entry = want ? app.targets.find((t) => t.name === want || t.file === want || t.file === `${want}.fmm`) : app.targets[0];
  if (!entry) {
    const names = app.targets.map((t) => t.name).join(', ') || 'none';
    inPage.view.notice(`No avatar named ${want}`, [`The avatars on this page: ${names}. Name one in the address: ?output=NAME.`]);
    return;
  }
  app.outputs.attach(entry, () => outputSource(entry), inPage.view);
  const kind = query.get('source');
  const sel = $('source-kind');
  if (kind && kind !== sel.value && [...sel.options].some((o) => o.value === kind)) {
    sel.value = kind;
    sel.dispatchEvent(new Event('change'));
  } else if (!kind || kind === 'track') play(true); // moving, even where motion is reduced: it was asked for
}

/** What an output view of target `entry` draws, as of now (null once it left the stage). */
function outputSource(entry) {
  const index = app.targets.indexOf(entry);
  if (index < 0) return null;
  return {
    name: entry.name,
    picture: entry.info.backdrop,
    render: (ctx, options) => app.cloner.renderTarget(index, ctx, options),
    anchor: () => headAnchor(app.cloner.targetLandmarks(index), entry.info.imageWidth, entry.info.imageHeight),
  };
}

/** Opens the output view of a target (in a click: it is a pop-up window). */
export function openOutput(entry) {
  if (!entry || !app.outputs) return;
  const win = app.outputs.openFor(entry, () => outputSource(entry));
  if (!win) notify('error', 'The output view did not open', 'the browser blocked its window: allow pop-ups for this page, then press Pop out again');
}

/** Targets drawn into their output's canvas this frame: entry -> that canvas. */
const drawnFor = new Map();

/**
 * The canvas the frame should draw target `entry` into, with its options, when an output view
 * shows it in its picture and its card shows it composited too (`targetOpts`: the card's
 * options): `{ canvas, options }`, or null for its card's own canvas.
 */
export function outputCanvas(entry, targetOpts) {
  drawnFor.delete(entry);
  if (!app.outputs?.open || !targetOpts.composite || targetOpts.mesh || !entry.info.backdrop) return null;
  const out = app.outputs.canvasFor(entry);
  if (out) drawnFor.set(entry, out.canvas);
  return out;
}

/** After each frame the page draws: the open output views get it, and the cards drawn into an
 *  output's canvas a copy. */
export function feedOutputs() {
  if (inPage && !inPage.attached) attachInPage();
  for (const [entry, canvas] of drawnFor) copyContain(entry.canvas, canvas, FACE_BG);
  app.outputs?.feed();
}

/** The panel's list of avatars, after the targets changed. */
export function refreshOutputTargets() {
  const sel = $('output-target');
  if (!sel || !app.outputs) return;
  const was = app.targets[Number(sel.value)];
  sel.replaceChildren(
    ...app.targets.map((t, i) => {
      const o = document.createElement('option');
      o.value = String(i);
      o.textContent = t.name;
      return o;
    }),
  );
  const keep = app.targets.indexOf(was);
  sel.value = String(keep >= 0 ? keep : 0);
  sel.disabled = $('output-open').disabled = app.targets.length === 0;
  showOpen();
}

/** Marks the cards whose avatar has an open output view. */
function showOpen() {
  const open = new Set(app.outputs.outputs.map((o) => o.key));
  for (const t of app.targets) {
    const b = t.card.querySelector('[data-action="popout"]');
    b?.classList.toggle('on', open.has(t));
    b?.setAttribute('aria-pressed', String(open.has(t)));
  }
}

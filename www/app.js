// facemimic demo page: one source face (spk07) drives every target face live.
//
// Data flow per animation frame: active source -> Params (cloner.setSourceParams, or for a
// tracked source cloner.sourceFromTracker: the parameters stay in wasm) -> cloner.drawFrame():
// map + synthesise every target, then draw the source, every target and, when open, the compare
// view (one target with every method of the package's methods()) into the canvases registered
// with the cloner (at device-pixel size).
// Nothing is rendered when nothing changed (paused and idle), except the inspector's animation
// (the Inspector panel's, or while "Create a face" is open, its preview's).

import init from './pkg/facemimic.js';
import { HiDpi, ctx2d } from './js/canvas.js';
import { notify, fileError, message } from './js/toasts.js';
import { fetchBytes, fetchJson } from './js/fetch.js';
import { registerSource, validateTrack, recentreTrack, TrackSource, SliderSource } from './js/sources.js';
import { ModelShelf } from './js/store.js';
import { Enrolment } from './js/enrol.js';
import './js/tracking.js'; // registers the video and webcam sources (when the package can track)
import { app, fm, $, bytesKey, loadMethods, FACE_BG, MODELS } from './js/page-state.js';
import { buildStage, wireTargetInputs, buildLibrary, addTargetFromBytes, setSourceFromBytes } from './js/targets.js';
import { buildControls, refreshModelLists } from './js/controls.js';
import { activate, buildSliders, play, syncSliders, syncTransport, usableTrack } from './js/source-control.js';
import { wireCapture, renderOptions, recordFrame } from './js/capture.js';
import { wireOutput, feedOutputs, outputCanvas } from './js/output-page.js';

// ---------------------------------------------------------------------------------------------
// Start-up

async function main() {
  try {
    await init();
  } catch (e) {
    fatal(
      'The WebAssembly package could not be loaded.',
      `Build it with scripts/build-wasm.sh (or run scripts/demo.sh). Details: ${message(e)}`,
    );
    return;
  }
  $('version').textContent = typeof fm.version === 'function' ? `facemimic ${fm.version()}` : '';
  try {
    loadMethods(); // the cloning methods and the default one, from the core's list
  } catch (e) {
    fatal('The cloning methods could not be read from the WebAssembly package.', `Build it again with scripts/build-wasm.sh. Details: ${message(e)}`);
    return;
  }

  app.hidpi = new HiDpi(() => {
    app.dirty = true;
    app.inspector?.invalidate();
    app.enrol?.preview.invalidate();
  });
  app.inspectorVisible = () => app.hidpi.visible($('inspect-mode')) || app.hidpi.visible($('inspect-mean'));

  // The built-in sources. The tracking work adds 'video' and 'webcam' the same way, from its
  // own module, with `available: (wasm) => typeof wasm.Tracker === 'function'`, so the menu
  // offers them only with a package that can track.
  registerSource('track', {
    label: 'Recorded track',
    available: () => usableTrack() !== null,
    create: () => usableTrack(),
  });
  registerSource('sliders', {
    label: 'Sliders',
    create: () => new SliderSource(app.params ?? app.source.model.baseParams()),
  });

  let manifest;
  try {
    manifest = await fetchJson(`${MODELS}manifest.json`);
  } catch (e) {
    fatal('The default models are missing.', `Build them with scripts/build-models.sh. Details: ${message(e)}`);
    return;
  }
  app.manifest = manifest;

  // Source model (required) and the track that goes with it.
  try {
    const bytes = await fetchBytes(MODELS + manifest.source);
    const model = fm.Model.fromBytes(bytes);
    app.cloner = new fm.Cloner(model);
    app.source = { name: model.name, file: manifest.source, model, info: model.info(), bundled: true };
    app.trackKey = bytesKey(bytes);
    app.source.bytesKey = app.trackKey;
  } catch (e) {
    fatal(`The source model ${manifest.source} could not be loaded.`, message(e));
    return;
  }
  if (manifest.track) {
    const t = typeof manifest.track === 'string' ? { file: manifest.track, fps: 25 } : manifest.track;
    try {
      const raw = validateTrack(await fetchJson(MODELS + t.file), app.source.model);
      const frames = recentreTrack(raw, app.source.model.baseParams().pose);
      app.track = new TrackSource(frames, t.fps || 25, 'Recorded track');
      app.track.description = t.description || '';
    } catch (e) {
      fileError(t.file, e);
    }
  }

  buildStage();
  buildControls();
  wireTargetInputs();
  wireCapture();
  wireOutput(); // the output views: one avatar alone in a pop-out window (js/output-page.js)
  // Models kept in this browser (www/js/store.js).
  app.shelf = new ModelShelf($('shelf'), {
    fm,
    notify,
    useAsSource: (bytes, name) => setSourceFromBytes(bytes, name),
    addAsTarget: (bytes, name) => addTargetFromBytes(bytes, name),
  });
  // "Create a face" (www/js/enrol.js).
  app.enrol = new Enrolment({
    ...app.shelf.page,
    shelf: app.shelf,
    inspect: (model, info, name) => app.inspector.show(model, info, name),
    hidpi: app.hidpi,
    faceOptions: { background: FACE_BG },
  });
  $('create-face').addEventListener('click', () => app.enrol.open());

  // Default targets, in parallel; a bad one is reported and skipped.
  const loaded = await Promise.all(
    (manifest.targets || []).map(async (file) => {
      try {
        return { file, bytes: await fetchBytes(MODELS + file) };
      } catch (e) {
        fileError(file, e);
        return null;
      }
    }),
  );
  for (const item of loaded) if (item) addTargetFromBytes(item.bytes, item.file);

  buildLibrary();
  buildSliders();
  refreshModelLists();
  app.inspector.show(app.source.model, app.source.info, 'source');

  activate(app.track ? 'track' : 'sliders');
  if (app.track && !matchMedia('(prefers-reduced-motion: reduce)').matches) play(true);

  $('loading').hidden = true;
  $('faces').hidden = false;
  requestAnimationFrame(frame);
}

function fatal(title, detail) {
  const el = $('loading');
  el.classList.add('fatal');
  el.replaceChildren();
  const h = document.createElement('strong');
  h.textContent = title;
  const p = document.createElement('p');
  p.textContent = detail;
  el.append(h, p);
  document.body.dataset.state = 'error';
}


// ---------------------------------------------------------------------------------------------
// The frame loop

let loopError = null;

function frame(now) {
  requestAnimationFrame(frame);
  const t = now / 1000;
  const playing = app.active === app.track && app.track?.playing;
  if (playing || app.dirty || app.recorder) {
    try {
      render(t);
      loopError = null;
    } catch (e) {
      // Report a failure once (not 60 times a second) and stop playback so the page stays usable.
      const msg = message(e);
      if (msg !== loopError) notify('error', 'Rendering failed', msg);
      loopError = msg;
      if (app.track) app.track.pause();
      syncTransport();
    }
    app.dirty = false;
  }
  // While "Create a face" is open (modal), its preview animates and the Inspector panel behind
  // the backdrop rests; closed, the preview does no work at all.
  if (app.enrol?.dialog.open) app.enrol.tick(t);
  else if (app.inspector && app.inspectorVisible()) app.inspector.tick(t);
  readouts(now);
}

// The canvases the cloner draws every frame, registered with it once (and again when a canvas,
// a drawing option or the compare view changes): a frame is then one drawFrame call.
const registered = { cloner: null, key: '', canvases: [] };

/** Registers the faces' canvases with the cloner when they changed; returns them in drawFrame's
 *  order (source, targets, compare views) with how many are compare views. */
function registerCanvases(c, opts, targetOpts) {
  const compareOn = !$('compare').hidden && app.targets.length > 0;
  const ci = compareOn ? Math.min(app.compareIndex, app.targets.length - 1) : null;
  const compare = compareOn ? app.compareViews : [];
  // A target whose output view shows it in its picture is drawn into the output's canvas (one
  // composite a frame, not two; its card gets a copy: js/output-page.js).
  const outputs = app.targets.map((e) => outputCanvas(e, targetOpts));
  const canvases = [app.source.canvas, ...app.targets.map((e, i) => outputs[i]?.canvas ?? e.canvas), ...compare.map((v) => v.canvas)];
  const key = [opts.background, opts.raster, opts.mesh, targetOpts.composite, targetOpts.keepWhole, ci, ...compare.map((v) => v.method)].join('|');
  const same =
    registered.cloner === c &&
    registered.key === key &&
    canvases.length === registered.canvases.length &&
    canvases.every((x, k) => x === registered.canvases[k]);
  if (!same) {
    c.setSourceCanvas(ctx2d(app.source.canvas), opts);
    app.targets.forEach((e, i) => c.setTargetCanvas(i, ctx2d(canvases[1 + i]), outputs[i]?.options ?? targetOpts));
    for (const { method, canvas } of app.compareViews) c.setCompareCanvas(method, compareOn ? ctx2d(canvas) : null, opts);
    c.setCompareTarget(ci);
    Object.assign(registered, { cloner: c, key, canvases });
  }
  return { canvases, compared: compare.length, ci };
}

function render(t) {
  const t0 = performance.now();
  const p = app.active.paramsAt(t);
  app.params = p;
  const c = app.cloner;
  // A tracked source's parameters stay in wasm: the cloner reads the tracker's last good fit
  // (the same parameters as `p`) and, from a follower, the face it observed; an unsure or lost
  // fit is not taken and the cloner holds the last good expression, appearance included.
  // Otherwise (sliders, the track, no good fit yet) they are set.
  const tracker = app.active.tracker;
  if (!(tracker && (c.sourceFromTracker(tracker) || app.active.lastGood))) c.setSourceParams(p);
  // "Fast raster" (on by default) rasterises with the package's fixed-point scanline warp into
  // the same tiny-skia pixmap (~3x faster, within ~1.5 levels); off, tiny-skia's pattern fills
  // (the reference renderer of the CLI and the npm package) draw every triangle.
  // Targets are composited into their pictures unless "Face only" is on. The compare view shows
  // the face alone, where the methods differ.
  const { face: opts, target: targetOpts } = renderOptions();
  const { canvases, compared, ci } = registerCanvases(c, opts, targetOpts);
  // Faces scrolled out of view are skipped (redrawn when they come back), except while
  // recording, which copies every face canvas into the video.
  const all = !!app.recorder;
  const faces = canvases.length - compared;
  const shown = Uint8Array.from(canvases, (canvas, k) => ((all && k < faces) || app.hidpi.visible(canvas) ? 1 : 0));
  // One call: update() (map + synthesise every target), then every canvas drawn and blitted.
  c.drawFrame(shown);
  if (ci !== null) {
    if ($('compare-name').textContent !== app.targets[ci].name) $('compare-name').textContent = app.targets[ci].name;
    const note = $('compare-note');
    if (note.hidden === !!app.targets[ci].info.isPhoto) note.hidden = !app.targets[ci].info.isPhoto;
  }
  // The stage timings of this frame (drawFrame's update() reset them).
  const tm = c.timings();
  const { mapMs: map, synthMs: synth, rasterMs: raster, blitMs: blit } = tm;
  feedOutputs(); // the open output views get this frame's avatars
  recordFrame();

  // Per-frame timings, smoothed.
  const s = app.stats;
  const a = 0.1;
  s.map += (map - s.map) * a;
  s.synth += (synth - s.synth) * a;
  s.raster += (raster - s.raster) * a;
  s.blit += (blit - s.blit) * a;
  const now = performance.now();
  s.frameMs += (now - t0 - s.frameMs) * a;
  if (s.last) {
    const dt = now - s.last;
    if (dt > 0 && dt < 1000) s.fps += (1000 / dt - s.fps) * a;
  }
  s.last = now;
  s.frames = (s.frames || 0) + 1;
  if (app.active) syncSliders(p); // the sliders show the params of whatever drives the source
  if (app.active === app.track) syncTransport();
  document.body.dataset.ready = '1';
  document.body.dataset.frames = String(s.frames);
}

function readouts(now) {
  const s = app.stats;
  if (now - s.shown < 250) return;
  s.shown = now;
  const idle = now - s.last > 500;
  $('ro-fps').textContent = idle ? 'idle' : s.fps.toFixed(0);
  $('ro-fps').title = `the page's whole frame (clone, render, copy to every canvas): ${s.frameMs.toFixed(2)} ms`;
  $('ro-map').textContent = `${s.map.toFixed(2)} ms`;
  $('ro-synth').textContent = `${s.synth.toFixed(2)} ms`;
  $('ro-raster').textContent = `${s.raster.toFixed(2)} ms`;
  $('ro-raster').title = `rasterising ${s.raster.toFixed(2)} ms + copying to the canvases ${s.blit.toFixed(2)} ms`;
  if (app.recorder) $('record').querySelector('.label').textContent = `Stop · ${app.recorder.seconds.toFixed(0)} s`;
}

main();
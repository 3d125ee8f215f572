// facemimic demo page: one source face (spk07) drives every target face live.
//
// Data flow per animation frame: active source -> Params -> cloner.setSourceParams -> update()
// (map + synthesise every target) -> render the source, every target and, when open, the
// compare view (one target with all three methods) into their canvases at device-pixel size.
// Nothing is rendered when nothing changed (paused and idle), except the inspector's animation
// (the Inspector panel's, or while "Create a face" is open, its preview's).

import init, * as fm from './pkg/facemimic.js';
import { HiDpi, ctx2d } from './js/canvas.js';
import { dropZone, hasFiles } from './js/drop.js';
import { notify, fileError, message } from './js/toasts.js';
import { fetchBytes, fetchJson } from './js/fetch.js';
import { Inspector, pct } from './js/inspector.js';
import { composite, fileName, WebmRecorder, addDownload, webmType } from './js/recorder.js';
import {
  registerSource,
  availableSources,
  createSource,
  cloneParams,
  validateTrack,
  recentreTrack,
  TrackSource,
  SliderSource,
} from './js/sources.js';
import { ModelShelf } from './js/store.js';
import { Enrolment } from './js/enrol.js';
import { isMediaFile } from './js/tracking.js'; // registers the video and webcam sources (when the package can track)
import { photoTarget, chooseFace, splitPhotos, isPts } from './js/photo-target.js';
import { looksLikeVideo } from './js/media.js';

/** Drops a target slot takes: anything but videos alone (those go on to the page: the source). */
const notVideos = (files) => !files.every(looksLikeVideo);

const MODELS = 'models/';
const METHODS = ['substitute', 'map', 'map-residual'];
// faceOnly: targets drawn as the face alone (the paper's view) instead of composited into their
// picture (the model's backdrop; models without one are drawn face only either way).
const DEFAULTS = { method: 'map-residual', gain: 1, clamp: true, k: 3, followPose: false, mesh: false, fast: true, faceOnly: false };
const FACE_BG = '#1b1d22'; // = --face-bg in style.css: the canvas background meets the card without a seam
const FACE_ASPECT = 0.8; // a face canvas's width / height (= the .face-card default --ar in style.css)
/** A picture's canvas keeps the picture's aspect within these bounds (beyond, it is letterboxed). */
const PICTURE_ASPECT = [0.75, 1.8];
const PHOTO_NOTE = 'photo · substitution';
const PHOTO_TITLE =
  "A target made from one photo: it has no modes of its own, so the source's expression is substituted onto the photo's face (the paper's Fig. 4 A), whatever the method";

const $ = (id) => document.getElementById(id);

const app = {
  wasm: fm,
  cloner: null,
  source: null, // { name, file, model, info, card, canvas, bytesKey }
  targets: [], // [{ name, file, model, info, card, canvas }], index = cloner target index
  track: null, // TrackSource for the bundled source model, or null
  trackKey: null, // identifies the model file the track belongs to
  active: null, // the active source object
  sliders: null, // SliderSource (when created)
  settings: { ...DEFAULTS },
  dirty: true,
  params: null, // the Params drawn last
  manifest: null,
  hidpi: null,
  inspector: null,
  recorder: null,
  compareIndex: 0,
  stats: { fps: 0, map: 0, synth: 0, raster: 0, blit: 0, frameMs: 0, last: 0, shown: 0 },
};

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

/** A cheap identity for a model file's bytes (FNV-1a over a sample + the length). */
function bytesKey(bytes) {
  let h = 2166136261 >>> 0;
  const step = Math.max(1, Math.floor(bytes.length / 65536));
  for (let i = 0; i < bytes.length; i += step) h = Math.imul(h ^ bytes[i], 16777619) >>> 0;
  return `${bytes.length}:${h.toString(16)}`;
}

// ---------------------------------------------------------------------------------------------
// Face cards

function buildStage() {
  const faces = $('faces');
  const card = makeCard('source');
  app.source.card = card.el;
  app.source.canvas = card.canvas;
  setCardName(app.source);
  faces.append(card.el);

  const add = document.createElement('button');
  add.type = 'button';
  add.className = 'card add-card';
  add.id = 'add-card';
  add.innerHTML =
    '<span class="plus" aria-hidden="true">+</span><span>Add a target</span><small>drop <code>.fmm</code> models or a photo of a face here, or click to choose</small>';
  add.title = 'A photo becomes a photo target (its face is found, or read from a .pts file dropped with it)';
  add.addEventListener('click', () => pickFiles({ kind: 'add' }));
  dropZone(add, (files) => loadFiles(files, { kind: 'add' }), { accept: notVideos });
  faces.append(add);

  // Drops anywhere else on the page add targets.
  let depth = 0;
  document.addEventListener('dragenter', (e) => {
    if (!hasFiles(e)) return;
    depth++;
    document.body.classList.add('dragging');
  });
  document.addEventListener('dragleave', () => {
    depth = Math.max(0, depth - 1);
    if (depth === 0) document.body.classList.remove('dragging');
  });
  document.addEventListener('dragover', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    e.dataTransfer.dropEffect = 'copy';
  });
  document.addEventListener('drop', (e) => {
    depth = 0;
    document.body.classList.remove('dragging');
    if (!e.dataTransfer?.files?.length) return;
    e.preventDefault();
    const files = [...e.dataTransfer.files];
    // A video or a photo dropped anywhere else is tracked (it drives the source): the faces in
    // it are found and shown. Photos for targets go on the "Add a target" card or a target.
    if (files.every(isMediaFile) && availableSources(fm).some((s) => s.kind === 'video-file')) {
      openMediaSource(files);
      return;
    }
    loadFiles(files, { kind: 'add' });
  });
}


/** A small button showing the SVG path `d`, its action in `data-action`. */
function iconButton(action, title, d) {
  const b = document.createElement('button');
  b.type = 'button';
  b.className = 'icon-btn';
  b.dataset.action = action;
  b.title = title;
  b.innerHTML = `<svg viewBox="0 0 16 16" aria-hidden="true"><path d="${d}"/></svg>`;
  return b;
}

/** A face card: a canvas, a caption with the name, and buttons. role: "source" | "target". */
function makeCard(role) {
  const el = document.createElement('figure');
  el.className = `card face-card ${role}`;
  const canvas = document.createElement('canvas');
  canvas.className = 'face';
  const cap = document.createElement('figcaption');
  const name = document.createElement('span');
  name.className = 'name';
  const tools = document.createElement('span');
  tools.className = 'tools';
  const replace = iconButton('replace', 'Replace with a model file…', 'M3 8a5 5 0 0 1 8.5-3.5M13 8a5 5 0 0 1-8.5 3.5M11.5 1.5v3h-3M4.5 14.5v-3h3');
  tools.append(replace);
  if (role === 'target') tools.append(iconButton('remove', 'Remove this target', 'M4 4l8 8M12 4l-8 8'));
  cap.append(name, tools);
  el.append(canvas, cap);
  if (role === 'source') {
    const badge = document.createElement('span');
    badge.className = 'badge';
    badge.textContent = 'source';
    el.append(badge);
  }
  app.hidpi.watch(canvas);

  const slot = () => (role === 'source' ? { kind: 'source' } : { kind: 'replace', entry: entryOf(el) });
  replace.addEventListener('click', () => pickFiles(slot()));
  tools.querySelector('[data-action="remove"]')?.addEventListener('click', () => removeTarget(entryOf(el)));
  // A video or a photo dropped on the source goes on to the page, which tracks it (the source is
  // driven by it); on a target, a photo replaces the target with a photo target (and a video
  // goes on to the page).
  dropZone(el, (files) => loadFiles(files, slot()), { accept: role === 'source' ? (files) => !files.every(isMediaFile) : notVideos });
  // Clicking a face shows its model in the inspector.
  canvas.addEventListener('click', () => {
    const entry = role === 'source' ? app.source : entryOf(el);
    if (!entry) return;
    app.inspector.show(entry.model, entry.info, role);
    refreshModelLists();
  });
  return { el, canvas };
}

function entryOf(cardEl) {
  return app.targets.find((t) => t.card === cardEl);
}

function setCardName(entry) {
  const name = entry.card.querySelector('.name');
  name.textContent = entry.name;
  name.title = entry.file;
  const canvas = entry.canvas;
  const role = entry === app.source ? 'Source' : 'Target';
  canvas.setAttribute('role', 'img');
  canvas.setAttribute('aria-label', `${role} face: ${entry.name}`);
  entry.card.querySelector('[data-action="replace"]').setAttribute('aria-label', `Replace ${entry.name} with a model file`);
  entry.card.querySelector('[data-action="remove"]')?.setAttribute('aria-label', `Remove target ${entry.name}`);
  entry.card.dataset.model = entry.name;
}

/** Whether a target is drawn composited into its picture (its canvas then has the picture's aspect). */
function composited(entry) {
  return !app.settings.faceOnly && !!entry.info.backdrop;
}

/** A target card's look: its canvas's aspect (the picture's, or a face's), the photo note, the
 *  backdrop notice. */
function styleTarget(entry) {
  const card = entry.card;
  const b = entry.info.backdrop;
  const ar = composited(entry) ? Math.min(PICTURE_ASPECT[1], Math.max(PICTURE_ASPECT[0], b.width / b.height)) : FACE_ASPECT;
  card.style.setProperty('--ar', ar.toFixed(4));
  card.classList.toggle('picture', composited(entry));
  card.classList.toggle('photo', !!entry.info.isPhoto);
  let badge = card.querySelector('.badge');
  if (entry.info.isPhoto) {
    if (!badge) {
      badge = document.createElement('span');
      badge.className = 'badge';
      card.append(badge);
    }
    badge.textContent = PHOTO_NOTE;
    badge.title = PHOTO_TITLE;
  } else badge?.remove();
  const name = card.querySelector('.name');
  const notes = [entry.file];
  if (entry.info.isPhoto) notes.push(PHOTO_TITLE);
  if (entry.info.backdropNotice) notes.push(`Shown face only: ${entry.info.backdropNotice}`);
  name.title = notes.join('\n');
  const what = entry.info.isPhoto ? `Target (${PHOTO_NOTE})` : 'Target';
  entry.canvas.setAttribute('aria-label', `${what}: ${entry.name}${composited(entry) ? ', in its picture' : ''}`);
}


// ---------------------------------------------------------------------------------------------
// Loading models

let pickSlot = { kind: 'add' };

function pickFiles(slot) {
  pickSlot = slot;
  const input = $('file-input');
  input.multiple = slot.kind !== 'source'; // a photo may come with its .pts
  input.accept = slot.kind === 'source' ? '.fmm,application/octet-stream' : '.fmm,application/octet-stream,image/*,.pts';
  input.value = '';
  input.click();
}

/**
 * Load dropped or picked files into a slot: { kind: "add" } adds each as a target,
 * { kind: "replace", entry } replaces that target with the first file, { kind: "source" } makes
 * the first file the source. For targets, a photo (with its .pts when one of the same name comes
 * with it) makes a photo target. Every failure is reported with the file's name and the reason.
 */
async function loadFiles(files, slot) {
  if (!files.length) return;
  if (slot.kind === 'source' && files.every(isMediaFile)) {
    openMediaSource(files);
    return;
  }
  let models = files;
  if (slot.kind !== 'source') {
    const { photos, loosePts, rest } = splitPhotos(files);
    if (loosePts.length) {
      notify(
        'error',
        `Not used: ${loosePts.map((f) => f.name).join(', ')}`,
        'a .pts file gives the landmarks of the photo of the same name; drop or choose them together',
      );
    }
    if (slot.kind === 'replace' && photos.length && (!rest.length || files.find((f) => !isPts(f)) === photos[0].file)) {
      if (photos.length + rest.length > 1) {
        notify('info', `Used ${photos[0].file.name}`, `one photo replaces one face; ${photos.length + rest.length - 1} other file(s) ignored`);
      }
      queuePhoto(photos[0], slot.entry);
      return;
    }
    if (slot.kind === 'add') for (const p of photos) queuePhoto(p, null);
    models = rest;
    if (!models.length) return;
  }
  const list = slot.kind === 'add' ? models : models.slice(0, 1);
  if (slot.kind !== 'add' && models.length > 1) {
    notify('info', `Used ${models[0].name}`, `one model replaces one face; ${models.length - 1} other file(s) ignored`);
  }
  for (const file of list) {
    let bytes;
    try {
      bytes = new Uint8Array(await file.arrayBuffer());
    } catch (e) {
      fileError(file.name, e);
      continue;
    }
    if (slot.kind === 'add') addTargetFromBytes(bytes, file.name);
    else if (slot.kind === 'replace') replaceTargetFromBytes(slot.entry, bytes, file.name);
    else if (slot.kind === 'source') setSourceFromBytes(bytes, file.name);
    app.shelf?.keep(bytes, file.name.replace(/\.fmm$/i, ''), 'dropped', { quiet: true });
  }
}

/** A video or a photo for the source: the tracking panel opens it (as a drop anywhere does). */
function openMediaSource(files) {
  if (!availableSources(fm).some((s) => s.kind === 'video-file')) {
    notify('error', `Could not use ${files[0].name}`, 'this build of the package cannot track faces in videos or photos');
    return;
  }
  if (app.active?.kind !== 'video-file') activate('video-file');
  window.facemimicTracking?.openFile(files[0]);
  if (files.length > 1) notify('info', `Used ${files[0].name}`, 'one file at a time; the other files were ignored');
}

function parseModel(bytes, file) {
  try {
    return fm.Model.fromBytes(bytes);
  } catch (e) {
    fileError(file, e);
    return null;
  }
}

const noticed = new Set();

/** A target whose file's backdrop was damaged: said once per file (the card's tooltip keeps it). */
function backdropNotice(entry) {
  const notice = entry.info.backdropNotice;
  if (!notice || noticed.has(`${entry.file}\n${notice}`)) return;
  noticed.add(`${entry.file}\n${notice}`);
  notify('warning', `Backdrop damaged: ${entry.file} is shown face only`, notice);
}

function addTargetFromBytes(bytes, file) {
  const model = parseModel(bytes, file);
  if (!model) return false;
  return addTargetModel(model, file);
}

/** Adds a parsed model (owned from here on: kept, or freed when refused) as a target. */
function addTargetModel(model, file) {
  try {
    app.cloner.addTarget(model);
  } catch (e) {
    model.free();
    fileError(file, e);
    return false;
  }
  const card = makeCard('target');
  const entry = { name: model.name, file, model, info: model.info(), card: card.el, canvas: card.canvas };
  app.targets.push(entry);
  setCardName(entry);
  styleTarget(entry);
  $('faces').insertBefore(card.el, $('add-card'));
  backdropNotice(entry);
  afterModelsChanged();
  return true;
}

function replaceTargetFromBytes(entry, bytes, file) {
  if (!entry) return;
  const model = parseModel(bytes, file);
  if (!model) return;
  replaceTargetModel(entry, model, file);
}

function replaceTargetModel(entry, model, file) {
  const index = app.targets.indexOf(entry);
  try {
    app.cloner.replaceTarget(index, model);
  } catch (e) {
    model.free();
    fileError(file, e);
    return false;
  }
  const old = entry.model;
  Object.assign(entry, { name: model.name, file, model, info: model.info() });
  setCardName(entry);
  styleTarget(entry);
  if (app.inspector.model === old) app.inspector.show(model, entry.info, 'target');
  old.free();
  backdropNotice(entry);
  afterModelsChanged();
  notify('info', `Replaced with ${model.name}`, file);
  return true;
}

// Photo targets, one at a time (the face picker is one dialog).
let photoQueue = Promise.resolve();

/** Makes a photo target of `{ file, pts }`: added, or replacing `entry` (a target card). */
function queuePhoto(photo, entry) {
  const pending = entry ? null : pendingCard(photo.file.name);
  entry?.card.classList.add('busy');
  const job = () => photoTargetFrom(photo, entry).finally(() => {
    pending?.remove();
    entry?.card.classList.remove('busy');
  });
  photoQueue = photoQueue.then(job, job);
  return photoQueue;
}

async function photoTargetFrom({ file, pts }, entry) {
  let made;
  try {
    made = await photoTarget(fm, file, pts, { choose: chooseFace });
  } catch (e) {
    console.warn(`facemimic: ${file.name}: ${message(e)}`);
    notify('error', `Could not make a target of ${file.name}`, message(e));
    return false;
  }
  if (!made) return false; // the face picker was cancelled
  const how = pts ? `landmarks from ${pts.name}` : made.faces > 1 ? `the face you chose of ${made.faces}` : 'the face found';
  let ok;
  if (entry && app.targets.includes(entry)) ok = replaceTargetModel(entry, made.model, file.name);
  else {
    ok = addTargetModel(made.model, file.name);
    if (ok) notify('info', `Added ${made.name}, a photo target`, `${file.name}: ${how}; cloned by substitution`);
  }
  if (!ok || !app.shelf) return ok;
  // Kept in "Your models" like a dropped model, so it comes back after a reload.
  try {
    app.shelf.keep(made.model.toBytes(), made.name, 'photo', { quiet: true });
  } catch (e) {
    console.warn(`facemimic: ${file.name} not kept: ${message(e)}`);
  }
  return ok;
}

/** A placeholder card while a photo's face is looked for. */
function pendingCard(fileName) {
  const el = document.createElement('figure');
  el.className = 'card face-card pending';
  el.setAttribute('aria-busy', 'true');
  const box = document.createElement('div');
  box.className = 'pending-box';
  box.textContent = 'Finding the face…';
  const cap = document.createElement('figcaption');
  const name = document.createElement('span');
  name.className = 'name';
  name.textContent = fileName;
  cap.append(name);
  el.append(box, cap);
  $('faces').insertBefore(el, $('add-card'));
  return el;
}

function setSourceFromBytes(bytes, file) {
  const model = parseModel(bytes, file);
  if (!model) return;
  try {
    app.cloner.setSource(model);
  } catch (e) {
    model.free();
    fileError(file, e);
    return;
  }
  const old = app.source.model;
  const key = bytesKey(bytes);
  Object.assign(app.source, { name: model.name, file, model, info: model.info(), bytesKey: key, bundled: key === app.trackKey });
  setCardName(app.source);
  if (app.inspector.model === old) app.inspector.show(model, app.source.info, 'source');
  old.free();
  // The bundled track holds parameters of the bundled source model only.
  const trackFits = usableTrack() !== null;
  app.params = null;
  app.sliders = null;
  buildSliders();
  activate(trackFits ? 'track' : 'sliders', { fresh: true });
  afterModelsChanged();
  notify(
    'info',
    `Source is now ${model.name}`,
    trackFits ? file : `${file}: the recorded track belongs to the bundled source; drive this one with the sliders`,
  );
}

function removeTarget(entry) {
  if (!entry) return;
  const index = app.targets.indexOf(entry);
  try {
    app.cloner.removeTarget(index);
  } catch (e) {
    notify('error', `Could not remove ${entry.name}`, message(e));
    return;
  }
  app.targets.splice(index, 1);
  // Keep comparing the same face when an earlier one goes.
  if (index < app.compareIndex) app.compareIndex--;
  app.hidpi.unwatch(entry.canvas);
  entry.card.remove();
  if (app.inspector.model === entry.model) app.inspector.show(app.source.model, app.source.info, 'source');
  entry.model.free();
  afterModelsChanged();
}

function afterModelsChanged() {
  if (!app.cloner || !app.inspector) return;
  refreshModelLists();
  app.dirty = true;
}

// ---------------------------------------------------------------------------------------------
// Controls

function buildControls() {
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
  for (const id of ['inspect-mean', 'inspect-mode', 'cmp-substitute', 'cmp-map', 'cmp-map-residual']) {
    app.hidpi.watch($(id));
  }

  $('method').addEventListener('change', (e) => {
    if (e.target.name === 'method') setMethod(e.target.value);
  });
  $('gain').addEventListener('input', () => setGain(Number($('gain').value)));
  $('clamp').addEventListener('change', applyClamp);
  $('clamp-k').addEventListener('input', applyClamp);
  $('follow-pose').addEventListener('change', () => {
    app.settings.followPose = $('follow-pose').checked;
    app.cloner.setFollowPose(app.settings.followPose);
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

  $('add-file').addEventListener('click', () => pickFiles({ kind: 'add' }));
  $('add-photo').addEventListener('click', () => {
    $('photo-input').value = '';
    $('photo-input').click();
  });
  $('photo-input').addEventListener('change', () => loadFiles([...$('photo-input').files], { kind: 'add' }));
  $('file-input').addEventListener('change', () => {
    const files = [...$('file-input').files];
    loadFiles(files, pickSlot);
    pickSlot = { kind: 'add' };
  });
  $('library').addEventListener('change', async () => {
    const file = $('library').value;
    $('library').value = '';
    if (!file) return;
    try {
      addTargetFromBytes(await fetchBytes(MODELS + file), file);
    } catch (e) {
      fileError(file, e);
    }
  });
  $('inspect-model').addEventListener('change', () => {
    const v = $('inspect-model').value;
    if (v === 'source') app.inspector.show(app.source.model, app.source.info, 'source');
    else {
      const t = app.targets[Number(v)];
      if (t) app.inspector.show(t.model, t.info, 'target');
    }
  });

  $('record').addEventListener('click', toggleRecording);
  $('snapshot').addEventListener('click', snapshot);
  if (!webmType()) {
    $('record').disabled = true;
    $('record').title = 'This browser cannot record WebM video';
  }

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

/** Targets as the face alone (the paper's view) or composited into their pictures. */
function setFaceOnly(on) {
  app.settings.faceOnly = on;
  for (const t of app.targets) styleTarget(t);
  app.dirty = true;
}

function setMethod(m) {
  if (!METHODS.includes(m)) return;
  app.settings.method = m;
  app.cloner.setMethod(m);
  app.dirty = true;
}

function setGain(g) {
  app.settings.gain = g;
  $('gain-out').value = g.toFixed(2);
  app.cloner.setGain(g);
  app.dirty = true;
}

function applyClamp() {
  app.settings.clamp = $('clamp').checked;
  app.settings.k = Number($('clamp-k').value);
  $('clamp-k').disabled = !app.settings.clamp;
  $('clamp-out').value = `±${app.settings.k.toFixed(1)}σ`;
  app.cloner.setClamp(app.settings.clamp ? app.settings.k : null);
  app.dirty = true;
}

function applySettingsToCloner() {
  const s = app.settings;
  app.cloner.setMethod(s.method);
  app.cloner.setGain(s.gain);
  app.cloner.setClamp(s.clamp ? s.k : null);
  app.cloner.setFollowPose(s.followPose);
}

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
  $('mesh').checked = s.mesh;
  $('fast-raster').checked = s.fast;
  $('face-only').checked = s.faceOnly;
}

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
function usableTrack() {
  return app.track && app.source?.bytesKey === app.trackKey ? app.track : null;
}

/** Make a source kind active. `fresh`: build a new instance even if one exists. */
function activate(kind, { fresh = false } = {}) {
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

function play(on) {
  if (!usableTrack()) return;
  if (on) {
    if (app.active !== app.track) activate('track');
    app.track.play();
  } else app.track.pause();
  app.dirty = true;
  syncTransport();
}

function syncTransport() {
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

function buildSliders() {
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
function syncSliders(p) {
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

function fmt(x) {
  return Number.isFinite(x) ? (Math.abs(x) >= 100 ? x.toFixed(0) : x.toPrecision(3)) : '–';
}

function buildLibrary() {
  const sel = $('library');
  const lib = app.manifest.library || [];
  for (const file of lib) {
    const o = document.createElement('option');
    o.value = file;
    o.textContent = file.replace(/\.fmm$/, '');
    sel.append(o);
  }
  sel.closest('.row').hidden = lib.length === 0;
}

function refreshModelLists() {
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

function option(value, label) {
  const o = document.createElement('option');
  o.value = value;
  o.textContent = label;
  return o;
}

// ---------------------------------------------------------------------------------------------
// Record

/** The options the faces are drawn with: the source's, and the targets' (composited unless "Face only"). */
function renderOptions() {
  const face = { background: FACE_BG, mesh: app.settings.mesh, raster: app.settings.fast ? 'scanline' : 'tiny-skia' };
  return { face, target: { ...face, composite: !app.settings.faceOnly } };
}

/** The faces to record, as shown: source then targets. `crisp`: render each afresh at the tile
 *  size (with the options the page draws them with). */
function recordTiles(crisp = false) {
  const { face, target } = renderOptions();
  return [app.source, ...app.targets].map((e) => {
    const isSource = e === app.source;
    const index = app.targets.indexOf(e);
    return {
      canvas: e.canvas,
      label: isSource ? `${e.name} (source)` : e.name,
      render: crisp
        ? (w, h) =>
            isSource ? app.cloner.renderSourceImageData(w, h, face) : app.cloner.renderTargetImageData(index, w, h, target)
        : null,
    };
  });
}

const compositeCanvas = document.createElement('canvas');

/** Video tiles at the page canvases' own height (no rescaling), even, within 240..720 px. */
function videoTileHeight() {
  const h = app.source.canvas.height;
  return Math.max(240, Math.min(720, h - (h & 1)));
}

async function snapshot() {
  try {
    // 480 device px per face, rendered at that size (not scaled up from the page's canvases).
    const crisp = typeof app.cloner.renderTargetImageData === 'function';
    composite(compositeCanvas, recordTiles(crisp), 480);
  } catch (e) {
    notify('error', 'Snapshot failed', message(e));
    return;
  }
  const blob = await new Promise((resolve) => compositeCanvas.toBlob(resolve, 'image/png'));
  if (!blob) {
    notify('error', 'Snapshot failed', 'the browser could not encode a PNG');
    return;
  }
  const name = fileName('png');
  const a = addDownload($('downloads'), blob, name, name);
  a.click();
}

async function toggleRecording() {
  const btn = $('record');
  if (app.recorder) {
    const rec = app.recorder;
    app.recorder = null;
    btn.dataset.state = 'idle';
    btn.querySelector('.label').textContent = 'Record WebM';
    btn.classList.remove('recording');
    try {
      const blob = await rec.stop();
      const name = fileName('webm');
      addDownload($('downloads'), blob, name, `${name} (${rec.seconds.toFixed(1)} s)`).click();
    } catch (e) {
      notify('error', 'Recording failed', message(e));
    }
    return;
  }
  try {
    app.recordTileH = videoTileHeight();
    composite(compositeCanvas, recordTiles(), app.recordTileH);
    app.recorder = new WebmRecorder(compositeCanvas, 30);
    app.recorder.start();
  } catch (e) {
    app.recorder = null;
    notify('error', 'Cannot record', message(e));
    return;
  }
  btn.dataset.state = 'recording';
  btn.querySelector('.label').textContent = 'Stop recording';
  btn.classList.add('recording');
  app.dirty = true;
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

function render(t) {
  const t0 = performance.now();
  const p = app.active.paramsAt(t);
  app.params = p;
  const c = app.cloner;
  c.setSourceParams(p);
  c.update();
  // "Fast raster" (on by default) rasterises with the package's fixed-point scanline warp into
  // the same tiny-skia pixmap (~3x faster, within ~1.5 levels); off, tiny-skia's pattern fills
  // (the reference renderer of the CLI and the npm package) draw every triangle.
  // Targets are composited into their pictures unless "Face only" is on. The compare view shows
  // the face alone, where the three methods differ (renderTargetWithMethod could composite too).
  const { face: opts, target: targetOpts } = renderOptions();
  // Faces scrolled out of view are skipped (redrawn when they come back), except while
  // recording, which copies every face canvas into the video.
  const all = !!app.recorder;
  const seen = (canvas) => all || app.hidpi.visible(canvas);
  if (seen(app.source.canvas)) c.renderSource(ctx2d(app.source.canvas), opts);
  for (let i = 0; i < app.targets.length; i++) {
    if (seen(app.targets[i].canvas)) c.renderTarget(i, ctx2d(app.targets[i].canvas), targetOpts);
  }
  if (!$('compare').hidden && app.targets.length) {
    const i = Math.min(app.compareIndex, app.targets.length - 1);
    if ($('compare-name').textContent !== app.targets[i].name) $('compare-name').textContent = app.targets[i].name;
    const note = $('compare-note');
    if (note.hidden === !!app.targets[i].info.isPhoto) note.hidden = !app.targets[i].info.isPhoto;
    for (const m of METHODS) {
      const canvas = $(`cmp-${m}`);
      if (app.hidpi.visible(canvas)) c.renderTargetWithMethod(i, m, ctx2d(canvas), opts);
    }
  }
  // The stage timings accumulate from update() over every render call of this frame.
  const tm = c.timings();
  const { mapMs: map, synthMs: synth, rasterMs: raster, blitMs: blit } = tm;
  if (app.recorder) composite(compositeCanvas, recordTiles(), app.recordTileH);

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

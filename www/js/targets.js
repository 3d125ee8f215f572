// The models on the stage: the source's and the targets' cards, and every way a model gets there
// or goes: files dropped or chosen (models, photos with or without their .pts, which become photo
// targets one at a time), the library menu, "Replace", "Remove", a model from "Your models".
// A video or a photo for the source goes on to the tracking panel (tracking.js).

import { dropZone, hasFiles } from './drop.js';
import { notify, fileError, message } from './toasts.js';
import { fetchBytes } from './fetch.js';
import { availableSources } from './sources.js';
import { isMediaFile } from './tracking.js';
import { photoTarget, chooseFace, splitPhotos, isPts } from './photo-target.js';
import { makeCard, setCardName, styleTarget, pendingCard } from './cards.js';
import { activate, buildSliders, usableTrack } from './source-control.js';
import { refreshModelLists } from './controls.js';
import { openOutput, refreshOutputTargets } from './output-page.js';
import { app, fm, $, bytesKey, notVideos, MODELS } from './page-state.js';

/** What a face card's buttons, drops and clicks do. */
const cardActions = {
  pick: (slot) => pickFiles(slot),
  load: (files, slot) => loadFiles(files, slot),
  remove: (entry) => removeTarget(entry),
  popout: (entry) => openOutput(entry),
  inspect: (entry, role) => {
    app.inspector.show(entry.model, entry.info, role);
    refreshModelLists();
  },
};

/** The stage: the source's card, the "Add a target" card, and drops anywhere else on the page. */
export function buildStage() {
  const faces = $('faces');
  const card = makeCard('source', cardActions);
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
    // Parsed once: the one Model goes on the stage, its info to the shelf (which keeps the file).
    const model = parseModel(bytes, file.name);
    if (!model) continue;
    const info = model.info();
    if (slot.kind === 'add') addTargetModel(model, file.name, info);
    else if (slot.kind === 'replace') replaceTargetModel(slot.entry, model, file.name, info);
    else if (slot.kind === 'source') setSourceModel(model, bytes, file.name, info);
    app.shelf?.keep(bytes, file.name.replace(/\.fmm$/i, ''), 'dropped', { quiet: true, info });
  }
}

/** A video or a photo for the source: the tracking panel opens it (as a drop anywhere does). */
function openMediaSource(files) {
  if (!availableSources(fm).some((s) => s.kind === 'video-file')) {
    notify('error', `Could not use ${files[0].name}`, 'this build of the package cannot track faces in videos or photos');
    return;
  }
  if (app.active?.kind !== 'video-file') activate('video-file');
  // The video source made active (www/js/tracking.js) opens it.
  if (app.active?.kind === 'video-file') app.active.openFile(files[0]);
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

export function addTargetFromBytes(bytes, file) {
  const model = parseModel(bytes, file);
  if (!model) return false;
  return addTargetModel(model, file);
}

/**
 * Adds a parsed model (owned from here on: kept, or freed when refused) as a target; `info`: its
 * `info()` when the caller has it.
 */
function addTargetModel(model, file, info = null) {
  try {
    app.cloner.addTarget(model);
  } catch (e) {
    model.free();
    fileError(file, e);
    return false;
  }
  const card = makeCard('target', cardActions);
  const entry = { name: model.name, file, model, info: info ?? model.info(), card: card.el, canvas: card.canvas };
  app.targets.push(entry);
  setCardName(entry);
  styleTarget(entry);
  $('faces').insertBefore(card.el, $('add-card'));
  backdropNotice(entry);
  afterModelsChanged();
  return true;
}

/** Replaces a target with a parsed model (owned from here on, as `addTargetModel`'s). */
function replaceTargetModel(entry, model, file, info = null) {
  if (!entry) {
    model.free();
    return false;
  }
  const index = app.targets.indexOf(entry);
  try {
    app.cloner.replaceTarget(index, model);
  } catch (e) {
    model.free();
    fileError(file, e);
    return false;
  }
  const old = entry.model;
  Object.assign(entry, { name: model.name, file, model, info: info ?? model.info() });
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
    if (ok) notify('info', `Added ${made.name}, a photo target`, `${file.name}: ${how}`);
  }
  if (!ok || !app.shelf) return ok;
  // Kept in "Your models" like a dropped model, so it comes back after a reload.
  try {
    const entryInfo = app.targets.find((t) => t.model === made.model)?.info;
    app.shelf.keep(made.model.toBytes(), made.name, 'photo', { quiet: true, info: entryInfo });
  } catch (e) {
    console.warn(`facemimic: ${file.name} not kept: ${message(e)}`);
  }
  return ok;
}


export function setSourceFromBytes(bytes, file) {
  const model = parseModel(bytes, file);
  if (model) setSourceModel(model, bytes, file);
}

/** Makes a parsed model (owned from here on) the source; `bytes`: its file (the track's key). */
function setSourceModel(model, bytes, file, info = null) {
  try {
    app.cloner.setSource(model);
  } catch (e) {
    model.free();
    fileError(file, e);
    return;
  }
  const old = app.source.model;
  const key = bytesKey(bytes);
  Object.assign(app.source, { name: model.name, file, model, info: info ?? model.info(), bytesKey: key, bundled: key === app.trackKey });
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
  refreshOutputTargets();
  app.dirty = true;
}

/** The "Add a target" menu's file and photo buttons, the file pickers, the library menu. */
export function wireTargetInputs() {
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
}

/** The library menu: the bundled models not on the stage by default. */
export function buildLibrary() {
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


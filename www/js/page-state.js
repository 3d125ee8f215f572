// The page's shared state and constants (www/app.js wires the page; the modules in js/ read and
// change this one `app` object): the models on the stage, the cloner, the active source, the
// settings, the statistics.

import * as fm from '../pkg/facemimic.js';
import { looksLikeVideo } from './media.js';

export { fm };

/** Drops a target slot takes: anything but videos alone (those go on to the page: the source). */
export const notVideos = (files) => !files.every(looksLikeVideo);

export const MODELS = 'models/';
export const METHODS = ['substitute', 'map', 'map-residual'];
// faceOnly: targets drawn as the face alone (the paper's view) instead of composited into their
// picture (the model's backdrop; models without one are drawn face only either way).
export const DEFAULTS = { method: 'map-residual', gain: 1, clamp: true, k: 3, followPose: false, mesh: false, fast: true, faceOnly: false };
export const FACE_BG = '#1b1d22'; // = --face-bg in style.css: the canvas background meets the card without a seam
export const FACE_ASPECT = 0.8; // a face canvas's width / height (= the .face-card default --ar in style.css)
/** A picture's canvas keeps the picture's aspect within these bounds (beyond, it is letterboxed). */
export const PICTURE_ASPECT = [0.75, 1.8];
export const PHOTO_NOTE = 'photo · substitution';
export const PHOTO_TITLE =
  "A target made from one photo: it has no modes of its own, so the source's expression is substituted onto the photo's face (the paper's Fig. 4 A), whatever the method";

export const $ = (id) => document.getElementById(id);

export const app = {
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

/** A cheap identity for a model file's bytes (FNV-1a over a sample + the length). */
export function bytesKey(bytes) {
  let h = 2166136261 >>> 0;
  const step = Math.max(1, Math.floor(bytes.length / 65536));
  for (let i = 0; i < bytes.length; i += step) h = Math.imul(h ^ bytes[i], 16777619) >>> 0;
  return `${bytes.length}:${h.toString(16)}`;
}


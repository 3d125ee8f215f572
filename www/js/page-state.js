// The page's shared state and constants (www/app.js wires the page; the modules in js/ read and
// change this one `app` object): the models on the stage, the cloner, the active source, the
// settings, the statistics.

import * as fm from '../pkg/facemimic.js';
import { looksLikeVideo } from './media.js';

export { fm };

/** Drops a target slot takes: anything but videos alone (those go on to the page: the source). */
export const notVideos = (files) => !files.every(looksLikeVideo);

export const MODELS = 'models/';
// The cloning settings (method, gain, clamp and k, followPose, the region gains, style) are the
// core's defaults, set by loadMethods from the package's `policy()` once it is loaded; the values
// here only stand before that. mouth, eyes, brows: the expressive method's region
// gains; style: 0 the target's own range .. 1 the source's full motion. faceOnly: targets drawn
// as the face alone (the paper's view) instead of composited into their picture (the model's
// backdrop; models without one are drawn face only either way).
export const DEFAULTS = {
  method: null, gain: 1, clamp: true, k: 3, followPose: false, keepWhole: true, mesh: false, fast: true, faceOnly: false,
  mouth: 1, eyes: 1, brows: 1, style: 1,
};
/** The expressive method's region gains, in `Cloner.setRegionGains`' order (settings' keys). */
export const REGIONS = ['mouth', 'eyes', 'brows'];
export const FACE_BG = '#1b1d22'; // = --face-bg in style.css: the canvas background meets the card without a seam
export const FACE_ASPECT = 0.8; // a face canvas's width / height (= the .face-card default --ar in style.css)
/** A picture's canvas keeps the picture's aspect within these bounds (beyond, it is letterboxed). */
export const PICTURE_ASPECT = [0.75, 1.8];
export const PHOTO_NOTE = 'photo';
export const PHOTO_TITLE =
  "A target made from one photo: it has no modes of its own, so a method that maps into the target's modes substitutes the source's expression onto the photo's face instead (the paper's Fig. 4 A); the expressive method needs none and clones it as any target";

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
  methods: [], // the package's methods(): [{ name, label, description, isDefault }], in the core's order
  compareViews: [], // the compare view: [{ method, canvas }], one per method
  stats: { fps: 0, map: 0, synth: 0, raster: 0, blit: 0, frameMs: 0, last: 0, shown: 0 },
};

/**
 * The cloning methods from the package (the core's one list), and the cloning defaults from the
 * core's policy (`policy().clone`: method, gain, clamp, head pose, region gains, style), so the
 * page starts where a new `Cloner` does.
 */
export function loadMethods() {
  app.methods = fm.methods();
  if (!app.methods.length) throw new Error('the package lists no cloning method');
  const c = fm.policy().clone;
  Object.assign(DEFAULTS, {
    method: c.method, gain: c.gain, clamp: c.clamp !== null, k: c.clamp ?? DEFAULTS.k,
    followPose: c.followPose, mouth: c.mouth, eyes: c.eyes, brows: c.brows, style: c.style,
  });
  app.settings = { ...app.settings, ...DEFAULTS };
}

/** A cheap identity for a model file's bytes (FNV-1a over a sample + the length). */
export function bytesKey(bytes) {
  let h = 2166136261 >>> 0;
  const step = Math.max(1, Math.floor(bytes.length / 65536));
  for (let i = 0; i < bytes.length; i += step) h = Math.imul(h ^ bytes[i], 16777619) >>> 0;
  return `${bytes.length}:${h.toString(16)}`;
}


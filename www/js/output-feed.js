// The output views' feeder, on the page that owns the cloner (the main page or the call page):
// each output view is a pop-out window (www/output.html, www/js/output-view.js) showing one
// avatar alone, at a chosen size, on its picture or on a key colour, for OBS's window capture
// (and from there Zoom, Meet, Discord: docs/obs.md).
//
// The page's own frame drives it: after the page's `drawFrame`, `feed()` renders each open
// output's avatar with the cloner (`renderTarget`, as of that frame's update) into a canvas of
// THIS page (wasm-bindgen's type checks refuse a canvas of another window's realm), then the
// pop-out's `present()` copies it into its own canvas with one `drawImage`, scaled to the chosen
// size. An avatar shown in its picture is not rendered twice: the page's `drawFrame` draws it
// straight into the output's canvas and the page's own card gets a copy (`canvasFor`). So the
// pop-out shows exactly the page's frames, one per frame, and costs nothing when the page does
// not draw. A closed pop-out is dropped at the next frame (or within a second); a pop-out whose
// page went away (closed, reloaded) notices it by itself and says so.

import { setCanvasSize } from './canvas.js';

/** The sizes offered (device pixels of the output picture); "custom" takes width and height. */
export const OUTPUT_PRESETS = [
  { id: '1280x720', label: '1280 × 720 · 720p' },
  { id: '1920x1080', label: '1920 × 1080 · 1080p' },
  { id: '720x720', label: '720 × 720 · square' },
  { id: '1080x1080', label: '1080 × 1080 · square' },
  { id: '640x480', label: '640 × 480 · 4:3' },
  { id: '720x1280', label: '720 × 1280 · portrait' },
  { id: 'custom', label: 'Custom…' },
];
export const KEY_DEFAULT = '#00ff00';
export const OUTPUT_MIN = 64;
export const OUTPUT_MAX = 3840;
/** The avatar is rendered into at most this many pixels and scaled up by the pop-out's
 *  drawImage (the face alone at 1280x720 and below is rendered at its own size)... */
export const RENDER_MAX_PIXELS = 1280 * 720;
/** ...and a picture at most this many times its own size (the bundled pictures are 360x288:
 *  drawing them larger adds no detail, only time). */
export const PICTURE_UPSCALE = 2;
/** Around the picture (a window of another aspect, a target without a picture). */
const PICTURE_SURROUND = '#000000';
const STORE_KEY = 'facemimic.output';

/** `{ preset, width, height, background: 'picture' | 'key', key }`, checked and completed. */
export function normaliseSettings(s = {}) {
  const preset = OUTPUT_PRESETS.some((p) => p.id === s.preset) ? s.preset : '1280x720';
  const clampSide = (v, d) => Math.max(OUTPUT_MIN, Math.min(OUTPUT_MAX, Math.round(Number(v)) || d));
  let width;
  let height;
  if (preset === 'custom') {
    width = clampSide(s.width, 1280);
    height = clampSide(s.height, 720);
  } else [width, height] = preset.split('x').map(Number);
  const key = /^#[0-9a-f]{6}$/i.test(s.key ?? '') ? s.key.toLowerCase() : KEY_DEFAULT;
  return { preset, width, height, background: s.background === 'key' ? 'key' : 'picture', key };
}

/** The settings kept in this browser (shared by the main page and the call page). */
export function loadSettings() {
  try {
    return normaliseSettings(JSON.parse(localStorage.getItem(STORE_KEY) || '{}'));
  } catch {
    return normaliseSettings();
  }
}

function saveSettings(s) {
  try {
    localStorage.setItem(STORE_KEY, JSON.stringify(s));
  } catch {
    // private mode or storage full: the settings last for this page only
  }
}

/** A window name for an avatar: opening the same avatar again reuses its window. */
function windowName(page, name) {
  return `facemimic-output-${page}-${String(name).replace(/[^A-Za-z0-9_-]+/g, '_').slice(0, 40)}`;
}

/**
 * Where the avatar is drawn, for an output `width x height`: the canvas to render into (`w x
 * h`) and the part of it that fills the output (`crop`). A picture (`{ width, height }`)
 * covers the output, cut at two sides so that `anchor` (a point of the picture, as fractions
 * of its width and height: the head) is as near the middle as the picture allows, and is
 * rendered at most PICTURE_UPSCALE times its own size; the face alone is rendered at the
 * output's own aspect. Either way at most RENDER_MAX_PIXELS: the pop-out scales it up.
 */
export function renderPlan(width, height, picture = null, anchor = { x: 0.5, y: 0.5 }) {
  let w = width;
  let h = height;
  let cap = RENDER_MAX_PIXELS;
  if (picture) {
    const aspect = picture.width / picture.height;
    if (aspect > width / height) w = height * aspect;
    else h = width / aspect;
    cap = Math.min(cap, PICTURE_UPSCALE ** 2 * picture.width * picture.height);
  }
  const f = Math.min(1, Math.sqrt(cap / (w * h)));
  const rw = Math.max(1, Math.round(w * f));
  const rh = Math.max(1, Math.round(h * f));
  const sw = Math.min(rw, width * f);
  const sh = Math.min(rh, height * f);
  const at = (c, whole, part) => Math.max(0, Math.min(whole - part, c * whole - part / 2));
  return { w: rw, h: rh, crop: { sx: at(anchor.x, rw, sw), sy: at(anchor.y, rh, sh), sw, sh } };
}

/** The middle of the head in a target's picture (fractions of its size), from its landmarks
 *  (`2n` image coordinates): the face's box, raised to take in the hair and keep the chin. */
export function headAnchor(landmarks, imageWidth, imageHeight) {
  if (!landmarks?.length || !imageWidth || !imageHeight) return { x: 0.5, y: 0.5 };
  let x0 = Infinity;
  let x1 = -Infinity;
  let y0 = Infinity;
  let y1 = -Infinity;
  for (let i = 0; i + 1 < landmarks.length; i += 2) {
    x0 = Math.min(x0, landmarks[i]);
    x1 = Math.max(x1, landmarks[i]);
    y0 = Math.min(y0, landmarks[i + 1]);
    y1 = Math.max(y1, landmarks[i + 1]);
  }
  const x = (x0 + x1) / 2 / imageWidth;
  const y = ((y0 + y1) / 2 - 0.2 * (y1 - y0)) / imageHeight;
  return Number.isFinite(x) && Number.isFinite(y) ? { x, y } : { x: 0.5, y: 0.5 };
}

export class OutputFeed {
  /**
   * `page`: names this page's windows ("page", "call"); `raster()`: the rasteriser to draw with
   * ("scanline" unless the page says otherwise); `wake()`: called when a pop-out is ready or the
   * settings changed, so a page that draws only on change draws a frame.
   */
  constructor({ page, raster = () => 'scanline', wake = () => {} }) {
    this.page = page;
    this.raster = raster;
    this.wake = wake;
    this.settings = loadSettings();
    this.outputs = []; // { key, source, win, api, configured, work, ctx, frames }
    this.listeners = new Set();
    window.facemimicOutputs = this; // the pop-outs find their page here (and the tests)
    // A pop-out closed while the page rests (nothing drawn) is noticed too.
    setInterval(() => this.outputs.length && this.prune(), 1000);
    addEventListener('pagehide', () => {
      for (const o of this.outputs) this.tell(o, 'disconnect', 'The facemimic page that fed this window was closed or reloaded.');
      this.outputs = [];
    });
  }

  /** Whether `win` (a pop-out) is fed by this page. */
  feeds(win) {
    return this.outputs.some((o) => o.win === win);
  }

  /** A pop-out's page is ready (its script calls this on its opener). */
  hello(win) {
    if (this.feeds(win)) this.wake();
  }

  get open() {
    return this.outputs.length;
  }

  /** Calls `fn()` when outputs open or close (for buttons showing it). */
  onChange(fn) {
    this.listeners.add(fn);
  }

  changed() {
    for (const fn of this.listeners) fn();
  }

  setSettings(s) {
    this.settings = normaliseSettings({ ...this.settings, ...s });
    saveSettings(this.settings);
    for (const o of this.outputs) o.configured = null;
    this.wake();
  }

  /**
   * Opens (or brings forward) the output view of one avatar. `key`: what identifies it on this
   * page (a target entry); `source()`: `{ name, picture: { width, height } | null, render(ctx,
   * options), anchor() }` as of now (`anchor`: `headAnchor` of the avatar now, where a picture
   * is cut to the output's shape), or null once the avatar is gone. Must run in a click
   * (pop-ups).
   * Returns the window, or null when the browser blocked it.
   */
  openFor(key, source) {
    const src = source();
    if (!src) return null;
    const s = this.settings;
    const existing = this.outputs.find((o) => o.key === key && !o.win.closed);
    if (existing) {
      existing.configured = null;
      existing.win.focus();
      this.wake();
      return existing.win;
    }
    // The window's inner size is the output's, scaled down to fit the screen.
    const fit = Math.min(1, (screen.availWidth * 0.9) / s.width, (screen.availHeight * 0.85) / s.height);
    const features = `popup=yes,width=${Math.round(s.width * fit)},height=${Math.round(s.height * fit)}`;
    const url = new URL('output.html', document.baseURI);
    url.searchParams.set('avatar', src.name);
    url.searchParams.set('from', this.page);
    const win = window.open(url.href, windowName(this.page, src.name), features);
    if (!win) return null;
    const work = document.createElement('canvas'); // this page's realm: the cloner draws into it
    this.outputs = this.outputs.filter((o) => o.win !== win);
    this.outputs.push({ key, source, win, api: null, configured: null, work, ctx: work.getContext('2d', { alpha: false }), frames: 0 });
    this.changed();
    return win;
  }

  /** An output view in this very page (`view`: www/js/output-view.js), fed as a pop-out is:
   *  the main page's output mode, for a browser source. */
  attach(key, source, view) {
    const win = { closed: false, facemimicOutput: view, focus() {}, close() {} };
    const work = document.createElement('canvas');
    this.outputs.push({ key, source, win, api: null, configured: null, work, ctx: work.getContext('2d', { alpha: false }), frames: 0 });
    this.changed();
    this.wake();
  }

  /** Closes the output of `key` (or every output). */
  close(key) {
    for (const o of this.outputs) if (key === undefined || o.key === key) o.win.close();
    this.prune();
  }

  prune() {
    const before = this.outputs.length;
    this.outputs = this.outputs.filter((o) => !o.win.closed && !o.dropped);
    if (this.outputs.length !== before) this.changed();
  }

  /** Calls the pop-out's `method` (its page may be loading, or gone): false when it could not. */
  tell(o, method, ...args) {
    try {
      const api = o.win.facemimicOutput;
      if (!api) return false;
      if (api !== o.api) {
        o.api = api;
        o.configured = null;
      }
      api[method](...args);
      return true;
    } catch {
      return false;
    }
  }

  /** After the page drew a frame: each open output's avatar, rendered and presented. */
  feed() {
    if (!this.outputs.length) return;
    let closed = false;
    for (const o of this.outputs) {
      if (o.win.closed || o.dropped) {
        closed = true;
        continue;
      }
      const src = o.source();
      if (!src) {
        this.tell(o, 'disconnect', 'This avatar was removed from the facemimic page.', true);
        o.dropped = true;
        closed = true;
        continue;
      }
      this.feedOne(o, src);
    }
    if (closed) this.prune();
  }

  /** The output's look now: `{ picture, surround }` (`picture`: null for the face alone). */
  look(src) {
    const s = this.settings;
    return { picture: s.background === 'picture' ? src.picture : null, surround: s.background === 'key' ? s.key : PICTURE_SURROUND };
  }

  /** Sizes the output's canvas for this frame; returns its plan. */
  plan(o, src) {
    const { picture } = this.look(src);
    const plan = renderPlan(this.settings.width, this.settings.height, picture, picture ? o.anchor : undefined);
    setCanvasSize(o.work, plan.w, plan.h);
    return plan;
  }

  /**
   * The canvas the page may draw `key`'s avatar into this frame, with `options`, in place of
   * its own canvas (then copying it there, `copyContain`), or null: an output of the avatar in
   * its picture, which the page draws composited too. One composite a frame instead of two at
   * two sizes (each target's compositor keeps its picture for one size: two sizes a frame would
   * make it again twice a frame).
   */
  canvasFor(key) {
    const o = this.outputs.find((x) => x.key === key && !x.win.closed && !x.dropped);
    const src = o?.source();
    if (!src || !this.look(src).picture) return null;
    this.plan(o, src);
    o.drawn = true; // by the page, this frame
    return { canvas: o.work, options: { background: PICTURE_SURROUND, composite: true, raster: this.raster(), mesh: false } };
  }

  feedOne(o, src) {
    const s = this.settings;
    const drawn = o.drawn;
    o.drawn = false;
    const { picture, surround } = this.look(src);
    const config = `${s.width}x${s.height}|${surround}|${src.name}`;
    if (o.configured !== config || o.api !== o.win.facemimicOutput) {
      const title = `${src.name} · facemimic output`;
      if (!this.tell(o, 'configure', { width: s.width, height: s.height, surround, title, name: src.name })) return;
      o.configured = config;
      o.anchor = picture ? src.anchor() : undefined; // fixed while the output is: no jitter
    }
    const plan = this.plan(o, src);
    if (!drawn) src.render(o.ctx, { background: surround, composite: !!picture, raster: this.raster(), mesh: false });
    const { sx, sy, sw, sh } = plan.crop;
    if (this.tell(o, 'present', o.work, sx, sy, sw, sh)) o.frames++;
  }
}

/** Draws all of `src` into `dst` at its aspect, centred, on `background` (a page's own canvas
 *  showing what was drawn for an output: `canvasFor`). */
export function copyContain(dst, src, background) {
  const g = dst.getContext('2d', { alpha: false });
  const f = Math.min(dst.width / src.width, dst.height / src.height);
  const w = src.width * f;
  const h = src.height * f;
  const x = (dst.width - w) / 2;
  const y = (dst.height - h) / 2;
  if (w < dst.width - 0.5 || h < dst.height - 0.5) {
    g.fillStyle = background;
    g.fillRect(0, 0, dst.width, dst.height);
  }
  g.drawImage(src, x, y, w, h);
}

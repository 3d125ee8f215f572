// Video sources: the source face driven by live AAM tracking of a video.
//
//   "Video (bundled clip)"  spk07's unseen GRID clip, tracked from its first frame's landmarks
//   "Video file…"           any video the user drops or picks; they place a box on the face first
//   "Webcam"                getUserMedia; a face guide to put the face into, then live tracking
//
// Every new video frame (requestVideoFrameCallback, else an animation frame whose currentTime
// changed) is drawn into an offscreen canvas, read as RGBA and fitted by the package's `Tracker`
// (the loaded source model's AAM). The fit's parameters drive the source face (`paramsAt`
// returns the latest fit, its head placement re-centred on the model's mean pose so the source
// face stays centred in its card; the head motion is kept). The panel shows the frame with the
// fitted landmarks drawn over it, the tracking state and its speed.
//
// Registered with `available: (wasm) => typeof wasm.Tracker === 'function'`, so the menu offers
// these sources only with a package that can track. The active source is also reachable as
// `window.facemimicTracking` (for the console and the end-to-end tests).

import { compose, invert, registerSource } from './sources.js';
import { notify, fileError } from './toasts.js';

const CLIP_JSON = 'media/spk07-clip.json';
/** The frame shown and placed on is at most this big (longer side, px). */
const MAX_TRACK_SIDE = 640;
/**
 * Fitting happens on the frame rescaled so the face is about the model's own size (the fit's
 * cost grows with the face's size in pixels: a face twice the model's size costs ~3x more),
 * within these limits (longer side, px; upscale factor). Faces within -25%..+33% of the model's
 * size are fitted at the video's own resolution.
 */
const MAX_FIT_SIDE = 1280;
const MIN_FIT_SIDE = 160;
const MAX_UPSCALE = 2;
/** Fit log kept for inspection (entries). */
const LOG_MAX = 3000;
/** Webcam: consecutive lost frames after which the guide comes back. */
const LOST_TO_GUIDE = 40;
/**
 * Webcam auto-start: a probe fit from the guide counts when its error is below this (measured
 * with the spk07 model: 0.03 on spk07's unseen clip, 0.05-0.11 on the nine other GRID speakers,
 * 0.16 on Chromium's fake camera picture)...
 */
const AUTO_MAX_ERROR = 0.1;
/** ...the image under it has a face's contrast (grey standard deviation, 0..1; a wall has ~0.01)... */
const AUTO_MIN_CONTRAST = 0.05;
/** ...and this many probes in a row succeed. */
const AUTO_HITS = 3;
/** Live sources: time constant (s) with which the head placement re-centres in the source card. */
const RECENTRE_TAU = 4;

const MESH = 'rgba(120, 255, 200, 0.95)';
const MESH_LOST = 'rgba(255, 110, 110, 0.95)';
const GUIDE = 'rgba(124, 196, 255, 0.95)';

// Load the panel's styles with the module (before any panel exists).
{
  const href = new URL('./tracking.css', import.meta.url).href;
  if (![...document.styleSheets].some((s) => s.href === href)) {
    const link = document.createElement('link');
    link.rel = 'stylesheet';
    link.href = href;
    document.head.append(link);
  }
}

// ---------------------------------------------------------------------------------------------
// Geometry

// compose / invert of poses come from sources.js.
function wrapAngle(a) {
  return Math.atan2(Math.sin(a), Math.cos(a));
}

/** `pts` times `f`, as a Float32Array. */
function scaled(pts, f) {
  const out = new Float32Array(pts.length);
  for (let i = 0; i < pts.length; i++) out[i] = pts[i] * f;
  return out;
}

function bounds(pts) {
  let x0 = Infinity;
  let y0 = Infinity;
  let x1 = -Infinity;
  let y1 = -Infinity;
  for (let i = 0; i + 1 < pts.length; i += 2) {
    x0 = Math.min(x0, pts[i]);
    x1 = Math.max(x1, pts[i]);
    y0 = Math.min(y0, pts[i + 1]);
    y1 = Math.max(y1, pts[i + 1]);
  }
  return { x: x0, y: y0, w: x1 - x0, h: y1 - y0 };
}

/** The 68-point (iBUG / dlib) contours: [first, last, closed]. */
const CONTOURS_68 = [
  [0, 16, false], // jaw
  [17, 21, false], // brows
  [22, 26, false],
  [27, 30, false], // nose bridge
  [31, 35, false], // nostrils
  [36, 41, true], // eyes
  [42, 47, true],
  [48, 59, true], // outer lips
  [60, 67, true], // inner lips
];

/**
 * Draw landmarks (`pts` in frame pixels) with `map(x, y) -> [X, Y]` into the canvas: contour
 * lines (68-point scheme) and points. `lw`: line width in canvas pixels.
 */
function drawLandmarks(ctx, pts, map, colour, lw, { points = true, only = null } = {}) {
  const n = pts.length / 2;
  ctx.save();
  ctx.strokeStyle = colour;
  ctx.fillStyle = colour;
  ctx.lineWidth = lw;
  ctx.lineJoin = 'round';
  ctx.lineCap = 'round';
  if (n === 68) {
    ctx.beginPath();
    for (const [a, b, closed] of only ?? CONTOURS_68) {
      for (let i = a; i <= b; i++) {
        const [X, Y] = map(pts[2 * i], pts[2 * i + 1]);
        if (i === a) ctx.moveTo(X, Y);
        else ctx.lineTo(X, Y);
      }
      if (closed) ctx.closePath();
    }
    ctx.stroke();
  }
  if (points || n !== 68) {
    const r = Math.max(1, lw * 1.1);
    ctx.beginPath();
    for (let i = 0; i < n; i++) {
      const [X, Y] = map(pts[2 * i], pts[2 * i + 1]);
      ctx.moveTo(X + r, Y);
      ctx.arc(X, Y, r, 0, Math.PI * 2);
    }
    ctx.fill();
  }
  ctx.restore();
}

// ---------------------------------------------------------------------------------------------
// Small DOM helpers

function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (k === 'class') e.className = v;
    else if (k === 'text') e.textContent = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (k in e && typeof v !== 'string') e[k] = v;
    else e.setAttribute(k, v);
  }
  e.append(...children);
  return e;
}

function button(label, onclick, extra = {}) {
  return el('button', { type: 'button', class: 'btn', onclick, ...extra }, label);
}

function message(e) {
  return e instanceof Error ? e.message : String(e);
}

// ---------------------------------------------------------------------------------------------
// One tracker per source model (the fitter's precomputation is done once per model).

let cachedTracker = null; // { model, tracker }

function trackerFor(wasm, model) {
  if (cachedTracker && cachedTracker.model === model) return cachedTracker.tracker;
  if (cachedTracker) {
    try {
      cachedTracker.tracker.free();
    } catch {
      // already freed
    }
  }
  const T = wasm.Tracker;
  const tracker = typeof T.fromModel === 'function' ? T.fromModel(model) : new T(model.toBytes());
  cachedTracker = { model, tracker };
  return tracker;
}

/** The clip's description (fetched once). */
let clipInfo = null;
async function loadClipInfo() {
  if (!clipInfo) {
    clipInfo = (async () => {
      const r = await fetch(CLIP_JSON);
      if (!r.ok) throw new Error(`HTTP ${r.status} for ${CLIP_JSON}`);
      const j = await r.json();
      if (!j || typeof j.video !== 'string' || !Array.isArray(j.initLandmarks) || !j.initLandmarks.every(Number.isFinite)) {
        throw new Error(`${CLIP_JSON}: expected { video, fps, initLandmarks: number[] }`);
      }
      return j;
    })();
    clipInfo.catch(() => {
      clipInfo = null;
    });
  }
  return clipInfo;
}

// ---------------------------------------------------------------------------------------------
// The source

const TITLES = { clip: 'Bundled clip', file: 'Video file', webcam: 'Webcam' };

/**
 * A source driven by tracking a video. `mode`: "clip" | "file" | "webcam".
 *
 * Phases: "loading" -> ("empty": file, no video yet) -> "placing" (file: a box on a paused frame;
 * webcam: the guide) -> "tracking" <-> "paused"; "error" when the video or camera fails.
 */
class VideoSource {
  constructor(mode, ctx) {
    this.kind = mode === 'clip' ? 'video-clip' : mode === 'file' ? 'video-file' : 'webcam';
    this.label = TITLES[mode];
    this.mode = mode;
    this.ctx = ctx;
    this.wasm = ctx.wasm;
    this.model = typeof ctx.sourceModel === 'function' ? ctx.sourceModel() : ctx.source?.model;
    this.info = typeof ctx.sourceInfo === 'function' ? ctx.sourceInfo() : ctx.source?.info;
    this.phase = 'loading';
    this.running = false;
    this.tracker = null;
    this.params = this.initialParams();
    this.meanPose = this.model.baseParams().pose;
    this.meanShape = this.model.landmarks(this.model.baseParams());
    const b = bounds(this.meanShape);
    this.meanBox = b;
    this.boxAspect = b.h / b.w; // a placement box is the mean shape's bounding box
    this.anchor = null; // pose the mean pose stands for (see mapPose)
    this.last = null; // last fit result
    this.state = 'idle'; // tracking | lost | reinit | idle
    this.lostRun = 0;
    this.log = [];
    this.fitTimes = [];
    this.msPerFit = 0;
    this.fits = 0;
    this.loops = 0;
    this.box = null; // placement box / guide, frame coordinates
    this.probeHits = 0;
    this.probe = null;
    this.autoStart = true;
    this.frameNo = 0;
    this.lastMediaTime = -1;
    this.objectUrl = null;
    this.stream = null;
    this.fileName = '';
    this.k = 1; // work (shown) frame px per video px
    this.kFit = 1; // fitted frame px per video px
    this.fitCanvas = document.createElement('canvas');
    this.fitCtx = this.fitCanvas.getContext('2d', { willReadFrequently: true });
    this.work = document.createElement('canvas');
    this.workCtx = this.work.getContext('2d', { willReadFrequently: true });
    this.haveFrame = false;
    this.shownAt = 0;
    this.lastResets = 0;
  }

  initialParams() {
    const p = typeof this.ctx.currentParams === 'function' ? this.ctx.currentParams() : this.ctx.params;
    const ok =
      p && p.pose && p.shape?.length === this.info.shapeModes && p.appearance?.length === this.info.appearanceModes;
    const src = ok ? p : this.model.baseParams();
    return { pose: { ...src.pose }, shape: Array.from(src.shape), appearance: Array.from(src.appearance) };
  }

  invalidate() {
    if (typeof this.ctx.invalidate === 'function') this.ctx.invalidate();
    else this.ctx.dirty = true;
  }

  // --- lifecycle ------------------------------------------------------------------------------

  start() {
    if (this.running) return;
    this.running = true;
    window.facemimicTracking = this;
    this.buildPanel();
    try {
      this.tracker = trackerFor(this.wasm, this.model);
    } catch (e) {
      this.fail('The tracker could not be made for this source model', e);
      return;
    }
    if (this.mode === 'clip') this.openClip();
    else if (this.mode === 'file') this.setPhase('empty');
    else this.openWebcam();
  }

  stop() {
    if (!this.running) return;
    this.running = false;
    this.cancelFrames();
    if (this.video) {
      this.video.pause();
      this.video.removeAttribute('src');
      this.video.srcObject = null;
      this.video.load();
    }
    if (this.stream) for (const t of this.stream.getTracks()) t.stop();
    this.stream = null;
    if (this.objectUrl) URL.revokeObjectURL(this.objectUrl);
    this.objectUrl = null;
    this.resizeObserver?.disconnect();
    document.removeEventListener('visibilitychange', this.onVisibility);
    window.removeEventListener('keydown', this.onSpace, true);
    this.panel?.remove();
    if (window.facemimicTracking === this) window.facemimicTracking = null;
  }

  paramsAt() {
    return this.params;
  }

  // --- panel ------------------------------------------------------------------------------------

  buildPanel() {
    const id = `trk-${this.mode}`;
    this.video = el('video', { class: 'trk-video', muted: true, playsInline: true, preload: 'auto', 'aria-hidden': 'true' });
    this.video.muted = true;
    this.video.defaultMuted = true;
    this.video.setAttribute('playsinline', '');
    this.canvas = el('canvas', { class: 'trk-canvas', role: 'img', 'aria-label': `${this.label}: video with the fitted face mesh` });
    this.stateEl = el('span', { class: 'trk-state', 'data-state': 'idle', text: 'starting' });
    this.msgEl = el('p', { class: 'trk-msg', role: 'status', 'aria-live': 'polite' });
    const stat = (key, label, title) => {
      const dd = el('dd', { 'data-k': key, text: '–' });
      return [el('div', { title }, el('dt', { text: label }), dd), dd];
    };
    const [sErr, dErr] = stat('error', 'fit error', 'RMS grey-level residual of the last fit (0..1)');
    const [sIt, dIt] = stat('iterations', 'iterations', 'Iterations of the last fit (converged or not)');
    const [sFps, dFps] = stat('fps', 'fits / s', 'Frames fitted in the last second');
    const [sMs, dMs] = stat('ms', 'ms / fit', 'Time per fit (smoothed), reading the frame excluded');
    const [sLost, dLost] = stat('lost', 'lost · reinit', 'Frames reported lost · re-initialisations, this sequence');
    this.readout = { error: dErr, iterations: dIt, fps: dFps, ms: dMs, lost: dLost };

    this.playBtn = button('Pause', () => this.togglePlay(), { class: 'btn primary', 'aria-keyshortcuts': 'Space', title: 'Pause / play (space)' });
    this.restartBtn = button('Re-start', () => this.restart(), { title: 'Place the face again and start a new sequence' });
    this.startBtn = button('Start tracking', () => this.startTracking(), { class: 'btn primary' });
    this.chooseBtn = button('Choose a video…', () => this.fileInput.click());
    this.otherBtn = button('Other video…', () => this.fileInput.click(), { title: 'Track another video file (or drop one on this panel)' });
    this.fileInput = el('input', { type: 'file', accept: 'video/*,.webm,.mp4,.mov,.m4v,.ogv,.mkv', hidden: true });
    this.fileInput.addEventListener('change', () => {
      const f = this.fileInput.files?.[0];
      this.fileInput.value = '';
      if (f) this.openFile(f);
    });
    this.meshCheck = el('input', { type: 'checkbox', checked: true });
    this.meshCheck.addEventListener('change', () => this.draw());
    const meshLabel = el('label', { class: 'check' }, this.meshCheck, el('span', { text: 'Mesh overlay' }));
    const extra = [];
    if (this.mode === 'webcam') {
      this.autoCheck = el('input', { type: 'checkbox', checked: true });
      this.autoCheck.addEventListener('change', () => {
        this.autoStart = this.autoCheck.checked;
        this.probeHits = 0;
      });
      extra.push(el('label', { class: 'check', title: 'Start by itself once a face fits the guide' }, this.autoCheck, el('span', { text: 'Auto-start' })));
    }

    this.dropHint = el(
      'div',
      { class: 'trk-drop' },
      el('p', {}, el('strong', { text: 'Drop a video here' }), el('span', { text: ' or ' })),
      this.chooseBtn,
      el('small', { text: 'Any format the browser plays (WebM, MP4…). It stays on this computer.' }),
    );
    this.dropHint.hidden = true;
    // Shown instead of the picture while there is none: waiting for the camera, or an error.
    this.retryBtn = button('Try again', () => this.retry());
    this.placeholderText = el('p');
    this.placeholder = el('div', { class: 'trk-placeholder' }, this.placeholderText, this.retryBtn);
    this.placeholder.hidden = true;
    this.view = el('div', { class: 'trk-view' }, this.canvas, this.dropHint, this.placeholder, this.video);

    const title = el('h2', { id: `${id}-title` }, `Tracking · ${this.label}`);
    this.panel = el(
      'section',
      { class: 'trk-panel', id, 'aria-labelledby': `${id}-title`, 'data-mode': this.mode, 'data-phase': 'loading' },
      el('header', { class: 'trk-head' }, title, this.stateEl),
      el(
        'div',
        { class: 'trk-body' },
        this.view,
        el(
          'div',
          { class: 'trk-side' },
          el('dl', { class: 'trk-stats' }, sErr, sIt, sFps, sMs, sLost),
          el('div', { class: 'trk-buttons' }, this.startBtn, this.playBtn, this.restartBtn, this.otherBtn),
          el('div', { class: 'trk-options' }, meshLabel, ...extra),
          this.msgEl,
          this.fileInput,
        ),
      ),
    );

    // Keyboard on the frame: move / scale the placement box, Enter starts.
    this.canvas.addEventListener('keydown', (e) => this.onKey(e));
    this.canvas.addEventListener('pointerdown', (e) => this.onPointerDown(e));
    this.canvas.addEventListener('pointermove', (e) => this.onPointerMove(e));
    this.canvas.addEventListener('pointerup', (e) => this.onPointerUp(e));
    this.canvas.addEventListener('pointercancel', (e) => this.onPointerUp(e));
    // Video files dropped on the panel (and not elsewhere: the page takes other drops as models).
    if (this.mode === 'file') {
      const panel = this.panel;
      panel.addEventListener('dragover', (e) => {
        if (![...(e.dataTransfer?.types || [])].includes('Files')) return;
        e.preventDefault();
        e.stopPropagation();
        e.dataTransfer.dropEffect = 'copy';
        panel.classList.add('drop-hover');
      });
      panel.addEventListener('dragleave', (e) => {
        if (!panel.contains(e.relatedTarget)) panel.classList.remove('drop-hover');
      });
      panel.addEventListener('drop', (e) => {
        panel.classList.remove('drop-hover');
        document.body.classList.remove('dragging');
        const f = e.dataTransfer?.files?.[0];
        if (!f) return;
        // Model files dropped here go to the page (which adds them as targets).
        if ([...e.dataTransfer.files].every((x) => /\.fmm$/i.test(x.name))) return;
        e.preventDefault();
        e.stopPropagation();
        if (e.dataTransfer.files.length > 1) notify('info', `Used ${f.name}`, 'one video at a time; the other files were ignored');
        this.openFile(f);
      });
    }

    const anchor = document.querySelector('.stage .transport');
    if (anchor) anchor.after(this.panel);
    else (document.querySelector('main') || document.body).append(this.panel);

    // A hidden tab presents no frames: pause a clip or file (the fit would have to jump).
    this.onVisibility = () => {
      if (this.mode === 'webcam' || !this.running) return;
      if (document.hidden && this.phase === 'tracking') {
        this.hiddenPause = true;
        this.togglePlay();
      } else if (!document.hidden && this.hiddenPause && this.phase === 'paused') {
        this.hiddenPause = false;
        this.togglePlay();
      }
    };
    document.addEventListener('visibilitychange', this.onVisibility);
    // Space pauses / plays this source (the page's Space would switch to the recorded track).
    this.onSpace = (e) => {
      if ((e.key !== ' ' && e.code !== 'Space') || e.altKey || e.ctrlKey || e.metaKey || e.defaultPrevented) return;
      if (this.phase !== 'tracking' && this.phase !== 'paused') return;
      const t = e.target;
      if (t instanceof HTMLElement) {
        const tag = t.tagName;
        if (['BUTTON', 'SELECT', 'TEXTAREA', 'SUMMARY', 'A'].includes(tag) || t.isContentEditable) return;
        if (tag === 'INPUT' && t.getAttribute('type') !== 'range') return;
      }
      e.preventDefault();
      this.togglePlay();
    };
    window.addEventListener('keydown', this.onSpace, true);
    this.resizeObserver = new ResizeObserver(() => this.draw());
    this.resizeObserver.observe(this.canvas);
    this.setPhase('loading');
  }

  setPhase(phase, msg) {
    this.phase = phase;
    if (!this.panel) return;
    this.panel.dataset.phase = phase;
    const m = this.mode;
    const tracking = phase === 'tracking' || phase === 'paused';
    this.startBtn.hidden = !(phase === 'placing');
    this.startBtn.textContent = m === 'webcam' ? 'Start' : 'Start tracking';
    this.playBtn.hidden = !tracking;
    this.restartBtn.hidden = !(tracking || (phase === 'error' && this.haveFrame && !this.streamEnded));
    this.playBtn.textContent = phase === 'paused' ? 'Play' : 'Pause';
    this.dropHint.hidden = !(m === 'file' && (phase === 'empty' || phase === 'error'));
    this.otherBtn.hidden = !(m === 'file' && ['placing', 'tracking', 'paused'].includes(phase));
    const blank = !this.haveFrame && (phase === 'loading' || phase === 'error') && !(m === 'file');
    this.canvas.hidden = (m === 'file' && phase === 'empty') || blank;
    this.placeholder.hidden = !blank;
    this.retryBtn.hidden = phase !== 'error';
    if (blank) this.placeholderText.textContent = phase === 'error' ? msg || 'Something went wrong.' : msg || 'Loading…';
    this.canvas.tabIndex = phase === 'placing' ? 0 : -1;
    if (phase === 'placing') {
      this.canvas.setAttribute(
        'aria-label',
        m === 'webcam'
          ? 'Webcam image with the face guide'
          : 'Video frame with the face box: drag it onto the face, or use the arrow keys to move it, + and − to resize it, Enter to start',
      );
    } else this.canvas.setAttribute('aria-label', `${this.label}: video with the fitted face mesh`);
    if (msg !== undefined) this.say(msg);
    else if (phase === 'empty') this.say('Drop a video file on this panel or choose one; then place the box on the face and start.');
    else if (phase === 'placing' && m === 'file') this.say('Drag the box onto the face (drag its corner to resize), then start tracking.');
    else if (phase === 'placing' && m === 'webcam') this.say('Put your face inside the oval and look at the camera; tracking starts when it fits (or press Start).');
    else if (phase === 'paused') this.say('Paused.');
    this.showState();
    this.draw();
  }

  /** After an error: open the clip or the camera again. */
  retry() {
    if (!this.running) return;
    this.cancelFrames();
    if (this.mode === 'clip') this.openClip();
    else if (this.mode === 'webcam') {
      if (this.stream) for (const t of this.stream.getTracks()) t.stop();
      this.stream = null;
      this.openWebcam();
    }
  }

  say(text) {
    if (this.msgEl && this.msgEl.textContent !== text) this.msgEl.textContent = text;
  }

  showState() {
    if (!this.stateEl) return;
    let s;
    let label;
    if (this.phase === 'tracking') {
      s = this.state;
      label = s === 'lost' ? 'face lost' : s === 'reinit' ? 're-initialised' : 'tracking';
    } else {
      s = this.phase;
      label = {
        loading: 'loading',
        empty: 'no video',
        placing: this.mode === 'webcam' ? 'looking for a face' : 'place the face',
        paused: 'paused',
        error: 'error',
        idle: 'idle',
      }[this.phase];
    }
    this.stateEl.dataset.state = s;
    if (this.stateEl.textContent !== label) this.stateEl.textContent = label;
    this.panel.dataset.state = s;
  }

  fail(what, e) {
    const reason = e === undefined ? '' : message(e);
    this.cancelFrames();
    this.setPhase('error', reason ? `${what}: ${reason}` : what);
    this.stateEl.textContent = 'error';
    this.stateEl.dataset.state = 'error';
    this.panel.dataset.state = 'error';
  }

  // --- opening videos -----------------------------------------------------------------------------

  async openClip() {
    try {
      const info = await loadClipInfo();
      if (!this.running) return;
      this.clip = info;
      this.fps = info.fps || 25;
      this.fileName = info.video;
      await this.loadVideo(new URL(info.video, new URL(CLIP_JSON, document.baseURI)).href, info.video);
      if (!this.running) return;
      if (info.initLandmarks.length !== this.meanShape.length) {
        throw new Error(
          `the clip has ${info.initLandmarks.length / 2} start landmarks, the source model ${this.meanShape.length / 2}`,
        );
      }
      this.video.loop = false;
      if (!this.endedHooked) {
        this.endedHooked = true;
        this.video.addEventListener('ended', () => this.onClipEnded());
      }
      await this.startClipSequence();
    } catch (e) {
      if (!this.running) return;
      fileError(this.fileName || CLIP_JSON, e);
      this.fail(`The bundled clip could not be played`, e);
    }
  }

  /** The clip from frame 0: the tracker starts from the clip's first-frame landmarks. */
  async startClipSequence() {
    this.cancelFrames();
    await this.seek(0);
    if (!this.running) return;
    const k = this.grab();
    const init = this.clip.initLandmarks.map((v) => v * k);
    this.kFit = this.fitScaleFor(bounds(init).h);
    this.tracker.startFromLandmarks(scaled(init, this.kFit / k));
    this.beginSequence();
    this.setPhase('tracking', `Tracking spk07's unseen clip (${this.clip.frames ?? '?'} frames at ${this.fps} fps) from its first frame's landmarks.`);
    this.fitCurrent(0);
    await this.play();
  }

  async onClipEnded() {
    if (!this.running || this.mode !== 'clip') return;
    this.loops++;
    try {
      await this.startClipSequence();
    } catch (e) {
      if (this.running) this.fail('The clip could not loop', e);
    }
  }

  async openFile(file) {
    if (!this.running) return;
    const name = file.name || 'the file';
    const looksVideo = (file.type || '').startsWith('video/') || /\.(webm|mp4|m4v|mov|ogv|ogg|mkv)$/i.test(name);
    if (!looksVideo) {
      const err = new Error(`not a video file (${file.type || 'unknown type'}); drop a WebM, MP4 or other video the browser plays`);
      fileError(name, err);
      if (!this.haveFrame) this.setPhase('empty', `${name}: ${err.message}`);
      else this.say(`${name}: ${err.message}`);
      return;
    }
    this.cancelFrames();
    if (this.objectUrl) URL.revokeObjectURL(this.objectUrl);
    this.objectUrl = URL.createObjectURL(file);
    this.fileName = name;
    this.haveFrame = false;
    this.last = null;
    this.setPhase('loading', `Opening ${name}…`);
    try {
      await this.loadVideo(this.objectUrl, name);
      if (!this.running) return;
      this.video.loop = false;
      if (!this.endedHooked) {
        this.endedHooked = true;
        this.video.addEventListener('ended', () => this.onFileEnded());
      }
      this.fps = 30;
      await this.seek(0);
      if (!this.running) return;
      this.grab();
      this.placeBox();
      this.setPhase('placing');
      this.canvas.focus({ preventScroll: true });
    } catch (e) {
      if (!this.running) return;
      fileError(name, e);
      this.haveFrame = false;
      this.setPhase(this.mode === 'file' ? 'empty' : 'error', `${name}: ${message(e)}`);
      this.panel.dataset.state = 'error';
    }
  }

  async openWebcam() {
    this.setPhase('loading', 'Asking for the camera…');
    const md = navigator.mediaDevices;
    if (!md || typeof md.getUserMedia !== 'function') {
      this.fail(
        window.isSecureContext
          ? 'This browser has no camera access (navigator.mediaDevices is missing)'
          : 'The camera needs a secure page: open the demo from http://127.0.0.1 or https',
      );
      return;
    }
    let stream;
    try {
      stream = await md.getUserMedia({
        video: { width: { ideal: 640 }, height: { ideal: 480 }, facingMode: 'user' },
        audio: false,
      });
    } catch (e) {
      if (!this.running) return;
      const name = e?.name || '';
      let text;
      if (name === 'NotAllowedError' || name === 'SecurityError') {
        text = 'Camera permission was denied. Allow the camera for this page (the icon in the address bar), then press Try again.';
      } else if (name === 'NotFoundError' || name === 'OverconstrainedError' || name === 'DevicesNotFoundError') {
        text = 'No camera was found. Connect one, or use the bundled clip or a video file.';
      } else if (name === 'NotReadableError' || name === 'TrackStartError') {
        text = 'The camera is busy (another application may be using it).';
      } else text = `The camera could not be opened: ${message(e)}`;
      notify('error', 'Webcam unavailable', text);
      this.fail(text);
      return;
    }
    if (!this.running) {
      for (const t of stream.getTracks()) t.stop();
      return;
    }
    this.stream = stream;
    this.streamEnded = false;
    this.fileName = stream.getVideoTracks()[0]?.label || 'camera';
    stream.getVideoTracks()[0]?.addEventListener('ended', () => {
      if (!this.running || this.stream !== stream) return;
      this.streamEnded = true;
      this.haveFrame = false;
      this.fail('The camera stopped sending pictures (unplugged, or access was withdrawn)');
    });
    try {
      this.video.srcObject = stream;
      await this.waitFor(this.video, 'loadeddata', 'the camera sent no picture');
      await this.video.play();
    } catch (e) {
      if (this.running) this.fail('The camera picture could not be shown', e);
      return;
    }
    if (!this.running) return;
    this.fps = stream.getVideoTracks()[0]?.getSettings?.().frameRate || 30;
    this.grab();
    this.placeBox();
    this.probeHits = 0;
    this.setPhase('placing');
    this.requestFrames();
  }

  /** Load `src` into the video element; rejects with a reason when it cannot be decoded. */
  async loadVideo(src, name) {
    const v = this.video;
    v.srcObject = null;
    v.src = src;
    v.load();
    await this.waitFor(v, 'loadeddata', `${name}: no video frame could be decoded`);
    if (!v.videoWidth || !v.videoHeight) throw new Error('the file has no video track');
  }

  waitFor(target, event, timeoutMessage, ms = 15000) {
    return new Promise((resolve, reject) => {
      const v = this.video;
      const done = (fn, arg) => {
        clearTimeout(timer);
        target.removeEventListener(event, onOk);
        v.removeEventListener('error', onErr);
        fn(arg);
      };
      const onOk = () => done(resolve);
      const onErr = () => done(reject, new Error(mediaErrorText(v.error)));
      const timer = setTimeout(() => done(reject, new Error(timeoutMessage)), ms);
      target.addEventListener(event, onOk);
      v.addEventListener('error', onErr);
    });
  }

  async seek(time) {
    const v = this.video;
    if (Math.abs(v.currentTime - time) < 1e-6 && v.readyState >= 2) return;
    const p = this.waitFor(v, 'seeked', 'the video could not seek');
    v.currentTime = time;
    await p;
  }

  async play() {
    try {
      await this.video.play();
    } catch (e) {
      // Autoplay refused (a browser without a user gesture): show it paused; Play starts it.
      if (!this.running) return;
      this.setPhase('paused', `The browser did not start the video by itself (${message(e)}): press Play.`);
      return;
    }
    this.requestFrames();
  }

  // --- the frame loop -------------------------------------------------------------------------------

  requestFrames() {
    if (!this.running || this.frameHandle) return;
    const v = this.video;
    if (typeof v.requestVideoFrameCallback === 'function') {
      const cb = (now, meta) => {
        this.frameHandle = null;
        if (!this.running) return;
        this.onVideoFrame(meta.mediaTime);
        if (this.running && !v.paused && !v.ended) this.requestFrames();
      };
      this.frameHandle = { rvfc: v.requestVideoFrameCallback(cb) };
    } else {
      const cb = () => {
        this.frameHandle = null;
        if (!this.running) return;
        if (v.currentTime !== this.lastMediaTime) this.onVideoFrame(v.currentTime);
        if (this.running && !v.paused && !v.ended) this.requestFrames();
      };
      this.frameHandle = { raf: requestAnimationFrame(cb) };
    }
  }

  cancelFrames() {
    const h = this.frameHandle;
    this.frameHandle = null;
    if (!h) return;
    if (h.rvfc !== undefined) this.video.cancelVideoFrameCallback?.(h.rvfc);
    if (h.raf !== undefined) cancelAnimationFrame(h.raf);
  }

  onVideoFrame(mediaTime) {
    if (mediaTime === this.lastMediaTime && this.mode !== 'webcam') return;
    this.lastMediaTime = mediaTime;
    this.grab();
    if (this.phase === 'tracking') this.fitCurrent(mediaTime);
    else if (this.phase === 'placing' && this.mode === 'webcam') this.probeGuide();
    this.draw();
  }

  /** Draw the current video frame into the work canvas (scaled to at most MAX_TRACK_SIDE). */
  grab() {
    const v = this.video;
    const vw = v.videoWidth;
    const vh = v.videoHeight;
    if (!vw || !vh) return this.k;
    const k = Math.min(1, MAX_TRACK_SIDE / Math.max(vw, vh));
    const w = Math.max(1, Math.round(vw * k));
    const h = Math.max(1, Math.round(vh * k));
    if (this.work.width !== w || this.work.height !== h) {
      this.work.width = w;
      this.work.height = h;
      this.canvas.style.aspectRatio = `${w} / ${h}`;
      this.canvas.style.setProperty('--ar', String(w / h));
    }
    this.k = k;
    this.workCtx.drawImage(v, 0, 0, w, h);
    this.haveFrame = true;
    return k;
  }

  /**
   * The fit scale (fitted px per video px) for a face `faceH` shown (work) px tall: the face at
   * about the model's size; the video's own resolution when that is close.
   */
  fitScaleFor(faceH) {
    const v = this.video;
    const side = Math.max(v.videoWidth, v.videoHeight) || 1;
    const kf = this.meanBox.h / Math.max(1, faceH / this.k);
    if (kf > 0.75 && kf < 1.33 && side <= MAX_FIT_SIDE) return 1;
    return Math.min(MAX_UPSCALE, MAX_FIT_SIDE / side, Math.max(MIN_FIT_SIDE / side, kf));
  }

  /** The current frame's RGBA at the fit scale: { data, width, height }. */
  fitImage() {
    if (Math.abs(this.kFit - this.k) < 1e-9) {
      const { width: w, height: h } = this.work;
      return this.workCtx.getImageData(0, 0, w, h);
    }
    const v = this.video;
    const w = Math.max(1, Math.round(v.videoWidth * this.kFit));
    const h = Math.max(1, Math.round(v.videoHeight * this.kFit));
    if (this.fitCanvas.width !== w || this.fitCanvas.height !== h) {
      this.fitCanvas.width = w;
      this.fitCanvas.height = h;
    }
    this.fitCtx.imageSmoothingQuality = 'medium';
    this.fitCtx.drawImage(v, 0, 0, w, h);
    return this.fitCtx.getImageData(0, 0, w, h);
  }

  /** A fit result in work (shown) coordinates. */
  toWork(r) {
    const f = this.k / this.kFit;
    return {
      ...r,
      landmarks: scaled(r.landmarks, f),
      pose: { scale: r.pose.scale * f, rotation: r.pose.rotation, tx: r.pose.tx * f, ty: r.pose.ty * f },
    };
  }

  beginSequence() {
    this.last = null;
    this.state = 'tracking';
    this.lostRun = 0;
    this.seqStartLost = this.tracker.lostCount;
    this.seqStartResets = this.tracker.resets;
    this.lastResets = this.tracker.resets;
    if (this.mode !== 'clip') this.anchor = null; // the clip keeps its first frame's placement
  }

  /** Fit the frame in the work canvas; update the params, state and stats. */
  fitCurrent(mediaTime) {
    const image = this.fitImage();
    const t0 = performance.now();
    let fit;
    try {
      fit = this.tracker.track(image.data, image.width, image.height);
    } catch (e) {
      this.fail('Tracking failed', e);
      return;
    }
    const t1 = performance.now();
    const r = this.toWork(fit);
    const ms = t1 - t0;
    this.fits++;
    this.msPerFit = this.fits === 1 ? ms : this.msPerFit + (ms - this.msPerFit) * 0.1;
    this.fitTimes.push(t1);
    while (this.fitTimes.length && t1 - this.fitTimes[0] > 1000) this.fitTimes.shift();

    const resets = this.tracker.resets;
    this.state = r.lost ? 'lost' : resets > this.lastResets ? 'reinit' : 'tracking';
    this.lastResets = resets;
    this.last = r;
    this.lostRun = r.lost ? this.lostRun + 1 : 0;
    if (!r.lost || !this.params) {
      this.params = { pose: this.mapPose(r.pose, t1), shape: r.shape, appearance: this.clampAppearance(r.appearance) };
      this.invalidate();
    }
    const frame = this.fps ? Math.round(mediaTime * this.fps) : this.frameNo;
    this.frameNo++;
    this.log.push({
      loop: this.loops,
      frame,
      time: mediaTime,
      error: r.error,
      iterations: r.iterations,
      converged: r.converged,
      lost: r.lost,
      ms,
      landmarks: Array.from(scaled(fit.landmarks, 1 / this.kFit)), // video pixels
    });
    if (this.log.length > LOG_MAX) this.log.splice(0, this.log.length - LOG_MAX);

    // The face grew or shrank a lot (moving to or from the camera): carry on at a new fit scale.
    if (!r.lost) {
      const want = this.fitScaleFor(bounds(r.landmarks).h);
      if (Math.abs(want / this.kFit - 1) > 0.3) {
        try {
          this.tracker.startFromLandmarks(scaled(fit.landmarks, want / this.kFit));
          this.kFit = want;
        } catch {
          // keep the current scale
        }
      }
    }

    if (this.mode === 'webcam' && this.lostRun >= LOST_TO_GUIDE) {
      this.placeBox();
      this.probeHits = 0;
      this.setPhase('placing', 'The face was lost: put it back inside the oval (tracking restarts when it fits, or press Start).');
      return;
    }
    if (r.lost) this.say('Face lost: the tracker keeps re-initialising from the last good fit. Re-start places it again.');
    else if (this.msgEl.textContent.startsWith('Face lost')) this.say('Tracking.');
    this.showStats(t1);
  }

  /**
   * The fitted pose, re-centred: `meanPose o anchor^-1 o pose`. The anchor is the sequence's first
   * fitted pose (the clip: its first frame, so the clip's motion is reproduced exactly); for live
   * video it then follows the head slowly, so a face anywhere in the picture ends up centred.
   */
  mapPose(pose, now) {
    if (!this.anchor) {
      this.anchor = { ls: Math.log(pose.scale), rotation: pose.rotation, tx: pose.tx, ty: pose.ty, at: now };
    } else if (this.mode !== 'clip') {
      const a = this.anchor;
      const u = 1 - Math.exp(-Math.max(0, now - a.at) / 1000 / RECENTRE_TAU);
      a.ls += (Math.log(pose.scale) - a.ls) * u;
      a.rotation += wrapAngle(pose.rotation - a.rotation) * u;
      a.tx += (pose.tx - a.tx) * u;
      a.ty += (pose.ty - a.ty) * u;
      a.at = now;
    }
    const a = this.anchor;
    const fix = compose(this.meanPose, invert({ scale: Math.exp(a.ls), rotation: a.rotation, tx: a.tx, ty: a.ty }));
    return compose(fix, pose);
  }

  /**
   * Appearance parameters limited to +-3 sigma: another person's face (a webcam, a dropped video)
   * projects far outside the source model's appearance space, and an unclamped projection
   * paints noise on the source face. Faces the model was built for are well inside the limit.
   */
  clampAppearance(lambda) {
    const sig = this.info.appearanceSigma;
    for (let i = 0; i < lambda.length; i++) {
      const lim = 3 * (sig[i] || 0);
      if (lim > 0) lambda[i] = Math.max(-lim, Math.min(lim, lambda[i]));
    }
    return lambda;
  }

  showStats(now = performance.now()) {
    if (now - this.shownAt < 200) return;
    this.shownAt = now;
    const r = this.last;
    const set = (k, v) => {
      if (this.readout[k].textContent !== v) this.readout[k].textContent = v;
    };
    set('error', r ? r.error.toFixed(3) : '–');
    set('iterations', r ? `${r.iterations}${r.converged ? '' : ' (max)'}` : '–');
    set('fps', String(this.fitTimes.length));
    set('ms', this.fits ? this.msPerFit.toFixed(1) : '–');
    set('lost', `${this.tracker.lostCount - (this.seqStartLost ?? 0)} · ${this.tracker.resets - (this.seqStartResets ?? 0)}`);
    this.readout.ms.parentElement.title = this.fits
      ? `Time per fit (smoothed): ${this.msPerFit.toFixed(2)} ms, i.e. up to ${Math.round(1000 / Math.max(0.01, this.msPerFit))} fits/s`
      : '';
    this.showState();
  }

  // --- placing the face -----------------------------------------------------------------------------

  /** A starting box: the last fit's box, else centred at half the frame height. */
  placeBox() {
    const { width: W, height: H } = this.work;
    if (this.last && !this.last.lost && this.mode === 'file') {
      const b = bounds(this.last.landmarks);
      const h = b.w * this.boxAspect > b.h ? b.w * this.boxAspect : b.h;
      const w = h / this.boxAspect;
      this.box = { x: b.x + b.w / 2 - w / 2, y: b.y + b.h / 2 - h / 2, w, h };
      return;
    }
    const h = H * (this.mode === 'webcam' ? 0.5 : 0.45);
    const w = h / this.boxAspect;
    this.box = { x: (W - w) / 2, y: (H - h) / 2 + (this.mode === 'webcam' ? H * 0.04 : 0), w, h };
  }

  /** Webcam: a quick fit from the guide every few frames; a few good ones in a row start tracking. */
  probeGuide() {
    if (!this.autoStart || !this.box) return;
    this.frameNo++;
    if (this.frameNo % 3 !== 0) return;
    const b = this.box;
    let r;
    try {
      this.kFit = this.fitScaleFor(b.h);
      const f = this.kFit / this.k;
      this.tracker.startFromBox(b.x * f, b.y * f, b.w * f, b.h * f);
      const image = this.fitImage();
      r = this.toWork(this.tracker.track(image.data, image.width, image.height));
    } catch (e) {
      this.fail('Tracking failed', e);
      return;
    }
    this.probe = r;
    const fb = bounds(r.landmarks);
    const inGuide =
      Math.abs(fb.x + fb.w / 2 - (b.x + b.w / 2)) < b.w * 0.2 &&
      Math.abs(fb.y + fb.h / 2 - (b.y + b.h / 2)) < b.h * 0.2 &&
      fb.h > b.h * 0.65 &&
      fb.h < b.h * 1.45;
    // Other people's faces project up to ~9 sigma into the source model's appearance modes;
    // far beyond that is not a face.
    const sig = this.info.appearanceSigma;
    const plausible = r.appearance.every((v, i) => !(Math.abs(v) > 12 * (sig[i] || Infinity)));
    const good =
      !r.lost && r.error < AUTO_MAX_ERROR && inGuide && plausible && greyContrast(this.workCtx, fb) > AUTO_MIN_CONTRAST;
    this.probeHits = good ? this.probeHits + 1 : 0;
    this.readout.error.textContent = r.error.toFixed(3);
    this.readout.iterations.textContent = String(r.iterations);
    this.say(
      good
        ? `Face found (${this.probeHits}/${AUTO_HITS})… hold still.`
        : 'Put your face inside the oval and look at the camera; tracking starts when it fits (or press Start).',
    );
    if (this.probeHits >= AUTO_HITS) this.startTracking(r.landmarks);
  }

  /** Start tracking from the placement box (or given landmarks) and play. */
  async startTracking(landmarks = null) {
    if (!this.haveFrame || !this.box) return;
    try {
      this.kFit = this.fitScaleFor(landmarks ? bounds(landmarks).h : this.box.h);
      const f = this.kFit / this.k;
      const b = this.box;
      if (landmarks) this.tracker.startFromLandmarks(scaled(landmarks, f));
      else this.tracker.startFromBox(b.x * f, b.y * f, b.w * f, b.h * f);
    } catch (e) {
      this.say(`Cannot start: ${message(e)}`);
      return;
    }
    this.beginSequence();
    this.setPhase('tracking', this.mode === 'webcam' ? 'Tracking your face.' : `Tracking ${this.fileName}.`);
    if (this.mode === 'file') {
      this.fitCurrent(this.video.currentTime);
      // Where the sequence began, to loop back to with a known fit.
      this.seqStart = this.last && !this.last.lost ? { time: this.video.currentTime, landmarks: this.last.landmarks } : null;
      this.draw();
      await this.play();
    } else this.requestFrames();
  }

  /** A file played to its end: loop back to where tracking began, from the fit found there. */
  async onFileEnded() {
    if (!this.running || this.mode !== 'file' || this.phase !== 'tracking') return;
    this.loops++;
    const start = this.seqStart;
    try {
      this.cancelFrames();
      await this.seek(start ? start.time : 0);
      if (!this.running || this.phase !== 'tracking') return;
      this.grab();
      if (start) {
        this.kFit = this.fitScaleFor(bounds(start.landmarks).h);
        this.tracker.startFromLandmarks(scaled(start.landmarks, this.kFit / this.k));
        this.beginSequence();
        this.fitCurrent(this.video.currentTime);
        this.draw();
        await this.play();
      } else {
        this.restart();
      }
    } catch (e) {
      if (this.running) this.fail('The video could not loop', e);
    }
  }

  async restart() {
    if (!this.running) return;
    if (this.mode === 'clip') {
      try {
        await this.startClipSequence();
      } catch (e) {
        this.fail('The clip could not restart', e);
      }
      return;
    }
    this.cancelFrames();
    if (this.mode === 'file') this.video.pause();
    this.grab();
    this.placeBox();
    this.probeHits = 0;
    this.setPhase('placing');
    if (this.mode === 'webcam') this.requestFrames();
    else this.canvas.focus({ preventScroll: true });
  }

  togglePlay() {
    if (this.phase === 'tracking') {
      this.cancelFrames();
      if (this.mode !== 'webcam') this.video.pause();
      this.setPhase('paused');
    } else if (this.phase === 'paused') {
      this.setPhase('tracking', 'Tracking.');
      if (this.mode === 'webcam') this.requestFrames();
      else this.play();
    }
  }

  // --- pointer and keyboard on the frame --------------------------------------------------------

  /** Canvas pixels per frame pixel, and whether the display is mirrored. */
  viewScale() {
    return { s: this.canvas.width / Math.max(1, this.work.width), mirror: this.mode === 'webcam' };
  }

  toFrame(e) {
    const r = this.canvas.getBoundingClientRect();
    const W = this.work.width;
    const H = this.work.height;
    let x = ((e.clientX - r.left) / r.width) * W;
    const y = ((e.clientY - r.top) / r.height) * H;
    if (this.mode === 'webcam') x = W - x;
    return { x, y };
  }

  onPointerDown(e) {
    if (this.phase !== 'placing' || this.mode !== 'file' || !this.box) return;
    const p = this.toFrame(e);
    const b = this.box;
    const handle = (14 / this.canvas.getBoundingClientRect().width) * this.work.width;
    const nearCorner = Math.abs(p.x - (b.x + b.w)) < handle && Math.abs(p.y - (b.y + b.h)) < handle;
    const inside = p.x >= b.x && p.x <= b.x + b.w && p.y >= b.y && p.y <= b.y + b.h;
    this.drag = nearCorner
      ? { kind: 'resize', x0: b.x, y0: b.y }
      : inside
        ? { kind: 'move', dx: p.x - b.x, dy: p.y - b.y }
        : { kind: 'new', x0: p.x, y0: p.y };
    this.canvas.setPointerCapture(e.pointerId);
    this.canvas.focus({ preventScroll: true });
    e.preventDefault();
  }

  onPointerMove(e) {
    if (this.phase !== 'placing' || this.mode !== 'file') return;
    const p = this.toFrame(e);
    if (!this.drag) {
      const b = this.box;
      if (!b) return;
      const handle = (14 / this.canvas.getBoundingClientRect().width) * this.work.width;
      const nearCorner = Math.abs(p.x - (b.x + b.w)) < handle && Math.abs(p.y - (b.y + b.h)) < handle;
      const inside = p.x >= b.x && p.x <= b.x + b.w && p.y >= b.y && p.y <= b.y + b.h;
      this.canvas.style.cursor = nearCorner ? 'nwse-resize' : inside ? 'move' : 'crosshair';
      return;
    }
    const d = this.drag;
    const b = this.box;
    if (d.kind === 'move') {
      b.x = p.x - d.dx;
      b.y = p.y - d.dy;
    } else {
      const x0 = d.x0;
      const y0 = d.y0;
      // Keep the mean shape's aspect: the larger of the two drag extents decides the size.
      const h = Math.max(8, Math.abs(p.y - y0), Math.abs(p.x - x0) * this.boxAspect);
      const w = h / this.boxAspect;
      b.x = p.x >= x0 ? x0 : x0 - w;
      b.y = p.y >= y0 ? y0 : y0 - h;
      b.w = w;
      b.h = h;
    }
    this.clampBox();
    this.draw();
  }

  onPointerUp() {
    this.drag = null;
  }

  clampBox() {
    const b = this.box;
    const { width: W, height: H } = this.work;
    b.h = Math.min(Math.max(b.h, 8), H * 1.5);
    b.w = b.h / this.boxAspect;
    b.x = Math.min(Math.max(b.x, -b.w / 2), W - b.w / 2);
    b.y = Math.min(Math.max(b.y, -b.h / 2), H - b.h / 2);
  }

  onKey(e) {
    if (this.phase !== 'placing') return;
    if (e.key === 'Enter') {
      e.preventDefault();
      this.startTracking();
      return;
    }
    if (this.mode !== 'file' || !this.box) return;
    const b = this.box;
    const step = (e.shiftKey ? 10 : 2) / this.k;
    const grow = (f) => {
      const cx = b.x + b.w / 2;
      const cy = b.y + b.h / 2;
      b.h *= f;
      b.w = b.h / this.boxAspect;
      b.x = cx - b.w / 2;
      b.y = cy - b.h / 2;
    };
    switch (e.key) {
      case 'ArrowLeft':
        b.x -= step;
        break;
      case 'ArrowRight':
        b.x += step;
        break;
      case 'ArrowUp':
        b.y -= step;
        break;
      case 'ArrowDown':
        b.y += step;
        break;
      case '+':
      case '=':
      case 'PageUp':
        grow(1.05);
        break;
      case '-':
      case '_':
      case 'PageDown':
        grow(1 / 1.05);
        break;
      default:
        return;
    }
    e.preventDefault();
    this.clampBox();
    this.draw();
  }

  // --- drawing ------------------------------------------------------------------------------------

  draw() {
    const c = this.canvas;
    if (!c || !this.running || c.hidden) return;
    const dpr = window.devicePixelRatio || 1;
    const cw = Math.max(1, Math.min(4096, Math.round(c.clientWidth * dpr)));
    const ch = Math.max(1, Math.min(4096, Math.round(c.clientHeight * dpr)));
    if (c.width !== cw || c.height !== ch) {
      c.width = cw;
      c.height = ch;
    }
    const g = c.getContext('2d', { alpha: false });
    g.fillStyle = '#101114';
    g.fillRect(0, 0, cw, ch);
    if (!this.haveFrame) return;
    const W = this.work.width;
    const H = this.work.height;
    const s = Math.min(cw / W, ch / H);
    const ox = (cw - W * s) / 2;
    const oy = (ch - H * s) / 2;
    const mirror = this.mode === 'webcam';
    g.save();
    g.imageSmoothingQuality = 'high';
    if (mirror) {
      g.translate(cw, 0);
      g.scale(-1, 1);
    }
    g.drawImage(this.work, ox, oy, W * s, H * s);
    g.restore();
    const map = mirror ? (x, y) => [cw - (ox + x * s), oy + y * s] : (x, y) => [ox + x * s, oy + y * s];
    const lw = Math.max(1, 1.25 * dpr);

    if (this.phase === 'placing' && this.box) {
      this.drawPlacement(g, map, s, lw, dpr);
    } else if ((this.phase === 'tracking' || this.phase === 'paused') && this.last && this.meshCheck.checked) {
      const lost = this.last.lost;
      drawLandmarks(g, this.last.landmarks, map, lost ? MESH_LOST : MESH, lw);
      if (lost) {
        g.save();
        g.font = `600 ${Math.round(13 * dpr)}px system-ui, sans-serif`;
        g.fillStyle = 'rgba(16, 17, 20, 0.75)';
        const text = 'face lost';
        const tw = g.measureText(text).width;
        g.fillRect(8 * dpr, 8 * dpr, tw + 16 * dpr, 22 * dpr);
        g.fillStyle = MESH_LOST;
        g.textBaseline = 'middle';
        g.fillText(text, 16 * dpr, 19 * dpr);
        g.restore();
      }
    }
  }

  drawPlacement(g, map, s, lw, dpr) {
    const b = this.box;
    // The mean shape in the box (as startFromBox will place it).
    const m = this.meanBox;
    const k = Math.min(b.w / m.w, b.h / m.h);
    const cx = b.x + b.w / 2;
    const cy = b.y + b.h / 2;
    const mx = m.x + m.w / 2;
    const my = m.y + m.h / 2;
    const shapeMap = (x, y) => map(cx + (x - mx) * k, cy + (y - my) * k);
    if (this.mode === 'webcam') {
      // The guide: an oval around the face box, the rest of the picture dimmed.
      const [X, Y] = map(cx, cy - b.h * 0.1);
      const rx = b.w * 0.62 * s;
      const ry = b.h * 0.72 * s;
      g.save();
      g.fillStyle = 'rgba(10, 11, 14, 0.45)';
      g.beginPath();
      g.rect(0, 0, g.canvas.width, g.canvas.height);
      g.ellipse(X, Y, rx, ry, 0, 0, Math.PI * 2);
      g.fill('evenodd');
      g.strokeStyle = this.probeHits > 0 ? MESH : GUIDE;
      g.lineWidth = lw * 2;
      g.setLineDash([8 * dpr, 6 * dpr]);
      g.beginPath();
      g.ellipse(X, Y, rx, ry, 0, 0, Math.PI * 2);
      g.stroke();
      g.restore();
      drawLandmarks(g, this.meanShape, shapeMap, 'rgba(124, 196, 255, 0.55)', lw, { points: false });
      return;
    }
    const [x0, y0] = map(b.x, b.y);
    const [x1, y1] = map(b.x + b.w, b.y + b.h);
    g.save();
    g.fillStyle = 'rgba(10, 11, 14, 0.35)';
    g.beginPath();
    g.rect(0, 0, g.canvas.width, g.canvas.height);
    g.rect(x0, y0, x1 - x0, y1 - y0);
    g.fill('evenodd');
    g.strokeStyle = GUIDE;
    g.lineWidth = lw * 1.5;
    g.strokeRect(x0, y0, x1 - x0, y1 - y0);
    const hs = 9 * dpr;
    g.fillStyle = GUIDE;
    g.fillRect(x1 - hs / 2, y1 - hs / 2, hs, hs);
    g.restore();
    drawLandmarks(g, this.meanShape, shapeMap, 'rgba(124, 196, 255, 0.8)', lw);
  }
}

/** Standard deviation of the grey level (0..1) inside a box of a canvas, on a sparse grid. */
function greyContrast(ctx, b) {
  const { width: W, height: H } = ctx.canvas;
  const x0 = Math.max(0, Math.floor(b.x));
  const y0 = Math.max(0, Math.floor(b.y));
  const x1 = Math.min(W, Math.ceil(b.x + b.w));
  const y1 = Math.min(H, Math.ceil(b.y + b.h));
  if (x1 - x0 < 4 || y1 - y0 < 4) return 0;
  const data = ctx.getImageData(x0, y0, x1 - x0, y1 - y0).data;
  const w = x1 - x0;
  const step = Math.max(1, Math.floor(Math.min(w, y1 - y0) / 48));
  let s = 0;
  let s2 = 0;
  let n = 0;
  for (let y = 0; y < y1 - y0; y += step) {
    for (let x = 0; x < w; x += step) {
      const i = (y * w + x) * 4;
      const g = (0.299 * data[i] + 0.587 * data[i + 1] + 0.114 * data[i + 2]) / 255;
      s += g;
      s2 += g * g;
      n++;
    }
  }
  const m = s / n;
  return Math.sqrt(Math.max(0, s2 / n - m * m));
}

function mediaErrorText(err) {
  if (!err) return 'the video could not be loaded';
  const what =
    {
      1: 'loading was aborted',
      2: 'a network error stopped the download',
      3: 'the video could not be decoded',
      4: 'the browser cannot play this format',
    }[err.code] || 'the video failed';
  return err.message ? `${what} (${err.message})` : what;
}

// ---------------------------------------------------------------------------------------------
// Registration

const canTrack = (wasm) => typeof wasm?.Tracker === 'function';

// This module is imported before the page registers its built-in sources; reserving their kinds
// first keeps the menu in the page's order (recorded track, sliders, then video). The page's own
// registrations replace these entries (same kind, same place); until then they are not offered.
for (const kind of ['track', 'sliders']) {
  registerSource(kind, { label: kind, available: () => false, create: () => null });
}

/** A video source, or null (with the reason shown) when the source model cannot be used. */
function create(mode, ctx) {
  try {
    return new VideoSource(mode, ctx);
  } catch (e) {
    notify('error', `${TITLES[mode]}: cannot track with this source model`, message(e));
    return null;
  }
}

registerSource('video-clip', { label: 'Video (bundled clip)', available: canTrack, create: (ctx) => create('clip', ctx) });
registerSource('video-file', { label: 'Video file…', available: canTrack, create: (ctx) => create('file', ctx) });
registerSource('webcam', { label: 'Webcam', available: canTrack, create: (ctx) => create('webcam', ctx) });

export { VideoSource, CONTOURS_68 };

// Video sources: the source face driven by live AAM tracking of a video, a webcam or a photo.
//
//   "Video (bundled clip)"  spk07's unseen GRID clip, tracked from its first frame's landmarks
//   "Video file…"           any video or photo the user drops or picks: the faces in it are found
//                           (the package's FaceFinder, in a worker) and shown in the placement
//                           step; tracking starts by itself from the face found (several: the
//                           most confident is selected and the user picks); a box is the fallback
//   "Webcam"                getUserMedia; tracking starts by itself when a face is found (the
//                           oval guide and Start are optional)
//
// Every new video frame is drawn into the work canvas (www/js/media.js), read as RGBA at the fit
// scale and fitted by the package's `Tracker` (the loaded source model's AAM). What the tracker
// decides is the core's: the fit scale for the face's size (`fitScale`), the bounds of the
// reported appearance, when a fit is a lost face, and which found face to (re-)acquire; the page
// feeds it faces found off the main thread when it `wantsFaces` (at the start of a search and
// while the face is lost), shows "face lost" while it is, and recovers without a click.
// The fit's parameters drive the source face (`paramsAt` returns the latest fit, its head
// placement re-centred on the model's mean pose with the package's `recentrePose`).
//
// This module is the tracking loop and the panel; media.js opens and reads the media,
// placement.js is the placement step, face-draw.js draws, finder-client.js finds faces.
//
// Registered with `available: (wasm) => typeof wasm.Tracker === 'function'`, so the menu offers
// these sources only with a package that can track. The active source is also reachable as
// `window.facemimicTracking` (for the console and the end-to-end tests).

import { registerSource } from './sources.js';
import { notify, fileError, message } from './toasts.js';
import { dropZone } from './drop.js';
import { MediaFeed, CLIP_JSON, loadClipInfo, looksLikeImage, looksLikeVideo, openCamera } from './media.js';
import { Placement } from './placement.js';
import { CONTOURS_68, MESH, MESH_LOST, GUIDE, bounds, scaled, drawFrame, drawLandmarks, drawBadge } from './face-draw.js';
import { findFaces } from './finder-client.js';
import { followPath, makeFollower, pathNotice } from './follow-path.js';

/** Fit log kept for inspection (entries). */
const LOG_MAX = 3000;
/** Live sources: time constant (s) with which the head placement re-centres in the source card. */
const RECENTRE_TAU = 4;

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

function wrapAngle(a) {
  return Math.atan2(Math.sin(a), Math.cos(a));
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

// ---------------------------------------------------------------------------------------------
// One tracker per source model (the fitter's precomputation is done once per model).

let cachedTracker = null; // { model, path, tracker }

/** The model's `Tracker` ("aam") or a `Follower` ("landmarks", www/js/follow-path.js). */
function trackerFor(wasm, model, path = 'aam') {
  if (cachedTracker && cachedTracker.model === model && cachedTracker.path === path) return cachedTracker.tracker;
  if (cachedTracker) {
    try {
      cachedTracker.tracker.free();
    } catch {
      // already freed
    }
  }
  let tracker;
  if (path === 'landmarks') tracker = makeFollower(wasm, model);
  else {
    const T = wasm.Tracker;
    tracker = typeof T.fromModel === 'function' ? T.fromModel(model) : new T(model.toBytes());
    // Faces are found in a worker and offered: a lost face is searched for in every sequence.
    tracker.expectOffers(true);
  }
  cachedTracker = { model, path, tracker };
  return tracker;
}

// ---------------------------------------------------------------------------------------------
// The source

const TITLES = { clip: 'Bundled clip', file: 'Video file', webcam: 'Webcam' };

/**
 * A source driven by tracking a video. `mode`: "clip" | "file" | "webcam".
 *
 * Phases: "loading" -> ("empty": file, nothing yet) -> "placing" (file: the faces found on a
 * paused frame, or a box; webcam: the guide while a face is looked for) -> "tracking" <->
 * "paused"; "error" when the video or camera fails. While tracking, `state` is "tracking",
 * "reinit", "lost" (a face was tracked and is lost) or "searching" (none found yet).
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
    if (typeof this.wasm.recentrePose !== 'function') throw new Error('this build of the package has no recentrePose');
    this.phase = 'loading';
    this.running = false;
    this.tracker = null;
    this.params = this.initialParams();
    this.meanPose = this.model.baseParams().pose;
    this.media = new MediaFeed();
    this.video = this.media.video;
    this.placement = new Placement(this.model.landmarks(this.model.baseParams()));
    this.anchor = null; // pose the mean pose stands for (see mapPose)
    this.last = null; // last fit result (work coordinates)
    this.lastGood = null; // last fit that was not lost, this sequence
    this.state = 'idle'; // tracking | lost | searching | reinit | idle
    this.log = [];
    this.logMax = ctx.logMax ?? LOG_MAX; // the call page keeps its own log (www/js/call-controls.js)
    this.fitTimes = [];
    this.msPerFit = 0;
    this.fits = 0;
    this.loops = 0;
    this.autoStart = true;
    this.frameNo = 0;
    this.fileName = '';
    this.kFit = 1; // fitted frame px per video px
    this.shownAt = 0;
    this.lastResets = 0;
    this.seqId = 0; // bumped by every new sequence / placement (stale finder results are dropped)
    this.finding = false; // the placement step waits for the finder
    this.findBusy = false; // a finder request is under way
    this.findLog = []; // { ms, faces } per finder request
    this.reacquired = 0;
  }

  // Read-only views used by the panel and the tests.
  get work() {
    return this.media.work;
  }
  get k() {
    return this.media.k;
  }
  get haveFrame() {
    return this.media.haveFrame;
  }
  get stream() {
    return this.media.stream;
  }
  get box() {
    return this.placement.box;
  }
  /** Setting the box places it by hand (the found face is deselected). */
  set box(b) {
    this.placement.box = b;
    this.placement.selected = -1;
  }
  get boxAspect() {
    return this.placement.aspect;
  }
  get faces() {
    return this.placement.faces;
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
    this.path = followPath(this.ctx, this.mode);
    this.buildPanel();
    try {
      this.tracker = trackerFor(this.wasm, this.model, this.path);
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
    this.seqId++;
    this.media.close();
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

  cancelFrames() {
    this.media.cancelFrames();
  }

  requestFrames() {
    if (!this.running) return;
    this.media.requestFrames((t) => {
      if (!this.running) return false;
      this.onVideoFrame(t);
      return this.running;
    });
  }

  // --- panel ------------------------------------------------------------------------------------

  buildPanel() {
    const id = `trk-${this.mode}`;
    this.video.classList.add('trk-video');
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
    this.chooseBtn = button('Choose a video or image…', () => this.fileInput.click());
    this.otherBtn = button('Other file…', () => this.fileInput.click(), { title: 'Track another video, or fit another image (or drop one on this panel)' });
    this.fileInput = el('input', { type: 'file', accept: 'video/*,image/*,.webm,.mp4,.mov,.m4v,.ogv,.mkv', hidden: true });
    this.fileInput.addEventListener('change', () => {
      const f = this.fileInput.files?.[0];
      this.fileInput.value = '';
      if (f) this.openFile(f);
    });
    this.meshCheck = el('input', { type: 'checkbox', checked: true });
    this.meshCheck.addEventListener('change', () => this.draw());
    const meshLabel = el('label', { class: 'check' }, this.meshCheck, el('span', { text: 'Mesh overlay' }));
    const extra = [];
    if (this.mode !== 'clip') {
      this.autoCheck = el('input', { type: 'checkbox', checked: this.autoStart });
      this.autoCheck.addEventListener('change', () => {
        this.autoStart = this.autoCheck.checked;
        if (this.phase === 'placing') this.restart();
      });
      extra.push(
        el('label', { class: 'check', title: 'Start tracking by itself as soon as a face is found' }, this.autoCheck, el('span', { text: 'Auto-start' })),
      );
    }

    this.dropHint = el(
      'div',
      { class: 'trk-drop' },
      el('p', {}, el('strong', { text: 'Drop a video or a photo here' }), el('span', { text: ' or ' })),
      this.chooseBtn,
      el('small', { text: 'Any format the browser plays (WebM, MP4, JPEG, PNG…). It stays on this computer.' }),
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
          pathNotice(this.path ?? 'aam', this.ctx.createFace),
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
    // Video and image files dropped on the panel (and not elsewhere: the page takes other drops as models).
    if (this.mode === 'file') {
      const panel = this.panel;
      // Model files dropped here go on to the page (which adds them as targets).
      dropZone(
        panel,
        (files) => {
          if (files.length > 1) notify('info', `Used ${files[0].name}`, 'one file at a time; the other files were ignored');
          this.openFile(files[0]);
        },
        { accept: (files) => !files.every((x) => /\.fmm$/i.test(x.name)), isolate: true },
      );
    }

    const anchor = document.querySelector('.stage .transport');
    if (this.ctx.panelHost) this.ctx.panelHost.append(this.panel); // the call page's place for it
    else if (anchor) anchor.after(this.panel);
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
    this.startBtn.textContent = m === 'webcam' ? 'Start' : this.media.still ? 'Fit the face' : 'Start tracking';
    this.playBtn.hidden = !tracking || Boolean(this.media.still);
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
          : 'Frame with the faces found: click a face (or Tab) to choose it; or drag the box onto the face, or use the arrow keys to move it, + and − to resize it; Enter starts',
      );
    } else this.canvas.setAttribute('aria-label', `${this.label}: video with the fitted face mesh`);
    if (msg !== undefined) this.say(msg);
    else if (phase === 'empty') this.say('Drop a video or a photo on this panel or choose one: the faces in it are found, and tracking starts.');
    else if (phase === 'placing' && m === 'file') this.say(this.placingText());
    else if (phase === 'placing' && m === 'webcam') this.say(this.placingText());
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
      this.media.stopStream();
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
      label = { lost: 'face lost', searching: 'looking for a face', reinit: 're-initialised', tracking: 'tracking' }[s] || s;
    } else {
      s = this.phase;
      label = {
        loading: 'loading',
        empty: 'no video',
        placing:
          this.mode === 'webcam' || this.finding
            ? 'looking for a face'
            : this.placement.face
              ? this.placement.faces.length > 1
                ? `${this.placement.faces.length} faces found`
                : 'face found'
              : 'place the face',
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

  /** What the placement step says, from what the finder found. */
  placingText() {
    if (this.mode === 'webcam') {
      return this.autoStart
        ? 'Looking for your face: look at the camera (the oval is only a guide); tracking starts when it is found, or press Start.'
        : 'Put your face inside the oval and press Start (Auto-start is off).';
    }
    if (this.finding) return 'Looking for faces…';
    const n = this.placement.faces.length;
    const start = this.media.still ? 'fit it' : 'start tracking';
    if (n > 1 && this.placement.face) {
      return `${n} faces found: the most confident is selected (${this.placement.selected + 1}); click another one (or Tab) to choose it, then ${start}. Dragging places a box by hand.`;
    }
    if (n === 1 && this.placement.face) return `A face was found: ${start}, or drag a box to place one by hand.`;
    if (n > 0) return `Box placed by hand (the faces found are shown faintly): ${start} from it.`;
    return this.findError
      ? `The face finder failed (${this.findError}): drag the box onto the face (drag its corner to resize), then ${start}.`
      : `No face was found on this frame: drag the box onto the face (drag its corner to resize), then ${start}.`;
  }

  // --- opening videos -----------------------------------------------------------------------------

  async openClip() {
    try {
      const info = await loadClipInfo();
      if (!this.running) return;
      this.clip = info;
      this.fps = info.fps || 25;
      this.fileName = info.video;
      await this.media.loadVideo(info.url, info.video);
      if (!this.running) return;
      if (info.initLandmarks.length !== this.placement.meanShape.length) {
        throw new Error(
          `the clip has ${info.initLandmarks.length / 2} start landmarks, the source model ${this.placement.meanShape.length / 2}`,
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
    await this.media.seek(0);
    if (!this.running) return;
    this.grab();
    const init = this.clip.initLandmarks;
    this.kFit = this.tracker.fitScale(bounds(init).h, this.media.width, this.media.height, 0);
    this.tracker.startFromLandmarks(scaled(init, this.kFit));
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

  /** A dropped or picked file: a video (tracked) or a photo (one face fitted). */
  async openFile(file) {
    if (!this.running) return;
    const name = file.name || 'the file';
    const image = looksLikeImage(file);
    if (!image && !looksLikeVideo(file)) {
      const err = new Error(
        `not a video or an image (${file.type || 'unknown type'}); drop a WebM, MP4 or other video the browser plays, or a JPEG / PNG photo`,
      );
      fileError(name, err);
      if (!this.haveFrame) this.setPhase('empty', `${name}: ${err.message}`);
      else this.say(`${name}: ${err.message}`);
      return;
    }
    this.cancelFrames();
    this.seqId++;
    if (this.objectUrl) URL.revokeObjectURL(this.objectUrl);
    this.objectUrl = null;
    this.fileName = name;
    this.media.haveFrame = false;
    this.last = null;
    this.lastGood = null;
    this.placement.setFaces([]);
    this.setPhase('loading', `Opening ${name}…`);
    try {
      if (image) {
        await this.media.loadImage(file);
        this.fps = 0;
      } else {
        this.objectUrl = URL.createObjectURL(file);
        await this.media.loadVideo(this.objectUrl, name);
        if (!this.running) return;
        this.video.loop = false;
        if (!this.endedHooked) {
          this.endedHooked = true;
          this.video.addEventListener('ended', () => this.onFileEnded());
        }
        this.fps = 30;
        await this.media.seek(0);
      }
      if (!this.running) return;
      this.grab();
      await this.enterPlacing();
    } catch (e) {
      if (!this.running) return;
      fileError(name, e);
      this.media.haveFrame = false;
      this.setPhase('empty', `${name}: ${message(e)}`);
      this.panel.dataset.state = 'error';
    }
  }

  /**
   * The placement step on the current frame. A file: the faces are found (in the worker) and
   * shown; with Auto-start, a video with one face starts tracking at once, with several it waits
   * for the user's pick, with none it plays while the tracker searches; a photo waits for Fit. The webcam: the guide
   * while the tracker searches the live picture.
   */
  async enterPlacing() {
    const seq = ++this.seqId;
    this.cancelFrames();
    if (this.mode === 'file') this.video.pause();
    this.placement.setFaces([]);
    this.placement.placeDefault(this.work.width, this.work.height, this.mode === 'webcam', this.lastGood?.landmarks);
    this.placement.touched = false;
    this.findError = null;
    if (this.mode === 'webcam') {
      this.searchingGuide = false;
      this.setPhase('placing');
      this.requestFrames();
      return;
    }
    this.finding = true;
    this.setPhase('placing');
    this.canvas.focus({ preventScroll: true });
    let faces = [];
    try {
      const r = await findFaces(this.media.workImage());
      faces = r.faces;
      this.findLog.push({ ms: r.ms, faces: faces.length, placing: true });
    } catch (e) {
      this.findError = message(e);
    }
    if (seq !== this.seqId || !this.running || this.phase !== 'placing') return;
    this.finding = false;
    const byHand = this.placement.touched;
    this.placement.setFaces(faces, true);
    if (!faces.length && !byHand) this.placement.placeDefault(this.work.width, this.work.height, false);
    this.setPhase('placing');
    // A photo waits for its Fit button; a video starts by itself (unless a box was placed).
    if (!this.autoStart || this.media.still || byHand) return;
    if (faces.length === 1) await this.startTracking();
    else if (!faces.length && !this.findError) await this.startSearch();
  }

  async openWebcam() {
    this.setPhase('loading', 'Asking for the camera…');
    let stream;
    try {
      stream = await openCamera();
    } catch (e) {
      if (!this.running) return;
      if (e.cause) notify('error', 'Webcam unavailable', e.message);
      this.fail(e.message);
      return;
    }
    if (!this.running) {
      for (const t of stream.getTracks()) t.stop();
      return;
    }
    this.streamEnded = false;
    this.fileName = stream.getVideoTracks()[0]?.label || 'camera';
    stream.getVideoTracks()[0]?.addEventListener('ended', () => {
      if (!this.running || this.media.stream !== stream) return;
      this.streamEnded = true;
      this.media.haveFrame = false;
      this.fail('The camera stopped sending pictures (unplugged, or access was withdrawn)');
    });
    try {
      await this.media.useStream(stream);
    } catch (e) {
      if (this.running) this.fail('The camera picture could not be shown', e);
      return;
    }
    if (!this.running) return;
    this.fps = stream.getVideoTracks()[0]?.getSettings?.().frameRate || 30;
    this.grab();
    await this.enterPlacing();
  }

  async play() {
    if (this.media.still) return;
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

  onVideoFrame(mediaTime) {
    if (mediaTime === this.lastMediaTime && this.mode !== 'webcam') return;
    this.lastMediaTime = mediaTime;
    this.grab();
    if (this.phase === 'tracking') this.fitCurrent(mediaTime);
    else if (this.phase === 'placing' && this.mode === 'webcam') this.searchGuide(mediaTime);
    this.draw();
  }

  /** Draw the current frame into the work canvas; returns k (work px per video px). */
  grab() {
    const k = this.media.grab();
    const { width: w, height: h } = this.work;
    if (this.canvas && this.arW !== w + h * 1e5) {
      this.arW = w + h * 1e5;
      this.canvas.style.aspectRatio = `${w} / ${h}`;
      this.canvas.style.setProperty('--ar', String(w / h));
    }
    return k;
  }

  /**
   * Webcam, placing with Auto-start: the tracker searches the live picture (faces found in the
   * worker are offered to it; it acquires one when its fit is plausible), and tracking starts
   * by itself when it does.
   */
  searchGuide(mediaTime) {
    this.frameNo++;
    if (!this.autoStart) return;
    if (!this.searchingGuide) {
      this.searchingGuide = true;
      this.tracker.startSearching();
      this.kFit = this.k;
      this.beginSequence(true);
    }
    this.feedFinder();
    if (this.tracker.wantsFaces) return; // nothing to try yet: no fit on this frame
    this.fitCurrent(mediaTime);
    if (this.last && !this.last.lost) {
      this.searchingGuide = false;
      this.setPhase('tracking', 'Tracking your face.');
    }
  }

  /**
   * When the tracker wants faces (a search, or a lost face), find them in the current frame in
   * the worker and offer them (in fit coordinates, at a fit scale for the most confident one).
   */
  feedFinder() {
    if (this.findBusy || !this.tracker.wantsFaces) return;
    this.findBusy = true;
    const seq = this.seqId;
    const k = this.k;
    const t0 = performance.now();
    findFaces(this.media.workImage()).then(
      ({ faces, ms }) => {
        this.findBusy = false;
        this.findLog.push({ ms, faces: faces.length, wall: performance.now() - t0 });
        if (this.findLog.length > this.logMax) this.findLog.shift();
        if (seq !== this.seqId || !this.running || !faces.length || !this.tracker.wantsFaces) return;
        const kFit = this.tracker.fitScale(bounds(faces[0].landmarks).h / k, this.media.width, this.media.height, this.kFit);
        try {
          this.tracker.offerFaces(faces.map((f) => scaled(f.landmarks, kFit / k)));
          this.kFit = kFit;
        } catch (e) {
          this.say(`The faces found could not be used: ${message(e)}`);
        }
      },
      (e) => {
        this.findBusy = false;
        if (this.running && seq === this.seqId) this.say(`The face finder failed: ${message(e)}`);
      },
    );
  }

  /** Start tracking from the selected face found, the placement box, or given landmarks (work px). */
  async startTracking(landmarks = null) {
    if (!this.haveFrame || !this.box) return;
    const face = landmarks ?? this.placement.face?.landmarks ?? null;
    const W = this.media.width;
    const H = this.media.height;
    try {
      if (face) {
        this.kFit = this.tracker.fitScale(bounds(face).h / this.k, W, H, 0);
        this.tracker.startFromLandmarks(scaled(face, this.kFit / this.k));
      } else {
        const b = this.box;
        this.kFit = this.tracker.fitScale(b.h / this.k, W, H, 0);
        const f = this.kFit / this.k;
        this.tracker.startFromBox(b.x * f, b.y * f, b.w * f, b.h * f);
      }
    } catch (e) {
      this.say(`Cannot start: ${message(e)}`);
      return;
    }
    this.seqId++;
    this.searchingGuide = false;
    this.beginSequence();
    if (this.media.still) {
      // A photo: the face is fitted (a few passes on the same picture), and stays.
      this.setPhase('tracking', `Fitting the face in ${this.fileName}.`);
      for (let i = 0; i < 3; i++) this.fitCurrent(0);
      this.setPhase('tracking', this.last && !this.last.lost ? `The face in ${this.fileName} drives the source.` : `The face in ${this.fileName} could not be fitted: Re-start places it again.`);
      this.draw();
      return;
    }
    this.setPhase('tracking', this.mode === 'webcam' ? 'Tracking your face.' : `Tracking ${this.fileName}.`);
    if (this.mode === 'file') {
      this.fitCurrent(this.video.currentTime);
      // Where the sequence began, to loop back to with a known fit.
      this.seqStart = this.last && !this.last.lost ? { time: this.video.currentTime, landmarks: this.last.landmarks } : null;
      this.draw();
      await this.play();
    } else this.requestFrames();
  }

  /** A video with no face found on its first frame: play it, the tracker looking for a face. */
  async startSearch() {
    this.seqId++;
    this.tracker.startSearching();
    this.kFit = this.k;
    this.beginSequence(true);
    this.seqStart = null;
    this.setPhase('tracking', `Looking for a face in ${this.fileName}…`);
    this.fitCurrent(this.video.currentTime);
    await this.play();
  }

  /** A file played to its end: loop back to where tracking began, from the fit found there. */
  async onFileEnded() {
    if (!this.running || this.mode !== 'file' || this.phase !== 'tracking') return;
    this.loops++;
    const start = this.seqStart;
    const searched = this.searchStart;
    try {
      this.cancelFrames();
      await this.media.seek(start ? start.time : 0);
      if (!this.running || this.phase !== 'tracking') return;
      this.grab();
      if (start) {
        this.kFit = this.tracker.fitScale(bounds(start.landmarks).h / this.k, this.media.width, this.media.height, 0);
        this.tracker.startFromLandmarks(scaled(start.landmarks, this.kFit / this.k));
        this.beginSequence();
        this.fitCurrent(this.video.currentTime);
        this.draw();
        await this.play();
      } else if (searched) {
        await this.startSearch();
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
    await this.enterPlacing();
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

  /** A fit result in work (shown) coordinates. */
  toWork(r) {
    const f = this.k / this.kFit;
    return {
      ...r,
      landmarks: scaled(r.landmarks, f),
      pose: { scale: r.pose.scale * f, rotation: r.pose.rotation, tx: r.pose.tx * f, ty: r.pose.ty * f },
    };
  }

  /** A new sequence's bookkeeping; `searching`: it starts with no face (startSearching). */
  beginSequence(searching = false) {
    this.last = null;
    this.lastGood = null;
    this.searchStart = searching;
    this.state = searching ? 'searching' : 'tracking';
    this.seqStartLost = this.tracker.lostCount;
    this.seqStartResets = this.tracker.resets;
    this.lastResets = this.tracker.resets;
    if (this.mode !== 'clip') this.anchor = null; // the clip keeps its first frame's placement
  }

  /** Fit the current frame; update the params, state and stats. */
  fitCurrent(mediaTime) {
    const image = this.media.fitImage(this.kFit);
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
    const wasLost = this.last?.lost;
    this.state = r.lost ? (this.lastGood ? 'lost' : this.searchStart ? 'searching' : 'lost') : resets > this.lastResets ? 'reinit' : 'tracking';
    this.lastResets = resets;
    this.last = r;
    if (r.reacquired) this.reacquired++;
    if (!r.lost) {
      this.lastGood = r;
      this.params = { pose: this.mapPose(r.pose, t1), shape: r.shape, appearance: r.appearance };
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
      reacquired: r.reacquired,
      ms,
      landmarks: Array.from(scaled(fit.landmarks, 1 / this.kFit)), // video pixels
    });
    if (this.log.length > this.logMax) this.log.splice(0, this.log.length - this.logMax);

    // The face grew or shrank a lot (moving to or from the camera): carry on at a new fit scale.
    // (Not when following landmarks: the finder's passes cost the same at any size, and a
    // restart would forget the person's neutral face.)
    if (!r.lost && !this.media.still && this.path !== 'landmarks') {
      const want = this.tracker.fitScale(bounds(fit.landmarks).h / this.kFit, this.media.width, this.media.height, this.kFit);
      if (want !== this.kFit) {
        try {
          this.tracker.startFromLandmarks(scaled(fit.landmarks, want / this.kFit));
          this.kFit = want;
        } catch {
          // keep the current scale
        }
      }
    }
    // Looking for the face (none yet, or lost): the worker finds faces for the tracker.
    if (this.tracker.wantsFaces && !this.media.still) this.feedFinder();
    // The call page renders and logs every fit, lost or not (www/js/call-avatar.js).
    if (typeof this.ctx.onFit === 'function') this.ctx.onFit(r, this.params);

    if (this.phase === 'tracking' && !this.media.still) {
      if (r.lost && this.lastGood === null && this.searchStart) this.say('Looking for a face…');
      else if (r.lost) this.say('Face lost: looking for it again (it is tracked again as soon as it is found).');
      else if (r.reacquired) this.say(wasLost && this.log.length > 1 ? 'Face found again: tracking.' : 'Face found: tracking.');
      else if (/^(Face lost|Looking for a face|Face found)/.test(this.msgEl.textContent)) this.say('Tracking.');
    }
    this.showStats(t1);
  }

  /**
   * The fitted pose, re-centred on the model's mean pose (`recentrePose(pose, anchor, mean)`).
   * The anchor is the sequence's first fitted pose (the clip: its first frame, so the clip's
   * motion is reproduced exactly); for live video it then follows the head slowly, so a face
   * anywhere in the picture ends up centred.
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
    return this.wasm.recentrePose(pose, { scale: Math.exp(a.ls), rotation: a.rotation, tx: a.tx, ty: a.ty }, this.meanPose);
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

  // --- pointer and keyboard on the frame --------------------------------------------------------

  toFrame(e) {
    const r = this.canvas.getBoundingClientRect();
    const W = this.work.width;
    const H = this.work.height;
    let x = ((e.clientX - r.left) / r.width) * W;
    const y = ((e.clientY - r.top) / r.height) * H;
    if (this.mode === 'webcam') x = W - x;
    return { x, y };
  }

  handleSize() {
    return (14 / this.canvas.getBoundingClientRect().width) * this.work.width;
  }

  onPointerDown(e) {
    if (this.phase !== 'placing' || this.mode !== 'file') return;
    this.placement.pointerDown(this.toFrame(e), this.handleSize());
    this.canvas.setPointerCapture(e.pointerId);
    this.canvas.focus({ preventScroll: true });
    e.preventDefault();
    this.say(this.placingText());
    this.draw();
  }

  onPointerMove(e) {
    if (this.phase !== 'placing' || this.mode !== 'file') return;
    const p = this.toFrame(e);
    if (!this.placement.drag) {
      const h = this.placement.hit(p, this.handleSize());
      this.canvas.style.cursor = h === 'corner' ? 'nwse-resize' : h === 'inside' ? 'move' : h.startsWith('face:') ? 'pointer' : 'crosshair';
      return;
    }
    const wasFace = this.placement.face;
    if (this.placement.pointerMove(p, this.work.width, this.work.height)) {
      if (wasFace) this.say(this.placingText());
      this.draw();
    }
  }

  onPointerUp() {
    this.placement.pointerUp();
  }

  onKey(e) {
    if (this.phase !== 'placing') return;
    if (e.key === 'Enter') {
      e.preventDefault();
      this.startTracking();
      return;
    }
    if (this.mode !== 'file') return;
    if (this.placement.key(e, (e.shiftKey ? 10 : 2) / this.k, this.work.width, this.work.height)) {
      e.preventDefault();
      this.say(this.placingText());
      this.draw();
    }
  }

  // --- drawing ------------------------------------------------------------------------------------

  draw() {
    const c = this.canvas;
    if (!c || !this.running || c.hidden) return;
    const v = drawFrame(c, this.work, { mirror: this.mode === 'webcam', haveFrame: this.haveFrame });
    if (!v) return;
    const { g, map, s, lw, dpr } = v;
    if (this.phase === 'placing') {
      this.placement.draw(g, map, s, lw, dpr, { webcam: this.mode === 'webcam', hot: this.tracker?.wantsFaces === false });
      if (this.finding) drawBadge(g, 'looking for faces…', GUIDE, dpr);
    } else if ((this.phase === 'tracking' || this.phase === 'paused') && this.last && this.meshCheck.checked) {
      if (!this.last.lost) drawLandmarks(g, this.last.landmarks, map, MESH, lw);
      else if (this.lastGood) {
        // The last good fit, in red: where the face was.
        drawLandmarks(g, this.lastGood.landmarks, map, MESH_LOST, lw);
        drawBadge(g, 'face lost', MESH_LOST, dpr);
      } else drawBadge(g, 'looking for a face', GUIDE, dpr);
    }
  }
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
registerSource('video-file', { label: 'Video or photo…', available: canTrack, create: (ctx) => create('file', ctx) });
registerSource('webcam', { label: 'Webcam', available: canTrack, create: (ctx) => create('webcam', ctx) });

/** Whether a file is one the tracking sources open (a video or an image). */
export function isMediaFile(file) {
  return looksLikeVideo(file) || looksLikeImage(file);
}

export { VideoSource, CONTOURS_68 };

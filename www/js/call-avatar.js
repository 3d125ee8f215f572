// One side of a call: the webcam tracked by the page's tracking source (www/js/tracking.js, the
// same VideoSource as the main page's "Webcam"), its expression cloned onto the avatar chosen
// (the package's Cloner) and drawn, composited, into one 640x480 canvas. That canvas is what the
// call sends (`canvas.captureStream()`); the webcam's own picture stays in this page.
//
// The webcam is followed as on the main page, by the core's policy (the package's
// `Tracker.kindFor`): a bundled source model is someone else's face, so anyone is followed by
// their landmarks mapped onto it; a model of one's own ("Your models") has its AAM fitted.
//
// Per fit: the Cloner reads the tracker's fit inside wasm (`sourceFromTracker`: the pose
// re-centred as on the main page, head-motion damped by the core's pose anchor,
// `setHeadDamping`) and clones it (the core's default method; gain and region gains, set when
// they change) -> `drawFrame` draws the avatar into the registered canvas -> a row of the frame
// log.
// A lost face draws nothing new: the avatar holds its last frame (and the other side is told).
// Changing the avatar replaces the Cloner's target: the same canvas, the same track, no
// renegotiation.

import { createSource } from './sources.js';
import { HEAD_TAU, FrameLog, clampSettings, REGIONS } from './call-controls.js';
import './tracking.js'; // registers the webcam source
import { OutputFeed, copyContain, headAnchor } from './output-feed.js';
import { popoutMenu } from './output-controls.js';
import { notify } from './toasts.js';

export const WIDTH = 640;
export const HEIGHT = 480;
/** The bench stamp: 24 blocks of STAMP_BLOCK px along the bottom edge, one bit each. */
export const STAMP_BITS = 24;
export const STAMP_BLOCK = 16;
/** A pause between two avatar frames drawn that `drawGaps` records (ms), and how many it keeps. */
const DRAW_GAP_MS = 150;
const MAX_DRAW_GAPS = 500;

/** Reads the stamp from the bottom-left of a picture's pixels (ImageData of a WIDTH x STAMP_BLOCK strip). */
export function readStamp(img) {
  let v = 0;
  for (let b = 0; b < STAMP_BITS; b++) {
    let s = 0;
    for (let y = 4; y < STAMP_BLOCK - 4; y++) {
      for (let x = 4; x < STAMP_BLOCK - 4; x++) {
        const i = (y * img.width + b * STAMP_BLOCK + x) * 4;
        s += img.data[i] + img.data[i + 1] + img.data[i + 2];
      }
    }
    if (s / ((STAMP_BLOCK - 8) ** 2 * 3) > 128) v |= 1 << b;
  }
  return v >>> 0;
}

export class Avatar {
  /**
   * `fm`: the package; `canvas`: the canvas sent; `panelHost`: where the tracking panel goes;
   * `bench`: stamp each frame's camera capture time into it (for the latency bench).
   */
  constructor({ fm, canvas, panelHost, bench = false, onStatus = () => {} }) {
    this.fm = fm;
    this.canvas = canvas;
    canvas.width = WIDTH;
    canvas.height = HEIGHT;
    this.ctx = canvas.getContext('2d', { alpha: false });
    this.panelHost = panelHost;
    this.bench = bench;
    this.onStatus = onStatus;
    this.cloner = null;
    this.source = null; // { model, info, name }
    this.target = null; // { model, info, name }
    this.video = null; // VideoSource
    this.settings = clampSettings({ gain: 1, head: 1 }); // and the region gains, 1
    // The cloning method: the core's default (the package's one list, `methods()`).
    const methods = fm.methods();
    this.method = (methods.find((m) => m.isDefault) ?? methods[0]).name;
    this.log = null;
    this.frames = 0; // avatar frames drawn
    this.fits = 0;
    this.lost = 0;
    this.captures = new Map(); // camera frame mediaTime -> capture time (performance clock)
    this.pipeline = []; // recent (drawn - captured) ms
    this.camera = 'starting';
    this.lastDrawn = 0;
    this.drawTimes = [];
    // Gaps over DRAW_GAP_MS between two avatar frames drawn (the canvas stream sends nothing new
    // in a gap): { at: wall-clock ms of the frame that ended it, ms, lost: fits lost within it }.
    this.drawGaps = [];
    this.lostAtDraw = 0;
    // The schedule's condition (call-schedule-ui.js), written in each row of the log: { number, name }.
    this.condition = null;
    // The output view (www/js/output-feed.js): this avatar alone in a pop-out window, for OBS,
    // fed every frame drawn; when no camera frame comes soon after a change, one is drawn.
    const wake = () => {
      const at = performance.now();
      setTimeout(() => this.lastDrawn < at && this.redraw(), 100);
    };
    this.outputs = new OutputFeed({ page: 'call', wake });
    this.drawnInto = null; // the output's canvas the cloner draws into, when not `canvas`
    const caption = canvas.closest('figure')?.querySelector('figcaption');
    if (caption) popoutMenu(caption, this.outputs, () => this.popOut());
  }

  /** Opens the output view of this avatar (in a click: a pop-up window). */
  popOut() {
    if (!this.target || !this.cloner) return; // no avatar yet (the models are loading)
    const source = () =>
      this.target && this.cloner
        ? {
            name: this.target.name,
            picture: this.target.info.backdrop,
            render: (ctx, options) => this.cloner.renderTarget(0, ctx, options),
            anchor: () => headAnchor(this.cloner.targetLandmarks(0), this.target.info.imageWidth, this.target.info.imageHeight),
          }
        : null;
    if (this.outputs.openFor('avatar', source)) this.redraw();
    else notify('error', 'The output view did not open', 'the browser blocked its window: allow pop-ups for this page, then press Pop out again');
  }

  /** Avatar frames drawn in the last second. */
  fpsNow() {
    const now = performance.now();
    while (this.drawTimes.length && now - this.drawTimes[0] > 1000) this.drawTimes.shift();
    return this.drawTimes.length;
  }

  /** Source model (whose face drives the avatar: www/js/follow-path.js) and avatar (target) model. */
  setModels(source, target) {
    const oldCloner = this.cloner;
    this.cloner = new this.fm.Cloner(source.model);
    this.cloner.addTarget(target.model);
    this.registerCanvas(target);
    this.cloner.setFollowPose(true);
    this.cloner.setHeadDamping(HEAD_TAU, this.settings.head);
    this.cloner.setMethod(this.method);
    this.applySettings();
    oldCloner?.free();
    const sourceChanged = this.source?.model !== source.model;
    this.source = source;
    this.target = target;
    this.resetLog();
    if (sourceChanged) this.restartCamera();
    this.drawParams(source.model.baseParams(), performance.now());
  }

  /** Change the avatar only (mid-call): the same canvas and track; nothing is renegotiated. */
  setTarget(target) {
    this.cloner.replaceTarget(0, target.model);
    this.registerCanvas(target);
    this.target = target;
    this.resetLog();
    this.redraw();
  }

  /** The canvas the cloner draws the avatar into (once per avatar: composited into its picture
   *  when it has one); a frame is then `setSourceParams` and `drawFrame`. */
  registerCanvas(target) {
    this.drawnInto = null;
    const composite = Boolean(target.info.backdrop);
    this.cloner.setTargetCanvas(0, this.ctx, { raster: 'scanline', composite, background: '#1b1d22' });
  }

  resetLog() {
    const si = this.source.info;
    const ti = this.target.info;
    if (!this.log) {
      this.log = new FrameLog({ shapeModes: si.shapeModes, appearanceModes: si.appearanceModes, targetShape: ti.shapeModes, targetAppearance: ti.appearanceModes });
    } else this.log.ensure(si.shapeModes, si.appearanceModes, ti.shapeModes, ti.appearanceModes);
  }

  setSettings(s) {
    this.settings = clampSettings({ ...this.settings, ...s });
    this.applySettings();
    this.redraw();
  }

  /** The settings into the cloner (when they change, never per frame). */
  applySettings() {
    const s = this.settings;
    this.cloner?.setGain(s.gain);
    this.cloner?.setRegionGains(...REGIONS.map((r) => s[r]));
    this.cloner?.setStyle(s.style);
    this.cloner?.setHeadDamping(HEAD_TAU, s.head);
  }

  restartCamera() {
    this.video?.stop();
    this.camera = 'starting';
    const ctx = {
      wasm: this.fm,
      sourceModel: () => this.source.model,
      sourceInfo: () => this.source.info,
      // Whose face the source model is: the tracking policy's input (www/js/follow-path.js).
      sourceIsOwn: () => !this.source.bundled,
      currentParams: () => null,
      invalidate: () => {},
      onFit: (r, params) => this.onFit(r, params),
      panelHost: this.panelHost,
      logMax: 300, // the tracking panel's own fit log: 10 s is plenty (the call keeps its FrameLog)
    };
    this.video = createSource('webcam', ctx);
    if (!this.video) {
      this.setCamera('camera-lost');
      return;
    }
    this.video.start();
    this.watchCaptures();
    this.watchCamera();
  }

  /** Camera frames' capture times (requestVideoFrameCallback metadata), for the latency. */
  watchCaptures() {
    const v = this.video.video;
    if (typeof v.requestVideoFrameCallback !== 'function') return;
    const vs = this.video;
    const cb = (now, meta) => {
      if (this.video !== vs || !vs.running) return;
      // captureTime is the camera's; without it, the moment the frame was handed to the page.
      this.captures.set(meta.mediaTime, meta.captureTime ?? meta.receiveTime ?? now);
      if (this.captures.size > 16) this.captures.delete(this.captures.keys().next().value);
      v.requestVideoFrameCallback(cb);
    };
    v.requestVideoFrameCallback(cb);
  }

  /** The camera's state, from the tracking source's phase (polled: it has no events). */
  watchCamera() {
    clearInterval(this.cameraTimer);
    this.cameraTimer = setInterval(() => {
      const vs = this.video;
      if (!vs) return;
      if (vs.phase === 'error' || vs.streamEnded) this.setCamera('camera-lost');
      else if (vs.phase === 'tracking' && vs.state === 'lost') this.setCamera('face-lost');
      else if (vs.phase === 'tracking' && vs.last && !vs.last.lost) this.setCamera('ok');
      else if (vs.phase === 'placing' || vs.phase === 'loading') this.setCamera(this.camera === 'ok' ? 'face-lost' : 'starting');
    }, 250);
  }

  setCamera(state) {
    if (this.camera === state) return;
    this.camera = state;
    this.onStatus(state);
  }

  onFit(r, params) {
    this.fits++;
    const now = performance.now();
    const mediaTime = this.video?.lastMediaTime;
    const captured = this.captures.get(mediaTime) ?? now;
    if (r.lost) {
      this.lost++;
      this.logRow({ now, captured, lost: true, fitPose: null, sent: null });
      this.setCamera('face-lost');
      return;
    }
    this.setCamera('ok');
    if (!this.cloner) return;
    this.params = params; // the frame log's copy (the tracking source has it already)
    // The parameters stay in wasm: the cloner reads the tracker's fit and damps the head itself.
    const tracker = this.video?.tracker;
    // Not taken (an unsure fit): the cloner holds the last good expression, appearance included.
    const held = tracker && (this.cloner.sourceFromTracker(tracker) || this.video?.lastGood);
    if (!held) this.cloner.setSourceParams(params);
    this.drawCurrent(captured, r.pose);
  }

  /** Clone and draw `params` given from JS (the base face before any fit), log the frame. */
  drawParams(params, captured) {
    if (!this.cloner) return;
    this.params = params;
    this.cloner.setSourceParams(params);
    this.drawCurrent(captured, params.pose);
  }

  /** Draw the cloner's current source parameters, stamp it in bench mode, log the frame (with
   *  the pose sent: the fit's, head-damped by the cloner). */
  drawCurrent(captured, fitPose) {
    // An output view showing the avatar in its picture: drawn once, at the output's size, and
    // copied into the canvas sent (one composite a frame, not two at two sizes).
    const out = this.outputs.open ? this.outputs.canvasFor('avatar') : null;
    if ((out?.canvas ?? null) !== this.drawnInto) {
      if (out) this.cloner.setTargetCanvas(0, out.canvas.getContext('2d', { alpha: false }), out.options);
      else this.registerCanvas(this.target);
      this.drawnInto = out?.canvas ?? null;
    }
    this.cloner.drawFrame();
    if (out) copyContain(this.canvas, out.canvas, '#1b1d22');
    this.outputs.feed();
    if (this.bench) this.stamp(captured);
    const drawn = performance.now();
    this.frames++;
    if (this.lastDrawn && drawn - this.lastDrawn > DRAW_GAP_MS) {
      this.drawGaps.push({ at: performance.timeOrigin + drawn, ms: drawn - this.lastDrawn, lost: this.lost - this.lostAtDraw });
      if (this.drawGaps.length > MAX_DRAW_GAPS) this.drawGaps.shift();
    }
    this.lostAtDraw = this.lost;
    this.lastDrawn = drawn;
    this.drawTimes.push(drawn);
    while (this.drawTimes.length && drawn - this.drawTimes[0] > 1000) this.drawTimes.shift();
    this.pipeline.push(drawn - captured);
    if (this.pipeline.length > 60) this.pipeline.shift();
    const sent = this.cloner.sourceParams().pose;
    this.logRow({ now: drawn, captured, lost: false, fitPose, sent });
  }

  redraw() {
    if (this.params && this.cloner) this.drawCurrent(performance.now(), this.params.pose);
  }

  /** Bench mode: the capture time (ms of the wall clock, mod 2^24) as black / white blocks. */
  stamp(captured) {
    const v = Math.round(performance.timeOrigin + captured) % 2 ** STAMP_BITS;
    const g = this.ctx;
    for (let b = 0; b < STAMP_BITS; b++) {
      g.fillStyle = (v >>> b) & 1 ? '#fff' : '#000';
      g.fillRect(b * STAMP_BLOCK, HEIGHT - STAMP_BLOCK, STAMP_BLOCK, STAMP_BLOCK);
    }
  }

  logRow({ now, captured, lost, fitPose, sent }) {
    if (!this.log) return;
    let tgt = null;
    if (!lost) {
      try {
        tgt = this.cloner.targetParams(0);
      } catch {
        tgt = null;
      }
    }
    this.log.push({
      wall: performance.timeOrigin + now,
      frame: this.fits,
      captureMs: performance.timeOrigin + captured,
      renderMs: lost ? NaN : now - captured,
      lost,
      ...this.settings, // gain, head, mouth, eyes, brows, style
      avatar: this.target.name,
      condition: this.condition?.number,
      conditionName: this.condition?.name,
      fitPose,
      sentPose: sent,
      src: lost ? null : this.params,
      tgt,
    });
  }

  /** Median camera-capture-to-drawn time of the last frames (track + clone + render), ms. */
  get pipelineMs() {
    if (!this.pipeline.length) return null;
    const s = [...this.pipeline].sort((a, b) => a - b);
    return s[s.length >> 1];
  }

  stop() {
    clearInterval(this.cameraTimer);
    this.video?.stop();
    this.video = null;
  }
}

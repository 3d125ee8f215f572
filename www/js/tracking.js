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
// Every new video frame is drawn into the work canvas (www/js/media.js), read as RGBA and given,
// at that size, to the package's `Tracker`: the loaded source model's AAM, or anyone's landmarks
// followed with it (the core's policy, www/js/follow-path.js). What the tracker decides is the core's: the scale it fits at for the
// face's size (it resamples the frame itself), the bounds of the reported appearance, when a fit
// is a lost face, which found face to (re-)acquire, and the head placement: each result carries
// `placed`, its pose re-centred on the model's mean pose about an anchor that follows the head
// (fixed for the clip, so the clip's motion is reproduced exactly). The page feeds it faces found
// off the main thread when it `wantsFaces` (at the start of a search, while the face is lost, and
// every `policy.recheckFrames` tracked frames for a second opinion on the tracked face), shows
// "face lost" while it is, and recovers without a click. Everything the tracker is given
// and returns is in the work canvas's pixels: one call a frame, no conversion.
//
// This module is the source, its frame loop and its registration; its collaborators, each its
// own class owned by the source: tracking-sequence.js (`Sequencer`: opening the media through
// tracking-open.js's `MediaOpener`, and the sequences: placement, acquisition, looping),
// tracking-panel.js (`TrackingPanel`: DOM, phases, the mesh and the readout), tracking-log.js
// (`FitLog`); media.js reads the media, placement.js is the placement step, face-draw.js draws,
// finder-client.js finds faces.
//
// Registered with `available: (wasm) => typeof wasm.Tracker === 'function'`, so the menu offers
// these sources only with a package that can track. The running source is also readable as
// `window.facemimicTracking` (a read-only handle for the console and the end-to-end tests; the
// page never reads it: whoever needs the source is given it, e.g. the page's `app.active`).

import { registerSource } from './sources.js';
import { notify, message } from './toasts.js';
import { MediaFeed, looksLikeImage, looksLikeVideo } from './media.js';
import { Placement } from './placement.js';
import { CONTOURS_68 } from './face-draw.js';
import { findFaces } from './finder-client.js';
import { followPath, makeTracker } from './follow-path.js';
import { TrackingPanel } from './tracking-panel.js';
import { Sequencer } from './tracking-sequence.js';
import { FitLog, LOG_MAX } from './tracking-log.js';
import { FLOW_METHODS, watchTransport, release } from './tracking-flow.js';

// ---------------------------------------------------------------------------------------------
// One tracker per source model (the fitter's precomputation is done once per model).

let cachedTracker = null; // { model, path, tracker, tau }

/**
 * The model's `Tracker`, "aam" or "landmarks" (the core's policy, www/js/follow-path.js), its pose
 * anchor fixed for the bundled clip (`recentreTau` 0) and following the head otherwise (the
 * package's default).
 */
function trackerFor(wasm, model, path, mode) {
  if (!(cachedTracker && cachedTracker.model === model && cachedTracker.path === path)) {
    if (cachedTracker) {
      try {
        cachedTracker.tracker.free();
      } catch {
        // already freed
      }
    }
    // Faces are found in a worker and offered: a lost face is searched for in every sequence.
    const tracker = makeTracker(wasm, model, path);
    cachedTracker = { model, path, tracker, tau: tracker.policy?.recentreTau };
  }
  const { tracker, tau } = cachedTracker;
  if (typeof tracker.setPolicy === 'function' && tau !== undefined) {
    tracker.setPolicy({ recentreTau: mode === 'clip' ? 0 : tau });
  }
  return tracker;
}

// ---------------------------------------------------------------------------------------------
// The source

const TITLES = { clip: 'Bundled clip', file: 'Video file', webcam: 'Webcam' };

/** The source being shown, for the console and the end-to-end tests (the page never reads it). */
let shown = null;
Object.defineProperty(window, 'facemimicTracking', { get: () => shown, configurable: true });

/**
 * A source driven by tracking a video. `mode`: "clip" | "file" | "webcam".
 *
 * Phases: "loading" -> ("empty": file, nothing yet) -> "placing" (file: the faces found on a
 * paused frame, or a box; webcam: the guide while a face is looked for) -> "tracking" <->
 * "paused"; "error" when the video or camera fails. While tracking, `state` is "tracking",
 * "reinit", "lost" (a face was tracked and is lost) or "searching" (none found yet).
 *
 * Its collaborators, each owned: `media` (the picture, www/js/media.js), `placement` (the
 * placement step, www/js/placement.js), `sequencer` (opens the media and runs the sequences,
 * www/js/tracking-sequence.js), `fitLog` (www/js/tracking-log.js) and, while it runs, `panel`
 * (www/js/tracking-panel.js). The source keeps the state they share and the frame loop.
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
    this.media = new MediaFeed(this.wasm.policy().workSide); // the core's work-frame side
    this.video = this.media.video;
    this.placement = new Placement(this.model.landmarks(this.model.baseParams()));
    this.sequencer = new Sequencer(this);
    // The call page keeps its own log (www/js/call-controls.js): it asks for a short one.
    this.fitLog = new FitLog(ctx.logMax ?? LOG_MAX);
    this.panel = null;
    this.last = null; // last fit result (work coordinates)
    this.lastGood = null; // last fit that was not lost, this sequence
    this.state = 'idle'; // tracking | unsure | lost | searching | reinit | idle (the panel's label)
    this.loops = 0;
    this.autoStart = true;
    this.fps = 0;
    this.lastFitAt = null; // performance.now() of the last fit (the tracker's time step)
    this.lastResets = 0;
    this.sequenceStart = { lost: 0, resets: 0 }; // the tracker's counts when the sequence began
    this.seqId = 0; // bumped by every new sequence / placement (stale finder results are dropped)
    this.finding = false; // the placement step waits for the finder
    this.findBusy = false; // a finder request is under way
    this.findError = null;
    this.streamEnded = false;
    this.reacquired = 0;
    this.previous = null; // the source held while a file is tried (www/js/tracking-flow.js)
    this.probing = false; // a file is being tried
    this.handed = null; // what the source this one replaced passed on (its camera stream, its file)
    watchTransport(this);
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
  get fileName() {
    return this.sequencer.opener.name;
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
  /** The fit log's entries (landmarks in the video's pixels), finder runs and counts. */
  get log() {
    return this.fitLog.entries;
  }
  get findLog() {
    return this.fitLog.finds;
  }
  get fits() {
    return this.fitLog.fits;
  }
  get frameNo() {
    return this.fitLog.frameNo;
  }
  get canvas() {
    return this.panel?.canvas ?? null;
  }

  initialParams() {
    const p = typeof this.ctx.currentParams === 'function' ? this.ctx.currentParams() : this.ctx.params;
    const ok = p && p.pose && p.shape?.length === this.info.shapeModes && p.appearance?.length === this.info.appearanceModes;
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
    shown = this;
    this.path = followPath(this.ctx, this.mode, this.model);
    this.panel = new TrackingPanel(this);
    if (this.previous) this.panel.el.hidden = true; // until the source held lets go
    this.setPhase('loading');
    // A file's tracker is made once a file opens (a source held meanwhile keeps its own).
    if (this.mode !== 'file' && !this.makeTracker()) return;
    this.sequencer.begin(this.handed);
    this.handed = null;
  }

  /** The tracker for the source model (false, with the reason shown, when it cannot be made). */
  makeTracker() {
    try {
      this.tracker = trackerFor(this.wasm, this.model, this.path, this.mode);
      return true;
    } catch (e) {
      this.fail('The tracker could not be made for this source model', e);
      return false;
    }
  }

  stop() {
    if (!this.running) return;
    this.running = false;
    this.seqId++;
    this.media.close();
    this.sequencer.opener.close();
    this.panel?.remove();
    if (shown === this) shown = null;
    release(this); // a source held (www/js/tracking-flow.js), if any, stops too
  }

  /** This source is the one shown (given its place back: www/js/tracking-flow.js). */
  show() {
    if (this.running) shown = this;
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

  // --- what the panel shows ---------------------------------------------------------------------

  setPhase(phase, msg) {
    this.phase = phase;
    this.panel?.show(phase, msg);
    if (this.running) this.ctx.transportChanged?.(this);
  }

  say(text) {
    this.panel?.say(text);
  }

  draw() {
    this.panel?.draw();
  }

  fail(what, e) {
    const reason = e === undefined ? '' : message(e);
    this.cancelFrames();
    this.setPhase('error', reason ? `${what}: ${reason}` : what);
    this.panel?.showError();
  }

  // --- the actions (the panel's buttons, the page's drops; www/js/tracking-sequence.js) -----------

  /** A dropped or picked file: a video (tracked) or a photo (one face fitted). */
  openFile(file) {
    return this.sequencer.openFile(file);
  }
  /** Start tracking from the selected face found, the placement box, or given landmarks (work px). */
  startTracking(landmarks = null) {
    return this.sequencer.startTracking(landmarks);
  }
  /** A new sequence: the clip from its start; a file or the webcam placed again. */
  restart() {
    return this.sequencer.restart();
  }
  togglePlay() {
    this.sequencer.togglePlay();
  }
  /** After an error: open the clip or the camera again. */
  retry() {
    this.sequencer.retry();
  }
  /** The panel's Auto-start box: start by itself when a face is found. */
  setAutoStart(on) {
    this.autoStart = on;
    if (this.phase === 'placing') this.restart();
  }

  // --- the frame loop -------------------------------------------------------------------------------

  onVideoFrame(mediaTime) {
    if (mediaTime === this.lastMediaTime && this.mode !== 'webcam') return;
    this.lastMediaTime = mediaTime;
    this.grab();
    if (this.phase === 'tracking') this.fitCurrent(mediaTime);
    else if (this.phase === 'placing' && this.mode === 'webcam') this.sequencer.searchGuide(mediaTime);
    this.draw();
  }

  /** Draw the current frame into the work canvas; returns k (work px per video px). */
  grab() {
    const k = this.media.grab();
    this.panel?.fitAspect(this.work.width, this.work.height);
    return k;
  }

  /** A new sequence's bookkeeping; `searching`: it starts with no face (startSearching). */
  beginSequence(searching = false) {
    this.last = null;
    this.lastGood = null;
    this.lastFitAt = null;
    this.searchStart = searching;
    this.state = searching ? 'searching' : 'tracking';
    this.sequenceStart = { lost: this.tracker.lostCount, resets: this.tracker.resets };
    this.lastResets = this.tracker.resets;
  }

  /**
   * Fit the current frame (the work canvas, as it is: the tracker chooses its scale); update the
   * params (the result's `placed` pose: the head re-centred by the tracker), state and stats.
   */
  fitCurrent(mediaTime) {
    const image = this.media.workImage();
    const t0 = performance.now();
    // The anchor's time step: the time since the last fit (the package's default, 1/30 s, on a
    // sequence's first fit or when no time passed).
    const dt = this.lastFitAt === null || t0 <= this.lastFitAt ? undefined : (t0 - this.lastFitAt) / 1000;
    let r;
    try {
      r = this.tracker.track(image.data, image.width, image.height, dt);
    } catch (e) {
      this.fail('Tracking failed', e);
      return;
    }
    const t1 = performance.now();
    this.lastFitAt = t0;
    const ms = t1 - t0;
    this.fitLog.time(ms, t1);

    const resets = this.tracker.resets;
    const wasLost = this.last?.lost;
    // An unsure fit (the core doubts it: r.status, r.reasons) drives nothing; never "tracking".
    const unsure = !r.lost && r.status === 'unsure';
    const shownState = this.state;
    this.state = r.lost ? (this.lastGood ? 'lost' : this.searchStart ? 'searching' : 'lost') : unsure ? 'unsure' : resets > this.lastResets ? 'reinit' : 'tracking';
    this.lastResets = resets;
    this.last = r;
    if (r.reacquired) this.reacquired++;
    if (!r.lost && !unsure) {
      this.lastGood = r;
      this.params = { pose: r.placed, shape: r.shape, appearance: r.appearance };
      this.invalidate();
    }
    this.fitLog.fit(r, { time: mediaTime, fps: this.fps, k: this.k, ms, loop: this.loops });
    // Looking for the face (none yet, or lost) or a second opinion due: the worker finds faces.
    if (this.tracker.wantsFaces && !this.media.still) this.feedFinder();
    // The call page renders and logs every fit, lost or not (www/js/call-avatar.js).
    if (typeof this.ctx.onFit === 'function') this.ctx.onFit(r, this.params);

    if (this.phase === 'tracking' && !this.media.still && this.panel) {
      if (r.lost && this.lastGood === null && this.searchStart) this.say('Looking for a face…');
      else if (r.lost) this.say('Face lost: looking for it again (it is tracked again as soon as it is found).');
      else if (r.reacquired) this.say(wasLost && this.log.length > 1 ? 'Face found again: tracking.' : 'Face found: tracking.');
      else if (unsure) this.say('Unsure of the fit: the targets hold the last good expression until the face is clear again.');
      else if (/^(Face lost|Looking for a face|Face found|Unsure of the fit)/.test(this.panel.message)) this.say('Tracking.');
      // The state's label changes with the message, not at the readout's next refresh.
      if (this.state !== shownState) this.panel.showState();
    }
    this.panel?.showStats(t1);
  }

  /**
   * When the tracker wants faces (a search, or a lost face), find them in the current frame in
   * the worker and offer them (work pixels, as the frames the tracker is given).
   */
  feedFinder() {
    if (this.findBusy || !this.tracker.wantsFaces) return;
    this.findBusy = true;
    const seq = this.seqId;
    const t0 = performance.now();
    findFaces(this.media.workImage()).then(
      ({ faces, ms }) => {
        this.findBusy = false;
        this.fitLog.find({ ms, faces: faces.length, wall: performance.now() - t0 });
        if (seq !== this.seqId || !this.running || !faces.length || !this.tracker.wantsFaces) return;
        try {
          this.tracker.offerFaces(faces);
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
}

// The page's flow (tracking-flow.js): transport(), keepsAcross(), takeOver(), release(), handBack().
Object.assign(VideoSource.prototype, FLOW_METHODS);

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

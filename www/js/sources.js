// Sources: what drives the source face. Every source has the same small shape,
//
//   { kind, label, start(), stop(), paramsAt(t) -> Params | null, ...transport (optional) }
//
// where `t` is the page clock in seconds and Params is the JS API's
// `{ pose: { scale, rotation, tx, ty }, shape: number[], appearance: number[] }`.
// `start()` is called when the source becomes active, `stop()` when another one takes over.
//
// Today there are two: the recorded track (the bundled, projected clip) and the sliders.
// The tracking work adds video-file and webcam sources (driven by the package's `Tracker`) by
// calling `registerSource` from its own module; the page lists them only when they are registered.

import { lerpPose, meanPose as averagePose, recentrePose } from '../pkg/facemimic.js';

/** Registered source factories, in menu order: kind -> { label, create(ctx) }. */
const registry = new Map();

/**
 * Register a kind of source. `create(ctx)` returns a source object (see above); `ctx` is what the
 * page offers every source: `{ wasm, sourceModel(), sourceInfo(), currentParams(), invalidate() }`
 * (`invalidate()` asks for a redraw, e.g. when a new video frame was tracked while the page is
 * otherwise idle).
 * `available(wasm)` (optional) decides whether the entry is offered at all.
 */
export function registerSource(kind, { label, create, available = () => true }) {
  registry.set(kind, { label, create, available });
}

/** The kinds that can be offered with this build of the package. */
export function availableSources(wasm) {
  return [...registry.entries()].filter(([, s]) => s.available(wasm)).map(([kind, s]) => ({ kind, label: s.label }));
}

/** Make a source of a registered kind. */
export function createSource(kind, ctx) {
  const entry = registry.get(kind);
  if (!entry) throw new Error(`unknown source "${kind}"`);
  return entry.create(ctx);
}

/** Deep copy of a Params object (plain arrays). */
export function cloneParams(p) {
  return {
    pose: { scale: p.pose.scale, rotation: p.pose.rotation, tx: p.pose.tx, ty: p.pose.ty },
    shape: Array.from(p.shape),
    appearance: Array.from(p.appearance),
  };
}

/**
 * Blend of two Params with the same lengths (u in [0, 1]): the pose the package's way
 * (`lerpPose`: log-scale, the angle the short way round, as its pose average), the modes
 * linearly.
 */
function lerpParams(a, b, u, out) {
  out.pose = lerpPose(a.pose, b.pose, u);
  for (let i = 0; i < out.shape.length; i++) out.shape[i] = a.shape[i] + (b.shape[i] - a.shape[i]) * u;
  for (let i = 0; i < out.appearance.length; i++) {
    out.appearance[i] = a.appearance[i] + (b.appearance[i] - a.appearance[i]) * u;
  }
  return out;
}

/**
 * Check that a parsed track is an array of Params that `model` accepts (the package's
 * `Model.checkParams`: mode counts, finite values within the library's bounds, a positive pose
 * scale); throws a message naming the first bad frame.
 */
export function validateTrack(frames, model) {
  if (!Array.isArray(frames) || frames.length === 0) throw new Error('the track holds no frames');
  frames.forEach((f, i) => {
    if (!f || typeof f !== 'object' || !f.pose) throw new Error(`frame ${i}: not a parameter set`);
    try {
      model.checkParams(f);
    } catch (e) {
      throw new Error(`frame ${i}: ${e instanceof Error ? e.message : e}`);
    }
  });
  return frames;
}

/**
 * Re-centre a track's head placement on the model's mean pose: every frame's pose becomes
 * `meanPose o trackMean^-1 o pose`, where trackMean is the track's average pose. The head
 * motion within the clip is kept exactly; only where the clip's camera happened to put the head
 * changes, so the source face sits centred in its canvas (and follow-pose moves the targets
 * about their own mean placement). The pose maths is the package's (`recentrePose`, the core's
 * `Similarity::recentred`). Returns new frames; the input is not modified.
 */
export function recentreTrack(frames, meanPose) {
  // The package's one pose average (`meanPose`: log-scale, circular angle).
  const trackMean = averagePose(frames.map((f) => f.pose));
  return frames.map((f) => ({ ...cloneParams(f), pose: recentrePose(f.pose, trackMean, meanPose) }));
}

/**
 * The recorded track: `frames` (Params at `fps`) played in a loop. It owns a transport:
 * `playing`, `play()`, `pause()`, `seek(frame)`, `frame` (the current integer frame),
 * `frameCount`. Between frames the parameters are blended (`lerpParams`), so playback is smooth at any
 * display rate while the track time advances at exactly `fps` frames per second.
 */
export class TrackSource {
  constructor(frames, fps = 25, label = 'Recorded track') {
    this.kind = 'track';
    this.label = label;
    this.frames = frames;
    this.fps = fps;
    this.position = 0; // in frames (fractional while playing)
    this.playing = false;
    this.lastT = null;
    this.scratch = cloneParams(frames[0]);
  }
  get frameCount() {
    return this.frames.length;
  }
  get frame() {
    return Math.min(this.frames.length - 1, Math.floor(this.position + 1e-6));
  }
  start() {
    this.lastT = null;
  }
  stop() {
    this.pause();
  }
  play() {
    if (this.position >= this.frames.length - 1) this.position = 0;
    this.playing = true;
    this.lastT = null;
  }
  pause() {
    this.playing = false;
    this.position = this.frame; // settle on a whole frame: what the counter shows is what is drawn
    this.lastT = null;
  }
  seek(frame) {
    const n = this.frames.length;
    this.position = Math.max(0, Math.min(n - 1, Math.round(frame)));
    this.lastT = null;
  }
  /** Advance with the page clock (seconds) and return the parameters to draw. */
  paramsAt(t) {
    const n = this.frames.length;
    if (this.playing) {
      if (this.lastT !== null) {
        // Cap a stall (hidden tab, debugger) to a few frames rather than jumping far ahead.
        const dt = Math.min(0.25, Math.max(0, t - this.lastT));
        this.position += dt * this.fps;
        if (this.position >= n - 1) this.position %= n - 1 || 1; // loop
      }
      this.lastT = t;
    }
    const i = Math.floor(this.position);
    const u = this.position - i;
    if (u < 1e-6 || i + 1 >= n) return this.frames[Math.min(i, n - 1)];
    return lerpParams(this.frames[i], this.frames[i + 1], u, this.scratch);
  }
}

/**
 * The sliders: a fixed parameter set that the page edits in place (`params`). Starts from
 * whatever the source showed when the user took over.
 */
export class SliderSource {
  constructor(params, label = 'Sliders') {
    this.kind = 'sliders';
    this.label = label;
    this.params = cloneParams(params);
  }
  start() {}
  stop() {}
  set(kind, index, value) {
    this.params[kind][index] = value;
  }
  paramsAt() {
    return this.params;
  }
}

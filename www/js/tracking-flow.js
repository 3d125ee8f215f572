// How a video source (www/js/tracking.js) takes its place in the page's flow, as the page's
// source-control.js asks: its transport (the page's Play button, scrubber and counter drive the
// video of the bundled clip or of a file; the webcam has none), taking over from the source
// before it, and giving the place back.
//
// Taking over: the same live kind made again for a new source model (a face made in "Create a
// face", one from Your models) gets the old one's camera picture or file, so the webcam or the
// video goes on, tracked as the core's policy says for the new model. A video file source made
// while another source runs (a video dropped on the page) holds that source, still running,
// until its file proves playable: a file the browser cannot play hands the place back, and the
// source before it goes on as if nothing had happened.

/** Whether `src` is a video source (tracking.js's `VideoSource`; not imported: no cycle). */
const isVideo = (src) => Boolean(src && src.media && src.sequencer);

/**
 * The transport of a video source, or null when it has none (the webcam, a photo, nothing
 * loaded yet): `{ playing, time, duration (null: unknown), toggle(), seek(seconds) }`.
 */
export function videoTransport(src) {
  if (src.mode === 'webcam' || src.media.still || !src.haveFrame) return null;
  if (!['placing', 'tracking', 'paused'].includes(src.phase)) return null;
  const v = src.video;
  return {
    playing: src.phase === 'tracking' && !v.paused,
    time: v.currentTime,
    duration: Number.isFinite(v.duration) && v.duration > 0 ? v.duration : null,
    // Placing (a file with Auto-start off, or several faces): Play starts from the face chosen.
    toggle: () => (src.phase === 'placing' ? src.startTracking() : src.togglePlay()),
    seek: (t) => seekVideo(src, t),
  };
}

/** Moves the video to `time` (s) for the user; the 'seeked' handler (watchTransport) follows up. */
function seekVideo(src, time) {
  const v = src.video;
  if (!Number.isFinite(v.duration)) return;
  src.userSeek = true;
  v.currentTime = Math.max(0, Math.min(v.duration, time));
}

/**
 * Tells the page (`ctx.transportChanged(src)`) when the video's transport changes, and follows a
 * seek the user made: paused, the frame there is fitted and shown (the source follows the
 * scrubber); placing, the faces are found again on it; playing, tracking goes on from there.
 */
export function watchTransport(src) {
  const v = src.video;
  const changed = () => src.running && src.ctx.transportChanged?.(src);
  for (const e of ['play', 'pause', 'timeupdate', 'durationchange', 'ended']) v.addEventListener(e, changed);
  v.addEventListener('seeked', () => {
    if (src.userSeek && src.running) {
      src.userSeek = false;
      if (src.phase === 'placing' && src.mode === 'file') src.restart();
      else if (src.phase === 'paused') {
        src.grab();
        src.fitCurrent(v.currentTime);
        src.draw();
      }
    }
    changed();
  });
}

/**
 * Whether `src` goes on through a change of the source model to `model`: the webcam with its
 * camera open, a video file with a file open.
 */
export function keepsAcross(src, model) {
  if (!src.running || src.model === model) return false;
  return src.mode === 'webcam' ? Boolean(src.media.stream) : src.mode === 'file' && Boolean(src.sequencer.file);
}

/**
 * `src` (not started yet) takes the place of `old`. Returns true when `old` is held (it keeps
 * running until `release` or `handBack`); false when the caller stops it now.
 */
export function takeOver(src, old) {
  if (!old) return false;
  if (isVideo(old) && old.mode === src.mode && old.running) {
    // Made again for a new model: the camera's stream (not stopped with the old source) and
    // where the face was, or the file and where it was.
    if (src.mode === 'webcam' && old.media.stream) {
      const face = old.lastGood && !old.last?.lost ? Float32Array.from(old.lastGood.landmarks) : null;
      src.handed = { stream: old.media.stream, landmarks: face };
      old.media.stream = null;
    } else if (src.mode === 'file' && old.sequencer.file) {
      src.handed = { file: old.sequencer.file, time: old.media.still ? 0 : old.video.currentTime };
    }
    return false;
  }
  if (src.mode !== 'file') return false;
  // A video file source: `old` goes on while a file given in this same task (a drop) is tried;
  // with none (chosen from the menu), it stops at the end of the task.
  src.previous = old;
  queueMicrotask(() => {
    if (src.previous === old && !src.probing) release(src);
  });
  return true;
}

/** The source held by `src` stops; `src`'s panel shows. */
export function release(src) {
  const prev = src.previous;
  src.previous = null;
  prev?.stop();
  if (src.panel) src.panel.el.hidden = false;
  if (prev && src.running) src.ctx.transportChanged?.(src);
}

/**
 * A file that could not be shown: the source `src` held takes its place back (the page's
 * `ctx.handBack(src, previous)` makes it the active source again and stops `src`). Returns
 * false when `src` held none.
 */
export function handBack(src) {
  const prev = src.previous;
  if (!prev) return false;
  src.previous = null;
  if (typeof src.ctx.handBack === 'function') src.ctx.handBack(src, prev);
  else prev.stop();
  prev.show?.();
  return true;
}

/** What a notice says goes on while a held source takes its place back. */
export function stillTheSource(prev) {
  const name = { track: 'the recorded track', sliders: 'the sliders', webcam: 'the webcam', 'video-clip': 'the bundled clip' }[prev.kind];
  return `The source stays on ${name ?? prev.label}.`;
}

/** The methods a video source gets from here (tracking.js assigns them to its class). */
export const FLOW_METHODS = {
  /** The video's transport for the page, or null (`videoTransport`). */
  transport() {
    return videoTransport(this);
  },
  /** Whether it goes on through a change of the source model (`keepsAcross`). */
  keepsAcross(model) {
    return keepsAcross(this, model);
  },
  /** Takes the place of `old` (`takeOver`): true when `old` is held. */
  takeOver(old) {
    return takeOver(this, old);
  },
  release() {
    release(this);
  },
  handBack() {
    return handBack(this);
  },
};

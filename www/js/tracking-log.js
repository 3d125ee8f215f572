// What a video source (www/js/tracking.js) keeps of its fits and finder runs, for the readout,
// the console and the end-to-end tests: `entries` (one a fit, landmarks in the video's pixels),
// `finds` (one a finder run), and the timing the readout shows (`fits`, `msPerFit` smoothed,
// `fitTimes` of the last second). The source owns one; nothing here reads the source.

import { workToVideo } from './media.js';

/** Fit log kept for inspection (entries). */
export const LOG_MAX = 3000;

/** A source's fit and finder log, at most `max` entries of each. */
export class FitLog {
  constructor(max = LOG_MAX) {
    this.max = max;
    this.entries = [];
    this.finds = []; // { ms, faces, wall?, placing? } per finder request
    this.fitTimes = []; // performance.now() of the fits of the last second
    this.msPerFit = 0;
    this.fits = 0;
    this.frameNo = 0; // frames seen (the frame number of a log entry without a frame rate)
  }

  /** Counts a fit that took `ms` and ended at `t1` (performance.now()). */
  time(ms, t1) {
    this.fits++;
    this.msPerFit = this.fits === 1 ? ms : this.msPerFit + (ms - this.msPerFit) * 0.1;
    this.fitTimes.push(t1);
    while (this.fitTimes.length && t1 - this.fitTimes[0] > 1000) this.fitTimes.shift();
  }

  /**
   * Logs a fit `r` (work pixels, `k` work px per video px) of the frame at `time` (seconds; with
   * `fps`, the frame number is the time's, else the count of frames seen) that took `ms`, in
   * loop `loop` of the video.
   */
  fit(r, { time, fps, k, ms, loop }) {
    const frame = fps ? Math.round(time * fps) : this.frameNo;
    this.frameNo++;
    this.entries.push({
      loop,
      frame,
      time,
      error: r.error,
      iterations: r.iterations,
      converged: r.converged,
      lost: r.lost,
      reacquired: r.reacquired,
      ms,
      landmarks: workToVideo(r.landmarks, k), // video pixels
    });
    if (this.entries.length > this.max) this.entries.splice(0, this.entries.length - this.max);
  }

  /** Logs a finder run. */
  find(entry) {
    this.finds.push(entry);
    if (this.finds.length > this.max) this.finds.shift();
  }
}

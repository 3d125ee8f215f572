// What a video source (www/js/tracking.js) keeps of its fits and finder runs, for the readout,
// the console and the end-to-end tests: `log` (one entry a fit, landmarks in the video's
// pixels), `findLog` (one entry a finder run), and the timing the readout shows (`fits`,
// `msPerFit` smoothed, `fitTimes` of the last second). Methods of `VideoSource`, mixed into it
// by tracking.js.

import { workToVideo } from './tracking-open.js';

/** Fit log kept for inspection (entries). */
export const LOG_MAX = 3000;

/** The logging methods (`this` is the `VideoSource`). */
export const logMethods = {
  /** Counts a fit that took `ms` and ended at `t1` (performance.now()). */
  timeFit(ms, t1) {
    this.fits++;
    this.msPerFit = this.fits === 1 ? ms : this.msPerFit + (ms - this.msPerFit) * 0.1;
    this.fitTimes.push(t1);
    while (this.fitTimes.length && t1 - this.fitTimes[0] > 1000) this.fitTimes.shift();
  },

  /** Logs a fit `r` (work pixels) of the frame at `mediaTime` that took `ms`. */
  logFit(r, mediaTime, ms) {
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
      landmarks: workToVideo(r.landmarks, this.k), // video pixels
    });
    if (this.log.length > this.logMax) this.log.splice(0, this.log.length - this.logMax);
  },

  /** Logs a finder run. */
  logFind(entry) {
    this.findLog.push(entry);
    if (this.findLog.length > this.logMax) this.findLog.shift();
  },
};

// The sequences of a video source (www/js/tracking.js): opening the bundled clip, a dropped file
// or the webcam (through the `MediaOpener`, www/js/tracking-open.js), the placement step (the
// faces found, or a box), starting, looping, restarting and pausing a sequence. Landmarks and
// boxes are in the work canvas's pixels, the frame the tracker is given: it chooses its fit
// scale itself.

import { fileError, message, notify } from './toasts.js';
import { CLIP_JSON, videoToWork, probeVideo, looksLikeImage } from './media.js';
import { findFaces } from './finder-client.js';
import { MediaOpener, notMediaReason } from './tracking-open.js';
import { unplayableHelp, unplayableLine } from './media-help.js';
import { stillTheSource } from './tracking-flow.js';

/** Rejects with the reason when the browser cannot decode the image `file`. */
async function probeImage(file) {
  try {
    (await createImageBitmap(file)).close();
  } catch (e) {
    throw new Error(`the image could not be decoded (${message(e)})`);
  }
}

/**
 * A video source's sequences, owned by the source (`src`). It keeps what a sequence starts from
 * (the clip, where a file's tracking began, the webcam's search) and drives the source through
 * its frame operations (`grab`, `requestFrames`, `cancelFrames`, `beginSequence`, `fitCurrent`,
 * `feedFinder`) and its display (`setPhase`, `say`, `draw`, `fail`, `panel`); it sets the
 * source's `fps`, `loops`, `seqId`, `finding`, `findError` and `streamEnded`.
 */
export class Sequencer {
  constructor(src) {
    this.src = src;
    this.clip = null; // the bundled clip's description
    this.seqStart = null; // a file: where tracking began ({ time, landmarks }), to loop back to
    this.searchingGuide = false; // the webcam's placement step: the tracker is searching
    this.file = null; // the file open (a video or a photo)
    this.opener = new MediaOpener(src.media, {
      live: () => src.running,
      onEnded: () => (src.mode === 'clip' ? this.onClipEnded() : this.onFileEnded()),
      onCameraEnded: () => {
        src.streamEnded = true;
        src.media.haveFrame = false;
        src.fail('The camera stopped sending pictures (unplugged, or access was withdrawn)');
      },
    });
  }

  /**
   * The source's start: the clip, the camera, or (a file) an empty panel. `handed`: what the
   * source it replaced passed on (www/js/tracking-flow.js): the camera's stream and where the
   * face was, or the file and where in it.
   */
  begin(handed) {
    const src = this.src;
    if (src.mode === 'clip') this.openClip();
    else if (src.mode === 'webcam') this.openWebcam(handed?.stream, handed?.landmarks);
    else {
      src.setPhase('empty');
      if (handed?.file) this.openFile(handed.file, handed.time);
    }
  }

  /** After an error: open the clip or the camera again. */
  retry() {
    const src = this.src;
    if (!src.running) return;
    src.cancelFrames();
    if (src.mode === 'clip') this.openClip();
    else if (src.mode === 'webcam') {
      src.media.stopStream();
      this.openWebcam();
    }
  }

  async openClip() {
    const src = this.src;
    try {
      const clip = await this.opener.clip(src.placement.meanShape.length);
      if (!clip) return;
      this.clip = clip;
      src.fps = clip.fps;
      await this.startClipSequence();
    } catch (e) {
      if (!src.running) return;
      fileError(src.fileName || CLIP_JSON, e);
      src.fail(`The bundled clip could not be played`, e);
    }
  }

  /** The clip from frame 0: the tracker starts from the clip's first-frame landmarks. */
  async startClipSequence() {
    const src = this.src;
    src.cancelFrames();
    await src.media.seek(0);
    if (!src.running) return;
    src.grab();
    src.tracker.startFromLandmarks(videoToWork(this.clip.initLandmarks, src.k));
    src.beginSequence();
    src.setPhase('tracking', `Tracking spk07's unseen clip (${this.clip.frames ?? '?'} frames at ${src.fps} fps) from its first frame's landmarks.`);
    src.fitCurrent(0);
    await this.play();
  }

  async onClipEnded() {
    const src = this.src;
    if (!src.running || src.mode !== 'clip') return;
    src.loops++;
    try {
      await this.startClipSequence();
    } catch (e) {
      if (src.running) src.fail('The clip could not loop', e);
    }
  }

  /**
   * A dropped or picked file: a video (tracked) or a photo (one face fitted); `resumeAt`: where
   * in the video to start (s). The file is tried on the side first: one that cannot be shown
   * leaves everything as it was (the file playing, or the source held, which takes its place back).
   */
  async openFile(file, resumeAt = 0) {
    const src = this.src;
    if (!src.running) return;
    const name = file.name || 'the file';
    const why = notMediaReason(file);
    if (why) {
      this.refuse(name, new Error(why));
      return;
    }
    src.probing = true;
    try {
      await (looksLikeImage(file) ? probeImage(file) : probeVideo(file));
    } catch (e) {
      src.probing = false;
      if (src.running) this.refuse(name, e);
      return;
    }
    src.probing = false;
    if (!src.running) return;
    src.release(); // the source held, if any, stops: this file takes over
    if (!src.tracker && !src.makeTracker()) return;
    src.cancelFrames();
    src.seqId++;
    src.media.haveFrame = false;
    src.last = null;
    src.lastGood = null;
    src.placement.setFaces([]);
    src.setPhase('loading', `Opening ${name}…`);
    try {
      const opened = await this.opener.file(file);
      if (!opened || !src.running) return;
      this.file = file;
      if (resumeAt > 0 && !src.media.still) await src.media.seek(Math.min(resumeAt, src.video.duration || 0)).catch(() => {});
      src.fps = opened.fps;
      src.grab();
      await this.enterPlacing();
    } catch (e) {
      if (!src.running) return;
      fileError(name, e);
      src.media.haveFrame = false;
      src.setPhase('empty', `${name}: ${message(e)}`);
      src.panel.showError();
    }
  }

  /**
   * A file that cannot be shown (`e` why): said (a video the browser cannot play, with the
   * commands that convert it); the source held takes its place back, or this one stays as it was.
   */
  refuse(name, e) {
    const src = this.src;
    const still = src.previous ? stillTheSource(src.previous) : src.haveFrame && this.file ? `${src.fileName} goes on.` : '';
    if (e.unplayable) {
      console.warn(`facemimic: ${name}: ${e.message} (${e.detail})`);
      notify('error', `Cannot play ${name}`, unplayableHelp({ name, detail: e.detail, still }));
    } else fileError(name, e);
    if (src.handBack()) return;
    const line = e.unplayable ? unplayableLine(name) : `${name}: ${message(e)}`;
    if (src.haveFrame) src.say(line);
    else {
      src.setPhase('empty', line);
      src.panel.showError();
    }
  }

  /**
   * The placement step on the current frame. A file: the faces are found (in the worker) and
   * shown; with Auto-start, a video with one face starts tracking at once, with several it waits
   * for the user's pick, with none it plays while the tracker searches; a photo waits for Fit.
   * The webcam: the guide while the tracker searches the live picture.
   */
  async enterPlacing() {
    const src = this.src;
    const seq = ++src.seqId;
    src.cancelFrames();
    if (src.mode === 'file') src.video.pause();
    src.placement.setFaces([]);
    src.placement.placeDefault(src.work.width, src.work.height, src.mode === 'webcam', src.lastGood?.landmarks);
    src.placement.touched = false;
    src.findError = null;
    if (src.mode === 'webcam') {
      this.searchingGuide = false;
      src.setPhase('placing');
      src.requestFrames();
      return;
    }
    src.finding = true;
    src.setPhase('placing');
    src.panel.focus();
    let faces = [];
    try {
      const r = await findFaces(src.media.workImage());
      faces = r.faces;
      src.fitLog.find({ ms: r.ms, faces: faces.length, placing: true });
    } catch (e) {
      src.findError = message(e);
    }
    if (seq !== src.seqId || !src.running || src.phase !== 'placing') return;
    src.finding = false;
    const byHand = src.placement.touched;
    src.placement.setFaces(faces, true);
    if (!faces.length && !byHand) src.placement.placeDefault(src.work.width, src.work.height, false);
    src.setPhase('placing');
    // A photo waits for its Fit button; a video starts by itself (unless a box was placed).
    if (!src.autoStart || src.media.still || byHand) return;
    if (faces.length === 1) await this.startTracking();
    else if (!faces.length && !src.findError) await this.startSearch();
  }

  /** The camera (`stream`: one already open, passed on), tracked from `landmarks` (work px) if given. */
  async openWebcam(stream = null, landmarks = null) {
    const src = this.src;
    src.setPhase('loading', stream ? 'Going on with the camera…' : 'Asking for the camera…');
    src.streamEnded = false;
    let fps;
    try {
      fps = await this.opener.camera(stream);
    } catch (e) {
      if (src.running) src.fail(e.message);
      return;
    }
    if (!fps || !src.running) return;
    src.fps = fps;
    src.grab();
    await this.enterPlacing();
    // Where the face was a moment ago: the new tracker starts there (and searches if it is not).
    if (landmarks && src.autoStart && src.running && src.phase === 'placing') await this.startTracking(landmarks);
  }

  async play() {
    const src = this.src;
    if (src.media.still) return;
    try {
      await src.video.play();
    } catch (e) {
      // Autoplay refused (a browser without a user gesture): show it paused; Play starts it.
      if (!src.running) return;
      src.setPhase('paused', `The browser did not start the video by itself (${message(e)}): press Play.`);
      return;
    }
    src.requestFrames();
  }

  /**
   * Webcam, placing with Auto-start: the tracker searches the live picture (faces found in the
   * worker are offered to it; it acquires one when its fit is plausible), and tracking starts
   * by itself when it does.
   */
  searchGuide(mediaTime) {
    const src = this.src;
    src.fitLog.frameNo++;
    if (!src.autoStart) return;
    if (!this.searchingGuide) {
      this.searchingGuide = true;
      src.tracker.startSearching();
      src.beginSequence(true);
    }
    src.feedFinder();
    if (src.tracker.wantsFaces) return; // nothing to try yet: no fit on this frame
    src.fitCurrent(mediaTime);
    if (src.last && !src.last.lost) {
      this.searchingGuide = false;
      src.setPhase('tracking', 'Tracking your face.');
    }
  }

  /** Start tracking from the selected face found, the placement box, or given landmarks (work px). */
  async startTracking(landmarks = null) {
    const src = this.src;
    if (!src.haveFrame || !src.box) return;
    const face = landmarks ?? src.placement.face?.landmarks ?? null;
    try {
      if (face) src.tracker.startFromLandmarks(face);
      else {
        const b = src.box;
        src.tracker.startFromBox(b.x, b.y, b.w, b.h);
      }
    } catch (e) {
      src.say(`Cannot start: ${message(e)}`);
      return;
    }
    src.seqId++;
    this.searchingGuide = false;
    src.beginSequence();
    if (src.media.still) {
      // A photo: the face is fitted (a few passes on the same picture), and stays.
      src.setPhase('tracking', `Fitting the face in ${src.fileName}.`);
      const passes = src.wasm.policy().photo.fitPasses; // the core's policy
      for (let i = 0; i < passes; i++) src.fitCurrent(0);
      src.setPhase('tracking', src.last && !src.last.lost ? `The face in ${src.fileName} drives the source.` : `The face in ${src.fileName} could not be fitted: Re-start places it again.`);
      src.draw();
      return;
    }
    src.setPhase('tracking', src.mode === 'webcam' ? 'Tracking your face.' : `Tracking ${src.fileName}.`);
    if (src.mode === 'file') {
      src.fitCurrent(src.video.currentTime);
      // Where the sequence began, to loop back to with a known fit.
      this.seqStart = src.last && !src.last.lost ? { time: src.video.currentTime, landmarks: src.last.landmarks } : null;
      src.draw();
      await this.play();
    } else src.requestFrames();
  }

  /** A video with no face found on its first frame: play it, the tracker looking for a face. */
  async startSearch() {
    const src = this.src;
    src.seqId++;
    src.tracker.startSearching();
    src.beginSequence(true);
    this.seqStart = null;
    src.setPhase('tracking', `Looking for a face in ${src.fileName}…`);
    src.fitCurrent(src.video.currentTime);
    await this.play();
  }

  /** A file played to its end: loop back to where tracking began, from the fit found there. */
  async onFileEnded() {
    const src = this.src;
    if (!src.running || src.mode !== 'file' || src.phase !== 'tracking') return;
    src.loops++;
    const start = this.seqStart;
    const searched = src.searchStart;
    try {
      src.cancelFrames();
      await src.media.seek(start ? start.time : 0);
      if (!src.running || src.phase !== 'tracking') return;
      src.grab();
      if (start) {
        src.tracker.startFromLandmarks(start.landmarks);
        src.beginSequence();
        src.fitCurrent(src.video.currentTime);
        src.draw();
        await this.play();
      } else if (searched) {
        await this.startSearch();
      } else {
        this.restart();
      }
    } catch (e) {
      if (src.running) src.fail('The video could not loop', e);
    }
  }

  async restart() {
    const src = this.src;
    if (!src.running) return;
    if (src.mode === 'clip') {
      try {
        await this.startClipSequence();
      } catch (e) {
        src.fail('The clip could not restart', e);
      }
      return;
    }
    src.cancelFrames();
    if (src.mode === 'file') src.video.pause();
    src.grab();
    await this.enterPlacing();
  }

  togglePlay() {
    const src = this.src;
    if (src.phase === 'tracking') {
      src.cancelFrames();
      if (src.mode !== 'webcam') src.video.pause();
      src.setPhase('paused');
    } else if (src.phase === 'paused') {
      src.setPhase('tracking', 'Tracking.');
      if (src.mode === 'webcam') src.requestFrames();
      else this.play();
    }
  }
}

// Opening and starting a video source (www/js/tracking.js): the bundled clip, a dropped file or
// the webcam; the placement step (the faces found, or a box); starting, looping, restarting and
// pausing a sequence; and feeding the tracker the faces found in a worker while it looks for
// one. Methods of `VideoSource`, mixed into it by tracking.js. Landmarks and boxes are in the
// work canvas's pixels, the frame the tracker is given: it chooses its fit scale itself.

import { notify, fileError, message } from './toasts.js';
import { CLIP_JSON, loadClipInfo, looksLikeImage, looksLikeVideo, openCamera } from './media.js';
import { findFaces } from './finder-client.js';

/**
 * Points in the video's pixels in the work canvas's, drawn `k` times the video's size (pixel
 * centres on integers, the canvas covering the same picture: the core's convention).
 */
export function videoToWork(pts, k) {
  const out = new Float32Array(pts.length);
  for (let i = 0; i < pts.length; i++) out[i] = (pts[i] + 0.5) * k - 0.5;
  return out;
}

/** Points in the work canvas's pixels back in the video's (`videoToWork`'s inverse). */
export function workToVideo(pts, k) {
  const out = new Array(pts.length);
  for (let i = 0; i < pts.length; i++) out[i] = (pts[i] + 0.5) / k - 0.5;
  return out;
}

/** The opening and starting methods (`this` is the `VideoSource`). */
export const openMethods = {
  /** After an error: open the clip or the camera again. */
  retry() {
    if (!this.running) return;
    this.cancelFrames();
    if (this.mode === 'clip') this.openClip();
    else if (this.mode === 'webcam') {
      this.media.stopStream();
      this.openWebcam();
    }
  },

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
  },

  /** The clip from frame 0: the tracker starts from the clip's first-frame landmarks. */
  async startClipSequence() {
    this.cancelFrames();
    await this.media.seek(0);
    if (!this.running) return;
    this.grab();
    this.tracker.startFromLandmarks(videoToWork(this.clip.initLandmarks, this.k));
    this.beginSequence();
    this.setPhase('tracking', `Tracking spk07's unseen clip (${this.clip.frames ?? '?'} frames at ${this.fps} fps) from its first frame's landmarks.`);
    this.fitCurrent(0);
    await this.play();
  },

  async onClipEnded() {
    if (!this.running || this.mode !== 'clip') return;
    this.loops++;
    try {
      await this.startClipSequence();
    } catch (e) {
      if (this.running) this.fail('The clip could not loop', e);
    }
  },

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
  },

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
      this.logFind({ ms: r.ms, faces: faces.length, placing: true });
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
  },

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
  },

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
  },

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
      this.beginSequence(true);
    }
    this.feedFinder();
    if (this.tracker.wantsFaces) return; // nothing to try yet: no fit on this frame
    this.fitCurrent(mediaTime);
    if (this.last && !this.last.lost) {
      this.searchingGuide = false;
      this.setPhase('tracking', 'Tracking your face.');
    }
  },

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
        this.logFind({ ms, faces: faces.length, wall: performance.now() - t0 });
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
  },

  /** Start tracking from the selected face found, the placement box, or given landmarks (work px). */
  async startTracking(landmarks = null) {
    if (!this.haveFrame || !this.box) return;
    const face = landmarks ?? this.placement.face?.landmarks ?? null;
    try {
      if (face) this.tracker.startFromLandmarks(face);
      else {
        const b = this.box;
        this.tracker.startFromBox(b.x, b.y, b.w, b.h);
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
  },

  /** A video with no face found on its first frame: play it, the tracker looking for a face. */
  async startSearch() {
    this.seqId++;
    this.tracker.startSearching();
    this.beginSequence(true);
    this.seqStart = null;
    this.setPhase('tracking', `Looking for a face in ${this.fileName}…`);
    this.fitCurrent(this.video.currentTime);
    await this.play();
  },

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
        this.tracker.startFromLandmarks(start.landmarks);
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
  },

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
  },

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
  },
};

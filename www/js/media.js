// Media for the page's live sources: opening the camera (with errors explained), loading a video
// file, an image or the bundled clip, seeking and playing, the per-frame callback, and reading
// the current frame as RGBA at a given scale. Nothing here knows about faces or tracking; the
// enrolment (www/js/enrol.js) and the tracking panel (www/js/tracking.js) both use it.

import { message } from './toasts.js';
import { setCanvasSize } from './canvas.js';

/** Image types a dropped file may be (beside videos). */
const IMAGE_RE = /\.(jpe?g|png|webp|gif|bmp|avif)$/i;
const VIDEO_RE = /\.(webm|mp4|m4v|mov|ogv|ogg|mkv)$/i;

export function looksLikeVideo(file) {
  return (file.type || '').startsWith('video/') || VIDEO_RE.test(file.name || '');
}

export function looksLikeImage(file) {
  return (file.type || '').startsWith('image/') || IMAGE_RE.test(file.name || '');
}

/** Why a <video> failed, in words. */
export function mediaErrorText(err) {
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

/**
 * Whether the browser can show a picture of a video file, found in a <video> of its own (the
 * page's sources are not touched): resolves once a frame is decoded; rejects with an Error
 * whose `unplayable` is true when the browser cannot read the format (its container or codec),
 * with the browser's own words in `detail`, or whose message says the file has no picture.
 */
export function probeVideo(file, ms = 15000) {
  const url = URL.createObjectURL(file);
  const v = document.createElement('video');
  v.muted = true;
  v.preload = 'auto';
  return new Promise((resolve, reject) => {
    const done = (err) => {
      clearTimeout(timer);
      v.onloadeddata = v.onerror = null;
      v.removeAttribute('src');
      v.load();
      URL.revokeObjectURL(url);
      if (err) reject(err);
      else resolve();
    };
    const unplayable = (detail) => Object.assign(new Error('the browser cannot play this format'), { unplayable: true, detail });
    v.onloadeddata = () => done(v.videoWidth && v.videoHeight ? null : new Error('the file has no video track (sound only?)'));
    // MEDIA_ERR_DECODE (3) and MEDIA_ERR_SRC_NOT_SUPPORTED (4): a container or codec it cannot read.
    v.onerror = () => done(v.error && v.error.code < 3 ? new Error(mediaErrorText(v.error)) : unplayable(v.error?.message || ''));
    const timer = setTimeout(() => done(unplayable('no frame was decoded')), ms);
    v.src = url;
  });
}

/** What a getUserMedia failure means for the user, and what to do. */
export function cameraErrorText(e) {
  const name = e?.name || '';
  if (name === 'NotAllowedError' || name === 'SecurityError') {
    return 'Camera permission was denied. Allow the camera for this page (the icon in the address bar), then press Try again.';
  }
  if (name === 'NotFoundError' || name === 'OverconstrainedError' || name === 'DevicesNotFoundError') {
    return 'No camera was found. Connect one, or use the bundled clip or a video file.';
  }
  if (name === 'NotReadableError' || name === 'TrackStartError') {
    return 'The camera is busy (another application may be using it).';
  }
  return `The camera could not be opened: ${message(e)}`;
}

/**
 * Open the user-facing camera. Resolves to a MediaStream; rejects with an Error whose message
 * says what happened and what to do (no camera API, an insecure page, refused, missing, busy).
 */
export async function openCamera({ width = 640, height = 480 } = {}) {
  const md = navigator.mediaDevices;
  if (!md || typeof md.getUserMedia !== 'function') {
    throw new Error(
      window.isSecureContext
        ? 'This browser has no camera access (navigator.mediaDevices is missing)'
        : 'The camera needs a secure page: open the demo from http://127.0.0.1 or https',
    );
  }
  try {
    return await md.getUserMedia({ video: { width: { ideal: width }, height: { ideal: height }, facingMode: 'user' }, audio: false });
  } catch (e) {
    const err = new Error(cameraErrorText(e));
    err.cause = e;
    throw err;
  }
}

const CLIP_JSON = 'media/spk07-clip.json';
let clipInfo = null;

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

/** The bundled clip's description `{ video, url, fps, frames, initLandmarks }` (fetched once). */
export function loadClipInfo() {
  if (!clipInfo) {
    clipInfo = (async () => {
      const r = await fetch(CLIP_JSON);
      if (!r.ok) throw new Error(`HTTP ${r.status} for ${CLIP_JSON}`);
      const j = await r.json();
      if (!j || typeof j.video !== 'string' || !Array.isArray(j.initLandmarks) || !j.initLandmarks.every(Number.isFinite)) {
        throw new Error(`${CLIP_JSON}: expected { video, fps, initLandmarks: number[] }`);
      }
      return { ...j, url: new URL(j.video, new URL(CLIP_JSON, document.baseURI)).href };
    })();
    clipInfo.catch(() => {
      clipInfo = null;
    });
  }
  return clipInfo;
}
export { CLIP_JSON };

/**
 * One picture source for a panel: a <video> element (a file, the clip or a camera stream) or a
 * still image, and the "work" canvas holding the current frame at most `workSide` px on its
 * longer side (the core's policy: the package's `policy().workSide`). `k` is work pixels per
 * source pixel.
 */
export class MediaFeed {
  constructor(workSide) {
    if (!(workSide > 0)) throw new Error(`MediaFeed: a work side in pixels is needed, got ${workSide}`);
    this.workSide = workSide;
    this.video = document.createElement('video');
    this.video.muted = true;
    this.video.defaultMuted = true;
    this.video.playsInline = true;
    this.video.preload = 'auto';
    this.video.setAttribute('playsinline', '');
    this.video.setAttribute('aria-hidden', 'true');
    this.still = null; // an ImageBitmap when the source is an image
    this.stream = null;
    this.work = document.createElement('canvas');
    this.workCtx = this.work.getContext('2d', { willReadFrequently: true });
    this.k = 1;
    this.haveFrame = false;
    this.frameHandle = null;
    this.lastMediaTime = -1;
  }

  /** Source size in pixels (0 before anything is loaded). */
  get width() {
    return this.still ? this.still.width : this.video.videoWidth;
  }
  get height() {
    return this.still ? this.still.height : this.video.videoHeight;
  }

  /** Stop everything: the camera's tracks, the video, the frame callback. */
  close() {
    this.cancelFrames();
    this.video.pause();
    this.video.removeAttribute('src');
    this.video.srcObject = null;
    this.video.load();
    this.stopStream();
    this.still?.close?.();
    this.still = null;
    this.haveFrame = false;
  }

  stopStream() {
    if (this.stream) for (const t of this.stream.getTracks()) t.stop();
    this.stream = null;
  }

  /** Load a video URL; rejects with a reason when no frame can be decoded. */
  async loadVideo(src, name) {
    this.still?.close?.();
    this.still = null;
    const v = this.video;
    v.srcObject = null;
    v.src = src;
    v.load();
    await this.waitFor(v, 'loadeddata', `${name}: no video frame could be decoded`);
    if (!v.videoWidth || !v.videoHeight) throw new Error('the file has no video track');
  }

  /** Load an image file as a still frame; rejects with a reason when it cannot be decoded. */
  async loadImage(file) {
    let bmp;
    try {
      bmp = await createImageBitmap(file);
    } catch (e) {
      throw new Error(`the image could not be decoded (${message(e)})`);
    }
    if (!bmp.width || !bmp.height) throw new Error('the image is empty');
    this.cancelFrames();
    this.video.pause();
    this.video.removeAttribute('src');
    this.video.srcObject = null;
    this.still?.close?.();
    this.still = bmp;
  }

  /** Show a camera stream in the video element; resolves once it plays. */
  async useStream(stream) {
    this.still = null;
    this.stream = stream;
    this.video.srcObject = stream;
    await this.waitFor(this.video, 'loadeddata', 'the camera sent no picture');
    await this.video.play();
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

  /**
   * Call `onFrame(mediaTime)` for every new video frame (requestVideoFrameCallback, else an
   * animation frame whose currentTime changed) while the video plays.
   */
  requestFrames(onFrame) {
    if (this.frameHandle || this.still) return;
    const v = this.video;
    if (typeof v.requestVideoFrameCallback === 'function') {
      const cb = (now, meta) => {
        this.frameHandle = null;
        if (onFrame(meta.mediaTime) !== false && !v.paused && !v.ended) this.requestFrames(onFrame);
      };
      this.frameHandle = { rvfc: v.requestVideoFrameCallback(cb) };
    } else {
      const cb = () => {
        this.frameHandle = null;
        let go = true;
        if (v.currentTime !== this.lastMediaTime) go = onFrame(v.currentTime) !== false;
        if (go && !v.paused && !v.ended) this.requestFrames(onFrame);
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

  /** Draw the current frame into the work canvas; returns `k` (work px per source px). */
  grab() {
    const src = this.still || this.video;
    const vw = this.width;
    const vh = this.height;
    if (!vw || !vh) return this.k;
    const k = Math.min(1, this.workSide / Math.max(vw, vh));
    const w = Math.max(1, Math.round(vw * k));
    const h = Math.max(1, Math.round(vh * k));
    setCanvasSize(this.work, w, h);
    this.k = k;
    this.workCtx.drawImage(src, 0, 0, w, h);
    this.haveFrame = true;
    return k;
  }

  /** The current work frame's RGBA (`ImageData`). */
  workImage() {
    return this.workCtx.getImageData(0, 0, this.work.width, this.work.height);
  }
}

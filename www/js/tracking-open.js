// Opening a video source's media (www/js/tracking.js): the bundled clip, a dropped or picked file
// (a video or a photo) or the webcam, loaded into the source's `MediaFeed` (www/js/media.js),
// with what went wrong in words. A `MediaOpener` is owned by its source and knows nothing of
// faces or tracking: once a frame is there, the source starts its sequences (placement,
// acquisition, tracking).

import { notify, message } from './toasts.js';
import { loadClipInfo, looksLikeImage, looksLikeVideo, openCamera } from './media.js';

/** Why a file is not one a video source opens, or null when it is (a video or an image). */
export function notMediaReason(file) {
  if (looksLikeImage(file) || looksLikeVideo(file)) return null;
  return `not a video or an image (${file.type || 'unknown type'}); drop a WebM, MP4 or other video the browser plays, or a JPEG / PNG photo`;
}

/** Loads a video source's media into its feed. */
export class MediaOpener {
  /**
   * `media`: the source's `MediaFeed`. Hooks: `live()` whether the source still wants the media
   * (it was not stopped meanwhile); `onEnded()` a video (the clip or a file) played to its end;
   * `onCameraEnded()` the camera stopped sending pictures.
   */
  constructor(media, { live, onEnded, onCameraEnded }) {
    this.media = media;
    this.live = live;
    this.onEnded = onEnded;
    this.onCameraEnded = onCameraEnded;
    this.objectUrl = null;
    this.endedHooked = false;
    /** The name of what is open (or being opened): the clip's video, the file, the camera. */
    this.name = '';
  }

  /** Lets go of the file's object URL (when stopping, or before another file). */
  close() {
    if (this.objectUrl) URL.revokeObjectURL(this.objectUrl);
    this.objectUrl = null;
  }

  /** A video (the clip or a file) plays once, then `onEnded`. */
  hookEnded() {
    const video = this.media.video;
    video.loop = false;
    if (this.endedHooked) return;
    this.endedHooked = true;
    video.addEventListener('ended', () => this.onEnded());
  }

  /**
   * The bundled clip, loaded: resolves to its description (`{ video, url, fps, frames,
   * initLandmarks }`; `fps` 25 when it gives none), or null when the source stopped meanwhile.
   * Rejects when it cannot be played, or when its start landmarks are not `points` values (the
   * source model's).
   */
  async clip(points) {
    const info = await loadClipInfo();
    if (!this.live()) return null;
    this.name = info.video;
    await this.media.loadVideo(info.url, info.video);
    if (!this.live()) return null;
    if (info.initLandmarks.length !== points) {
      throw new Error(`the clip has ${info.initLandmarks.length / 2} start landmarks, the source model ${points / 2}`);
    }
    this.hookEnded();
    return { ...info, fps: info.fps || 25 };
  }

  /**
   * A dropped or picked file (check it with `notMediaReason` first), loaded and at its first
   * frame: resolves to `{ fps }` (0 for a photo), or null when the source stopped meanwhile;
   * rejects with the reason it cannot be shown.
   */
  async file(file) {
    this.close();
    this.name = file.name || 'the file';
    if (looksLikeImage(file)) {
      await this.media.loadImage(file);
      return { fps: 0 };
    }
    this.objectUrl = URL.createObjectURL(file);
    await this.media.loadVideo(this.objectUrl, this.name);
    if (!this.live()) return null;
    this.hookEnded();
    await this.media.seek(0);
    return { fps: 30 };
  }

  /**
   * The user's camera (`given`: a stream already open, passed on by the source this one
   * replaced), showing in the feed: resolves to its frame rate, or null when the source
   * stopped meanwhile. Rejects with an Error whose message says what happened (a refusal or a
   * missing camera is also notified).
   */
  async camera(given = null) {
    let stream = given;
    try {
      stream ??= await openCamera();
    } catch (e) {
      if (this.live() && e.cause) notify('error', 'Webcam unavailable', e.message);
      throw e;
    }
    if (!this.live()) {
      for (const t of stream.getTracks()) t.stop();
      return null;
    }
    const track = stream.getVideoTracks()[0];
    this.name = track?.label || 'camera';
    track?.addEventListener('ended', () => {
      if (this.live() && this.media.stream === stream) this.onCameraEnded();
    });
    try {
      await this.media.useStream(stream);
    } catch (e) {
      throw new Error(`The camera picture could not be shown: ${message(e)}`);
    }
    return track?.getSettings?.().frameRate || 30;
  }
}

// "Create a face": enrolment of a person's model in the page, from photos, a video file or the
// webcam. Frames are read as RGBA; each frame's 68 landmarks come from a `.pts` file dropped with
// a photo, else from the package's face finder in the page's finder worker (finder-client.js
// `enrolFace`) so the page keeps drawing; frames without a face, or rejected by the quality
// checks, are counted by reason. A checklist shows the expressions the kept frames cover
// (`expressionCoverage`), the live guide asks for the missing ones, and a live picture that stops
// changing is a frozen camera, said in the guide. About 20 varied frames are chosen
// (`selectVaried`; their coverage shown while sampling), the model is built in a Web Worker
// (build-client.js) with a progress bar and a Cancel button, kept in this browser (store.js) and
// shown in the page's inspector and in the dialog's preview (enrol-dialog.js: the mean face and
// one mode animated, drawn only while the dialog is open); then "Use as source", "Add as
// target" and "Download .fmm". Nothing is stored until the build has finished.

import { parsePts as parsePtsFile, policy } from '../pkg/facemimic.js';
import { buildInWorker } from './build-client.js';
import { enrolFace } from './finder-client.js';
import { enrolDialog, enrolPreview, faceThumbs, drawChecklist, EXPRESSIONS } from './enrol-dialog.js';
import { openCamera, looksLikeImage, looksLikeVideo } from './media.js';

// How frames are sampled (frames built from, fewest usable, kept in memory, frame side, ms
// between live samples, frames searched in a video): the core's policy, read once the package
// is initialised.
let sampling = null;
const enrolPolicy = () => (sampling ??= policy().enrol);
const MIN_SCORE = 0; // finder score to keep a face: any face it accepts (see buildModel's minScore)
const GUIDE = 'Talk, smile, open your mouth wide, raise your eyebrows, look a little left and right.';
const REASONS = { occluded: 'something covers the face', blurred: 'blurred', dark: 'too dark', turned: 'turned too far', outside: 'the face is partly out of the picture', frozen: 'the camera seems frozen' };
// A live picture unchanged this long (ms) is a frozen camera (the core's samePicture decides "unchanged").
const FROZEN_MS = 2000;

/** Reads a .pts (iBUG, 1-based) into 0-based points (also used by photo-target.js). */
export function parsePts(text) {
  // The package's parser (the CLI's): 0-based coordinates; the page needs the 68-point scheme.
  const v = parsePtsFile(text);
  if (v.length !== 136) throw new Error(`${v.length / 2} points, 68 are needed`);
  return v;
}

/** Draws a bitmap or video frame scaled to at most the policy's maxSide; returns { rgba, width, height, scale }. */
function grab(source, w, h) {
  const scale = Math.min(1, enrolPolicy().maxSide / Math.max(w, h));
  const width = Math.max(1, Math.round(w * scale));
  const height = Math.max(1, Math.round(h * scale));
  const c = new OffscreenCanvas(width, height);
  const g = c.getContext('2d', { willReadFrequently: true });
  g.drawImage(source, 0, 0, width, height);
  const d = g.getImageData(0, 0, width, height);
  return { rgba: new Uint8Array(d.data.buffer), width, height, scale };
}

export class Enrolment {
  /** `page`: { fm, notify, shelf, useAsSource(bytes, name), addAsTarget(bytes, name), inspect(model, info),
   *  hidpi (canvas.js HiDpi: sizes the preview's canvases, says whether they are on screen),
   *  faceOptions (RenderOptions of the preview) }. */
  constructor(page) {
    this.page = page;
    this.candidates = []; // { rgba, width, height, landmarks }
    this.seen = 0;
    this.usable = 0; // usable faces seen: never lowered when the pool is pruned
    this.stream = null;
    this.timer = null;
    this.abort = null;
    this.result = null;
    const { dialog, els } = enrolDialog({
      webcam: () => this.startWebcam(),
      addFiles: (files) => this.addFiles(files),
      build: () => this.build(),
      cancel: () => this.cancel(),
      // Closing ends the capture; a search under way finishes in the worker and is dropped
      // (sampleFrom checks the session).
      closed: () => this.stopCapture(),
      result: () => this.result,
      useAsSource: (r) => this.page.useAsSource(r.bytes, r.name),
      addAsTarget: (r) => this.page.addAsTarget(r.bytes, r.name),
    });
    this.dialog = dialog;
    this.els = els;
    this.preview = enrolPreview(els.preview, page); // an Inspector
    this.update();
    window.facemimicEnrol = this; // for the console and the end-to-end tests
  }

  /** Called by the page's frame loop (t in seconds): draws the preview while it can be seen. */
  tick(t) {
    if (!this.dialog.open || this.els.preview.hidden || !this.preview.model) return;
    const hidpi = this.page.hidpi;
    if (hidpi && !hidpi.visible(this.preview.els.mode) && !hidpi.visible(this.preview.els.mean)) return;
    this.preview.tick(t);
  }

  /** Forgets the last build's result: its buttons and preview are hidden, and the preview
   *  draws nothing. */
  hideResult() {
    this.result = null;
    this.els.done.hidden = true;
    this.els.preview.hidden = true;
    this.preview.clear();
  }

  /** Shows a built model in the dialog's preview; a dialog that scrolls (a phone) is scrolled
   *  to the status line, so the preview and the buttons under it come into view. */
  showPreview(model, info, name) {
    this.els.preview.hidden = false;
    this.preview.show(model, info, name);
    if (this.dialog.scrollHeight > this.dialog.clientHeight) {
      this.dialog.scrollTop += this.els.status.getBoundingClientRect().top - this.dialog.getBoundingClientRect().top - 12;
    }
  }

  open() {
    this.reset();
    this.dialog.showModal();
  }

  reset() {
    this.stopCapture();
    this.candidates = [];
    this.seen = 0;
    this.usable = 0;
    this.rejected = {}; // frames not used, by reason
    this.lastReason = '';
    this.counts = {}; // expressionCoverage's counts, never lowered in a session
    this.enough = false;
    this.frozen = false;
    this.lastPicture = null;
    drawChecklist(this.els.checklist, this.counts);
    this.hideResult();
    this.els.progress.hidden = true;
    this.els.guide.textContent = '';
    this.update('Choose the webcam, or drop photos or a video.');
  }

  /** Landmarks of the most confident face in a frame (found in the page's finder worker), or
   *  null; a face the core's quality checks reject (occluded, blurred, dark, turned, outside)
   *  is null too, counted and its reason shown in the guide. A frame kept stays kept. */
  async findFace(frame) {
    const face = await enrolFace(frame, MIN_SCORE); // its Float32Array transferred: our own copy
    const why = face ? face.reason && (REASONS[face.reason] || face.reason) : 'no face found';
    if (!why) return face.landmarks;
    this.rejected[why] = (this.rejected[why] || 0) + 1;
    this.lastReason = `frame not used: ${why}`;
    return null;
  }

  /** Adds a frame with its landmarks, pruning to the most varied when there are too many. */
  addCandidate(frame) {
    frame.id = this.nextId = (this.nextId || 0) + 1;
    this.usable++;
    this.candidates.push(frame);
    if (this.candidates.length > enrolPolicy().maxCandidates) {
      const keep = this.page.fm.selectVaried(this.candidates.map((c) => c.landmarks), Math.round(enrolPolicy().maxCandidates * 0.75));
      this.candidates = [...keep].sort((a, b) => a - b).map((i) => this.candidates[i]);
    }
  }

  /** Updates the status line, the coverage meter and the Build button. */
  update(text) {
    const n = this.candidates.length;
    let cover = 0;
    let pick = [];
    if (n >= 2) {
      const shapes = this.candidates.map((c) => c.landmarks);
      pick = this.page.fm.selectVaried(shapes, Math.min(enrolPolicy().want, n));
      cover = this.page.fm.shapeCoverage(shapes, pick);
    }
    this.drawStrip([...pick].sort((a, b) => a - b));
    this.updateExpressions();
    this.els.coverage.value = cover;
    this.els.coverage.title = `${Math.round(cover * 100)}% of the variety seen is covered by the ${Math.min(enrolPolicy().want, n)} frames that would be used`;
    // The count is of usable faces seen, which never goes down; the pool they are chosen from
    // keeps the most varied (enrolPolicy().maxCandidates), and says so once it is pruned.
    const u = this.usable;
    const pool = n < u ? ` (the ${n} most varied kept)` : '';
    if (text !== undefined || !this.abort) this.els.status.textContent = text ?? `${u} usable face${u === 1 ? '' : 's'} out of ${this.seen} frame${this.seen === 1 ? '' : 's'}${pool}${n < enrolPolicy().minFrames ? ` (at least ${enrolPolicy().minFrames} are needed)` : ''}.${this.notUsed()}`;
    this.els.build.disabled = n < enrolPolicy().minFrames || this.abort !== null || this.intake > 0;
    this.els.cancel.textContent = this.abort ? 'Cancel' : 'Close';
  }

  /** " Not used: 8 something covers the face, 2 no face found." (or empty). */
  notUsed() {
    const parts = Object.entries(this.rejected || {}).map(([why, n]) => `${n} ${why}`);
    return parts.length ? ` Not used: ${parts.join(', ')}.` : '';
  }

  /** The checklist of expressions from the kept frames (the core's expressionCoverage); a
   *  count never goes down, so an expression ticked stays ticked. */
  updateExpressions() {
    if (this.candidates.length < 5 || !this.page.fm.expressionCoverage) return;
    const c = this.page.fm.expressionCoverage(this.candidates.map((f) => f.landmarks));
    for (const [, key] of EXPRESSIONS) this.counts[key] = Math.max(this.counts[key] || 0, c[key]);
    this.enough = EXPRESSIONS.every(([, key]) => this.counts[key] > 0);
    drawChecklist(this.els.checklist, this.counts);
    this.els.checklist.dataset.enough = this.enough ? '1' : '0';
  }

  /** What the guide asks for now: the next expression missing, or "enough". */
  ask(k = 0) {
    if (this.frozen) return 'The camera seems frozen: the picture has not changed for a few seconds. Check the camera (another app may be using it), or press Webcam again.';
    if (this.enough) return 'Enough: every expression is covered. Press Build (or keep going for more variety).';
    const missing = EXPRESSIONS.filter(([, key]) => !(this.counts[key] > 0));
    return `${GUIDE} Now: ${missing[k % missing.length][3]}.`;
  }

  /** Thumbnails of the frames a build would use, with their landmarks (redrawn when they change). */
  drawStrip(pick) {
    const key = pick.map((i) => this.candidates[i].id).join(',');
    if (key === this.stripKey) return;
    this.stripKey = key;
    this.els.strip.replaceChildren(...faceThumbs(this.candidates, pick));
  }

  /** Photos (with or without .pts files) and videos: faces found in the worker, one at a time;
   *  Build waits until every file has been looked at. */
  async addFiles(files) {
    this.intake = (this.intake || 0) + 1;
    try {
      await this.readFiles(files);
    } finally {
      this.intake--;
      this.update();
    }
  }

  async readFiles(files) {
    const pts = new Map();
    for (const f of files) if (/\.pts$/i.test(f.name)) pts.set(f.name.replace(/\.pts$/i, ''), f);
    const images = files.filter(looksLikeImage);
    const videos = files.filter((f) => !looksLikeImage(f) && looksLikeVideo(f));
    const problems = [];
    for (const f of images) {
      this.seen++;
      try {
        const bmp = await createImageBitmap(f);
        const frame = grab(bmp, bmp.width, bmp.height);
        bmp.close();
        const p = pts.get(f.name.replace(/\.[^.]+$/, ''));
        if (p) {
          frame.landmarks = parsePts(await p.text()).map((v) => v * frame.scale);
        } else {
          this.update(`Looking for the face in ${f.name}…`);
          frame.landmarks = await this.findFace(frame);
          if (!frame.landmarks) {
            problems.push(`${f.name}: ${this.lastReason || 'no face found'}`);
            this.lastReason = '';
            continue;
          }
        }
        this.addCandidate(frame);
      } catch (e) {
        problems.push(`${f.name}: ${e.message || e}`);
      }
      this.update();
    }
    for (const v of videos) await this.sampleVideoFile(v);
    if (problems.length) this.page.notify('error', `${problems.length} file(s) not used`, problems.slice(0, 4).join('; '));
    if (!images.length && !videos.length) this.page.notify('error', 'Nothing to use', 'drop photos (with or without .pts files) or a video');
    this.update();
  }

  /** Searches the policy's videoSamples evenly spaced frames of a video file (seeking, so the whole video
   *  is covered whatever the finder's speed). */
  async sampleVideoFile(file) {
    const url = URL.createObjectURL(file);
    const v = this.els.video;
    v.hidden = false;
    v.srcObject = null;
    v.src = url;
    const session = (this.session = (this.session || 0) + 1);
    try {
      await new Promise((resolve, reject) => {
        v.onloadeddata = resolve;
        v.onerror = () => reject(new Error(v.error?.message || 'the browser cannot decode it'));
      });
      if (!Number.isFinite(v.duration)) {
        // Recorded WebM often declares no duration: seeking past the end makes the browser find it.
        v.currentTime = 1e101;
        await new Promise((resolve) => { v.onseeked = resolve; });
      }
      const duration = Number.isFinite(v.duration) ? v.duration : 0;
      if (!(duration > 0)) throw new Error('the video has no length');
      const n = Math.max(1, Math.min(enrolPolicy().videoSamples, Math.round(duration * 10)));
      for (let k = 0; k < n && this.dialog.open && this.session === session; k++) {
        v.currentTime = ((k + 0.5) / n) * duration;
        await new Promise((resolve) => { v.onseeked = resolve; });
        this.update(`Looking for faces in ${file.name}: frame ${k + 1} of ${n}…`);
        await this.sampleFrom(v);
      }
    } catch (e) {
      this.page.notify('error', `${file.name}: cannot be played`, e.message || String(e));
    } finally {
      v.onloadeddata = v.onerror = v.onseeked = null;
      v.removeAttribute('src');
      v.load();
      v.hidden = true;
      URL.revokeObjectURL(url);
    }
  }

  /** Grabs the video's current frame and keeps it if the finder places a face confidently. */
  async sampleFrom(video) {
    if (!video.videoWidth) return;
    const session = this.session;
    const frame = grab(video, video.videoWidth, video.videoHeight);
    if (this.stream && this.isFrozen(frame)) return void (this.seen++, this.update());
    try {
      frame.landmarks = await this.findFace(frame);
    } catch (e) {
      if (e.message !== 'cancelled' && this.session === session) this.update(`The face finder failed: ${e.message}`);
      return;
    }
    if (this.session !== session) return; // the capture ended meanwhile
    this.seen++;
    if (frame.landmarks) {
      this.lastReason = '';
      this.addCandidate(frame);
    }
    this.update();
  }

  /** Whether a live frame shows the same picture as the last one (not searched then); after
   *  FROZEN_MS of the same picture the camera is frozen and the guide says so. */
  isFrozen(frame) {
    const last = this.lastPicture;
    const now = performance.now();
    const same = last && last.width === frame.width && last.height === frame.height
      && this.page.fm.samePicture?.(last.rgba, frame.rgba, frame.width, frame.height);
    if (!same) {
      this.lastPicture = { rgba: frame.rgba, width: frame.width, height: frame.height, since: now };
      return (this.frozen = false);
    }
    if (now - last.since >= FROZEN_MS && !this.frozen) {
      this.frozen = true;
      this.els.guide.textContent = this.ask();
    }
    const why = this.frozen ? REASONS.frozen : 'the same picture as before';
    this.rejected[why] = (this.rejected[why] || 0) + 1;
    return true;
  }

  /** Live sampling: one frame at a time, the next as soon as the finder is free again. */
  sampleLive(video) {
    const session = this.session;
    const step = async () => {
      if (!this.stream || this.session !== session) return;
      await this.sampleFrom(video);
      if (this.stream && this.session === session) this.timer = setTimeout(step, enrolPolicy().sampleMs);
    };
    this.timer = setTimeout(step, enrolPolicy().sampleMs);
    let k = 0;
    const prompt = () => {
      this.els.guide.textContent = this.ask(k++);
    };
    prompt();
    this.promptTimer = setInterval(prompt, 2500);
  }

  async startWebcam() {
    this.stopCapture();
    try {
      this.stream = await openCamera();
    } catch (e) {
      // openCamera (media.js) says what happened and what to do; here "Try again" is "Webcam".
      this.update(e.message.replace('press Try again', 'press Webcam again'));
      return;
    }
    const v = this.els.video;
    v.removeAttribute('src');
    v.srcObject = this.stream;
    v.hidden = false;
    this.session = (this.session || 0) + 1;
    for (const track of this.stream.getVideoTracks()) {
      track.addEventListener('ended', () => {
        if (this.stream) {
          this.stopCapture();
          this.update(`The camera stopped. ${this.candidates.length} usable face(s) were kept${this.candidates.length >= enrolPolicy().minFrames ? '; you can build from them' : ''}.`);
        }
      });
    }
    await v.play().catch(() => {});
    this.update('Sampling the webcam…');
    this.sampleLive(v);
  }

  stopCapture() {
    clearTimeout(this.timer);
    clearInterval(this.promptTimer);
    this.timer = this.promptTimer = null;
    this.session = (this.session || 0) + 1;
    if (this.stream) for (const t of this.stream.getTracks()) t.stop();
    this.stream = null;
    this.els.video.srcObject = null;
    this.els.video.hidden = true;
    if (!this.frozen) this.els.guide.textContent = '';
  }

  async build() {
    const n = this.candidates.length;
    if (n < enrolPolicy().minFrames) {
      this.update(`Too few usable faces: ${n} (at least ${enrolPolicy().minFrames}).`);
      return;
    }
    this.stopCapture();
    const name = this.els.name.value.trim() || 'My face';
    const shapes = this.candidates.map((c) => c.landmarks);
    const pick = [...this.page.fm.selectVaried(shapes, Math.min(enrolPolicy().want, n))];
    // The model is built about the person's face at rest (buildModel's reference "rest": their
    // expressions are measured from it when they are tracked with it): the face most at rest
    // among all kept faces goes in, in place of the last varied one.
    const rest = this.page.fm.mostAtRest(shapes);
    if (!pick.includes(rest)) pick[pick.length - 1] = rest;
    pick.sort((a, b) => a - b);
    const frames = pick.map((i) => {
      const c = this.candidates[i];
      return { rgba: c.rgba.slice(), width: c.width, height: c.height, landmarks: c.landmarks };
    });
    // The preview and the buttons are for the result of this build: hidden until it is done.
    this.hideResult();
    this.abort = new AbortController();
    const p = this.els.progress;
    p.hidden = false;
    p.value = 0;
    this.update(`Building ${name} from ${frames.length} frames…`);
    const t0 = performance.now();
    const refine = this.els.refine.checked ? 1 : 0;
    try {
      const r = await buildInWorker({ frames, name, refine, reference: 'rest', quality: 'all', minFrames: Math.min(enrolPolicy().minFrames, frames.length) }, {
        signal: this.abort.signal,
        onProgress: (done, total, stage) => {
          p.value = done / total;
          this.els.status.textContent = `Building ${name} from ${frames.length} frames: ${stage === 'landmarks' ? 'landmarks' : 'model'} ${done} of ${total}…`;
        },
      });
      this.result = { bytes: r.bytes, name };
      // The worker parsed the model it built: its info stands for the file (not parsed again).
      await this.page.shelf.keep(r.bytes, name, 'built', { info: r.info });
      // Ask the browser not to evict the store under storage pressure (it may say no).
      navigator.storage?.persist?.().catch(() => {});
      const model = this.page.fm.Model.fromBytes(r.bytes);
      const info = model.info();
      this.page.inspect(model, info, name);
      this.els.done.hidden = false;
      this.showPreview(model, info, name);
      this.lastBuild = { frames: pick.map((i) => this.candidates[i].id), rejected: r.rejected };
      const left = r.rejected.length ? `; ${r.rejected.length} not used (${[...new Set(r.rejected.map((x) => REASONS[x.reason] || x.reason))].join(', ')})` : '';
      this.update(`Built ${name} from ${r.rejected.length ? `${frames.length - r.rejected.length} of ` : ''}${frames.length} frames${left} in ${((performance.now() - t0) / 1000).toFixed(1)} s: ${r.info.shapeModes} shape and ${r.info.appearanceModes} appearance modes. It is kept under Your models.`);
    } catch (e) {
      this.update(e.message === 'cancelled' ? 'Build cancelled; nothing was kept.' : `The build failed: ${e.message}`);
    } finally {
      this.abort = null;
      this.els.cancel.textContent = 'Close';
      p.hidden = true;
      this.els.build.disabled = this.candidates.length < enrolPolicy().minFrames;
    }
  }

  cancel() {
    if (this.abort) {
      this.abort.abort();
      return;
    }
    this.dialog.close();
  }
}

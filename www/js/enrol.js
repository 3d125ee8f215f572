// "Create a face": enrolment of a person's model in the page, from photos, a video file or the
// webcam. Frames are read as RGBA; each frame's 68 landmarks come from a `.pts` file dropped with
// a photo, else from the package's face finder, run in the page's finder worker (finder-client.js
// `enrolFace`, the worker the tracking sources use too) so the page keeps drawing while frames
// are sampled; frames whose face was not found confidently
// are skipped and counted. Out of the frames kept, about 20 varied ones
// are chosen (farthest-point sampling of the aligned shapes, `selectVaried`; the coverage of the
// expression space is shown while sampling), the model is built in a Web Worker
// (build-client.js) with a progress bar and a Cancel button, kept in this browser (store.js) and
// shown in the page's inspector and, in the dialog itself, in a preview (a second `Inspector`:
// the mean face and one mode animated, shape or appearance, picked from the bars; drawn by the
// page's frame loop only while the dialog is open); then "Use as source", "Add as target" and
// "Download .fmm".
// Nothing is stored until the build has finished: a cancelled or failed build leaves nothing.

import { parsePts as parsePtsFile } from '../pkg/facemimic.js';
import { buildInWorker } from './build-client.js';
import { Inspector } from './inspector.js';
import { enrolFace } from './finder-client.js';
import { download, safeName } from './store.js';
import { openCamera, looksLikeImage, looksLikeVideo } from './media.js';

const WANT = 20; // frames a model is built from
const MIN_FRAMES = 8; // fewer usable frames than this is an error
const MAX_CANDIDATES = 60; // sampled frames kept in memory (pruned to the most varied)
const MAX_SIDE = 640; // frames are scaled down to this longer side
const MIN_SCORE = 0; // finder score to keep a face: any face it accepts (see buildModel's minScore)
const SAMPLE_MS = 100; // live sampling: the next frame is taken this long after a search ends
const VIDEO_SAMPLES = 120; // frames searched in a dropped video (evenly spaced)
const GUIDE = 'Talk, smile, open your mouth wide, raise your eyebrows, look a little left and right.';
const PROMPTS = ['Talk', 'Smile', 'Open your mouth wide', 'Raise your eyebrows', 'Look a little left', 'Look a little right', 'Frown', 'Talk again'];

/** Reads a .pts (iBUG, 1-based) into 0-based points (also used by photo-target.js). */
export function parsePts(text) {
  // The package's parser (the CLI's): 0-based coordinates; the page needs the 68-point scheme.
  const v = parsePtsFile(text);
  if (v.length !== 136) throw new Error(`${v.length / 2} points, 68 are needed`);
  return v;
}

/** Draws a bitmap or video frame scaled to at most MAX_SIDE; returns { rgba, width, height, scale }. */
function grab(source, w, h) {
  const scale = Math.min(1, MAX_SIDE / Math.max(w, h));
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
    this.stream = null;
    this.timer = null;
    this.abort = null;
    this.result = null;
    this.dialog = this.buildDialog();
    this.preview = this.buildPreview();
    window.facemimicEnrol = this; // for the console and the end-to-end tests
  }

  el(tag, props = {}, ...children) {
    const e = document.createElement(tag);
    Object.assign(e, props);
    e.append(...children);
    return e;
  }

  buildDialog() {
    const d = this.el('dialog', { id: 'enrol', className: 'enrol' });
    d.setAttribute('aria-labelledby', 'enrol-title');
    const $ = (tag, props, ...c) => this.el(tag, props, ...c);
    this.els = {
      webcam: $('button', { type: 'button', className: 'btn', textContent: 'Webcam' }),
      photos: $('button', { type: 'button', className: 'btn', textContent: 'Photos or video…' }),
      file: $('input', { type: 'file', multiple: true, accept: 'image/*,video/*,.pts', hidden: true }),
      guide: $('p', { className: 'hint enrol-guide' }),
      video: $('video', { muted: true, playsInline: true, className: 'enrol-video', hidden: true }),
      status: $('p', { className: 'enrol-status', role: 'status' }),
      coverage: $('meter', { min: 0, max: 1, value: 0, className: 'enrol-coverage' }),
      name: $('input', { type: 'text', value: 'My face', maxLength: 80, className: 'enrol-name' }),
      refine: $('input', { type: 'checkbox', className: 'enrol-refine' }),
      build: $('button', { type: 'button', className: 'btn primary', textContent: 'Build', disabled: true }),
      cancel: $('button', { type: 'button', className: 'btn', textContent: 'Cancel' }),
      progress: $('progress', { max: 1, value: 0, hidden: true, className: 'enrol-progress' }),
      done: $('div', { className: 'enrol-done', hidden: true }),
      preview: $('section', { className: 'enrol-preview', hidden: true }),
      strip: $('div', { className: 'enrol-strip' }),
    };
    const e = this.els;
    e.strip.setAttribute('aria-label', 'The frames the model will be built from, with their landmarks');
    e.coverage.setAttribute('aria-label', 'Expression coverage');
    e.name.setAttribute('aria-label', 'Name of the new face');
    e.webcam.addEventListener('click', () => this.startWebcam());
    e.photos.addEventListener('click', () => {
      e.file.value = '';
      e.file.click();
    });
    e.file.addEventListener('change', () => this.addFiles([...e.file.files]));
    e.build.addEventListener('click', () => this.build());
    e.cancel.addEventListener('click', () => this.cancel());
    // Closing ends the capture; a search under way finishes in the worker and is dropped
    // (sampleFrom checks the session).
    d.addEventListener('close', () => this.stopCapture());
    d.addEventListener('dragover', (ev) => {
      ev.preventDefault();
      ev.stopPropagation();
    });
    d.addEventListener('drop', (ev) => {
      ev.preventDefault();
      ev.stopPropagation();
      if (ev.dataTransfer?.files?.length) this.addFiles([...ev.dataTransfer.files]);
    });
    const use = (label, fn) => {
      const b = $('button', { type: 'button', className: 'btn', textContent: label });
      b.addEventListener('click', () => this.result && fn(this.result));
      return b;
    };
    e.done.append(
      use('Use as source', (r) => { this.page.useAsSource(r.bytes, r.name); d.close(); }),
      use('Add as target', (r) => { this.page.addAsTarget(r.bytes, r.name); d.close(); }),
      use('Download .fmm', (r) => download(r.bytes, `${safeName(r.name)}.fmm`)),
    );
    d.append(
      $('h2', { id: 'enrol-title', textContent: 'Create a face' }),
      $('p', {
        className: 'hint',
        // Touch screens cannot drop files: say how to choose them there.
        textContent: matchMedia('(pointer: coarse)').matches
          ? 'Use the camera, a video, or about 20 photos of one person (choose them with "Photos or video…"; a .pts landmark file chosen with a photo is used). Everything stays on this device.'
          : 'Use the webcam, a video, or about 20 photos of one person (drop them here; a .pts landmark file beside a photo is used when given). Everything stays in this browser.',
      }),
      $('div', { className: 'row buttons' }, e.webcam, e.photos, e.file),
      e.guide,
      e.video,
      $('div', { className: 'row' }, $('span', { textContent: 'Coverage' }), e.coverage),
      e.strip,
      e.status,
      e.preview,
      e.done,
      $('div', { className: 'row' }, $('label', { textContent: 'Name' }), e.name),
      $('label', { className: 'row hint', title: 'Fits the new model to its own frames and rebuilds it from the fitted landmarks. Measured on a webcam clip, it tracks unseen frames worse, so it is off by default.' }, e.refine, ' Refine (slower; measured to track worse)'),
      e.progress,
      $('div', { className: 'row buttons' }, e.build, e.cancel),
    );
    document.body.append(d);
    this.update();
    return d;
  }

  /** The preview of a built model (the Inspector's look, paper Fig. 1): mean face, one mode
   *  animated as base + k sigma sin(t), shape or appearance, a mode picked from the bars. */
  buildPreview() {
    const $ = (tag, props, ...c) => this.el(tag, props, ...c);
    const host = this.els.preview;
    host.setAttribute('aria-labelledby', 'enrol-preview-title');
    const canvas = (label) => {
      const c = $('canvas', { className: 'face small' });
      c.setAttribute('role', 'img');
      c.setAttribute('aria-label', label);
      return c;
    };
    const els = {
      mean: canvas('Mean face of the new model'),
      mode: canvas('The chosen mode of the new model, animated'),
      caption: $('figcaption'),
      bars: $('div', { className: 'bars' }),
      kind: $('fieldset', { className: 'segmented small' }),
    };
    els.bars.setAttribute('role', 'radiogroup');
    els.bars.setAttribute('aria-label', 'Modes of the new model by share of variance');
    const radio = (value, label, checked) => $('label', {}, $('input', { type: 'radio', name: 'enrol-kind', value, checked }), $('span', { textContent: label }));
    els.kind.append($('legend', { className: 'visually-hidden', textContent: 'Mode kind' }), radio('shape', 'Shape', true), radio('appearance', 'Appearance', false));
    host.append(
      $('h3', { id: 'enrol-preview-title', textContent: 'Preview' }),
      $('div', { className: 'enrol-preview-body' },
        $('div', { className: 'inspect-views' },
          $('figure', {}, els.mean, $('figcaption', { textContent: 'Mean' })),
          $('figure', {}, els.mode, els.caption)),
        $('div', { className: 'enrol-preview-modes' },
          els.kind,
          els.bars,
          $('p', { className: 'hint bars-caption', textContent: 'Each mode\'s share of the variance; pick one to animate it.' }))),
    );
    for (const c of [els.mean, els.mode]) this.page.hidpi?.watch(c);
    return new Inspector(this.page.fm, els, this.page.faceOptions ?? {});
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
    this.hideResult();
    this.els.progress.hidden = true;
    this.els.guide.textContent = '';
    this.update('Choose the webcam, or drop photos or a video.');
  }

  /** Landmarks of the most confident face in a frame (found in the page's finder worker), or null. */
  async findFace(frame) {
    // The worker's Float32Array, transferred: this page's own copy.
    const face = await enrolFace(frame, MIN_SCORE);
    return face ? face.landmarks : null;
  }

  /** Adds a frame with its landmarks, pruning to the most varied when there are too many. */
  addCandidate(frame) {
    frame.id = this.nextId = (this.nextId || 0) + 1;
    this.candidates.push(frame);
    if (this.candidates.length > MAX_CANDIDATES) {
      const keep = this.page.fm.selectVaried(this.candidates.map((c) => c.landmarks), Math.round(MAX_CANDIDATES * 0.75));
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
      pick = this.page.fm.selectVaried(shapes, Math.min(WANT, n));
      cover = this.page.fm.shapeCoverage(shapes, pick);
    }
    this.drawStrip([...pick].sort((a, b) => a - b));
    this.els.coverage.value = cover;
    this.els.coverage.title = `${Math.round(cover * 100)}% of the variety seen is covered by the ${Math.min(WANT, n)} frames that would be used`;
    if (text !== undefined || !this.abort) this.els.status.textContent = text ?? `${n} usable face${n === 1 ? '' : 's'} out of ${this.seen} frame${this.seen === 1 ? '' : 's'}${n < MIN_FRAMES ? ` (at least ${MIN_FRAMES} are needed)` : ''}.`;
    this.els.build.disabled = n < MIN_FRAMES || this.abort !== null || this.intake > 0;
    this.els.cancel.textContent = this.abort ? 'Cancel' : 'Close';
  }

  /** Thumbnails of the frames a build would use, with their landmarks (redrawn when they change). */
  drawStrip(pick) {
    const key = pick.map((i) => this.candidates[i].id).join(',');
    if (key === this.stripKey) return;
    this.stripKey = key;
    const H = 56;
    const thumbs = pick.map((i) => {
      const c = this.candidates[i];
      // Crop around the face (landmark box + 30%), scaled to H pixels high.
      let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
      for (let k = 0; k < c.landmarks.length; k += 2) {
        x0 = Math.min(x0, c.landmarks[k]); x1 = Math.max(x1, c.landmarks[k]);
        y0 = Math.min(y0, c.landmarks[k + 1]); y1 = Math.max(y1, c.landmarks[k + 1]);
      }
      const side = Math.max(x1 - x0, y1 - y0) * 1.3;
      const [cx, cy] = [(x0 + x1) / 2, (y0 + y1) / 2];
      const k = H / side;
      const canvas = document.createElement('canvas');
      canvas.width = H;
      canvas.height = H;
      const g = canvas.getContext('2d');
      if (!c.thumb) {
        // The frame once as a canvas (drawn again only if the crop changes: never).
        const img = new ImageData(new Uint8ClampedArray(c.rgba.buffer, c.rgba.byteOffset, c.rgba.length), c.width, c.height);
        c.thumb = new OffscreenCanvas(c.width, c.height);
        c.thumb.getContext('2d').putImageData(img, 0, 0);
      }
      g.drawImage(c.thumb, cx - side / 2, cy - side / 2, side, side, 0, 0, H, H);
      g.fillStyle = '#7cc4ff';
      for (let j = 0; j < c.landmarks.length; j += 2) {
        g.fillRect((c.landmarks[j] - cx + side / 2) * k - 0.5, (c.landmarks[j + 1] - cy + side / 2) * k - 0.5, 1.2, 1.2);
      }
      return canvas;
    });
    this.els.strip.replaceChildren(...thumbs);
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
            problems.push(`${f.name}: no face found`);
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

  /** Searches VIDEO_SAMPLES evenly spaced frames of a video file (seeking, so the whole video
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
      const n = Math.max(1, Math.min(VIDEO_SAMPLES, Math.round(duration * 10)));
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
    try {
      frame.landmarks = await this.findFace(frame);
    } catch (e) {
      if (e.message !== 'cancelled' && this.session === session) this.update(`The face finder failed: ${e.message}`);
      return;
    }
    if (this.session !== session) return; // the capture ended meanwhile
    this.seen++;
    if (frame.landmarks) this.addCandidate(frame);
    this.update();
  }

  /** Live sampling: one frame at a time, the next as soon as the finder is free again. */
  sampleLive(video) {
    const session = this.session;
    const step = async () => {
      if (!this.stream || this.session !== session) return;
      await this.sampleFrom(video);
      if (this.stream && this.session === session) this.timer = setTimeout(step, SAMPLE_MS);
    };
    this.timer = setTimeout(step, SAMPLE_MS);
    let k = 0;
    const prompt = () => {
      this.els.guide.textContent = `${GUIDE} Now: ${PROMPTS[k++ % PROMPTS.length].toLowerCase()}.`;
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
          this.update(`The camera stopped. ${this.candidates.length} usable face(s) were kept${this.candidates.length >= MIN_FRAMES ? '; you can build from them' : ''}.`);
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
    if (this.els.guide.textContent.startsWith(GUIDE)) this.els.guide.textContent = '';
  }

  async build() {
    const n = this.candidates.length;
    if (n < MIN_FRAMES) {
      this.update(`Too few usable faces: ${n} (at least ${MIN_FRAMES}).`);
      return;
    }
    this.stopCapture();
    const name = this.els.name.value.trim() || 'My face';
    const pick = [...this.page.fm.selectVaried(this.candidates.map((c) => c.landmarks), Math.min(WANT, n))].sort((a, b) => a - b);
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
      const r = await buildInWorker({ frames, name, refine, minFrames: Math.min(MIN_FRAMES, frames.length) }, {
        signal: this.abort.signal,
        onProgress: (done, total, stage) => {
          p.value = done / total;
          this.els.status.textContent = `Building ${name} from ${frames.length} frames: ${stage === 'landmarks' ? 'landmarks' : 'model'} ${done} of ${total}…`;
        },
      });
      this.result = { bytes: r.bytes, name };
      await this.page.shelf.keep(r.bytes, name, 'built');
      // Ask the browser not to evict the store under storage pressure (it may say no).
      navigator.storage?.persist?.().catch(() => {});
      const model = this.page.fm.Model.fromBytes(r.bytes);
      const info = model.info();
      this.page.inspect(model, info, name);
      this.els.done.hidden = false;
      this.showPreview(model, info, name);
      this.update(`Built ${name} from ${frames.length} frames in ${((performance.now() - t0) / 1000).toFixed(1)} s: ${r.info.shapeModes} shape and ${r.info.appearanceModes} appearance modes. It is kept under Your models.`);
    } catch (e) {
      this.update(e.message === 'cancelled' ? 'Build cancelled; nothing was kept.' : `The build failed: ${e.message}`);
    } finally {
      this.abort = null;
      this.els.cancel.textContent = 'Close';
      p.hidden = true;
      this.els.build.disabled = this.candidates.length < MIN_FRAMES;
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

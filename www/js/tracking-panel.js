// The tracking panel of a video source (www/js/tracking.js): its DOM (the picture, the readout,
// the buttons), the phase it shows, the fit's display (the mesh over the picture, the figures),
// and the pointer and keyboard on the frame. A `TrackingPanel` is owned by its source: it reads
// the source's state and draws it, and acts only through the source's actions (`togglePlay`,
// `restart`, `startTracking`, `openFile`, `retry`, `setAutoStart`); it changes nothing the
// tracker keeps.

import { notify } from './toasts.js';
import { dropZone } from './drop.js';
import { MESH, MESH_LOST, GUIDE, drawFrame, drawLandmarks, drawBadge } from './face-draw.js';
import { pathNotice } from './follow-path.js';

// Load the panel's styles with the module (before any panel exists).
{
  const href = new URL('./tracking.css', import.meta.url).href;
  if (![...document.styleSheets].some((s) => s.href === href)) {
    const link = document.createElement('link');
    link.rel = 'stylesheet';
    link.href = href;
    document.head.append(link);
  }
}

// ---------------------------------------------------------------------------------------------
// Small DOM helpers

function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (k === 'class') e.className = v;
    else if (k === 'text') e.textContent = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (k in e && typeof v !== 'string') e[k] = v;
    else e.setAttribute(k, v);
  }
  e.append(...children);
  return e;
}

function button(label, onclick, extra = {}) {
  return el('button', { type: 'button', class: 'btn', onclick, ...extra }, label);
}

/** The readout of a fitted AAM: key -> [label, tooltip]. */
const FIT_STATS = {
  error: ['fit error', 'RMS grey-level residual of the last fit (0..1)'],
  iterations: ['iterations', 'Iterations of the last fit (converged or not)'],
  fps: ['fits / s', 'Frames fitted in the last second'],
  ms: ['ms / fit', 'Time per fit (smoothed), reading the frame excluded'],
  lost: ['lost · reinit', 'Frames reported lost · re-initialisations, this sequence'],
};

/** The readout of a face followed by its landmarks (the same keys). */
const FOLLOW_STATS = {
  ...FIT_STATS,
  error: ['face score', "The face mesh's confidence that the followed region is a face (0..1; – on a frame the finder's search gave)"],
  iterations: ['mesh passes', 'Face-mesh passes run near the last face this frame (1 while following, 2 from a box; the search not counted)'],
  fps: ['frames / s', 'Frames followed in the last second'],
  ms: ['ms / frame', 'Time per frame followed (smoothed), reading the frame excluded'],
};

/**
 * A video source's panel. `src` is the source (www/js/tracking.js); what the panel reads of it:
 * `mode`, `label`, `path`, `ctx` (`createFace`, `panelHost`), `running`, `phase`, `state`,
 * `autoStart`, `finding`, `findError`, `streamEnded`, `media` (`video`, `work`, `k`,
 * `haveFrame`, `still`), `placement`, `last`, `lastGood`, `tracker` (`wantsFaces`,
 * `lostCount`, `resets`), `sequenceStart` (the tracker's counts when the sequence began) and
 * `fitLog` (the timing).
 */
export class TrackingPanel {
  constructor(src) {
    this.src = src;
    this.hiddenPause = false;
    this.shownAt = 0;
    this.build();
  }

  build() {
    const src = this.src;
    const { mode, label } = src;
    const id = `trk-${mode}`;
    src.media.video.classList.add('trk-video');
    this.canvas = el('canvas', { class: 'trk-canvas', role: 'img', 'aria-label': `${label}: video with the fitted face mesh` });
    this.stateEl = el('span', { class: 'trk-state', 'data-state': 'idle', text: 'starting' });
    this.msgEl = el('p', { class: 'trk-msg', role: 'status', 'aria-live': 'polite' });
    // The readout, per path: key -> [label, tooltip]. Following landmarks
    // (www/js/follow-path.js) fits no AAM: its readout is the face mesh's.
    const labels = src.path === 'landmarks' ? FOLLOW_STATS : FIT_STATS;
    const dl = el('dl', { class: 'trk-stats' });
    this.readout = {};
    for (const [key, [text, title]] of Object.entries(labels)) {
      const dd = el('dd', { 'data-k': key, text: '–' });
      dl.append(el('div', { title }, el('dt', { text }), dd));
      this.readout[key] = dd;
    }

    this.playBtn = button('Pause', () => src.togglePlay(), { class: 'btn primary', 'aria-keyshortcuts': 'Space', title: 'Pause / play (space)' });
    this.restartBtn = button('Re-start', () => src.restart(), { title: 'Place the face again and start a new sequence' });
    this.startBtn = button('Start tracking', () => src.startTracking(), { class: 'btn primary' });
    this.chooseBtn = button('Choose a video or image…', () => this.fileInput.click());
    this.otherBtn = button('Other file…', () => this.fileInput.click(), { title: 'Track another video, or fit another image (or drop one on this panel)' });
    this.fileInput = el('input', { type: 'file', accept: 'video/*,image/*,.webm,.mp4,.mov,.m4v,.ogv,.mkv', hidden: true });
    this.fileInput.addEventListener('change', () => {
      const f = this.fileInput.files?.[0];
      this.fileInput.value = '';
      if (f) src.openFile(f);
    });
    this.meshCheck = el('input', { type: 'checkbox', checked: true });
    this.meshCheck.addEventListener('change', () => this.draw());
    const meshLabel = el('label', { class: 'check' }, this.meshCheck, el('span', { text: 'Mesh overlay' }));
    const extra = [];
    if (mode !== 'clip') {
      const autoCheck = el('input', { type: 'checkbox', checked: src.autoStart, onchange: () => src.setAutoStart(autoCheck.checked) });
      extra.push(el('label', { class: 'check', title: 'Start tracking by itself as soon as a face is found' }, autoCheck, el('span', { text: 'Auto-start' })));
    }

    this.dropHint = el(
      'div',
      { class: 'trk-drop' },
      el('p', {}, el('strong', { text: 'Drop a video or a photo here' }), el('span', { text: ' or ' })),
      this.chooseBtn,
      el('small', { text: 'Any format the browser plays (WebM, MP4, JPEG, PNG…). It stays on this computer.' }),
    );
    this.dropHint.hidden = true;
    // Shown instead of the picture while there is none: waiting for the camera, or an error.
    this.retryBtn = button('Try again', () => src.retry());
    this.placeholderText = el('p');
    this.placeholder = el('div', { class: 'trk-placeholder' }, this.placeholderText, this.retryBtn);
    this.placeholder.hidden = true;
    this.view = el('div', { class: 'trk-view' }, this.canvas, this.dropHint, this.placeholder, src.media.video);

    const title = el('h2', { id: `${id}-title` }, `Tracking · ${label}`);
    this.el = el(
      'section',
      { class: 'trk-panel', id, 'aria-labelledby': `${id}-title`, 'data-mode': mode, 'data-phase': 'loading' },
      el('header', { class: 'trk-head' }, title, this.stateEl),
      el(
        'div',
        { class: 'trk-body' },
        this.view,
        el(
          'div',
          { class: 'trk-side' },
          dl,
          el('div', { class: 'trk-buttons' }, this.startBtn, this.playBtn, this.restartBtn, this.otherBtn),
          el('div', { class: 'trk-options' }, meshLabel, ...extra),
          pathNotice(src.path ?? 'aam', src.ctx.createFace),
          this.msgEl,
          this.fileInput,
        ),
      ),
    );

    // Keyboard on the frame: move / scale the placement box, Enter starts.
    this.canvas.addEventListener('keydown', (e) => this.onKey(e));
    this.canvas.addEventListener('pointerdown', (e) => this.onPointerDown(e));
    this.canvas.addEventListener('pointermove', (e) => this.onPointerMove(e));
    this.canvas.addEventListener('pointerup', (e) => this.onPointerUp(e));
    this.canvas.addEventListener('pointercancel', (e) => this.onPointerUp(e));
    // Video and image files dropped on the panel (and not elsewhere: the page takes other drops as models).
    if (mode === 'file') {
      // Model files dropped here go on to the page (which adds them as targets).
      dropZone(
        this.el,
        (files) => {
          if (files.length > 1) notify('info', `Used ${files[0].name}`, 'one file at a time; the other files were ignored');
          src.openFile(files[0]);
        },
        { accept: (files) => !files.every((x) => /\.fmm$/i.test(x.name)), isolate: true },
      );
    }

    const anchor = document.querySelector('.stage .transport');
    if (src.ctx.panelHost) src.ctx.panelHost.append(this.el); // the call page's place for it
    else if (anchor) anchor.after(this.el);
    else (document.querySelector('main') || document.body).append(this.el);

    // A hidden tab presents no frames: pause a clip or file (the fit would have to jump).
    this.onVisibility = () => {
      if (mode === 'webcam' || !src.running) return;
      if (document.hidden && src.phase === 'tracking') {
        this.hiddenPause = true;
        src.togglePlay();
      } else if (!document.hidden && this.hiddenPause && src.phase === 'paused') {
        this.hiddenPause = false;
        src.togglePlay();
      }
    };
    document.addEventListener('visibilitychange', this.onVisibility);
    // Space pauses / plays this source (the page's Space would switch to the recorded track).
    this.onSpace = (e) => {
      if ((e.key !== ' ' && e.code !== 'Space') || e.altKey || e.ctrlKey || e.metaKey || e.defaultPrevented) return;
      if (src.phase !== 'tracking' && src.phase !== 'paused') return;
      const t = e.target;
      if (t instanceof HTMLElement) {
        const tag = t.tagName;
        if (['BUTTON', 'SELECT', 'TEXTAREA', 'SUMMARY', 'A'].includes(tag) || t.isContentEditable) return;
        if (tag === 'INPUT' && t.getAttribute('type') !== 'range') return;
      }
      e.preventDefault();
      src.togglePlay();
    };
    window.addEventListener('keydown', this.onSpace, true);
    this.resizeObserver = new ResizeObserver(() => this.draw());
    this.resizeObserver.observe(this.canvas);
  }

  /** Takes the panel off the page, with its listeners. */
  remove() {
    this.resizeObserver.disconnect();
    document.removeEventListener('visibilitychange', this.onVisibility);
    window.removeEventListener('keydown', this.onSpace, true);
    this.el.remove();
  }

  /** The picture's proportions follow the work canvas's (`w` x `h`). */
  fitAspect(w, h) {
    if (this.aspectKey === w + h * 1e5) return;
    this.aspectKey = w + h * 1e5;
    this.canvas.style.aspectRatio = `${w} / ${h}`;
    this.canvas.style.setProperty('--ar', String(w / h));
  }

  /** Keyboard focus on the picture (the placement step's keys). */
  focus() {
    this.canvas.focus({ preventScroll: true });
  }
  /** The message shown. */
  get message() {
    return this.msgEl.textContent;
  }

  /** Shows the source's `phase`, with `msg` (or the phase's own message). */
  show(phase, msg) {
    const src = this.src;
    const still = Boolean(src.media.still);
    const haveFrame = src.media.haveFrame;
    this.el.dataset.phase = phase;
    const m = src.mode;
    const tracking = phase === 'tracking' || phase === 'paused';
    this.startBtn.hidden = !(phase === 'placing');
    this.startBtn.textContent = m === 'webcam' ? 'Start' : still ? 'Fit the face' : 'Start tracking';
    this.playBtn.hidden = !tracking || still;
    this.restartBtn.hidden = !(tracking || (phase === 'error' && haveFrame && !src.streamEnded));
    this.playBtn.textContent = phase === 'paused' ? 'Play' : 'Pause';
    this.dropHint.hidden = !(m === 'file' && (phase === 'empty' || phase === 'error'));
    this.otherBtn.hidden = !(m === 'file' && ['placing', 'tracking', 'paused'].includes(phase));
    const blank = !haveFrame && (phase === 'loading' || phase === 'error') && !(m === 'file');
    this.canvas.hidden = (m === 'file' && phase === 'empty') || blank;
    this.placeholder.hidden = !blank;
    this.retryBtn.hidden = phase !== 'error';
    if (blank) this.placeholderText.textContent = phase === 'error' ? msg || 'Something went wrong.' : msg || 'Loading…';
    this.canvas.tabIndex = phase === 'placing' ? 0 : -1;
    if (phase === 'placing') {
      this.canvas.setAttribute(
        'aria-label',
        m === 'webcam'
          ? 'Webcam image with the face guide'
          : 'Frame with the faces found: click a face (or Tab) to choose it; or drag the box onto the face, or use the arrow keys to move it, + and − to resize it; Enter starts',
      );
    } else this.canvas.setAttribute('aria-label', `${src.label}: video with the fitted face mesh`);
    if (msg !== undefined) this.say(msg);
    else if (phase === 'empty') this.say('Drop a video or a photo on this panel or choose one: the faces in it are found, and tracking starts.');
    else if (phase === 'placing' && m !== 'clip') this.say(this.placingText());
    else if (phase === 'paused') this.say('Paused.');
    this.showState();
    this.draw();
  }

  say(text) {
    if (this.msgEl.textContent !== text) this.msgEl.textContent = text;
  }

  showState() {
    const src = this.src;
    let s;
    let label;
    if (src.phase === 'tracking') {
      s = src.state;
      label = { lost: 'face lost', unsure: 'unsure', searching: 'looking for a face', reinit: 're-initialised', tracking: 'tracking' }[s] || s;
      if (s === 'unsure' && src.last?.reasons?.length) label = `unsure · ${src.last.reasons.join(', ')}`;
    } else {
      s = src.phase;
      const { faces, face } = src.placement;
      const found = face ? (faces.length > 1 ? `${faces.length} faces found` : 'face found') : 'place the face';
      label = {
        loading: 'loading',
        empty: 'no video',
        placing: src.mode === 'webcam' || src.finding ? 'looking for a face' : found,
        paused: 'paused',
        error: 'error',
        idle: 'idle',
      }[src.phase];
    }
    this.stateEl.dataset.state = s;
    if (this.stateEl.textContent !== label) this.stateEl.textContent = label;
    this.el.dataset.state = s;
  }

  /** Shows an error state (after the phase's message). */
  showError() {
    this.stateEl.textContent = 'error';
    this.stateEl.dataset.state = 'error';
    this.el.dataset.state = 'error';
  }

  /** What the placement step says, from what the finder found. */
  placingText() {
    const src = this.src;
    if (src.mode === 'webcam') {
      return src.autoStart
        ? 'Looking for your face: look at the camera (the oval is only a guide); tracking starts when it is found, or press Start.'
        : 'Put your face inside the oval and press Start (Auto-start is off).';
    }
    if (src.finding) return 'Looking for faces…';
    const { faces, face, selected } = src.placement;
    const n = faces.length;
    const start = src.media.still ? 'fit it' : 'start tracking';
    if (n > 1 && face) {
      return `${n} faces found: the most confident is selected (${selected + 1}); click another one (or Tab) to choose it, then ${start}. Dragging places a box by hand.`;
    }
    if (n === 1 && face) return `A face was found: ${start}, or drag a box to place one by hand.`;
    if (n > 0) return `Box placed by hand (the faces found are shown faintly): ${start} from it.`;
    return src.findError
      ? `The face finder failed (${src.findError}): drag the box onto the face (drag its corner to resize), then ${start}.`
      : `No face was found on this frame: drag the box onto the face (drag its corner to resize), then ${start}.`;
  }

  /** The readout (at most five times a second). */
  showStats(now = performance.now()) {
    if (now - this.shownAt < 200) return;
    this.shownAt = now;
    const src = this.src;
    const { fits, msPerFit, fitTimes } = src.fitLog;
    const r = src.last;
    const set = (k, v) => {
      if (this.readout[k].textContent !== v) this.readout[k].textContent = v;
    };
    if (src.path === 'landmarks') {
      // The landmark path's `error` is 1 minus the mesh's face score (0 when a search gave the face).
      set('error', r && r.iterations > 0 ? (1 - r.error).toFixed(3) : '–');
      set('iterations', r ? String(r.iterations) : '–');
    } else {
      set('error', r ? r.error.toFixed(3) : '–');
      set('iterations', r ? `${r.iterations}${r.converged ? '' : ' (max)'}` : '–');
    }
    set('fps', String(fitTimes.length));
    set('ms', fits ? msPerFit.toFixed(1) : '–');
    const start = src.sequenceStart;
    set('lost', `${src.tracker.lostCount - start.lost} · ${src.tracker.resets - start.resets}`);
    this.readout.ms.parentElement.title = fits
      ? src.path === 'landmarks'
        ? `Time per frame followed (smoothed): ${msPerFit.toFixed(2)} ms, i.e. up to ${Math.round(1000 / Math.max(0.01, msPerFit))} frames/s`
        : `Time per fit (smoothed): ${msPerFit.toFixed(2)} ms, i.e. up to ${Math.round(1000 / Math.max(0.01, msPerFit))} fits/s`
      : '';
    this.showState();
  }

  // --- pointer and keyboard on the frame --------------------------------------------------------

  toFrame(e) {
    const r = this.canvas.getBoundingClientRect();
    const { width: W, height: H } = this.src.media.work;
    let x = ((e.clientX - r.left) / r.width) * W;
    const y = ((e.clientY - r.top) / r.height) * H;
    if (this.src.mode === 'webcam') x = W - x;
    return { x, y };
  }

  handleSize() {
    return (14 / this.canvas.getBoundingClientRect().width) * this.src.media.work.width;
  }

  /** Whether the pointer places the box (a file's placement step). */
  placingFile() {
    return this.src.phase === 'placing' && this.src.mode === 'file';
  }

  onPointerDown(e) {
    if (!this.placingFile()) return;
    this.src.placement.pointerDown(this.toFrame(e), this.handleSize());
    this.canvas.setPointerCapture(e.pointerId);
    this.focus();
    e.preventDefault();
    this.say(this.placingText());
    this.draw();
  }

  onPointerMove(e) {
    if (!this.placingFile()) return;
    const placement = this.src.placement;
    const p = this.toFrame(e);
    if (!placement.drag) {
      const h = placement.hit(p, this.handleSize());
      this.canvas.style.cursor = h === 'corner' ? 'nwse-resize' : h === 'inside' ? 'move' : h.startsWith('face:') ? 'pointer' : 'crosshair';
      return;
    }
    const wasFace = placement.face;
    const { width, height } = this.src.media.work;
    if (placement.pointerMove(p, width, height)) {
      if (wasFace) this.say(this.placingText());
      this.draw();
    }
  }

  onPointerUp() {
    this.src.placement.pointerUp();
  }

  onKey(e) {
    const src = this.src;
    if (src.phase !== 'placing') return;
    if (e.key === 'Enter') {
      e.preventDefault();
      src.startTracking();
      return;
    }
    if (src.mode !== 'file') return;
    const { work, k } = src.media;
    if (src.placement.key(e, (e.shiftKey ? 10 : 2) / k, work.width, work.height)) {
      e.preventDefault();
      this.say(this.placingText());
      this.draw();
    }
  }

  // --- drawing ------------------------------------------------------------------------------------

  draw() {
    const src = this.src;
    const c = this.canvas;
    if (!src.running || c.hidden) return;
    const webcam = src.mode === 'webcam';
    const v = drawFrame(c, src.media.work, { mirror: webcam, haveFrame: src.media.haveFrame });
    if (!v) return;
    const { g, map, s, lw, dpr } = v;
    if (src.phase === 'placing') {
      src.placement.draw(g, map, s, lw, dpr, { webcam, hot: src.tracker?.wantsFaces === false });
      if (src.finding) drawBadge(g, 'looking for faces…', GUIDE, dpr);
    } else if ((src.phase === 'tracking' || src.phase === 'paused') && src.last && this.meshCheck.checked) {
      if (!src.last.lost) drawLandmarks(g, src.last.landmarks, map, MESH, lw);
      else if (src.lastGood) {
        // The last good fit, in red: where the face was.
        drawLandmarks(g, src.lastGood.landmarks, map, MESH_LOST, lw);
        drawBadge(g, 'face lost', MESH_LOST, dpr);
      } else drawBadge(g, 'looking for a face', GUIDE, dpr);
    }
  }
}

// The inspector (the paper's Fig. 1): a model's mean face, one mode animated as
// base + k sigma * sin(t), its sizes, and a bar chart of each mode's share of the variance
// (the bars are buttons: pick a mode by clicking one or with the arrow keys).
// One class serves the page's Inspector panel and the preview in "Create a face" (enrol.js): each
// instance draws into the elements it is given; the page's frame loop calls `tick`.

import { ctx2d } from './canvas.js';

const PERIOD = 2.4; // seconds per oscillation

export class Inspector {
  constructor(wasm, els, options = {}) {
    this.options = options; // RenderOptions (background)
    this.wasm = wasm;
    // { mean, mode, caption, bars, kind (fieldset of radios), info?, sigma?, sigmaOut? }:
    // without `info` no details are listed; without `sigma` the amplitude is options.sigmas (2).
    this.els = els;
    this.model = null;
    this.info = null;
    this.kind = 'shape';
    this.mode = 0;
    this.sigmas = els.sigma ? Number(els.sigma.value) : (options.sigmas ?? 2);
    this.meanDirty = true;
    this.failed = false;
    this.drawn = 0; // animation frames drawn (the end-to-end tests check it stops)
    els.kind.addEventListener('change', (e) => {
      if (e.target.type === 'radio') this.setKind(e.target.value);
    });
    els.sigma?.addEventListener('input', () => {
      this.sigmas = Number(els.sigma.value);
      els.sigmaOut.value = `±${this.sigmas}σ`;
      this.caption();
    });
  }

  /** Show another model (a JS API `Model`, with its `info()`), keeping the kind and mode when they exist. */
  show(model, info, label) {
    this.model = model;
    this.info = info;
    this.label = label;
    this.failed = false;
    const n = this.count();
    if (this.mode >= n) this.mode = 0;
    this.meanDirty = true;
    // The bases are the training mean or a chosen face (the page's enrolment: the face at rest).
    const mean = !info?.reference || info.reference === 'mean';
    const fig = this.els.mean.parentElement?.querySelector('figcaption');
    if (fig) {
      fig.textContent = mean ? 'Mean' : 'Reference face';
      fig.title = mean ? 'the mean of the training faces' : `the training face ${info.reference} (the modes are about it)`;
    }
    this.els.mean.setAttribute('aria-label', mean ? 'Mean face of the model' : 'Reference face of the model');
    this.bars();
    this.details();
    this.caption();
  }

  /** Forget the model: nothing is drawn until the next `show`. */
  clear() {
    this.model = null;
    this.info = null;
  }

  count() {
    if (!this.info) return 0;
    return this.kind === 'shape' ? this.info.shapeModes : this.info.appearanceModes;
  }

  setKind(kind) {
    this.kind = kind;
    this.mode = 0;
    this.bars();
    this.caption();
  }

  select(mode) {
    this.mode = mode;
    for (const b of this.els.bars.children) {
      const on = Number(b.dataset.mode) === mode;
      b.setAttribute('aria-checked', String(on));
      b.tabIndex = on ? 0 : -1;
    }
    this.caption();
  }

  caption() {
    const n = this.count();
    const share = this.shares()[this.mode];
    this.els.caption.title = `${pct(share)} of the variance`;
    this.els.caption.textContent = n
      ? `${this.kind === 'shape' ? 'Shape' : 'Appearance'} ${this.mode + 1} ±${this.sigmas}σ`
      : this.info?.isPhoto
        ? 'No modes (a photo)'
        : 'No modes';
  }

  shares() {
    if (!this.info) return [];
    return this.kind === 'shape' ? this.info.shapeVarianceShare : this.info.appearanceVarianceShare;
  }

  bars() {
    const host = this.els.bars;
    host.replaceChildren();
    const shares = this.shares();
    const max = Math.max(1e-9, ...shares);
    shares.forEach((s, i) => {
      const b = document.createElement('button');
      b.type = 'button';
      b.className = 'bar';
      b.dataset.mode = String(i);
      b.setAttribute('role', 'radio');
      b.setAttribute('aria-checked', String(i === this.mode));
      b.setAttribute('aria-label', `Mode ${i + 1}: ${pct(s)} of the variance`);
      b.title = `Mode ${i + 1}: ${pct(s)}`;
      b.tabIndex = i === this.mode ? 0 : -1;
      b.style.setProperty('--h', `${Math.max(2, (s / max) * 100)}%`);
      b.addEventListener('click', () => this.select(i));
      b.addEventListener('keydown', (e) => {
        const step = { ArrowRight: 1, ArrowDown: 1, ArrowLeft: -1, ArrowUp: -1 }[e.key];
        if (step) {
          e.preventDefault();
          const j = Math.max(0, Math.min(shares.length - 1, i + step));
          this.select(j);
          host.children[j].focus();
        }
      });
      host.append(b);
    });
  }

  details() {
    if (!this.els.info) return;
    const i = this.info;
    const rows = [
      ['Name', i.name],
      ['Landmarks', i.landmarks],
      ['Triangles', i.triangles],
      ['Frame', `${i.frameWidth}×${i.frameHeight} px, ${i.pixels.toLocaleString()} inside`],
      ['Shape modes', `${i.shapeModes}`],
      ['Appearance modes', `${i.appearanceModes}`],
      ['Reference', i.reference],
      ['Images', `${i.imageWidth}×${i.imageHeight}`],
      ['Frame id', String(i.fingerprint).slice(0, 12)],
    ];
    if (i.isPhoto) rows.splice(1, 0, ['Kind', 'photo target (no modes of its own)']);
    if (i.backdrop) rows.push(['Picture', `${i.backdrop.width}×${i.backdrop.height}, ${(i.backdrop.bytes / 1024).toFixed(0)} KB`]);
    else if (i.backdropNotice) rows.push(['Picture', 'damaged: shown face only']);
    const dl = this.els.info;
    dl.replaceChildren();
    for (const [k, v] of rows) {
      const div = document.createElement('div');
      const dt = document.createElement('dt');
      dt.textContent = k;
      const dd = document.createElement('dd');
      dd.textContent = String(v);
      div.append(dt, dd);
      dl.append(div);
    }
  }

  /** Redraw the mean when asked (resize, model change). */
  invalidate() {
    this.meanDirty = true;
  }

  /** Draw (called once per animation frame with the page clock in seconds). */
  tick(t) {
    if (!this.model || this.failed) return;
    try {
      if (this.meanDirty) {
        // sigmas = 0 draws the base face; any mode that exists will do. A model without modes
        // (a photo target) is its base face.
        const kind = this.info.appearanceModes > 0 ? 'appearance' : 'shape';
        if (this.info.appearanceModes + this.info.shapeModes > 0) {
          this.wasm.renderMode(this.model, kind, 0, 0, ctx2d(this.els.mean), this.options);
        } else {
          this.model.render(this.model.baseParams(), ctx2d(this.els.mean), this.options);
        }
        this.meanDirty = false;
      }
      if (this.count() === 0) return;
      const k = this.sigmas * Math.sin((2 * Math.PI * t) / PERIOD);
      this.wasm.renderMode(this.model, this.kind, this.mode, k, ctx2d(this.els.mode), this.options);
      this.drawn++;
    } catch (e) {
      // Do not flood: report once per model.
      this.failed = true;
      console.error('facemimic inspector:', e);
    }
  }
}

export function pct(x) {
  if (!Number.isFinite(x)) return '–';
  const v = x * 100;
  return `${v >= 10 ? v.toFixed(0) : v.toFixed(1)}%`;
}

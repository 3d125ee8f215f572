// Canvases drawn at their device-pixel size: the backing store is the CSS box times
// devicePixelRatio, kept in step with layout by a ResizeObserver (and DPR changes, e.g. moving
// the window to another screen or zooming). `onResize` is told so the page can redraw at once.

const contexts = new WeakMap();

/** The 2D context of a canvas, created once (opaque: faces are drawn over a solid background). */
export function ctx2d(canvas) {
  let ctx = contexts.get(canvas);
  if (!ctx) {
    ctx = canvas.getContext('2d', { alpha: false });
    contexts.set(canvas, ctx);
  }
  return ctx;
}

/** Set one canvas's backing store from its CSS box; returns true when the size changed. */
export function fitCanvas(canvas, entry) {
  const dpr = window.devicePixelRatio || 1;
  // CSS size x devicePixelRatio. (The observer's device-pixel-content-box is not used: it
  // ignores emulated pixel ratios and browser zoom in some builds.)
  const box = entry?.contentBoxSize?.[0];
  let cssW;
  let cssH;
  if (box) {
    cssW = box.inlineSize;
    cssH = box.blockSize;
  } else {
    const r = canvas.getBoundingClientRect();
    cssW = r.width;
    cssH = r.height;
  }
  let w = Math.round(cssW * dpr);
  let h = Math.round(cssH * dpr);
  w = Math.max(1, Math.min(4096, w));
  h = Math.max(1, Math.min(4096, h));
  return setCanvasSize(canvas, w, h);
}

/** Give `canvas` a `w`x`h` backing store unless it has it already (a new size clears the
 *  canvas, so it is set only when it changes); returns true when the size changed. */
export function setCanvasSize(canvas, w, h) {
  if (canvas.width === w && canvas.height === h) return false;
  canvas.width = w;
  canvas.height = h;
  return true;
}

/**
 * Keep canvases sized to their device pixels. `watch(canvas)` starts, `unwatch(canvas)` stops;
 * `onResize(canvas)` runs after a canvas's backing store changed, or when it scrolled into
 * view (so it can be drawn again). `visible(canvas)` says whether any of it is on screen:
 * the page skips drawing faces nobody can see.
 */
export class HiDpi {
  constructor(onResize) {
    this.onResize = onResize;
    this.shown = new WeakMap();
    this.io = new IntersectionObserver(
      (entries) => {
        for (const e of entries) {
          const was = this.shown.get(e.target);
          this.shown.set(e.target, e.isIntersecting);
          if (e.isIntersecting && !was) this.onResize(e.target);
        }
      },
      { rootMargin: '64px' },
    );
    this.observer = new ResizeObserver((entries) => {
      for (const e of entries) {
        if (e.target.isConnected && fitCanvas(e.target, e)) this.onResize(e.target);
      }
    });
    this.canvases = new Set();
    this.watchDpr();
  }
  watch(canvas) {
    this.canvases.add(canvas);
    this.observer.observe(canvas);
    this.io.observe(canvas);
    fitCanvas(canvas);
  }
  unwatch(canvas) {
    this.canvases.delete(canvas);
    this.observer.unobserve(canvas);
    this.io.unobserve(canvas);
  }
  /** Whether the canvas is (nearly) on screen; true until the first report. */
  visible(canvas) {
    return this.shown.get(canvas) ?? true;
  }
  watchDpr() {
    const mq = matchMedia(`(resolution: ${window.devicePixelRatio || 1}dppx)`);
    mq.addEventListener(
      'change',
      () => {
        for (const c of this.canvases) if (fitCanvas(c)) this.onResize(c);
        this.watchDpr();
      },
      { once: true },
    );
  }
}

// Recording the target view: the visible face canvases are composited side by side, with their
// names, onto one canvas; a PNG snapshot is that canvas once, a WebM video is a MediaRecorder
// on its captureStream, fed one composite per rendered frame.

import { setCanvasSize } from './canvas.js';

/**
 * Draw `tiles` ([{ canvas, label, render? }]) in one row onto `out` at height `tileH` (device
 * px). A tile with `render(w, h) -> ImageData` is rendered afresh at exactly the tile's size
 * (crisp at any size); otherwise its canvas is scaled.
 */
export function composite(out, tiles, tileH = 360) {
  // Labels and gaps scale with the tiles.
  const LABEL_H = Math.round(tileH * 0.085);
  const GAP = Math.max(4, Math.round(tileH / 48));
  const ws = tiles.map((t) => Math.round((t.canvas.width / t.canvas.height) * tileH) || tileH);
  const width = ws.reduce((a, b) => a + b, 0) + GAP * (tiles.length + 1);
  const height = tileH + LABEL_H + GAP * 2;
  // Even sizes: video encoders want them.
  const W = width + (width & 1);
  const H = height + (height & 1);
  setCanvasSize(out, W, H);
  const ctx = out.getContext('2d', { alpha: false });
  ctx.fillStyle = '#121316';
  ctx.fillRect(0, 0, W, H);
  ctx.imageSmoothingQuality = 'high';
  ctx.font = `500 ${Math.round(LABEL_H * 0.55)}px system-ui, sans-serif`;
  ctx.textBaseline = 'middle';
  ctx.textAlign = 'center';
  let x = GAP;
  tiles.forEach((t, i) => {
    if (t.render) ctx.putImageData(t.render(ws[i], tileH), x, GAP);
    else ctx.drawImage(t.canvas, x, GAP, ws[i], tileH);
    ctx.fillStyle = '#d8dae0';
    ctx.fillText(t.label, x + ws[i] / 2, GAP + tileH + LABEL_H / 2 + 2);
    x += ws[i] + GAP;
  });
  return out;
}

/** A timestamped file name: facemimic-2026-11-21T08-12-03.<ext>. */
export function fileName(ext) {
  const stamp = new Date().toISOString().replace(/\..*$/, '').replace(/:/g, '-');
  return `facemimic-${stamp}.${ext}`;
}

/** The best WebM type this browser can record, or null. */
export function webmType() {
  if (typeof MediaRecorder === 'undefined') return null;
  for (const t of ['video/webm;codecs=vp9', 'video/webm;codecs=vp8', 'video/webm']) {
    if (MediaRecorder.isTypeSupported(t)) return t;
  }
  return null;
}

/** Records a canvas to WebM. `start()`, then `frame()` after each composite, then `await stop()` -> Blob. */
export class WebmRecorder {
  constructor(canvas, fps = 30) {
    const type = webmType();
    if (!type) throw new Error('this browser cannot record WebM video (no MediaRecorder support)');
    if (!canvas.captureStream) throw new Error('this browser cannot capture a canvas as a video stream');
    this.type = type;
    this.stream = canvas.captureStream(fps);
    this.chunks = [];
    this.recorder = new MediaRecorder(this.stream, { mimeType: type, videoBitsPerSecond: 6_000_000 });
    this.recorder.addEventListener('dataavailable', (e) => {
      if (e.data && e.data.size) this.chunks.push(e.data);
    });
    this.startedAt = 0;
  }
  start() {
    this.recorder.start(250);
    this.startedAt = performance.now();
  }
  get seconds() {
    return (performance.now() - this.startedAt) / 1000;
  }
  stop() {
    return new Promise((resolve, reject) => {
      this.recorder.addEventListener('stop', () => {
        for (const tr of this.stream.getTracks()) tr.stop();
        resolve(new Blob(this.chunks, { type: 'video/webm' }));
      });
      this.recorder.addEventListener('error', (e) => reject(e.error || new Error('recording failed')));
      this.recorder.stop();
    });
  }
}

/** Add a download link for `blob` to the list `ul` (newest first) and return the <a>. */
export function addDownload(ul, blob, name, label) {
  const url = URL.createObjectURL(blob);
  const li = document.createElement('li');
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  a.textContent = label;
  const size = document.createElement('span');
  size.className = 'muted';
  size.textContent = ` ${(blob.size / 1024).toFixed(blob.size < 10240 ? 1 : 0)} KB`;
  const rm = document.createElement('button');
  rm.type = 'button';
  rm.className = 'link-btn';
  rm.setAttribute('aria-label', `Discard ${name}`);
  rm.textContent = '×';
  rm.addEventListener('click', () => {
    URL.revokeObjectURL(url);
    li.remove();
  });
  li.append(a, size, rm);
  ul.prepend(li);
  return a;
}

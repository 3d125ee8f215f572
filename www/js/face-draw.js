// Drawing for the tracking panel: the video frame scaled into the panel's canvas (mirrored for a
// webcam), landmarks as contours and points, and small labels. No state: every function draws
// what it is given.

import { setCanvasSize } from './canvas.js';

export const MESH = 'rgba(120, 255, 200, 0.95)';
export const MESH_LOST = 'rgba(255, 110, 110, 0.95)';
export const GUIDE = 'rgba(124, 196, 255, 0.95)';
export const FOUND = 'rgba(255, 214, 102, 0.95)';
export const FOUND_OTHER = 'rgba(255, 214, 102, 0.5)';

/** The 68-point (iBUG / dlib) contours: [first, last, closed]. */
export const CONTOURS_68 = [
  [0, 16, false], // jaw
  [17, 21, false], // brows
  [22, 26, false],
  [27, 30, false], // nose bridge
  [31, 35, false], // nostrils
  [36, 41, true], // eyes
  [42, 47, true],
  [48, 59, true], // outer lips
  [60, 67, true], // inner lips
];

/** `pts` times `f`, as a Float32Array. */
export function scaled(pts, f) {
  const out = new Float32Array(pts.length);
  for (let i = 0; i < pts.length; i++) out[i] = pts[i] * f;
  return out;
}

/** Bounding box `{ x, y, w, h }` of interleaved points. */
export function bounds(pts) {
  let x0 = Infinity;
  let y0 = Infinity;
  let x1 = -Infinity;
  let y1 = -Infinity;
  for (let i = 0; i + 1 < pts.length; i += 2) {
    x0 = Math.min(x0, pts[i]);
    x1 = Math.max(x1, pts[i]);
    y0 = Math.min(y0, pts[i + 1]);
    y1 = Math.max(y1, pts[i + 1]);
  }
  return { x: x0, y: y0, w: x1 - x0, h: y1 - y0 };
}

/**
 * Draw landmarks (`pts` in frame pixels) with `map(x, y) -> [X, Y]` into the canvas: contour
 * lines (68-point scheme) and points. `lw`: line width in canvas pixels.
 */
export function drawLandmarks(ctx, pts, map, colour, lw, { points = true, only = null } = {}) {
  const n = pts.length / 2;
  ctx.save();
  ctx.strokeStyle = colour;
  ctx.fillStyle = colour;
  ctx.lineWidth = lw;
  ctx.lineJoin = 'round';
  ctx.lineCap = 'round';
  if (n === 68) {
    ctx.beginPath();
    for (const [a, b, closed] of only ?? CONTOURS_68) {
      for (let i = a; i <= b; i++) {
        const [X, Y] = map(pts[2 * i], pts[2 * i + 1]);
        if (i === a) ctx.moveTo(X, Y);
        else ctx.lineTo(X, Y);
      }
      if (closed) ctx.closePath();
    }
    ctx.stroke();
  }
  if (points || n !== 68) {
    const r = Math.max(1, lw * 1.1);
    ctx.beginPath();
    for (let i = 0; i < n; i++) {
      const [X, Y] = map(pts[2 * i], pts[2 * i + 1]);
      ctx.moveTo(X + r, Y);
      ctx.arc(X, Y, r, 0, Math.PI * 2);
    }
    ctx.fill();
  }
  ctx.restore();
}

/**
 * Draw the frame (`work`, a canvas) centred and scaled into `canvas` (sized to its CSS box at
 * the device pixel ratio), mirrored when asked. Returns `{ g, map, s, lw, dpr }` (`map`: frame
 * pixel -> canvas pixel; `s`: canvas pixels per frame pixel) or `null` when there is no frame.
 */
export function drawFrame(canvas, work, { mirror = false, haveFrame = true } = {}) {
  const dpr = window.devicePixelRatio || 1;
  const cw = Math.max(1, Math.min(4096, Math.round(canvas.clientWidth * dpr)));
  const ch = Math.max(1, Math.min(4096, Math.round(canvas.clientHeight * dpr)));
  setCanvasSize(canvas, cw, ch);
  const g = canvas.getContext('2d', { alpha: false });
  g.fillStyle = '#101114';
  g.fillRect(0, 0, cw, ch);
  if (!haveFrame) return null;
  const W = work.width;
  const H = work.height;
  const s = Math.min(cw / W, ch / H);
  const ox = (cw - W * s) / 2;
  const oy = (ch - H * s) / 2;
  g.save();
  g.imageSmoothingQuality = 'high';
  if (mirror) {
    g.translate(cw, 0);
    g.scale(-1, 1);
  }
  g.drawImage(work, ox, oy, W * s, H * s);
  g.restore();
  const map = mirror ? (x, y) => [cw - (ox + x * s), oy + y * s] : (x, y) => [ox + x * s, oy + y * s];
  return { g, map, s, lw: Math.max(1, 1.25 * dpr), dpr };
}

/** A small label in the canvas's top-left corner (e.g. "face lost"). */
export function drawBadge(g, text, colour, dpr) {
  g.save();
  g.font = `600 ${Math.round(13 * dpr)}px system-ui, sans-serif`;
  g.fillStyle = 'rgba(16, 17, 20, 0.75)';
  const tw = g.measureText(text).width;
  g.fillRect(8 * dpr, 8 * dpr, tw + 16 * dpr, 22 * dpr);
  g.fillStyle = colour;
  g.textBaseline = 'middle';
  g.fillText(text, 16 * dpr, 19 * dpr);
  g.restore();
}

// Shared by the page's end-to-end tests (page.test.mjs, methods.test.mjs): the page's suite
// (server + browser, lib.mjs `pageSuite`), opening it, and the checks of what its canvases show.

import assert from 'node:assert/strict';
import path from 'node:path';
import { ROOT, canvasStats, faceBox, cornerDistances, openPage, pageSuite } from './lib.mjs';

// FACEMIMIC_WWW serves another folder laid out like www/ (for developing the page).
export const WWW = path.resolve(ROOT, process.env.FACEMIMIC_WWW || 'www');
export const MODELS = path.join(WWW, 'models');

export const TARGETS = '.face-card.target canvas.face';
export const FACE_BG = [0x1b, 0x1d, 0x22]; // the page's canvas background (FACE_BG in www/js/page-state.js)
export const SOURCE = '.face-card.source canvas.face';

/** The page's suite (registers the file's before / after hooks) and `open(t, options)`, which
 *  opens the page in a fresh context (lib.mjs `openPage`); `autoplay` false asks for reduced motion. */
export function pageTests() {
  const suite = pageSuite(WWW);
  const open = (t, { width = 1440, height = 900, dpr = 1, autoplay = true } = {}) =>
    openPage(t, suite.browser, suite.server, {
      context: { viewport: { width, height }, deviceScaleFactor: dpr, acceptDownloads: true, reducedMotion: autoplay ? 'no-preference' : 'reduce' },
    });
  return { suite, open };
}

/** A face alone on the background: varied, centred, inside the canvas and large. */
export async function assertFace(page, selector, what) {
  const s = await canvasStats(page, selector);
  assert.ok(s.width > 50 && s.height > 50, `${what}: canvas backing store is ${s.width}x${s.height}`);
  // A face (skin, eyes, mouth, hair, background) varies a lot; a blank or flat canvas does not.
  assert.ok(s.variance > 60 && s.distinct > 200, `${what}: centre looks blank (${JSON.stringify(s)})`);
  // Centred and scaled: the face's box is in the middle, inside the canvas, and large.
  const box = await faceBox(page, selector, FACE_BG);
  const r = (v) => v.toFixed(2);
  const desc = box && `box ${r(box.left)}..${r(box.right)} x ${r(box.top)}..${r(box.bottom)}`;
  assert.ok(box, `${what}: nothing drawn over the background`);
  assert.ok(Math.abs(box.cx - 0.5) < 0.08 && Math.abs(box.cy - 0.5) < 0.08, `${what}: face not centred (${desc})`);
  assert.ok(box.left > 0.01 && box.top > 0.01 && box.right < 0.99 && box.bottom < 0.99, `${what}: face touches the edge (${desc})`);
  assert.ok(box.right - box.left > 0.6, `${what}: face too small (${desc})`);
  return s;
}

/**
 * A target composited into its picture (the page's default): the canvas has the picture's
 * aspect (the bundled GRID pictures are 360x288), its corners are the picture (not the
 * background) and its middle (the face) varies.
 */
export async function assertPicture(page, selector, what) {
  const s = await canvasStats(page, selector);
  assert.ok(s.width > 50 && s.height > 50, `${what}: canvas backing store is ${s.width}x${s.height}`);
  assert.ok(Math.abs(s.width / s.height - 1.25) < 0.03, `${what}: a ${s.width}x${s.height} canvas for a 5:4 picture`);
  assert.ok(s.variance > 60 && s.distinct > 200, `${what}: centre looks blank (${JSON.stringify(s)})`);
  const corners = await cornerDistances(page, selector, FACE_BG);
  assert.ok(corners.every((d) => d > 12), `${what}: a corner is background, not the picture (${corners.map((d) => d.toFixed(1))})`);
  return s;
}

export async function pause(page) {
  if ((await page.getAttribute('#play', 'data-state')) === 'playing') await page.click('#play');
  assert.equal(await page.getAttribute('#play', 'data-state'), 'paused');
}

export async function setSlider(page, id, value) {
  await page.$eval(
    `#${id}`,
    (el, v) => {
      el.focus();
      el.value = String(v);
      el.dispatchEvent(new Event('input', { bubbles: true }));
    },
    value,
  );
}

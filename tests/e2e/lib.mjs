// Shared helpers for the browser end-to-end tests (node:test + playwright-core + Debian chromium):
// what the benchmarks need too (paths, the package in Node, the static server, Chromium and its
// flags, screenshots, fake cameras) lives in scripts/lib/browser.mjs and is re-exported here;
// the rest (canvas measures, page suites and assertions) is the tests' own.
//
// Nothing here touches the network beyond 127.0.0.1.

import fs from 'node:fs';
import path from 'node:path';
import assert from 'node:assert/strict';
import { before, after } from 'node:test';
import { ROOT, pkg, CHROMIUM, serveStatic, launchBrowser, haveChromium, fakeCameraArgs, fakeCameraFile } from '../../scripts/lib/browser.mjs';

export {
  ROOT, pkg, ARTIFACTS, CHROMIUM, CHROMIUM_ARGS, serveStatic, launchBrowser, haveChromium, screenshot,
  readPts, FAKE_CAMERA_ARGS, fakeCameraArgs, mjpegCamera, fakeCameraFile, clipFrames, READ_MARKER, OCCLUDER_SKIN,
} from '../../scripts/lib/browser.mjs';

/**
 * Statistics of a canvas's centre region (the middle `frac` of each side), computed in the page:
 * `{ width, height, mean, variance, distinct }` over the RGB values. A painted face has a large
 * variance; a blank or one-colour canvas has ~0.
 */
export async function canvasStats(page, selector, frac = 0.5) {
  return page.$eval(
    selector,
    (canvas, frac) => {
      const w = canvas.width;
      const h = canvas.height;
      if (!w || !h) return { width: w, height: h, mean: 0, variance: 0, distinct: 0 };
      const ctx = canvas.getContext('2d');
      const cw = Math.max(1, Math.round(w * frac));
      const ch = Math.max(1, Math.round(h * frac));
      const data = ctx.getImageData(Math.round((w - cw) / 2), Math.round((h - ch) / 2), cw, ch).data;
      let sum = 0;
      let sum2 = 0;
      let n = 0;
      const seen = new Set();
      for (let i = 0; i < data.length; i += 4) {
        const lum = 0.299 * data[i] + 0.587 * data[i + 1] + 0.114 * data[i + 2];
        sum += lum;
        sum2 += lum * lum;
        n++;
        if (seen.size < 4096) seen.add((data[i] << 16) | (data[i + 1] << 8) | data[i + 2]);
      }
      const mean = sum / n;
      return { width: w, height: h, mean, variance: sum2 / n - mean * mean, distinct: seen.size };
    },
    frac,
  );
}

/** A cheap fingerprint of a canvas's pixels (to tell whether it changed). */
export async function canvasDigest(page, selector) {
  return page.$eval(selector, (canvas) => {
    const ctx = canvas.getContext('2d');
    const data = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
    let h = 2166136261 >>> 0;
    for (let i = 0; i < data.length; i += 4) {
      h = Math.imul(h ^ data[i], 16777619) >>> 0;
      h = Math.imul(h ^ data[i + 1], 16777619) >>> 0;
      h = Math.imul(h ^ data[i + 2], 16777619) >>> 0;
    }
    return h.toString(16);
  });
}

/** Mean absolute per-channel difference between two canvases' current pixels, as returned by `canvasPixels`. */
export function meanAbsDiff(a, b) {
  if (a.length !== b.length) return Infinity;
  let s = 0;
  for (let i = 0; i < a.length; i++) s += Math.abs(a[i] - b[i]);
  return s / a.length;
}

/** A canvas's RGB pixels on a grid of every `step`-th pixel, as a plain array (for `meanAbsDiff`). */
export async function canvasPixels(page, selector, step = 3) {
  return page.$eval(
    selector,
    (canvas, step) => {
      const { width: w, height: h } = canvas;
      const data = canvas.getContext('2d').getImageData(0, 0, w, h).data;
      const out = [];
      for (let y = 0; y < h; y += step) {
        for (let x = 0; x < w; x += step) {
          const i = (y * w + x) * 4;
          out.push(data[i], data[i + 1], data[i + 2]);
        }
      }
      return out;
    },
    step,
  );
}

/**
 * Where the face is in a canvas: the bounding box and centroid of the pixels that differ from
 * the background colour `bg` ([r, g, b]) by more than `tol`, relative to the canvas size (0..1).
 */
export async function faceBox(page, selector, bg, tol = 24) {
  return page.$eval(
    selector,
    (canvas, [bg, tol]) => {
      const { width: w, height: h } = canvas;
      const data = canvas.getContext('2d').getImageData(0, 0, w, h).data;
      let x0 = w;
      let y0 = h;
      let x1 = -1;
      let y1 = -1;
      let sx = 0;
      let sy = 0;
      let n = 0;
      for (let y = 0; y < h; y++) {
        for (let x = 0; x < w; x++) {
          const i = (y * w + x) * 4;
          const d = Math.abs(data[i] - bg[0]) + Math.abs(data[i + 1] - bg[1]) + Math.abs(data[i + 2] - bg[2]);
          if (d > tol) {
            if (x < x0) x0 = x;
            if (x > x1) x1 = x;
            if (y < y0) y0 = y;
            if (y > y1) y1 = y;
            sx += x;
            sy += y;
            n++;
          }
        }
      }
      if (!n) return null;
      return {
        left: x0 / w,
        top: y0 / h,
        right: (x1 + 1) / w,
        bottom: (y1 + 1) / h,
        cx: (x0 + x1 + 1) / 2 / w,
        cy: (y0 + y1 + 1) / 2 / h,
        coverage: n / (w * h),
      };
    },
    [bg, tol],
  );
}

/** Fails (saying what to run) unless chromium, the page's wasm package and its default models
 *  (in `www`, the page's folder) are there. */
export function assertPageBuilt(www = path.join(ROOT, 'www')) {
  assert.ok(haveChromium(), `chromium not found at ${CHROMIUM}: run scripts/setup.sh --browser`);
  assert.ok(fs.existsSync(path.join(www, 'pkg', 'facemimic.js')), `${www}/pkg/facemimic.js is missing: run scripts/build-wasm.sh`);
  assert.ok(fs.existsSync(path.join(www, 'models', 'manifest.json')), `${www}/models/ is missing: run scripts/build-models.sh`);
}

/**
 * Drops files (`{ name, bytes, type? }`; `type` defaults to `defaultType`) on the element
 * `selector` of `page` through a synthetic DataTransfer, as a user's drag and drop would.
 */
export async function dropFiles(page, selector, files, defaultType = '') {
  const payload = files.map((f) => ({ name: f.name, type: f.type || defaultType, b64: Buffer.from(f.bytes).toString('base64') }));
  await page.$eval(
    selector,
    (el, payload) => {
      const dt = new DataTransfer();
      for (const f of payload) {
        const bin = atob(f.b64);
        const bytes = new Uint8Array(bin.length);
        for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
        dt.items.add(new File([bytes], f.name, { type: f.type }));
      }
      for (const type of ['dragenter', 'dragover', 'drop']) {
        el.dispatchEvent(new DragEvent(type, { dataTransfer: dt, bubbles: true, cancelable: true }));
      }
    },
    payload,
  );
}

/**
 * Switches the page's source to the webcam and waits until it tracks (the panel within
 * `timeout` ms) and has fitted 40 frames; returns the tracking log as `{ lost, error }` a fit.
 */
export async function webcamLog(page, timeout) {
  await page.selectOption('#source-kind', 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout });
  await page.waitForFunction(() => window.facemimicTracking?.log.length >= 40, null, { timeout: 60_000 });
  return page.evaluate(() => window.facemimicTracking.log.map((l) => ({ lost: l.lost, error: l.error })));
}

/**
 * A test file's page in `www` (the page's folder): before its tests, checks that the page is
 * built, serves `www` and launches a browser; after them, closes both. Returns `{ server,
 * browser, manifest }` (`manifest`: the default models' manifest.json), set by then. With
 * `camera: { frames, name }` the browser's fake camera plays that folder of JPEG frames
 * (`fakeCameraFile`; its file is removed afterwards).
 */
export function pageSuite(www, { camera } = {}) {
  const suite = {};
  const cleanups = [];
  before(async () => {
    assertPageBuilt(www);
    suite.manifest = JSON.parse(fs.readFileSync(path.join(www, 'models', 'manifest.json'), 'utf8'));
    suite.server = await serveStatic(www);
    const args = camera
      ? fakeCameraArgs(await fakeCameraFile({ after: (fn) => cleanups.push(fn) }, camera.frames, { name: camera.name }))
      : [];
    suite.browser = await launchBrowser(args);
  });
  after(async () => {
    await suite.browser?.close();
    await suite.server?.close();
    for (const fn of cleanups) fn();
  });
  return suite;
}

/**
 * Presses the enrol dialog's build button, then Cancel while the build worker runs (the
 * worker's wasm is held back 1.5 s, so the build is surely not over when Cancel is pressed: a
 * 20-frame build takes well under a second), and waits for the dialog to say nothing was kept.
 */
export async function cancelEnrolBuild(page) {
  await page.route('**/facemimic_bg.wasm', async (route) => {
    await new Promise((r) => setTimeout(r, 1500));
    await route.continue().catch(() => {}); // the cancelled worker is gone by then
  });
  await page.click('#enrol .btn.primary');
  await page.getByRole('button', { name: 'Cancel' }).click();
  await page.waitForFunction(() => /cancelled; nothing was kept/.test(document.querySelector('#enrol .enrol-status').textContent));
}

/**
 * Opens `server`'s page in a fresh context of `browser` (`context`: its options; closed after
 * the test `t`) and waits until it has drawn (and `ready`, more selectors to wait for). Returns
 * `{ page, errors, offOrigin, frames }`: the page errors (and console errors unless `console`
 * is false) as they come, the requests that left the page's origin (also counted as errors
 * with `originErrors`), and `frames(n)`, which waits for `n` animation frames (the page renders
 * every frame while playing, and once after any change while paused).
 */
export async function openPage(t, browser, server, { context: options = {}, ready = [], init, console: consoleErrors = true, originErrors = false } = {}) {
  const context = await browser.newContext({ viewport: { width: 1440, height: 900 }, ...options });
  t.after(() => context.close().catch(() => {}));
  const page = await context.newPage();
  const errors = [];
  const offOrigin = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  if (consoleErrors) {
    page.on('console', (m) => {
      if (m.type() === 'error') errors.push(m.text());
    });
  }
  page.on('request', (r) => {
    const u = r.url();
    if (u.startsWith(server.url) || u.startsWith('blob:') || u.startsWith('data:')) return;
    offOrigin.push(u);
    if (originErrors) errors.push(`request off the origin: ${u}`);
  });
  if (init) await page.addInitScript(init);
  await page.goto(server.url);
  for (const selector of ['body[data-ready="1"]', ...ready]) await page.waitForSelector(selector, { timeout: 30_000 });
  const frames = (n = 2) =>
    page.evaluate(
      (n) =>
        new Promise((resolve) => {
          let k = 0;
          const step = () => (++k > n ? resolve() : requestAnimationFrame(step));
          requestAnimationFrame(step);
        }),
      n,
    );
  return { page, errors, offOrigin, frames };
}

/** A browser whose camera plays `camera` (`fakeCameraArgs`), closed after the test `t`. */
export async function cameraBrowser(t, camera) {
  const browser = await launchBrowser(fakeCameraArgs(camera));
  t.after(() => browser.close());
  return browser;
}

/** Asserts that the page has a target card and that every target's face changes within `ms`. */
export async function assertTargetsMove(page, ms) {
  const targets = await page.$$eval('.face-card.target canvas.face', (c) => c.length);
  assert.ok(targets >= 1);
  const digest = (i) => canvasDigest(page, `.face-card.target >> nth=${i} >> canvas.face`);
  const before = [];
  for (let i = 0; i < targets; i++) before.push(await digest(i));
  await page.waitForTimeout(ms);
  for (let i = 0; i < targets; i++) assert.notEqual(await digest(i), before[i], `target ${i} does not move`);
}

/**
 * The landmark error used throughout the project's figures (the package's `landmarkError`, the
 * core's `find::landmark_error`): the mean point-to-point distance between `a` and `truth`
 * (68 points, interleaved x, y) over `truth`'s outer-eye-corner distance (landmarks 36 and 45).
 */
export function landmarkError(a, truth) {
  return pkg().landmarkError(a, truth);
}

/**
 * How far the four corner regions of a canvas (each `frac` of its width and height) are from
 * the colour `bg` ([r, g, b]): per corner (top-left, top-right, bottom-left, bottom-right), the
 * mean over the region's pixels of the largest per-channel difference. A corner that is all
 * background gives ~0; a picture (a target composited into its backdrop) gives tens.
 */
export async function cornerDistances(page, selector, bg, frac = 0.08) {
  return page.$eval(
    selector,
    (canvas, [bg, frac]) => {
      const { width: w, height: h } = canvas;
      const cw = Math.max(1, Math.round(w * frac));
      const ch = Math.max(1, Math.round(h * frac));
      const g = canvas.getContext('2d');
      return [
        [0, 0],
        [w - cw, 0],
        [0, h - ch],
        [w - cw, h - ch],
      ].map(([x, y]) => {
        const d = g.getImageData(x, y, cw, ch).data;
        let s = 0;
        for (let i = 0; i < d.length; i += 4) {
          s += Math.max(Math.abs(d[i] - bg[0]), Math.abs(d[i + 1] - bg[1]), Math.abs(d[i + 2] - bg[2]));
        }
        return s / (d.length / 4);
      });
    },
    [bg, frac],
  );
}

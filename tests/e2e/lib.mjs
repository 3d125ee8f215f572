// Shared helpers for the browser end-to-end tests (node:test + playwright-core + Debian chromium).
//
//   const server = await serveStatic('www');        // { url, port, close() }
//   const browser = await launchBrowser();          // playwright Browser
//   await screenshot(page, 'page-desktop');         // -> artifacts/page-desktop.png
//
// Nothing here touches the network beyond 127.0.0.1.

import http from 'node:http';
import fs from 'node:fs';
import fsp from 'node:fs/promises';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';
import assert from 'node:assert/strict';
import zlib from 'node:zlib';
import { before, after } from 'node:test';
import { chromium } from 'playwright-core';

/** The repository root (two levels above this file). */
export const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');

/** The npm package as the page loads it (www/pkg, built by scripts/build-wasm.sh). */
const WWW_PKG = path.join(ROOT, 'www', 'pkg');
const pkgModule = fs.existsSync(path.join(WWW_PKG, 'facemimic.js'))
  ? await import(pathToFileURL(path.join(WWW_PKG, 'facemimic.js')).href)
  : null;
let pkgReady = false;

/** The npm package in Node (www/pkg), its wasm instantiated on first use: the tests measure and
 *  parse with the core's own functions, not copies of them. */
export function pkg() {
  assert.ok(pkgModule, 'www/pkg/ is missing: run scripts/build-wasm.sh');
  if (!pkgReady) {
    pkgModule.initSync({ module: fs.readFileSync(path.join(WWW_PKG, 'facemimic_bg.wasm')) });
    pkgReady = true;
  }
  return pkgModule;
}

/** Where screenshots and other test outputs go (gitignored). */
export const ARTIFACTS = path.join(ROOT, 'artifacts');

/** The browser the tests drive (Debian's package; override with CHROMIUM=/path). */
export const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';

/** Flags for a quiet, offline, headless chromium. */
export const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--no-first-run',
  '--disable-quic',
];

const MIME = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8',
  '.css': 'text/css; charset=utf-8',
  '.json': 'application/json; charset=utf-8',
  '.wasm': 'application/wasm',
  '.svg': 'image/svg+xml',
  '.png': 'image/png',
  '.jpg': 'image/jpeg',
  '.ico': 'image/x-icon',
  '.txt': 'text/plain; charset=utf-8',
  '.md': 'text/plain; charset=utf-8',
  '.ts': 'text/plain; charset=utf-8',
  '.fmm': 'application/octet-stream',
};

/** File types served gzip-compressed (text and wasm; not models or media). */
const GZIP_TYPES = new Set(['.html', '.js', '.mjs', '.css', '.json', '.wasm', '.svg', '.txt']);
const gzipCache = new Map();
/** The gzip of a file, cached by path, size and modification time. */
async function gzipped(file, st) {
  const key = `${file}:${st.size}:${st.mtimeMs}`;
  let body = gzipCache.get(key);
  if (!body) {
    body = zlib.gzipSync(await fsp.readFile(file), { level: 9 });
    gzipCache.set(key, body);
  }
  return body;
}

/**
 * Serve a directory (relative to the repo root, or absolute) on 127.0.0.1 at a free port.
 * GET/HEAD only; paths are confined to the directory; `/` and directories serve `index.html`.
 * `mounts` maps URL prefixes to other directories served on the same origin, e.g.
 * `{ '/research/webcam-dev/': '/abs/path' }` (research data read where it lies, never copied).
 * Returns `{ url, port, requests, close }`; `requests` lists every path asked for (so a test can
 * check that nothing outside the origin was wanted).
 */
export async function serveStatic(dir, { mounts = {} } = {}) {
  const roots = Object.entries(mounts).map(([prefix, d]) => [prefix.endsWith('/') ? prefix : `${prefix}/`, path.resolve(ROOT, d)]);
  const requests = [];
  const server = http.createServer(async (req, res) => {
    try {
      const url = new URL(req.url, 'http://127.0.0.1');
      requests.push(url.pathname);
      if (req.method !== 'GET' && req.method !== 'HEAD') {
        res.writeHead(405).end();
        return;
      }
      const mount = roots.find(([prefix]) => url.pathname.startsWith(prefix));
      const base = mount ? mount[1] : path.resolve(ROOT, dir);
      const rel = mount ? url.pathname.slice(mount[0].length - 1) : url.pathname;
      let file = path.join(base, decodeURIComponent(rel));
      if (file !== base && !file.startsWith(base + path.sep)) {
        res.writeHead(403).end();
        return;
      }
      let st = await fsp.stat(file).catch(() => null);
      if (st && st.isDirectory()) {
        file = path.join(file, 'index.html');
        st = await fsp.stat(file).catch(() => null);
      }
      if (!st || !st.isFile()) {
        res.writeHead(404, { 'content-type': 'text/plain' }).end('not found');
        return;
      }
      const ext = path.extname(file).toLowerCase();
      const type = MIME[ext] || 'application/octet-stream';
      // As an ordinary static host does (and as scripts/serve.mjs does): text and wasm go out
      // gzip-compressed to a client that accepts it; model files and media as they are.
      if (GZIP_TYPES.has(ext) && /\bgzip\b/.test(req.headers['accept-encoding'] || '')) {
        const body = await gzipped(file, st);
        res.writeHead(200, {
          'content-type': type,
          'content-encoding': 'gzip',
          vary: 'accept-encoding',
          'content-length': body.length,
          'cache-control': 'no-store',
        });
        res.end(req.method === 'HEAD' ? undefined : body);
        return;
      }
      res.writeHead(200, { 'content-type': type, 'content-length': st.size, 'cache-control': 'no-store' });
      if (req.method === 'HEAD') res.end();
      else fs.createReadStream(file).pipe(res);
    } catch (e) {
      res.writeHead(500, { 'content-type': 'text/plain' }).end(String(e));
    }
  });
  await new Promise((resolve, reject) => {
    server.once('error', reject);
    server.listen(0, '127.0.0.1', resolve);
  });
  const { port } = server.address();
  return {
    url: `http://127.0.0.1:${port}/`,
    port,
    requests,
    close: () =>
      new Promise((resolve) => {
        server.closeAllConnections?.();
        server.close(() => resolve());
      }),
  };
}

/** Launch headless chromium with the standard flags (extra args appended). */
export async function launchBrowser(extraArgs = []) {
  return chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: [...CHROMIUM_ARGS, ...extraArgs],
  });
}

/** True when the browser binary exists (tests skip with a message otherwise). */
export function haveChromium() {
  return fs.existsSync(CHROMIUM);
}

/** Save a full-page PNG screenshot as `artifacts/<name>.png`; returns the path. */
export async function screenshot(page, name, options = {}) {
  await fsp.mkdir(ARTIFACTS, { recursive: true });
  const file = path.join(ARTIFACTS, `${name}.png`);
  await page.screenshot({ path: file, fullPage: true, ...options });
  return file;
}

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

/** Read an iBUG `.pts` file (1-based) as 0-based image coordinates `[x0, y0, ...]` (the
 *  package's parser, the CLI's). */
export function readPts(file) {
  return Array.from(pkg().parsePts(fs.readFileSync(file, 'utf8')));
}

/**
 * Frames of a GRID clip folder (`NNNNNN.jpg`, with `000000.pts`) drawn by Chromium into a
 * `width x height` picture with the face where the webcam guide is (0.95 of its height 0.5 H,
 * centred, 0.04 H below the middle; www/js/placement.js `placeDefault`), on a dark blue
 * background. Frames whose index is in `black` (a Set) are all black. Returns the JPEGs
 * (base64) in order.
 */
async function guideFrames({ dir, count, width = 640, height = 480, black = new Set() }) {
  const browser = await launchBrowser();
  const frames = await serveStatic(dir);
  try {
    const page = await browser.newPage();
    await page.goto(`${frames.url}000000.jpg`);
    const v = readPts(path.join(dir, '000000.pts'));
    const xs = v.filter((_, i) => i % 2 === 0);
    const ys = v.filter((_, i) => i % 2 === 1);
    const face = { cx: (Math.min(...xs) + Math.max(...xs)) / 2, cy: (Math.min(...ys) + Math.max(...ys)) / 2, h: Math.max(...ys) - Math.min(...ys) };
    const scale = (0.5 * height * 0.95) / face.h;
    const dx = width / 2 - face.cx * scale;
    const dy = height / 2 + 0.04 * height - face.cy * scale;
    const n = count ?? fs.readdirSync(dir).filter((f) => /^\d{6}\.jpg$/.test(f)).length;
    return await page.evaluate(
      async ({ n, W, H, scale, dx, dy, black }) => {
        const c = document.createElement('canvas');
        c.width = W;
        c.height = H;
        const g = c.getContext('2d');
        const out = [];
        for (let i = 0; i < n; i++) {
          if (black.includes(i)) {
            g.fillStyle = '#000';
            g.fillRect(0, 0, W, H);
          } else {
            const img = new Image();
            img.src = `${String(i).padStart(6, '0')}.jpg`;
            await img.decode();
            g.fillStyle = '#203040';
            g.fillRect(0, 0, W, H);
            g.drawImage(img, dx, dy, img.width * scale, img.height * scale);
          }
          const blob = await new Promise((r) => c.toBlob(r, 'image/jpeg', 0.92));
          const bytes = new Uint8Array(await blob.arrayBuffer());
          let bin = '';
          for (let k = 0; k < bytes.length; k += 0x8000) bin += String.fromCharCode(...bytes.subarray(k, k + 0x8000));
          out.push(btoa(bin));
        }
        return out;
      },
      { n, W: width, H: height, scale, dx, dy, black: [...black] },
    );
  } finally {
    await browser.close();
    await frames.close();
  }
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
 * browser, manifest }` (`manifest`: the default models' manifest.json), set by then.
 */
export function pageSuite(www) {
  const suite = {};
  before(async () => {
    assertPageBuilt(www);
    suite.manifest = JSON.parse(fs.readFileSync(path.join(www, 'models', 'manifest.json'), 'utf8'));
    suite.server = await serveStatic(www);
    suite.browser = await launchBrowser();
  });
  after(async () => {
    await suite.browser?.close();
    await suite.server?.close();
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

/** Chromium's switches for a fake camera the page may use without asking (and autoplay). */
export const FAKE_CAMERA_ARGS = [
  '--autoplay-policy=no-user-gesture-required',
  '--use-fake-ui-for-media-stream',
  '--use-fake-device-for-media-stream',
];

/** `FAKE_CAMERA_ARGS` playing `file` (a `fakeCameraFile`) as the camera. */
export function fakeCameraArgs(file) {
  return [...FAKE_CAMERA_ARGS, `--use-file-for-fake-video-capture=${file}`];
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
 * A fake camera for Chromium (`--use-file-for-fake-video-capture=FILE`, which plays an MJPEG file
 * like a .y4m): `jpegs` (buffers) one after another, written to the temporary folder (removed
 * after the test `t`; never committed). Returns the file's path.
 */
export function mjpegCamera(t, jpegs, name = 'camera') {
  const file = path.join(os.tmpdir(), `facemimic-${name}-${process.pid}.mjpeg`);
  fs.writeFileSync(file, Buffer.concat(jpegs));
  t.after(() => fs.rmSync(file, { force: true }));
  return file;
}

/**
 * A fake camera (`mjpegCamera`) playing the frames of a GRID clip folder as a 640x480 MJPEG
 * with the face in the webcam guide. Returns the file's path.
 */
export async function fakeCameraFile(t, dir, { name = 'camera', black } = {}) {
  const jpegs = await guideFrames({ dir, black });
  return mjpegCamera(t, jpegs.map((b) => Buffer.from(b, 'base64')), name);
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

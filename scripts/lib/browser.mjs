// What the browser end-to-end tests (tests/e2e) and the benchmarks (scripts/bench) share:
// the repository's paths, the npm package in Node, a static server, headless Chromium with its
// flags, screenshots and fake cameras (playwright-core + Debian chromium).
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
import { chromium } from 'playwright-core';

/** The repository root (two levels above this file: scripts/lib/). */
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

/** Read an iBUG `.pts` file (1-based) as 0-based image coordinates `[x0, y0, ...]` (the
 *  package's parser, the CLI's). */
export function readPts(file) {
  return Array.from(pkg().parsePts(fs.readFileSync(file, 'utf8')));
}

/** The flat skin tone of the drawn occluders ([r, g, b]). */
export const OCCLUDER_SKIN = [201, 152, 124];
/** Bits of the frame marker `clipFrames` draws (`marker`) and `readMarker` reads. */
const MARKER_BITS = 12;
/** Side of one marker block, in pixels (top-left corner, 4 px in). */
const MARKER_BLOCK = 10;

/**
 * Frames of a GRID clip folder (`NNNNNN.jpg` with its `.pts`) drawn by Chromium into a
 * `width x height` picture with the face where the webcam guide is (0.95 of its height 0.5 H,
 * centred, 0.04 H below the middle, placed from frame 0; www/js/placement.js `placeDefault`),
 * on a dark blue background. Each entry of `frames` is a clip frame index or
 * `{ i, black, rotate, cover, marker }`: `black` draws an all-black picture; `rotate` turns the
 * picture by that many degrees about the face's centre; `cover` paints a flat skin-coloured
 * occluder (`OCCLUDER_SKIN`): "mouth" (a rectangle over the mouth), "lower" (everything from the
 * nose tip down: a hand over the lower face), "hand" (a palm and four fingers entering from the
 * left over the cheek and mouth), "eyes" (a bar); `marker` draws that number in `MARKER_BITS`
 * black and white blocks in the top-left corner (`readMarker`). Returns `{ jpegs, truth }`:
 * the JPEGs (Buffers) in order and each frame's 68 points where they now are (null for black).
 */
export async function clipFrames({ dir, frames, width = 640, height = 480 }) {
  const names = fs.readdirSync(dir).filter((f) => /^\d{6}\.jpg$/.test(f)).sort();
  const specs = (frames ?? names.map((_, i) => i)).map((f) => (typeof f === 'number' ? { i: f } : f));
  const pts = specs.map((f) => (f.black ? null : readPts(path.join(dir, names[f.i].replace('.jpg', '.pts')))));
  const v = readPts(path.join(dir, names[0].replace('.jpg', '.pts')));
  const xs = v.filter((_, i) => i % 2 === 0);
  const ys = v.filter((_, i) => i % 2 === 1);
  const face = { cx: (Math.min(...xs) + Math.max(...xs)) / 2, cy: (Math.min(...ys) + Math.max(...ys)) / 2, h: Math.max(...ys) - Math.min(...ys) };
  const scale = (0.5 * height * 0.95) / face.h;
  const dx = width / 2 - face.cx * scale;
  const dy = height / 2 + 0.04 * height - face.cy * scale;
  const browser = await launchBrowser();
  const server = await serveStatic(dir);
  try {
    const page = await browser.newPage();
    await page.goto(`${server.url}${names[0]}`);
    const list = specs.map((f, k) => ({ ...f, name: f.black ? null : names[f.i], lm: pts[k] }));
    const out = await page.evaluate(
      async ({ list, W, H, scale, dx, dy, SKIN, BITS, BLOCK }) => {
        const c = document.createElement('canvas');
        c.width = W;
        c.height = H;
        const g = c.getContext('2d');
        const res = [];
        for (const f of list) {
          let truth = null;
          if (f.black) {
            g.fillStyle = '#000';
            g.fillRect(0, 0, W, H);
          } else {
            const img = new Image();
            img.src = f.name;
            await img.decode();
            g.fillStyle = '#203040';
            g.fillRect(0, 0, W, H);
            // The face's centre in the picture, the pivot of the rotation.
            const [px, py] = [W / 2, H / 2 + 0.04 * H];
            const a = ((f.rotate || 0) * Math.PI) / 180;
            const [cs, sn] = [Math.cos(a), Math.sin(a)];
            const place = (x, y) => {
              const [u, v] = [x * scale + dx - px, y * scale + dy - py];
              return [px + cs * u - sn * v, py + sn * u + cs * v];
            };
            g.save();
            g.translate(px, py);
            g.rotate(a);
            g.translate(-px, -py);
            g.drawImage(img, dx, dy, img.width * scale, img.height * scale);
            g.restore();
            truth = [];
            for (let k = 0; k < 68; k++) truth.push(...place(f.lm[2 * k], f.lm[2 * k + 1]));
            const P = (k) => [truth[2 * k], truth[2 * k + 1]];
            const box = (from, to) => {
              const q = [];
              for (let k = from; k <= to; k++) q.push(P(k));
              const qx = q.map((p) => p[0]), qy = q.map((p) => p[1]);
              return [Math.min(...qx), Math.max(...qx), Math.min(...qy), Math.max(...qy)];
            };
            const iod = Math.hypot(P(45)[0] - P(36)[0], P(45)[1] - P(36)[1]);
            g.fillStyle = `rgb(${SKIN.join(',')})`;
            if (f.cover === 'mouth') {
              const [x0, x1, y0, y1] = box(48, 67);
              const [w, h] = [(x1 - x0) * 1.6, (y1 - y0) * 2.2];
              g.fillRect((x0 + x1) / 2 - w / 2, (y0 + y1) / 2 - h / 2, w, h);
            } else if (f.cover === 'lower') {
              const [x0, x1] = box(0, 16);
              const top = P(30)[1];
              g.fillRect(x0 - 0.3 * iod, top, x1 - x0 + 0.6 * iod, H - top);
            } else if (f.cover === 'eyes') {
              const [x0, x1, y0, y1] = box(36, 47);
              g.fillRect(x0 - 0.3 * iod, y0 - 0.2 * iod, x1 - x0 + 0.6 * iod, y1 - y0 + 0.4 * iod);
            } else if (f.cover === 'hand') {
              const m = [(P(48)[0] + P(54)[0]) / 2, (P(51)[1] + P(57)[1]) / 2];
              const palm = [P(3)[0] - 0.2 * iod, m[1] + 0.1 * iod];
              const ell = (cx, cy, rx, ry, rot) => { g.beginPath(); g.ellipse(cx, cy, rx, ry, rot, 0, 2 * Math.PI); g.fill(); };
              ell(palm[0], palm[1], 0.7 * iod, 0.55 * iod, 0);
              ell(palm[0] - 1.2 * iod, palm[1] + 0.5 * iod, 1.2 * iod, 0.4 * iod, 0.3);
              for (let k = 0; k < 4; k++) ell(palm[0] + 0.85 * iod, palm[1] - 0.45 * iod + 0.3 * iod * k, 0.5 * iod, 0.12 * iod, -0.1);
            }
          }
          if (f.marker !== undefined) {
            for (let b = 0; b < BITS; b++) {
              g.fillStyle = (f.marker >> b) & 1 ? '#fff' : '#000';
              g.fillRect(4 + b * BLOCK, 4, BLOCK, BLOCK);
            }
          }
          const blob = await new Promise((r) => c.toBlob(r, 'image/jpeg', 0.92));
          const bytes = new Uint8Array(await blob.arrayBuffer());
          let bin = '';
          for (let k = 0; k < bytes.length; k += 0x8000) bin += String.fromCharCode(...bytes.subarray(k, k + 0x8000));
          res.push({ jpeg: btoa(bin), truth });
        }
        return res;
      },
      { list, W: width, H: height, scale, dx, dy, SKIN: OCCLUDER_SKIN, BITS: MARKER_BITS, BLOCK: MARKER_BLOCK },
    );
    return { jpegs: out.map((o) => Buffer.from(o.jpeg, 'base64')), truth: out.map((o) => o.truth) };
  } finally {
    await browser.close();
    await server.close();
  }
}

/**
 * The source of a function (run in the page: `new Function` or `page.evaluate`) reading the
 * marker `clipFrames` drew into RGBA pixels `data` of width `width`: `(data, width) => number`.
 */
export const READ_MARKER = `(data, width) => {
  let n = 0;
  for (let b = 0; b < ${MARKER_BITS}; b++) {
    const x = 4 + b * ${MARKER_BLOCK} + ${MARKER_BLOCK / 2}, y = 4 + ${MARKER_BLOCK / 2};
    const i = 4 * (y * width + x);
    if (data[i] + data[i + 1] + data[i + 2] > 3 * 128) n |= 1 << b;
  }
  return n;
}`;

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
export async function fakeCameraFile(t, dir, { name = 'camera', black = new Set() } = {}) {
  const n = fs.readdirSync(dir).filter((f) => /^\d{6}\.jpg$/.test(f)).length;
  const frames = Array.from({ length: n }, (_, i) => (black.has(i) ? { i, black: true } : i));
  const { jpegs } = await clipFrames({ dir, frames });
  return mjpegCamera(t, jpegs, name);
}

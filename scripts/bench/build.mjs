// Building a model from 20 frames in Chromium, in the page's build worker (a script, not a test):
// GRID spk02's 20 training frames (360x288, decoded by the browser), (a) without landmarks: the
// face finder places them inside buildModel, (b) with the .pts landmarks given. Prints the time
// inside the worker (buildModel + toBytes) and from the page's request to the bytes back, per
// run (each in a fresh worker, as the page does; one run first to warm the caches), and the
// medians, as JSON; also the longest gap between the page's animation frames (while
// the builds run in the worker) and the finder's time per frame (FaceFinder.find, enrolFace).
//   node scripts/bench/build.mjs [--runs 5]
// Needs www/pkg (scripts/build-wasm.sh) and www/models (scripts/build-models.sh).
import fs from 'node:fs';
import path from 'node:path';
import { ROOT, serveStatic, launchBrowser } from '../lib/browser.mjs';

const args = process.argv.slice(2);
const runs = Number(args[args.indexOf('--runs') + 1]) || 5;
const CLIP = path.join(ROOT, 'data', 'grid', 'spk02_brbk7n');
const stems = fs.readFileSync(path.join(CLIP, 'train20.txt'), 'utf8').split('\n').map((s) => s.trim()).filter(Boolean);
const frames = stems.map((stem) => {
  const pts = fs.readFileSync(path.join(CLIP, `${stem}.pts`), 'utf8');
  return {
    jpeg: fs.readFileSync(path.join(CLIP, `${stem}.jpg`)).toString('base64'),
    landmarks: pts.slice(pts.indexOf('{') + 1, pts.indexOf('}')).trim().split(/\s+/).map((v) => Number(v) - 1),
  };
});

const server = await serveStatic('www');
const browser = await launchBrowser();
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 900 } });
  page.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  await page.goto(server.url);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 60_000 });
  const result = await page.evaluate(async ({ frames, runs }) => {
    const { buildInWorker } = await import('./js/build-client.js');
    const decoded = [];
    for (const f of frames) {
      const bytes = Uint8Array.from(atob(f.jpeg), (c) => c.charCodeAt(0));
      const bmp = await createImageBitmap(new Blob([bytes], { type: 'image/jpeg' }));
      const c = new OffscreenCanvas(bmp.width, bmp.height);
      const g = c.getContext('2d');
      g.drawImage(bmp, 0, 0);
      const d = g.getImageData(0, 0, bmp.width, bmp.height);
      decoded.push({ rgba: new Uint8Array(d.data.buffer), width: bmp.width, height: bmp.height, landmarks: f.landmarks });
    }
    let gap = 0;
    let last = performance.now();
    let on = true;
    const tick = (t) => {
      gap = Math.max(gap, t - last);
      last = t;
      if (on) requestAnimationFrame(tick);
    };
    requestAnimationFrame(tick);
    const out = {};
    for (const [label, withLandmarks] of [['finder landmarks', false], ['landmarks given', true]]) {
      const rows = [];
      for (let r = 0; r < runs + 1; r++) {
        const opts = {
          name: 'bench',
          frames: decoded.map((f) => ({ rgba: f.rgba.slice(), width: f.width, height: f.height, landmarks: withLandmarks ? f.landmarks : undefined })),
        };
        const t0 = performance.now();
        const res = await buildInWorker(opts);
        const total = performance.now() - t0;
        if (res.skipped.length) throw new Error(`frames skipped: ${res.skipped}`);
        if (r > 0) rows.push({ worker: res.ms, total }); // run 0 warms the HTTP and code caches
      }
      const med = (k) => rows.map((x) => x[k]).sort((a, b) => a - b)[rows.length >> 1];
      out[label] = { runs: rows.map((x) => [Math.round(x.worker), Math.round(x.total)]), medianWorkerMs: Math.round(med('worker')), medianTotalMs: Math.round(med('total')) };
    }
    on = false;
    out.longestFrameGapMs = Math.round(gap);
    // Where the time goes: the finder alone (FaceFinder.find) and the enrolment finder
    // (enrolFace: find + the mirror pass), per frame, on this thread.
    const fm = await import('./pkg/facemimic.js');
    const finder = new fm.FaceFinder();
    const per = (fn) => {
      fn(decoded[0]);
      const t0 = performance.now();
      for (const f of decoded) fn(f);
      return Math.round((performance.now() - t0) / decoded.length);
    };
    out.findMsPerFrame = per((f) => finder.find(f.rgba, f.width, f.height));
    out.enrolFaceMsPerFrame = per((f) => fm.enrolFace(f.rgba, f.width, f.height));
    finder.free();
    out.frames = `${decoded.length} x ${decoded[0].width}x${decoded[0].height}`;
    out.hardwareConcurrency = navigator.hardwareConcurrency;
    return out;
  }, { frames, runs });
  console.log(JSON.stringify(result, null, 2));
} finally {
  await browser.close();
  await server.close();
}

// How the page runs while it looks for a face (a script, not a test): the webcam source on
// Chromium's fake camera (no face, so the tracker keeps asking for faces), the FaceFinder in its
// Web Worker. Prints the finder's time per 640x480 frame in the worker, the gaps between the
// page's animation frames meanwhile, and what one find costs on the main thread (the stall the
// worker avoids).
//   node scripts/bench/page-finder.mjs [--seconds 6]
// Needs www/pkg (scripts/build-wasm.sh) and www/models (scripts/build-models.sh).
import { serveStatic, launchBrowser } from '../lib/browser.mjs';

const args = process.argv.slice(2);
const i = args.indexOf('--seconds');
const seconds = i >= 0 ? Number(args[i + 1]) : 6;

const server = await serveStatic('www');
const browser = await launchBrowser(['--autoplay-policy=no-user-gesture-required', '--use-fake-ui-for-media-stream', '--use-fake-device-for-media-stream']);
try {
  const page = await browser.newPage({ viewport: { width: 1440, height: 1400 } });
  page.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  await page.goto(server.url);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30000 });
  await page.selectOption('#source-kind', 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="placing"]', { timeout: 20000 });
  await page.waitForTimeout(1500); // the worker's first find (loading the package) is not counted
  const r = await page.evaluate(async (seconds) => {
    const s = window.facemimicTracking;
    const n0 = s.findLog.length;
    const gaps = [];
    let last = performance.now();
    await new Promise((done) => {
      const t0 = last;
      const tick = (now) => {
        gaps.push(now - last);
        last = now;
        if (now - t0 < seconds * 1000) requestAnimationFrame(tick);
        else done();
      };
      requestAnimationFrame(tick);
    });
    const finds = s.findLog.slice(n0).map((f) => f.ms).sort((a, b) => a - b);
    gaps.sort((a, b) => a - b);
    const img = s.media.workImage();
    const { FaceFinder } = await import(new URL('pkg/facemimic.js', document.baseURI).href);
    const f = new FaceFinder();
    f.find(img.data, img.width, img.height);
    const main = [];
    for (let k = 0; k < 5; k++) {
      const t = performance.now();
      f.find(img.data, img.width, img.height);
      main.push(performance.now() - t);
    }
    f.free();
    main.sort((a, b) => a - b);
    const med = (a) => +a[a.length >> 1].toFixed(1);
    return {
      frame: `${img.width}x${img.height}`,
      findsInWorker: finds.length,
      workerFindMsMedian: finds.length ? med(finds) : null,
      animationFrames: gaps.length,
      frameGapMs: { median: med(gaps), p95: +gaps[Math.floor(gaps.length * 0.95)].toFixed(1), max: +gaps.at(-1).toFixed(1) },
      mainThreadFindMsMedian: med(main),
    };
  }, seconds);
  console.log(JSON.stringify(r, null, 2));
} finally {
  await browser.close();
  await server.close();
}

// Counts the page's JS -> wasm calls per frame (and putImageData calls) in headless Chromium:
// the package's wasm exports are replaced by counting wrappers (the generated glue is rewritten
// as it is served), the page plays its recorded track with its four targets, and the counts over
// a run of frames are divided by the frames rendered. A script, not a test.
//   node scripts/bench/calls.mjs [--frames N] [--compare on|off] [--app FILE]
//     --compare   open or close the compare view (one target with every method; as the page
//                 starts when not given)
//     --app FILE  serve FILE as www/app.js (e.g. an earlier version, to count "before")
// Prints JSON: { frames, perFrame: { api, exports, putImageData }, byName: { export: count } }.
// `api` counts the package's class and function calls (exports named like `cloner_update`);
// `exports` every export called (the glue's allocations for arguments included).
// Needs www/pkg (scripts/build-wasm.sh) and www/models (scripts/build-models.sh).
import fs from 'node:fs';
import { serveStatic, launchBrowser } from '../lib/browser.mjs';

const args = process.argv.slice(2);
const opt = (name, dflt) => {
  const i = args.indexOf(`--${name}`);
  return i >= 0 && args[i + 1] ? args[i + 1] : dflt;
};
const frames = Number(opt('frames', '120'));
const appFile = opt('app', '');
const compare = opt('compare', '');

// Installed before the page's scripts: the counters and the Proxy maker the glue calls.
function instrument() {
  const counts = new Map();
  let puts = 0;
  window.__fmCalls = { counts, puts: () => puts, reset: () => { counts.clear(); puts = 0; } };
  // A copy of the exports with every function counted (a Proxy cannot stand in for them: the
  // exports object is frozen, and a Proxy's get must then return the very same values).
  globalThis.__fmCount = (exports) => {
    const counted = {};
    for (const [key, v] of Object.entries(exports)) {
      counted[key] =
        typeof v !== 'function'
          ? v
          : (...a) => {
              counts.set(key, (counts.get(key) ?? 0) + 1);
              return v(...a);
            };
    }
    return counted;
  };
  for (const proto of [CanvasRenderingContext2D.prototype, OffscreenCanvasRenderingContext2D.prototype]) {
    const put = proto.putImageData;
    proto.putImageData = function (...a) {
      puts++;
      return put.apply(this, a);
    };
  }
}

const server = await serveStatic('www');
const browser = await launchBrowser();
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 2400 } });
  page.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  page.on('console', (m) => m.type() === 'error' && console.error(`console: ${m.text()}`));
  await page.addInitScript(instrument);
  await page.route('**/pkg/facemimic.js', async (route) => {
    const res = await route.fetch();
    const body = (await res.text()).replace(
      /wasm = instance\.exports;/,
      'wasm = globalThis.__fmCount ? globalThis.__fmCount(instance.exports) : instance.exports;',
    );
    if (!body.includes('__fmCount')) throw new Error('facemimic.js: the exports assignment was not found');
    const headers = { ...res.headers() };
    delete headers['content-encoding'];
    delete headers['content-length'];
    await route.fulfill({ status: res.status(), body, headers });
  });
  if (appFile) {
    const body = fs.readFileSync(appFile, 'utf8');
    await page.route('**/app.js', (route) => route.fulfill({ body, contentType: 'text/javascript' }));
  }
  await page.goto(server.url);
  await page.waitForFunction(() => Number(document.body.dataset.frames || 0) > 10, null, { timeout: 120000 });
  if (compare) {
    await page.evaluate((want) => {
      const on = document.getElementById('compare-on');
      if (on.checked !== want) on.click();
    }, compare === 'on');
    await page.waitForTimeout(500);
  }
  const targets = await page.evaluate(() => document.querySelectorAll('#targets canvas, .target canvas').length);
  const start = await page.evaluate(() => {
    window.__fmCalls.reset();
    return Number(document.body.dataset.frames);
  });
  await page.waitForFunction((n) => Number(document.body.dataset.frames) >= n, start + frames, { timeout: 120000 });
  const out = await page.evaluate((s) => {
    const n = Number(document.body.dataset.frames) - s;
    const byName = Object.fromEntries([...window.__fmCalls.counts].sort((a, b) => b[1] - a[1]));
    const total = (f) => Object.entries(byName).filter(([k]) => f(k)).reduce((a, [, v]) => a + v, 0);
    const internal = (k) => k.startsWith('__') || k === 'memory';
    return {
      frames: n,
      perFrame: {
        api: total((k) => !internal(k)) / n,
        exports: total(() => true) / n,
        putImageData: window.__fmCalls.puts() / n,
      },
      byName: Object.fromEntries(Object.entries(byName).map(([k, v]) => [k, +(v / n).toFixed(2)])),
    };
  }, start);
  const compareShown = await page.evaluate(() => !document.getElementById('compare').hidden);
  console.log(JSON.stringify({ app: appFile || 'www/app.js', compareShown, targetCanvases: targets, ...out }, null, 1));
} finally {
  await browser.close();
  await server.close();
}

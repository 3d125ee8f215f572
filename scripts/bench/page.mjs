// Runs www/bench.html in headless Chromium and prints its JSON summary (a script, not a test).
//   node scripts/bench/page.mjs [--frames N] [--method NAME (default: the core's)] [--mesh] [--raster tiny-skia|scanline]
//     [--composite FRAMES]  (source + targets composited at 640x480, follow-pose; 0 skips)
//     [--finder RUNS]  (face finder runs on a 640x480 frame; 0 skips)
//     [--track PASSES] [--lost FRAMES]  (tracking the bundled clip: ms per fit, and per lost
//                      frame while the finder searches; --track 0 skips)
// Both rasterisers are measured; --raster picks the headline (default scanline, the page's default).
// Needs www/pkg (scripts/build-wasm.sh) and www/models (scripts/build-models.sh).
import { serveStatic, launchBrowser, screenshot } from '../lib/browser.mjs';

const args = process.argv.slice(2);
const opt = (name, dflt) => {
  const i = args.indexOf(`--${name}`);
  return i >= 0 && args[i + 1] ? args[i + 1] : dflt;
};
const method = opt('method', '');
const query = new URLSearchParams({
  ...(method ? { method } : {}),
  frames: opt('frames', '300'),
  warmup: opt('warmup', '30'),
  targets: opt('targets', '4'),
  mesh: args.includes('--mesh') ? '1' : '0',
  raster: opt('raster', 'scanline'),
  finder: opt('finder', '20'),
  track: opt('track', '6'),
  lost: opt('lost', '12'),
  composite: opt('composite', '300'),
});

const server = await serveStatic('www');
const browser = await launchBrowser();
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 1000 } });
  page.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  await page.goto(`${server.url}bench.html?${query}`);
  await page.waitForSelector('#result[data-done="1"]', { timeout: 300000 });
  const text = await page.textContent('#result');
  await screenshot(page, 'bench');
  console.log(text);
  if (JSON.parse(text).error) process.exitCode = 1;
} finally {
  await browser.close();
  await server.close();
}

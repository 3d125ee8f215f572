// End-to-end tests of the demo page (www/): served from 127.0.0.1, driven in Debian's headless
// chromium through playwright-core. Needs the wasm package (scripts/build-wasm.sh -> www/pkg/)
// and the default models (scripts/build-models.sh -> www/models/). Screenshots go to artifacts/.
//
//   node --test --test-concurrency=1 tests/e2e/

import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { ROOT, screenshot, canvasPixels, meanAbsDiff, dropFiles as dropFilesOn } from './lib.mjs';
import { MODELS, TARGETS, SOURCE, pageTests, assertFace, assertPicture, pause, setSlider } from './page-lib.mjs';

const { suite, open } = pageTests();

/** Drop model files on an element (lib.mjs `dropFiles`, as `application/octet-stream`). */
const dropFiles = (page, selector, files) => dropFilesOn(page, selector, files, 'application/octet-stream');

function modelBytes(file) {
  return fs.readFileSync(path.join(MODELS, file));
}

test('the page opens playing, with the source painted as a face and every default target as its picture', async (t) => {
  const { page, errors, offOrigin, frames } = await open(t);
  const nTargets = suite.manifest.targets.length;
  assert.ok(nTargets >= 4, `the manifest lists ${nTargets} default targets`);
  assert.equal(await page.locator(TARGETS).count(), nTargets);
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing', 'the track plays on load');
  await frames(3);
  await assertFace(page, SOURCE, 'source');
  for (let i = 0; i < nTargets; i++) await assertPicture(page, `${TARGETS} >> nth=${i}`, `target ${i + 1}`);
  // The targets are different people: their pixels differ.
  const a = await canvasPixels(page, `${TARGETS} >> nth=0`);
  const b = await canvasPixels(page, `${TARGETS} >> nth=1`);
  assert.ok(meanAbsDiff(a, b) > 3, 'two targets look identical');
  // One slider per source mode.
  const info = await page.$$eval('#shape-sliders input[type=range], #app-sliders input[type=range]', (els) => els.length);
  assert.ok(info > 2, `only ${info} sliders`);
  // Readouts show numbers.
  await page.waitForFunction(() => /^\d+$/.test(document.getElementById('ro-fps').textContent));
  const map = await page.textContent('#ro-map');
  assert.match(map, /^\d+\.\d+ ms$/);
  await screenshot(page, 'page-desktop');
  assert.deepEqual(offOrigin, [], 'requests left the origin');
  assert.deepEqual(errors, [], 'page errors');
});

test('backing stores are the CSS size times devicePixelRatio, and the phone layout fits', async (t) => {
  const { page, errors, frames } = await open(t, { width: 390, height: 844, dpr: 2 });
  await frames(2);
  const sizes = await page.$$eval('canvas.face', (cs) =>
    cs
      .filter((c) => c.offsetParent !== null)
      .map((c) => {
        const r = c.getBoundingClientRect();
        return { w: c.width, h: c.height, cw: r.width * devicePixelRatio, ch: r.height * devicePixelRatio };
      }),
  );
  assert.ok(sizes.length >= 5);
  for (const s of sizes) {
    assert.ok(Math.abs(s.w - s.cw) <= 1 && Math.abs(s.h - s.ch) <= 1, `canvas ${s.w}x${s.h} for ${s.cw}x${s.ch} device px`);
  }
  const overflow = await page.evaluate(() => document.documentElement.scrollWidth - window.innerWidth);
  assert.ok(overflow <= 0, `the page scrolls sideways by ${overflow}px on a phone`);
  await assertFace(page, SOURCE, 'source (phone)');
  await assertPicture(page, `${TARGETS} >> nth=0`, 'target 1 (phone)');
  await screenshot(page, 'page-phone', { fullPage: false });
  // Faces off screen are not drawn; scrolled into view, they are (the compare view's last method).
  await page.locator('#compare-grid canvas >> nth=-1').scrollIntoViewIfNeeded();
  await frames(3);
  await assertFace(page, '#compare-grid canvas >> nth=-1', 'compare view after scrolling (phone)');
  await page.locator('#inspect-mode').scrollIntoViewIfNeeded();
  await frames(3);
  await assertFace(page, '#inspect-mean', 'inspector after scrolling (phone)');
  await screenshot(page, 'page-phone-full');
  assert.deepEqual(errors, []);
});

test('play advances the track at 25 fps and the sliders follow it; space toggles', async (t) => {
  const { page, errors } = await open(t);
  await pause(page);
  await page.$eval('#scrub', (el) => {
    el.value = '0';
    el.dispatchEvent(new Event('input', { bubbles: true }));
  });
  assert.match(await page.textContent('#frame-counter'), /^1 \/ \d+$/);
  const slidersBefore = await page.$$eval('#shape-sliders input', (els) => els.map((e) => e.value).join());
  // Click and read the clock in the page, so the test's own latency does not count.
  const t0 = await page.evaluate(() => {
    document.getElementById('play').click();
    return performance.now();
  });
  await page.waitForTimeout(1200);
  const { counter, t1 } = await page.evaluate(() => ({
    counter: document.getElementById('frame-counter').textContent,
    t1: performance.now(),
  }));
  const elapsed = (t1 - t0) / 1000;
  const frame = Number(counter.split('/')[0]) - 1;
  // 25 frames per second of track time (allow for start-up and a loaded machine).
  assert.ok(frame > 5 && frame <= Math.ceil(elapsed * 25) + 1, `frame ${frame} after ${elapsed.toFixed(2)} s`);
  const slidersAfter = await page.$$eval('#shape-sliders input', (els) => els.map((e) => e.value).join());
  assert.notEqual(slidersAfter, slidersBefore, 'the sliders did not follow the track');
  // Space pauses (focus on the page body, not a button).
  await page.evaluate(() => document.activeElement?.blur());
  await page.keyboard.press('Space');
  assert.equal(await page.getAttribute('#play', 'data-state'), 'paused');
  const stopped = await page.textContent('#frame-counter');
  await page.waitForTimeout(300);
  assert.equal(await page.textContent('#frame-counter'), stopped, 'paused track still moves');
  await page.keyboard.press('Space');
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');
  assert.deepEqual(errors, []);
});

test('dropping valid models adds and replaces targets; removing one works', async (t) => {
  const { page, errors, frames } = await open(t);
  const loaded = new Set(suite.manifest.targets);
  const spare = (suite.manifest.library || []).filter((f) => !loaded.has(f));
  assert.ok(spare.length >= 2, 'the library needs two models that are not default targets');
  const n0 = await page.locator(TARGETS).count();

  await dropFiles(page, '#add-card', [{ name: spare[0], bytes: modelBytes(spare[0]) }]);
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 1);
  await frames(2);
  const name0 = spare[0].replace(/\.fmm$/, '');
  assert.equal(await page.textContent('.face-card.target >> nth=-1 >> .name'), name0);
  await assertPicture(page, `${TARGETS} >> nth=-1`, `dropped ${spare[0]}`);

  // The file picker adds too.
  await page.setInputFiles('#file-input', path.join(MODELS, spare[1]));
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 2);

  // Dropping on a target replaces it.
  await dropFiles(page, '.face-card.target >> nth=0', [{ name: spare[0], bytes: modelBytes(spare[0]) }]);
  await page.waitForFunction((name) => document.querySelector('.face-card.target .name').textContent === name, name0);
  assert.equal(await page.locator(TARGETS).count(), n0 + 2);

  // Remove the first target.
  await page.click('.face-card.target >> nth=0 >> [data-action=remove]');
  assert.equal(await page.locator(TARGETS).count(), n0 + 1);
  await frames(2);
  await assertPicture(page, `${TARGETS} >> nth=0`, 'target 1 after removal');
  await screenshot(page, 'page-models-added');
  assert.deepEqual(errors, []);
});

test('dropping a model on the source swaps the source; the track comes back with the bundled one', async (t) => {
  const { page, errors, frames } = await open(t);
  const other = (suite.manifest.library || []).find((f) => !suite.manifest.targets.includes(f));
  assert.ok(other, 'no spare model in the library');
  const before = await page.$$eval('#shape-sliders input', (els) => els.length);
  await dropFiles(page, '.face-card.source', [{ name: other, bytes: modelBytes(other) }]);
  const name = other.replace(/\.fmm$/, '');
  await page.waitForFunction((n) => document.querySelector('.face-card.source .name').textContent === n, name);
  // The recorded track belongs to the bundled source: the new source is driven by the sliders.
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'sliders');
  // Without the bundled source there is no recorded track; the sliders (and, with a package that
  // can track, the video and webcam sources, which work with any model) remain.
  const kinds = await page.$$eval('#source-kind option', (os) => os.map((o) => o.value));
  assert.ok(kinds.includes('sliders') && !kinds.includes('track'), `source menu: ${kinds}`);
  assert.equal(await page.getAttribute('#play', 'data-state'), 'paused');
  assert.ok(await page.isDisabled('#play'), 'play is offered without a track');
  const info = await page.$$eval('#shape-sliders input', (els) => els.length);
  assert.ok(info > 0);
  await frames(2);
  await assertFace(page, SOURCE, `source ${name}`);
  const a = await canvasPixels(page, `${TARGETS} >> nth=0`);
  await setSlider(page, 'p-shape-0', 2.5);
  await frames(2);
  assert.ok(meanAbsDiff(a, await canvasPixels(page, `${TARGETS} >> nth=0`)) > 0.5, 'the new source does not drive the targets');

  // The bundled source back: the track is offered again and plays.
  await dropFiles(page, '.face-card.source', [{ name: suite.manifest.source, bytes: modelBytes(suite.manifest.source) }]);
  await page.waitForFunction(() => document.querySelector('#source-kind').value === 'track');
  assert.equal(await page.$$eval('#shape-sliders input', (els) => els.length), before);
  await page.click('#play');
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');
  assert.deepEqual(errors, []);
});

test('bad files show an error naming the file and the reason; the page keeps rendering', async (t) => {
  const { page, frames } = await open(t);
  const n0 = await page.locator(TARGETS).count();
  const good = modelBytes(suite.manifest.targets[0]);

  const corrupt = Buffer.from(good);
  for (let i = 200; i < corrupt.length; i += 97) corrupt[i] ^= 0x5a; // bit rot after the header
  const future = Buffer.from(good);
  future.writeUInt32LE(7, 8); // format version 7
  const junk = Buffer.from('this is not a facemimic model\n');

  const cases = [
    ['corrupt.fmm', corrupt, /checksum|crc|corrupt/i],
    ['from-the-future.fmm', future, /version/i],
    ['notes.fmm', junk, /magic|not a|model file/i],
  ];
  for (const [name, bytes, reason] of cases) {
    await dropFiles(page, '#add-card', [{ name, bytes }]);
    const toast = page.locator('.toast.error', { hasText: name });
    await toast.waitFor({ timeout: 5000 });
    const text = await toast.textContent();
    assert.match(text, reason, `error for ${name} gives the reason: ${text}`);
  }
  // Dropped on the source, a bad file also leaves the source as it was.
  await dropFiles(page, '.face-card.source', [{ name: 'corrupt-source.fmm', bytes: corrupt }]);
  await page.locator('.toast.error', { hasText: 'corrupt-source.fmm' }).waitFor();
  assert.equal(await page.textContent('.face-card.source .name'), suite.manifest.source.replace(/\.fmm$/, ''));

  assert.equal(await page.locator(TARGETS).count(), n0, 'a bad file changed the targets');
  await screenshot(page, 'page-bad-files');

  // Still playing and still drawing faces.
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');
  const f0 = await page.textContent('#frame-counter');
  await frames(5);
  await page.waitForTimeout(300);
  assert.notEqual(await page.textContent('#frame-counter'), f0, 'playback stopped after the errors');
  await assertPicture(page, `${TARGETS} >> nth=0`, 'target 1 after the errors');

  // The notices are dismissible.
  const before = await page.locator('.toast.error').count();
  await page.click('.toast.error >> nth=0 >> .toast-close');
  assert.equal(await page.locator('.toast.error').count(), before - 1);
});

test('a model built in another reference frame is refused as a target', async (t) => {
  const bin = path.join(process.env.CARGO_TARGET_DIR || path.join(ROOT, 'target'), 'release', 'facemimic');
  if (!fs.existsSync(bin)) {
    t.skip('target/release/facemimic not built (scripts/build-models.sh builds it)');
    return;
  }
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'facemimic-e2e-'));
  t.after(() => fs.rmSync(dir, { recursive: true, force: true }));
  const clip = path.join(ROOT, 'data', 'grid', 'spk02_brbk7n');
  const out = path.join(dir, 'own-frame.fmm');
  // Built with --own-frame: spk02 in its own reference frame, incompatible with the canonical one.
  execFileSync(bin, ['build', '--own-frame', '--name', 'own-frame', '--out', out, '--list', path.join(clip, 'train20.txt')], {
    stdio: 'pipe',
  });
  const { page } = await open(t);
  const n0 = await page.locator(TARGETS).count();
  await dropFiles(page, '#add-card', [{ name: 'own-frame.fmm', bytes: fs.readFileSync(out) }]);
  const toast = page.locator('.toast.error', { hasText: 'own-frame.fmm' });
  await toast.waitFor({ timeout: 5000 });
  assert.match(await toast.textContent(), /incompatible|frame/i);
  assert.equal(await page.locator(TARGETS).count(), n0);
});

test('the inspector animates a mode and lists the variance shares', async (t) => {
  const { page, errors, frames } = await open(t);
  // The page draws only what is on screen: bring the inspector into view.
  await page.locator('#inspect-mode').scrollIntoViewIfNeeded();
  await frames(3);
  await assertFace(page, '#inspect-mean', 'inspector mean');
  // It moves within a few seconds (sampled every 400 ms: a loaded machine may skip frames).
  const a = await canvasPixels(page, '#inspect-mode');
  let moved = 0;
  for (let i = 0; i < 8 && moved <= 0.1; i++) {
    await page.waitForTimeout(400);
    moved = meanAbsDiff(a, await canvasPixels(page, '#inspect-mode'));
  }
  assert.ok(moved > 0.1, `the mode animation is still (mean change ${moved})`);
  const bars = await page.locator('#inspect-bars .bar').count();
  assert.equal(bars, await page.locator('#shape-sliders input').count());
  await page.click('label:has(input[value="appearance"][name="inspect-kind"])');
  assert.equal(await page.locator('#inspect-bars .bar').count(), await page.locator('#app-sliders input').count());
  await page.click('#inspect-bars .bar >> nth=2');
  assert.match(await page.textContent('#inspect-mode-caption'), /^Appearance 3 /);
  // Inspect a target.
  await page.selectOption('#inspect-model', '0');
  const targetName = await page.textContent('.face-card.target >> nth=0 >> .name');
  await page.waitForFunction((n) => document.querySelector('#inspect-info dd')?.textContent === n, targetName);
  await screenshot(page, 'page-inspector', { fullPage: false });
  assert.deepEqual(errors, []);
});

test('PNG snapshot and WebM recording produce downloads', async (t) => {
  const { page, errors } = await open(t);
  const [png] = await Promise.all([page.waitForEvent('download'), page.click('#snapshot')]);
  assert.match(png.suggestedFilename(), /^facemimic-.*\.png$/);
  const pngPath = await png.path();
  const head = fs.readFileSync(pngPath).subarray(0, 8);
  assert.deepEqual([...head], [0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]);
  fs.copyFileSync(pngPath, path.join(ROOT, 'artifacts', 'snapshot.png'));

  await page.click('#record');
  assert.equal(await page.getAttribute('#record', 'data-state'), 'recording');
  await page.waitForTimeout(1500);
  const [webm] = await Promise.all([page.waitForEvent('download'), page.click('#record')]);
  assert.match(webm.suggestedFilename(), /^facemimic-.*\.webm$/);
  const data = fs.readFileSync(await webm.path());
  assert.ok(data.length > 10_000, `the video is only ${data.length} bytes`);
  assert.deepEqual([...data.subarray(0, 4)], [0x1a, 0x45, 0xdf, 0xa3], 'not a WebM (EBML) file');
  assert.equal(await page.locator('#downloads li').count(), 2);
  assert.deepEqual(errors, []);
});

test('"Fast raster" (the scanline warp) is on by default; off, tiny-skia draws the same faces', async (t) => {
  const { page, errors, frames } = await open(t);
  await frames(2);
  assert.ok(await page.isChecked('#fast-raster'), '"Fast raster" is not on by default');
  await setSlider(page, 'p-shape-0', 1.5); // pauses on a fixed expression
  await frames(2);
  const fast = await canvasPixels(page, `${TARGETS} >> nth=0`);
  await page.uncheck('#fast-raster');
  await frames(2);
  await assertFace(page, SOURCE, 'source (tiny-skia)');
  await assertPicture(page, `${TARGETS} >> nth=0`, 'target (tiny-skia)');
  const skia = await canvasPixels(page, `${TARGETS} >> nth=0`);
  const d = meanAbsDiff(skia, fast);
  assert.ok(d > 0, 'switching the rasteriser changed no pixel: is the switch wired?');
  assert.ok(d < 2, `scanline and tiny-skia renders differ by ${d} levels on average`);
  await page.check('#fast-raster');
  await frames(2);
  assert.ok(meanAbsDiff(fast, await canvasPixels(page, `${TARGETS} >> nth=0`)) < 0.01, 'scanline render not restored');
  assert.deepEqual(errors, []);
});

test('first load (wasm, JS and the bundled models) is at most 6 MB', async (t) => {
  // A fresh context (empty cache; the server sends no-store): every byte the page fetches until
  // it is ready and has drawn a few frames, from the network log (response body + headers).
  const context = await suite.browser.newContext({ viewport: { width: 1440, height: 900 } });
  t.after(async () => {
    await context.close();
  });
  const page = await context.newPage();
  const sizes = [];
  page.on('requestfinished', (r) => {
    sizes.push(
      r.sizes().then((s) => ({
        path: new URL(r.url()).pathname,
        bytes: s.responseBodySize + s.responseHeadersSize,
      })),
    );
  });
  await page.goto(suite.server.url);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30_000 });
  await page.waitForFunction(() => /^\d+$/.test(document.getElementById('ro-fps').textContent));
  const got = await Promise.all(sizes);
  const total = got.reduce((a, r) => a + r.bytes, 0);
  const sum = (re) => got.filter((r) => re.test(r.path)).reduce((a, r) => a + r.bytes, 0);
  const models = got.filter((r) => r.path.endsWith('.fmm'));
  console.log(
    `first load: ${got.length} responses, ${(total / 1e6).toFixed(3)} MB (${total} bytes): ` +
      `${models.length} models ${(sum(/\.fmm$/) / 1e6).toFixed(3)} MB, wasm ${(sum(/\.wasm$/) / 1e6).toFixed(3)} MB, ` +
      `JS ${(sum(/\.m?js$/) / 1e6).toFixed(3)} MB, other ${((total - sum(/\.fmm$|\.wasm$|\.m?js$/)) / 1e6).toFixed(3)} MB`,
  );
  const wanted = [suite.manifest.source, ...suite.manifest.targets].map((f) => `/models/${f}`);
  for (const w of wanted) assert.ok(models.some((r) => r.path === w), `${w} was not loaded`);
  assert.ok(sum(/\.wasm$/) > 0, 'no wasm in the network log');
  assert.ok(total <= 6e6, `first load ${total} bytes, more than 6 MB`);
});

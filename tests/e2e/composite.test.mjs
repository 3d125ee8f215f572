// End-to-end tests of the page's pictures (issue 18): targets composited into their backdrops by
// default and the "Face only" switch, photo targets (a photo dropped on the targets: its face
// found, or its .pts used; several faces: the face picker; no face: an error), a damaged
// backdrop's notice, and the snapshot and the recording of what is shown. Needs the wasm
// package (scripts/build-wasm.sh) and the default models (scripts/build-models.sh). Screenshots
// go to artifacts/.
//
//   node --test --test-concurrency=1 tests/e2e/composite.test.mjs

import { test, before } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import zlib from 'node:zlib';
import {
  ROOT,
  screenshot,
  canvasStats,
  canvasPixels,
  meanAbsDiff,
  cornerDistances,
  openPage,
  pageSuite,
  dropFiles,
  pkg,
} from './lib.mjs';

const WWW = path.resolve(ROOT, process.env.FACEMIMIC_WWW || 'www');
const MODELS = path.join(WWW, 'models');
const GRID = path.join(ROOT, 'data', 'grid');
const PHOTO = path.join(GRID, 'spk03_lbax4n', '000012.jpg'); // a GRID frame: one face, 360x288
const PHOTO_PTS = path.join(GRID, 'spk03_lbax4n', '000012.pts');
const OTHER_PHOTO = path.join(GRID, 'spk08_sbia1a', fs.readdirSync(path.join(GRID, 'spk08_sbia1a')).find((f) => f.endsWith('.jpg')));

const TARGETS = '.face-card.target canvas.face';
const FACE_BG = [0x1b, 0x1d, 0x22]; // the page's canvas background (FACE_BG in www/app.js)

const suite = pageSuite(WWW);

before(() => assert.ok(fs.existsSync(PHOTO), `${PHOTO} is missing`));

/** Open the page in a fresh context (lib.mjs `openPage`). */
function open(t, { width = 1440, height = 900 } = {}) {
  return openPage(t, suite.browser, suite.server, { context: { viewport: { width, height }, deviceScaleFactor: 1, acceptDownloads: true } });
}

const file = (p, type = 'image/jpeg') => ({ name: path.basename(p), bytes: fs.readFileSync(p), type });
const targetCount = (page) => page.locator('.face-card.target').count();

/** Pictures drawn by Chromium (`draw` runs in the page on a `width x height` 2D context, may
 *  load `urls` as images first), returned as PNG or JPEG bytes. */
async function makeImage(page, { width, height, urls = [], type = 'image/png' }, draw) {
  const b64 = await page.evaluate(
    async ({ width, height, urls, type, draw }) => {
      const images = [];
      for (const u of urls) {
        const img = new Image();
        img.src = u;
        await img.decode();
        images.push(img);
      }
      const c = document.createElement('canvas');
      c.width = width;
      c.height = height;
      const g = c.getContext('2d');
      new Function('g', 'images', 'width', 'height', draw)(g, images, width, height);
      const blob = await new Promise((r) => c.toBlob(r, type, 0.92));
      const bytes = new Uint8Array(await blob.arrayBuffer());
      let bin = '';
      for (let k = 0; k < bytes.length; k += 0x8000) bin += String.fromCharCode(...bytes.subarray(k, k + 0x8000));
      return btoa(bin);
    },
    { width, height, urls, type, draw },
  );
  return Buffer.from(b64, 'base64');
}

/** A data: URL of a file (the test server serves www/ only). */
function dataUrl(p) {
  return `data:image/jpeg;base64,${fs.readFileSync(p).toString('base64')}`;
}

async function assertPicture(page, selector, what, aspect = 1.25) {
  const s = await canvasStats(page, selector);
  assert.ok(Math.abs(s.width / s.height - aspect) < 0.03, `${what}: a ${s.width}x${s.height} canvas for a picture of aspect ${aspect}`);
  assert.ok(s.variance > 60 && s.distinct > 200, `${what}: centre looks blank (${JSON.stringify(s)})`);
  const corners = await cornerDistances(page, selector, FACE_BG);
  assert.ok(corners.every((d) => d > 12), `${what}: a corner is background, not the picture (${corners.map((d) => d.toFixed(1))})`);
}

async function assertFaceOnly(page, selector, what) {
  const s = await canvasStats(page, selector);
  assert.ok(Math.abs(s.width / s.height - 0.8) < 0.03, `${what}: a ${s.width}x${s.height} canvas for a face`);
  assert.ok(s.variance > 60, `${what}: no face drawn (${JSON.stringify(s)})`);
  const corners = await cornerDistances(page, selector, FACE_BG);
  assert.ok(corners.every((d) => d < 2), `${what}: the corners are not background (${corners.map((d) => d.toFixed(1))})`);
}

test('targets open composited into their pictures; "Face only" shows the faces alone, Reset brings the pictures back', async (t) => {
  const { page, errors, frames } = await open(t);
  const n = suite.manifest.targets.length;
  assert.equal(await targetCount(page), n);
  assert.equal(await page.isChecked('#face-only'), false, 'Face only is off by default');
  await frames(3);
  for (let i = 0; i < n; i++) await assertPicture(page, `${TARGETS} >> nth=${i}`, `target ${i + 1}`);
  // The source stays a face: its corners are background.
  const src = await cornerDistances(page, '.face-card.source canvas.face', FACE_BG);
  assert.ok(src.every((d) => d < 2), `the source's corners: ${src}`);
  // One row: the source's canvas and the pictures are as tall.
  const heights = await page.$$eval('.face-card canvas.face', (cs) => cs.map((c) => Math.round(c.getBoundingClientRect().height)));
  assert.ok(Math.max(...heights) - Math.min(...heights) <= 1, `canvas heights ${heights}`);
  await screenshot(page, 'composite-default', { fullPage: false });

  await page.check('#face-only');
  await frames(3);
  for (let i = 0; i < n; i++) await assertFaceOnly(page, `${TARGETS} >> nth=${i}`, `target ${i + 1} (face only)`);
  await screenshot(page, 'composite-face-only', { fullPage: false });

  await page.click('#reset');
  await frames(3);
  assert.equal(await page.isChecked('#face-only'), false, 'Reset turns Face only off');
  await assertPicture(page, `${TARGETS} >> nth=0`, 'target 1 after Reset');
  assert.deepEqual(errors, []);
});

test('the package: keepWhole (default true) holds a far head motion back; false applies all of it; the page has the switch', async (t) => {
  // In Node, through the package the page uses: spk07 drives spk02 in its picture with
  // follow-pose, the source's head turned 0.45 rad, 1.3x larger and moved 40, -30 pixels.
  const { Model, Cloner } = pkg();
  const source = Model.fromBytes(fs.readFileSync(path.join(MODELS, 'spk07.fmm')));
  const c = new Cloner(source);
  c.addTarget(Model.fromBytes(fs.readFileSync(path.join(MODELS, 'spk02.fmm'))));
  c.setFollowPose(true);
  const p = source.baseParams();
  const pose = { scale: p.pose.scale * 1.3, rotation: p.pose.rotation + 0.45, tx: p.pose.tx + 40, ty: p.pose.ty - 30 };
  c.setSourceParams({ ...p, pose });
  c.update();
  const draw = (opts) => c.renderTargetRGBA(0, 360, 288, { composite: true, ...opts });
  const byDefault = draw({});
  const whole = draw({ keepWhole: true });
  const full = draw({ keepWhole: false });
  assert.deepEqual(byDefault, whole, 'keepWhole is not the default');
  let differ = 0;
  for (let i = 0; i < full.length; i += 4) if (Math.abs(full[i] - whole[i]) + Math.abs(full[i + 1] - whole[i + 1]) + Math.abs(full[i + 2] - whole[i + 2]) > 30) differ++;
  console.log(`# keepWhole false against true: ${differ} of ${full.length / 4} pixels differ`);
  assert.ok(differ > 500, `the whole motion draws the same picture (${differ} pixels differ)`);
  assert.throws(() => draw({ keepWhole: 'no' }), /keepWhole must be a boolean/);
  c.free();
  // The page: "Keep picture whole", on by default, reaches the targets' options.
  // (The track's head moves little about its mean: the pictures are the same either way;
  // a keepWhole the package refused would throw in the frame loop.)
  const { page, errors, frames } = await open(t);
  assert.equal(await page.isChecked('#keep-whole'), true, 'Keep picture whole is on by default');
  await page.check('#follow-pose');
  await page.uncheck('#keep-whole');
  await frames(3);
  for (let i = 0; i < suite.manifest.targets.length; i++) await assertPicture(page, `${TARGETS} >> nth=${i}`, `target ${i + 1}`);
  await screenshot(page, 'composite-keep-whole-off', { fullPage: false });
  assert.deepEqual(errors, []);
});

test('a photo dropped on "Add a target" becomes a photo target, animated by the track and kept in Your models', async (t) => {
  const { page, errors, frames } = await open(t);
  const n0 = await targetCount(page);
  await dropFiles(page, '#add-card', [file(PHOTO)]);
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 1, { timeout: 60_000 });
  const card = '.face-card.target >> nth=-1';
  assert.equal(await page.textContent(`${card} >> .name`), '000012');
  assert.match(await page.textContent(`${card} >> .badge`), /^photo$/);
  assert.equal(await page.locator('.face-card.pending').count(), 0, 'the placeholder card stayed');
  await page.locator('.toast', { hasText: '000012' }).waitFor();
  await frames(3);
  await assertPicture(page, `${TARGETS} >> nth=-1`, 'the photo target');

  // Animated by the recorded track: two moments of the playing track, two pictures.
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');
  const f0 = await page.textContent('#frame-counter');
  const a = await canvasPixels(page, `${TARGETS} >> nth=-1`, 2);
  await page.waitForTimeout(400);
  const f1 = await page.textContent('#frame-counter');
  const b = await canvasPixels(page, `${TARGETS} >> nth=-1`, 2);
  assert.notEqual(f1, f0, 'the track did not advance');
  const moved = meanAbsDiff(a, b);
  assert.ok(moved > 0.05, `the photo target did not move with the track (${f0} -> ${f1}: ${moved})`);
  console.log(`# photo target: mean change ${moved.toFixed(3)} levels between track frames ${f0} and ${f1}`);
  // And two fixed frames of the track differ (scrubbing pauses).
  const seek = (k) =>
    page.$eval(
      '#scrub',
      (el, k) => {
        el.value = String(k);
        el.dispatchEvent(new Event('input', { bubbles: true }));
      },
      k,
    );
  await seek(0);
  await frames(2);
  const s0 = await canvasPixels(page, `${TARGETS} >> nth=-1`, 2);
  await seek(30);
  await frames(2);
  const s30 = await canvasPixels(page, `${TARGETS} >> nth=-1`, 2);
  assert.ok(meanAbsDiff(s0, s30) > 0.05, `track frames 1 and 31 look the same on the photo target (${meanAbsDiff(s0, s30)})`);

  // Face only: the photo's face alone.
  await page.check('#face-only');
  await frames(3);
  await assertFaceOnly(page, `${TARGETS} >> nth=-1`, 'the photo target (face only)');
  await page.uncheck('#face-only');
  await frames(2);

  // The inspector shows its face and says what it is.
  await page.click(`${TARGETS} >> nth=-1`);
  await page.waitForFunction(() => [...document.querySelectorAll('#inspect-info dd')].some((d) => /photo target/.test(d.textContent)));
  await page.locator('#inspect-mean').scrollIntoViewIfNeeded();
  await frames(3);
  const mean = await canvasStats(page, '#inspect-mean');
  assert.ok(mean.variance > 60, `the inspector's mean is blank for a photo target (${JSON.stringify(mean)})`);
  await page.evaluate(() => window.scrollTo(0, 0));

  // Kept in this browser, listed as a photo target (which cannot be a source).
  await page.waitForFunction(() => [...document.querySelectorAll('.shelf-item')].some((li) => li.textContent.includes('000012')));
  const row = page.locator('.shelf-item', { hasText: '000012' });
  assert.match(await row.textContent(), /photo target/);
  assert.equal(await row.locator('button', { hasText: /^Source$/ }).count(), 0);
  await screenshot(page, 'composite-photo-target', { fullPage: false });
  assert.deepEqual(errors, []);
});

test('a photo with its .pts uses those landmarks; a photo dropped on a target replaces it', async (t) => {
  const { page, errors, frames } = await open(t);
  const n0 = await targetCount(page);
  await dropFiles(page, '#add-card', [file(PHOTO), file(PHOTO_PTS, 'text/plain')]);
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 1, { timeout: 60_000 });
  await page.locator('.toast', { hasText: 'landmarks from 000012.pts' }).waitFor();
  await frames(2);
  await assertPicture(page, `${TARGETS} >> nth=-1`, 'the photo target from .pts');

  // Dropped on the first target: that target becomes the photo target.
  const other = file(OTHER_PHOTO);
  await dropFiles(page, '.face-card.target >> nth=0', [other]);
  const name = other.name.replace(/\.jpg$/, '');
  await page.waitForFunction((name) => document.querySelector('.face-card.target .name').textContent === name, name, { timeout: 60_000 });
  assert.equal(await targetCount(page), n0 + 1);
  assert.match(await page.textContent('.face-card.target >> nth=0 >> .badge'), /photo/);
  await frames(2);
  await assertPicture(page, `${TARGETS} >> nth=0`, 'the replacing photo target');
  // The compare view says the methods that map into a target's modes substitute on a photo.
  await page.selectOption('#compare-target', '0');
  await frames(2);
  assert.equal(await page.isVisible('#compare-note'), true);
  assert.deepEqual(errors, []);
});

test('with several faces in a photo the user picks one; Cancel adds nothing', async (t) => {
  const { page, errors, frames } = await open(t);
  const n0 = await targetCount(page);
  // Two GRID frames side by side: two faces, in a 640x400 picture.
  const twoFaces = await makeImage(
    page,
    { width: 640, height: 400, urls: [dataUrl(PHOTO), dataUrl(OTHER_PHOTO)] },
    "g.fillStyle = '#2a6f80'; g.fillRect(0, 0, width, height); g.drawImage(images[0], 0, 72, 320, 256); g.drawImage(images[1], 320, 72, 320, 256);",
  );
  await dropFiles(page, '#add-card', [{ name: 'two-faces.png', bytes: twoFaces, type: 'image/png' }]);
  await page.waitForSelector('#photo-pick[open]', { timeout: 60_000 });
  assert.match(await page.textContent('#photo-pick'), /2 faces were found/);
  await screenshot(page, 'composite-face-picker', { fullPage: false });
  await page.click('#photo-pick >> text=Cancel');
  await page.waitForFunction(() => !document.querySelector('#photo-pick').open);
  await frames(2);
  assert.equal(await targetCount(page), n0, 'Cancel added a target');
  assert.equal(await page.locator('.face-card.pending').count(), 0);

  // Again, choosing the face that was not selected (Tab cycles the faces).
  await dropFiles(page, '#add-card', [{ name: 'two-faces.png', bytes: twoFaces, type: 'image/png' }]);
  await page.waitForSelector('#photo-pick[open]', { timeout: 60_000 });
  await page.focus('#photo-pick canvas');
  await page.keyboard.press('Tab');
  assert.match(await page.textContent('#photo-pick-use'), /^Use face 2$/);
  await page.click('#photo-pick-use');
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 1, { timeout: 30_000 });
  await page.locator('.toast', { hasText: 'the face you chose of 2' }).waitFor();
  await frames(3);
  // The canvas has the picture's aspect.
  await assertPicture(page, `${TARGETS} >> nth=-1`, 'the chosen face', 1.6);
  assert.deepEqual(errors, []);
});

test('a photo without a face, or with a face too small, gives an error naming the file; the page keeps running', async (t) => {
  const { page, frames } = await open(t);
  const n0 = await targetCount(page);
  const flat = await makeImage(page, { width: 320, height: 240 }, "g.fillStyle = '#8a8f99'; g.fillRect(0, 0, width, height);");
  await dropFiles(page, '#add-card', [{ name: 'flat-grey.png', bytes: flat, type: 'image/png' }]);
  const toast = page.locator('.toast.error', { hasText: 'flat-grey.png' });
  await toast.waitFor({ timeout: 60_000 });
  assert.match(await toast.textContent(), /no face/i);
  // A GRID frame at a quarter of its size: the face is about 30 pixels wide.
  const tiny = await makeImage(page, { width: 360, height: 288, urls: [dataUrl(PHOTO)] }, "g.fillStyle = '#2a6f80'; g.fillRect(0, 0, width, height); g.drawImage(images[0], 130, 110, 90, 72);");
  await dropFiles(page, '#add-card', [{ name: 'tiny-face.png', bytes: tiny, type: 'image/png' }]);
  const small = page.locator('.toast.error', { hasText: 'tiny-face.png' });
  await small.waitFor({ timeout: 60_000 });
  assert.match(await small.textContent(), /no face|pixels wide|too small/i);
  console.log(`# tiny face: ${(await small.textContent()).replace(/×$/, '')}`);
  // A .pts alone is not used (it goes with a photo).
  await dropFiles(page, '#add-card', [file(PHOTO_PTS, 'text/plain')]);
  await page.locator('.toast.error', { hasText: '000012.pts' }).waitFor();
  await screenshot(page, 'composite-photo-errors', { fullPage: false });

  assert.equal(await targetCount(page), n0, 'a target was added');
  assert.equal(await page.locator('.face-card.pending').count(), 0);
  const f0 = await page.textContent('#frame-counter');
  await frames(5);
  await page.waitForTimeout(300);
  assert.notEqual(await page.textContent('#frame-counter'), f0, 'playback stopped');
  await assertPicture(page, `${TARGETS} >> nth=0`, 'target 1 after the errors');
});

test('a photo dropped on the source still drives the source (tracking), not a target', async (t) => {
  const { page, frames } = await open(t);
  const n0 = await targetCount(page);
  await dropFiles(page, '.face-card.source', [file(PHOTO)]);
  await page.waitForFunction(() => document.querySelector('#source-kind').value === 'video-file', null, { timeout: 30_000 });
  await page.waitForSelector('.trk-panel');
  await frames(2);
  assert.equal(await targetCount(page), n0);
});

/** A bundled model file with its backdrop's JPEG damaged (the checksum made right again). */
function damagedBackdrop(bytes) {
  const b = Buffer.from(bytes);
  const tag = b.indexOf(Buffer.from('BKDR'));
  assert.ok(tag > 0, 'the bundled model has no backdrop section');
  const soi = b.indexOf(Buffer.from([0xff, 0xd8, 0xff]), tag);
  assert.ok(soi > tag, 'no JPEG in the backdrop section');
  b.fill(0, soi, soi + 64);
  b.writeUInt32LE(zlib.crc32(b.subarray(0, b.length - 4)), b.length - 4);
  return b;
}

test('a model whose backdrop is damaged says so once and is drawn face only', async (t) => {
  const { page, errors, frames } = await open(t);
  const spare = (suite.manifest.library || []).find((f) => !suite.manifest.targets.includes(f));
  const bad = damagedBackdrop(fs.readFileSync(path.join(MODELS, spare)));
  const n0 = await targetCount(page);
  await dropFiles(page, '#add-card', [{ name: `damaged-${spare}`, bytes: bad }]);
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 1);
  const notice = page.locator('.toast.warning', { hasText: `damaged-${spare}` });
  await notice.waitFor();
  assert.match(await notice.textContent(), /backdrop damaged/i);
  assert.match(await notice.textContent(), /face only/i);
  await frames(3);
  await assertFaceOnly(page, `${TARGETS} >> nth=-1`, 'the model with a damaged backdrop');
  await assertPicture(page, `${TARGETS} >> nth=0`, 'a sound target beside it');
  // Loaded again: no second notice.
  await dropFiles(page, '#add-card', [{ name: `damaged-${spare}`, bytes: bad }]);
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, n0 + 2);
  assert.equal(await page.locator('.toast.warning', { hasText: `damaged-${spare}` }).count(), 1);
  assert.deepEqual(errors, []);
});

test('the PNG snapshot and the WebM recording hold the pictures as shown', async (t) => {
  const { page, errors, frames } = await open(t);
  await dropFiles(page, '#add-card', [file(PHOTO), file(PHOTO_PTS, 'text/plain')]);
  await page.waitForFunction((n) => document.querySelectorAll('.face-card.target').length === n, suite.manifest.targets.length + 1, { timeout: 60_000 });
  await frames(2);
  const snapshot = async () => {
    const [png] = await Promise.all([page.waitForEvent('download'), page.click('#snapshot')]);
    const bytes = fs.readFileSync(await png.path());
    // Decoded in the page: its size, and how much of the strip is the face background.
    return page.evaluate(async (b64) => {
      const bin = atob(b64);
      const u8 = new Uint8Array(bin.length);
      for (let i = 0; i < bin.length; i++) u8[i] = bin.charCodeAt(i);
      const bmp = await createImageBitmap(new Blob([u8], { type: 'image/png' }));
      const c = new OffscreenCanvas(bmp.width, bmp.height);
      const g = c.getContext('2d');
      g.drawImage(bmp, 0, 0);
      const d = g.getImageData(0, 0, bmp.width, bmp.height).data;
      let bg = 0;
      for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x1b) + Math.abs(d[i + 1] - 0x1d) + Math.abs(d[i + 2] - 0x22) < 6) bg++;
      return { width: bmp.width, height: bmp.height, bgShare: bg / (d.length / 4) };
    }, bytes.toString('base64'));
  };
  const pictures = await snapshot();
  await page.check('#face-only');
  await frames(2);
  const faces = await snapshot();
  console.log(`# snapshot: pictures ${pictures.width}x${pictures.height} (${(pictures.bgShare * 100).toFixed(1)}% face background), faces ${faces.width}x${faces.height} (${(faces.bgShare * 100).toFixed(1)}%)`);
  // Landscape pictures make a wider strip than portrait faces, and leave little background.
  assert.ok(pictures.width > faces.width * 1.2, `snapshot widths: pictures ${pictures.width}, faces ${faces.width}`);
  assert.ok(pictures.bgShare < faces.bgShare / 2, `background share: pictures ${pictures.bgShare}, faces ${faces.bgShare}`);
  await page.uncheck('#face-only');
  await frames(2);

  await page.click('#record');
  assert.equal(await page.getAttribute('#record', 'data-state'), 'recording');
  await page.waitForTimeout(1500);
  const [webm] = await Promise.all([page.waitForEvent('download'), page.click('#record')]);
  const data = fs.readFileSync(await webm.path());
  assert.ok(data.length > 10_000, `the video is only ${data.length} bytes`);
  assert.deepEqual([...data.subarray(0, 4)], [0x1a, 0x45, 0xdf, 0xa3], 'not a WebM (EBML) file');
  assert.deepEqual(errors, []);
});

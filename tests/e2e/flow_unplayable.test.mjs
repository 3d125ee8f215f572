// The page's flow, issue 33 part 4, item 3: a video the browser cannot play (random bytes named
// .mov; the bundled WebM with its codec id changed to one no browser knows: a valid container,
// an unsupported codec) gets a plain message saying what to do, with the ffmpeg commands that
// convert it to an H.264 MP4 or a WebM, each copyable; the browser's own words (Chromium's
// "PipelineStatus::DEMUXER_..." text) only under a closed "The browser's words". The page stays
// usable and the source before keeps going: the recorded track, the webcam (a fake camera
// playing spk07's unseen GRID clip, committed data), a video file already tracked. Screenshots:
// artifacts/flow-unplayable*.png.
//
//   node --test --test-concurrency=1 tests/e2e/flow_unplayable.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import crypto from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import { ROOT, screenshot, openPage, dropFiles, pageSuite } from './lib.mjs';

const WWW = path.join(ROOT, 'www');
const CLIP = JSON.parse(fs.readFileSync(path.join(WWW, 'media', 'spk07-clip.json'), 'utf8'));
const CLIP_VIDEO = path.join(WWW, 'media', CLIP.video);
const CAMERA_CLIP = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');

/** Not a video at all: random bytes named like a QuickTime movie. */
const GARBAGE = { name: 'holiday.mov', bytes: crypto.randomBytes(64 * 1024), type: 'video/quicktime' };
/** A valid WebM whose video codec no browser knows (the bundled clip's V_VP9 renamed V_XV9). */
function unknownCodec() {
  const b = Buffer.from(fs.readFileSync(CLIP_VIDEO));
  const at = b.indexOf('V_VP9');
  assert.ok(at > 0, 'the bundled clip is a VP9 WebM');
  b.write('V_XV9', at);
  return { name: 'interview.webm', bytes: b, type: 'video/webm' };
}

const suite = pageSuite(WWW, { camera: { frames: CAMERA_CLIP, name: 'flow-unplayable' } });

const open = (t) =>
  openPage(t, suite.browser, suite.server, { context: { viewport: { width: 1440, height: 1100 }, permissions: ['clipboard-read', 'clipboard-write'] } });

/** The notice about `name`, once it shows: its visible text, its commands and its details. */
async function notice(page, name) {
  const toast = page.locator('.toast.error', { hasText: `Cannot play ${name}` });
  await toast.waitFor({ timeout: 20_000 });
  return {
    toast,
    ...(await toast.evaluate((el) => ({
      text: el.innerText,
      commands: [...el.querySelectorAll('.media-cmd code')].map((c) => c.textContent),
      copies: el.querySelectorAll('.media-cmd button').length,
      detail: el.querySelector('.media-detail code')?.textContent ?? null,
      detailOpen: el.querySelector('.media-detail')?.open ?? null,
    }))),
  };
}

/** The notice says what to do in plain words; the browser's own words are tucked away. */
function assertPlain(n, name, mp4, webm) {
  assert.match(n.text, /cannot play the format of this video/);
  assert.match(n.text, /Convert it to an H\.264 MP4 or a WebM/);
  assert.doesNotMatch(n.text, /PipelineStatus|DEMUXER|FFmpegDemuxer/, `raw error text in the notice: ${n.text}`);
  assert.deepEqual(n.commands, [
    `ffmpeg -i ${name} -c:v libx264 -pix_fmt yuv420p -an ${mp4}`,
    `ffmpeg -i ${name} -c:v libvpx-vp9 -crf 32 -b:v 0 -an ${webm}`,
  ]);
  assert.equal(n.copies, 2);
  assert.equal(n.detailOpen, false);
}

const frameCounter = (page) => page.textContent('#frame-counter');

test('a dropped video the browser cannot play: a plain message with the commands to convert it; the recorded track plays on', async (t) => {
  const { page, errors } = await open(t);
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');

  // Dropped anywhere on the page (where a playable video would become the source).
  await dropFiles(page, 'footer', [GARBAGE]);
  const n = await notice(page, GARBAGE.name);
  assertPlain(n, 'holiday.mov', 'holiday.mp4', 'holiday.webm');
  assert.match(n.text, /The source stays on the recorded track\./);
  assert.ok(n.detail && n.detail.length > 0, "the browser's words are kept under the details");
  console.log(`# the browser's words for ${GARBAGE.name}: ${n.detail}`);

  // Nothing else changed: the track is the source, plays and drives the faces; no video panel.
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'track');
  assert.equal(await page.locator('.trk-panel').count(), 0);
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');
  const f0 = await frameCounter(page);
  await page.waitForTimeout(400);
  assert.notEqual(await frameCounter(page), f0, 'the track stopped');

  // Copy puts the command on the clipboard.
  await n.toast.getByRole('button', { name: /H\.264 MP4/ }).click();
  await page.waitForFunction(() => [...document.querySelectorAll('.media-copy')].some((b) => b.textContent === 'Copied'));
  await page.waitForTimeout(300); // the notice's entrance
  assert.equal(await page.evaluate(() => navigator.clipboard.readText()), n.commands[0]);
  await screenshot(page, 'flow-unplayable', { fullPage: false });
  await n.toast.screenshot({ path: path.join(ROOT, 'artifacts', 'flow-unplayable-notice.png') });

  // A valid container with a codec the browser does not know: the same, named after it.
  const bad = unknownCodec();
  await dropFiles(page, 'footer', [bad]);
  const m = await notice(page, bad.name);
  // (never over the file itself)
  assertPlain(m, 'interview.webm', 'interview.mp4', 'interview-converted.webm');
  console.log(`# the browser's words for ${bad.name}: ${m.detail}`);
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'track');
  assert.equal(await page.locator('.trk-panel').count(), 0);

  // The page is usable: a playable video dropped the same way becomes the source.
  await dropFiles(page, 'footer', [{ name: 'clip.webm', bytes: fs.readFileSync(CLIP_VIDEO), type: 'video/webm' }]);
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'video-file');
  assert.deepEqual(errors, []);
});

test('the webcam and a tracked video go on when an unplayable video is dropped; an empty video panel says it plainly', async (t) => {
  const { page, errors } = await open(t);

  // The webcam tracks; a bad video dropped on the page leaves it tracking, on the same camera.
  await page.selectOption('#source-kind', 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 60_000 });
  const cam = await page.evaluate(() => ({ id: window.facemimicTracking.stream.id, fits: window.facemimicTracking.fits }));
  await dropFiles(page, 'footer', [GARBAGE]);
  const n = await notice(page, GARBAGE.name);
  assert.match(n.text, /The source stays on the webcam\./);
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'webcam');
  assert.equal(await page.locator('.trk-panel').count(), 1);
  assert.equal(await page.getAttribute('.trk-panel', 'data-mode'), 'webcam');
  const same = await page.evaluate(() => ({ id: window.facemimicTracking.stream?.id, live: window.facemimicTracking.stream?.getVideoTracks()[0].readyState }));
  assert.deepEqual(same, { id: cam.id, live: 'live' }, 'the camera was closed or opened again');
  await page.waitForFunction((f) => window.facemimicTracking.fits > f + 10, cam.fits, { timeout: 20_000 });
  assert.equal((await page.$eval('.transport', (e) => e.dataset.transport)), 'none');
  await n.toast.locator('.toast-close').click();

  // A video file tracked in the panel; a bad one dropped on the panel: the first goes on.
  await page.selectOption('#source-kind', 'video-file');
  await page.setInputFiles('.trk-panel input[type="file"]', CLIP_VIDEO);
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  const fits = await page.evaluate(() => window.facemimicTracking.fits);
  await dropFiles(page, '.trk-panel', [unknownCodec()]);
  const m = await notice(page, 'interview.webm');
  assert.match(m.text, new RegExp(`${CLIP.video.replace('.', '\\.')} goes on\\.`));
  assert.equal(await page.getAttribute('.trk-panel', 'data-phase'), 'tracking');
  assert.equal(await page.evaluate(() => window.facemimicTracking.fileName), CLIP.video);
  await page.waitForFunction((f) => window.facemimicTracking.fits > f + 10, fits, { timeout: 20_000 });
  assert.match(await page.textContent('.trk-panel .trk-msg'), /interview\.webm: this browser cannot play its format/);
  await m.toast.locator('.toast-close').click();

  // An empty video panel given a bad file: the panel says it in plain words too.
  await page.selectOption('#source-kind', 'sliders');
  await page.selectOption('#source-kind', 'video-file');
  await page.waitForSelector('.trk-panel[data-phase="empty"]');
  await page.setInputFiles('.trk-panel input[type="file"]', { name: GARBAGE.name, mimeType: GARBAGE.type, buffer: GARBAGE.bytes });
  await notice(page, GARBAGE.name);
  assert.equal(await page.getAttribute('.trk-panel', 'data-phase'), 'empty');
  const msg = await page.textContent('.trk-panel .trk-msg');
  assert.match(msg, /holiday\.mov: this browser cannot play its format\. Convert it to an H\.264 MP4 or a WebM/);
  assert.doesNotMatch(msg, /PipelineStatus|DEMUXER/);
  await page.waitForTimeout(300); // the notice's entrance
  await screenshot(page, 'flow-unplayable-panel', { fullPage: false });
  assert.deepEqual(errors, []);
});

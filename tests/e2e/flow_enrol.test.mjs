// The page's flow, issue 33 part 4, item 1: "Use as source" after "Create a face" keeps the live
// source. With the webcam as the source (a fake camera playing spk07's unseen GRID clip,
// committed data, the face where the webcam guide is), the face made from the webcam becomes the
// source and the webcam stays the source, on the same camera (not opened again), now fitted by
// the AAM of the person's own model (the core's policy); a video file stays the source the same
// way when the model changes again (the bundled model dropped on the source: followed by its
// landmarks). Screenshots: artifacts/flow-enrol-*.png.
//
//   node --test --test-concurrency=1 tests/e2e/flow_enrol.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { ROOT, screenshot, openPage, dropFiles, assertTargetsMove, pageSuite } from './lib.mjs';

const WWW = path.join(ROOT, 'www');
const MANIFEST = JSON.parse(fs.readFileSync(path.join(WWW, 'models', 'manifest.json'), 'utf8'));
const CLIP = JSON.parse(fs.readFileSync(path.join(WWW, 'media', 'spk07-clip.json'), 'utf8'));
const CLIP_VIDEO = path.join(WWW, 'media', CLIP.video);
const CAMERA_CLIP = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');

const suite = pageSuite(WWW, { camera: { frames: CAMERA_CLIP, name: 'flow-enrol' } });

/** The live source as the page runs it. */
const live = (page) =>
  page.evaluate(() => {
    const s = window.facemimicTracking;
    return {
      kind: document.getElementById('source-kind').value,
      mode: s?.mode ?? null,
      phase: s?.phase ?? null,
      path: s?.path ?? null,
      trackerPath: s?.tracker?.path ?? null,
      notice: document.querySelector('.trk-panel .trk-path')?.dataset.path ?? null,
      panels: document.querySelectorAll('.trk-panel').length,
      stream: s?.stream?.id ?? null,
      camera: s?.stream?.getVideoTracks()[0]?.readyState ?? null,
      file: s?.mode === 'file' ? s.fileName : null,
      source: document.querySelector('.face-card.source .name').textContent,
    };
  });

/** Waits until the live source has fitted `n` more frames; returns how many of them were lost. */
async function fitsMore(page, n) {
  const from = await page.evaluate(() => window.facemimicTracking.log.length);
  await page.waitForFunction(([f, k]) => window.facemimicTracking.log.length >= f + k, [from, n], { timeout: 30_000 });
  return page.evaluate((f) => window.facemimicTracking.log.slice(f).filter((l) => l.lost).length, from);
}

test('"Use as source" after Create a face keeps the webcam as the source, now fitted with the own model; a video file stays too', async (t) => {
  const { page, errors } = await openPage(t, suite.browser, suite.server, {
    context: { viewport: { width: 1440, height: 1200 } },
    ready: ['body[data-shelf="ready"]'],
  });

  // The webcam drives the source, followed by its landmarks with the bundled model.
  await page.selectOption('#source-kind', 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 60_000 });
  const before = await live(page);
  assert.deepEqual([before.kind, before.path, before.trackerPath, before.notice], ['webcam', 'landmarks', 'landmarks', 'landmarks']);

  // Create a face from the webcam (the dialog samples the same fake camera), build it.
  await page.click('#create-face');
  await page.waitForSelector('dialog#enrol[open]');
  await page.fill('#enrol .enrol-name', 'Flow face');
  await page.getByRole('button', { name: 'Webcam', exact: true }).click();
  await page.waitForFunction(() => window.facemimicEnrol.candidates.length >= 12, null, { timeout: 120_000 });
  await page.click('#enrol .btn.primary');
  await page.waitForFunction(() => /^Built Flow face/.test(document.querySelector('#enrol .enrol-status').textContent), null, { timeout: 120_000 });
  console.log(`# ${await page.textContent('#enrol .enrol-status')}`);

  // Use as source: the model is the source, and the webcam still drives it, on the same camera,
  // now with the AAM of the person's own model.
  await page.getByRole('button', { name: 'Use as source' }).click();
  await page.waitForFunction(() => document.querySelector('.face-card.source .name').textContent === 'Flow face');
  const toast = page.locator('.toast', { hasText: 'Source is now Flow face' });
  await toast.waitFor();
  assert.match(await toast.textContent(), /The webcam goes on driving it, now fitted with this model's AAM\./);
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  const after = await live(page);
  assert.deepEqual(
    { kind: after.kind, mode: after.mode, path: after.path, tracker: after.trackerPath, notice: after.notice, panels: after.panels },
    { kind: 'webcam', mode: 'webcam', path: 'aam', tracker: 'aam', notice: 'aam', panels: 1 },
  );
  assert.deepEqual([after.stream, after.camera], [before.stream, 'live'], 'the camera was opened again');
  assert.equal((await page.$eval('.transport', (e) => e.dataset.transport)), 'none', 'the webcam has no transport');
  const lost = await fitsMore(page, 40);
  console.log(`# the webcam fitted with the own model's AAM: ${lost} of 40 frames lost`);
  assert.ok(lost <= 10, `${lost} of 40 frames lost with the own model`);
  await assertTargetsMove(page, 1000);
  await page.waitForTimeout(300);
  await screenshot(page, 'flow-enrol-webcam-source', { fullPage: false });

  // A video file as the source, then the bundled model dropped on the source: the video stays
  // the source (now followed by its landmarks: the bundled model is not this person's own), and
  // is not handed to the recorded track.
  await page.selectOption('#source-kind', 'video-file');
  await page.setInputFiles('.trk-panel input[type="file"]', CLIP_VIDEO);
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  assert.equal((await live(page)).path, 'aam');
  const bytes = fs.readFileSync(path.join(WWW, 'models', MANIFEST.source));
  await dropFiles(page, '.face-card.source', [{ name: MANIFEST.source, bytes }]);
  await page.waitForFunction((n) => document.querySelector('.face-card.source .name').textContent === n, MANIFEST.source.replace(/\.fmm$/, ''));
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  const video = await live(page);
  assert.deepEqual([video.kind, video.mode, video.file, video.path, video.panels], ['video-file', 'file', CLIP.video, 'landmarks', 1]);
  assert.match(await page.locator('.toast', { hasText: `Source is now ${MANIFEST.source.replace(/\.fmm$/, '')}` }).textContent(), /The video file goes on driving it, following the face by its landmarks\./);
  assert.ok((await fitsMore(page, 20)) <= 5);
  // The recorded track is offered again, and taken when chosen.
  await page.selectOption('#source-kind', 'track');
  assert.equal(await page.getAttribute('#play', 'data-state'), 'playing');
  assert.equal(await page.locator('.trk-panel').count(), 0);
  assert.deepEqual(errors, []);
});

// Driving the targets with one's own face: a model of GRID speaker 7 is created in the page
// ("Create a face", from the 20 photos of data/grid/spk07_pwij3p/train20.txt with their .pts
// files), used as the source, and the webcam source (Chromium's fake camera playing speaker 7's
// unseen clip data/grid/spk07_id2_vcd_swwp2s, none of whose frames built the model) tracks it
// with that model and drives every target. The fake camera file is made by the test (MJPEG, in
// the temporary folder, never committed).
//   node --test tests/e2e/enrol.test.mjs   (after scripts/build-wasm.sh and scripts/build-models.sh)
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { ROOT, serveStatic, canvasStats, screenshot, fakeCameraFile, assertPageBuilt, cameraBrowser, assertTargetsMove, openPage, webcamLog } from './lib.mjs';

const WWW = path.join(ROOT, 'www');
const TRAIN = path.join(ROOT, 'data', 'grid', 'spk07_pwij3p');
const UNSEEN = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');

let server;

before(async () => {
  assertPageBuilt(WWW);
  server = await serveStatic(WWW);
});

after(() => server?.close());

/** The unseen clip as a 640x480 MJPEG with the face in the webcam guide (tests/e2e/lib.mjs). */
function faceCamera(t) {
  return fakeCameraFile(t, UNSEEN, { name: 'enrol-camera' });
}

test('a face created in the page becomes the source, and the webcam tracks it with its own model and drives the targets', async (t) => {
  const camera = await faceCamera(t);
  const browser = await cameraBrowser(t, camera);
  const { page, errors } = await openPage(t, browser, server, { context: { viewport: { width: 1440, height: 1600 } }, ready: ['body[data-shelf="ready"]'], console: false });

  // Create the face from photos.
  const stems = fs.readFileSync(path.join(TRAIN, 'train20.txt'), 'utf8').split('\n').map((s) => s.trim()).filter(Boolean);
  await page.click('#create-face');
  await page.setInputFiles('#enrol input[type="file"]', stems.flatMap((s) => [path.join(TRAIN, `${s}.jpg`), path.join(TRAIN, `${s}.pts`)]));
  await page.waitForFunction(() => /20 usable faces/.test(document.querySelector('#enrol .enrol-status').textContent));
  await page.fill('#enrol .enrol-name', 'Me');
  await page.click('#enrol .btn.primary');
  await page.waitForFunction(() => /^Built Me/.test(document.querySelector('#enrol .enrol-status').textContent), null, { timeout: 60_000 });
  // Previewed in the dialog (the preview itself is tested in store.test.mjs): the mean face drawn.
  await page.waitForFunction(() => window.facemimicEnrol.preview.drawn > 2);
  const mean = await canvasStats(page, '#enrol .enrol-preview canvas >> nth=0');
  assert.ok(mean.variance > 60 && mean.distinct > 200, `the preview's mean face is blank (${JSON.stringify(mean)})`);
  await page.getByRole('button', { name: 'Use as source' }).click();
  await page.waitForFunction(() => document.querySelector('.face-card.source')?.textContent.includes('Me'));

  // The webcam source tracks the face with the enrolled model.
  const log = await webcamLog(page, 30_000);
  const lost = log.filter((l) => l.lost).length;
  const meanErr = log.reduce((s, l) => s + l.error, 0) / log.length;
  console.log(`# enrolled source on the face camera: ${log.length} fits, ${lost} lost, fit error mean ${meanErr.toFixed(4)}`);
  assert.equal(lost, 0, 'frames lost');
  assert.ok(meanErr < 0.06, `fit error mean ${meanErr}`);
  assert.ok((await page.textContent('.face-card.source')).includes('Me'), 'the source is still the enrolled face');
  // Every target follows.
  await assertTargetsMove(page, 800);
  await screenshot(page, 'enrol-drives-targets', { fullPage: false });
  assert.deepEqual(errors, []);
});

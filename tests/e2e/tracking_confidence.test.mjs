// The tracker's confidence on the page (issue 33, "a tracker that knows when it is wrong"), in
// headless Chromium with a fake camera the test draws from committed GRID frames (MJPEG in the
// temporary folder, never committed; no research data).
//
// Split: the source model is created in the page ("Create a face") from the 20 photos of clip
// spk07_pwij3p that the bundled spk07.fmm is built from (train20.txt); the camera plays speaker 7's other clip, spk07_id2_vcd_swwp2s
// (75 frames), which no model was built from, four times over:
//   clean    as filmed;
//   tilted   the picture turned about the face, up to +-30 degrees and back;
//   lower    a flat skin-coloured cover over everything from the nose tip down (a hand over
//            the lower face: the fit that used to collapse while the status said TRACKING);
//   hand     a palm and four fingers entering from the left over the cheek and mouth.
// Each frame carries its number in a row of black and white blocks in the top-left corner, read
// back from the very pixels the page hands the tracker, so every fit is matched with the points
// where the face really is (dlib's points on the clip, moved as the picture was).
//
// The created model is the person's own, so the page fits the AAM (not the landmark follower).
// Measured over more than a loop of the clip:
// - silent failures: fits the status calls "tracking" whose points are off (more than 0.1 of the
//   eye distance, the measure): at most 0.5% of fits (at most 1 here);
// - the clean part is tracked (at least 90% "tracking"); with the lower face covered, at least
//   half the fits are "unsure" or "lost" (the expression cannot be read);
// - the panel shows "unsure" or "face lost" while the face is covered, and while a fit is
//   unsure or lost the source (and so every target) holds the last good expression.
// Screenshots: artifacts/confidence-*.png.
//   node --test --test-concurrency=1 tests/e2e/tracking_confidence.test.mjs   (after scripts/build-wasm.sh)
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { ROOT, serveStatic, screenshot, mjpegCamera, clipFrames, READ_MARKER, assertPageBuilt, cameraBrowser, openPage, landmarkError } from './lib.mjs';

const WWW = path.join(ROOT, 'www');
const CLIP = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');
const TRAIN = path.join(ROOT, 'data', 'grid', 'spk07_pwij3p');
const SEGMENTS = ['clean', 'tilted', 'lower', 'hand'];
/** A fit this far off (in eye distances) is broken (the measure). */
const OFF = 0.1;

let server;

before(async () => {
  assertPageBuilt(WWW);
  server = await serveStatic(WWW);
});

after(() => server?.close());

test('the status never says tracking over a broken fit, and the targets hold while unsure', async (t) => {
  const n = fs.readdirSync(CLIP).filter((f) => /^\d{6}\.jpg$/.test(f)).length;
  const frames = [];
  SEGMENTS.forEach((seg, s) => {
    for (let i = 0; i < n; i++) {
      const rotate = seg === 'tilted' ? 30 * Math.sin((2 * Math.PI * i) / n) : 0;
      frames.push({ i, rotate, cover: ['lower', 'hand'].includes(seg) ? seg : null, marker: s * 100 + i });
    }
  });
  const { jpegs, truth } = await clipFrames({ dir: CLIP, frames });
  const truthOf = new Map(frames.map((f, k) => [f.marker, truth[k]]));
  const camera = mjpegCamera(t, jpegs, 'confidence-camera');
  const browser = await cameraBrowser(t, camera);
  const { page, errors } = await openPage(t, browser, server, { context: { viewport: { width: 1280, height: 1000 } }, ready: ['body[data-shelf="ready"]'], console: false });

  // The person's own model on the source, created in the page from the 20 photos the bundled
  // spk07.fmm is built from (with their .pts files): the page fits the AAM, not the follower.
  const stems = fs.readFileSync(path.join(TRAIN, 'train20.txt'), 'utf8').split('\n').map((s) => s.trim()).filter(Boolean);
  await page.click('#create-face');
  await page.setInputFiles('#enrol input[type="file"]', stems.flatMap((s) => [path.join(TRAIN, `${s}.jpg`), path.join(TRAIN, `${s}.pts`)]));
  await page.waitForFunction(() => /20 usable faces/.test(document.querySelector('#enrol .enrol-status').textContent), null, { timeout: 30_000 });
  await page.fill('#enrol .enrol-name', 'Me');
  await page.click('#enrol .btn.primary');
  await page.waitForFunction(() => /^Built Me/.test(document.querySelector('#enrol .enrol-status').textContent), null, { timeout: 60_000 });
  await page.getByRole('button', { name: 'Use as source' }).click();
  await page.waitForFunction(() => document.querySelector('.face-card.source')?.textContent.includes('Me'));
  await page.selectOption('#source-kind', 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  assert.equal(await page.$eval('.trk-path', (e) => e.dataset.path), 'aam', 'the own model is not fitted');

  // Every fit, with the frame's marker read from the pixels the tracker is given, the status,
  // and the source's parameters before the fit (the last good fit's, which drive the targets).
  await page.evaluate((readMarker) => {
    const read = new Function(`return ${readMarker}`)();
    window.confidenceLog = [];
    window.confidenceStates = new Set();
    const patch = () => {
      const src = window.facemimicTracking;
      const tr = src?.tracker;
      if (tr && !tr.confidencePatched) {
        const track = tr.track.bind(tr);
        tr.track = (data, width, height, dt) => {
          const marker = read(data, width);
          const before = JSON.stringify(src.params?.shape ?? null);
          const r = track(data, width, height, dt);
          window.confidenceLog.push({ marker, k: width / 640, status: r.status, reasons: r.reasons, lost: r.lost, landmarks: Array.from(r.landmarks), before });
          return r;
        };
        tr.confidencePatched = true;
      }
      const state = document.querySelector('.trk-state')?.dataset.state;
      if (state) window.confidenceStates.add(`${state}: ${document.querySelector('.trk-msg')?.textContent}`);
    };
    setInterval(patch, 20);
    patch();
  }, READ_MARKER);

  // Over a loop and a half of the clip, with a screenshot while the face is covered; longer
  // (up to four loops) while fewer fits than a loop's frames have come: the page fits as fast
  // as the machine lets it, and this test counts what the status says, not how fast (a loaded
  // 2-core machine once gave 278 fits in the loop and a half where 300 were needed; speed is
  // measured in www/bench.html).
  const loop = (SEGMENTS.length * n) / 30;
  const want = SEGMENTS.length * n + Math.ceil(n / 4);
  let shot = false;
  const start = Date.now();
  const until = start + 1500 * loop;
  const cap = start + 4000 * loop;
  for (;;) {
    await page.waitForTimeout(250);
    // One read a tick: how many fits have come, and the last one's marker.
    const { count, marker } = await page.evaluate(() => ({ count: window.confidenceLog.length, marker: window.confidenceLog.at(-1)?.marker }));
    const now = Date.now();
    if (now >= cap || (now >= until && count >= want)) break;
    if (!shot) {
      if (marker !== undefined && Math.floor(marker / 100) === 2 && marker % 100 > n / 2) {
        await screenshot(page, 'confidence-covered', { fullPage: false });
        shot = true;
      }
    }
  }
  const log = await page.evaluate(() => window.confidenceLog);
  const states = await page.evaluate(() => [...window.confidenceStates]);

  const per = Object.fromEntries(SEGMENTS.map((s) => [s, { fits: 0, tracking: 0, unsure: 0, lost: 0, off: 0, silent: 0, err: 0 }]));
  let unknown = 0;
  let held = 0;
  let moved = 0;
  log.forEach((l, j) => {
    const want = truthOf.get(l.marker);
    if (!want) {
      unknown++;
      return;
    }
    const seg = per[SEGMENTS[Math.floor(l.marker / 100)]];
    const err = landmarkError(l.landmarks, want.map((v) => v * l.k));
    seg.fits++;
    seg[l.status]++;
    if (err > OFF) seg.off++;
    if (l.status === 'tracking') {
      seg.err += err;
      if (err > OFF) seg.silent++;
    }
    // A fit that is not "tracking" leaves the source's expression where it was.
    if (l.status !== 'tracking' && j + 1 < log.length) {
      if (log[j + 1].before === l.before) held++;
      else moved++;
    }
  });
  for (const [name, s] of Object.entries(per)) {
    console.log(`# ${name}: ${s.fits} fits, ${s.tracking} tracking (mean error ${(s.err / Math.max(1, s.tracking)).toFixed(3)}), ${s.unsure} unsure, ${s.lost} lost; off by more than ${OFF}: ${s.off}, of them called tracking: ${s.silent}`);
  }
  const fits = log.length - unknown;
  const silent = Object.values(per).reduce((a, s) => a + s.silent, 0);
  console.log(`# ${fits} fits (${unknown} unreadable markers), silent failures ${silent} (${((100 * silent) / fits).toFixed(2)}%); not tracking: held ${held}, moved ${moved}; panel states seen: ${states.join('; ')}`);

  assert.ok(unknown <= fits * 0.02, `${unknown} fits on frames without a readable marker`);
  assert.ok(fits >= SEGMENTS.length * n, `only ${fits} fits in a loop and a half`);
  for (const s of SEGMENTS) assert.ok(per[s].fits >= n / 2, `${s}: only ${per[s].fits} fits`);
  assert.ok(silent <= Math.max(1, Math.floor(fits * 0.005)), `${silent} fits called tracking while off by more than ${OFF}`);
  assert.ok(per.clean.tracking >= 0.9 * per.clean.fits, `clean: ${per.clean.tracking} of ${per.clean.fits} tracking`);
  // With the lower face covered the expression cannot be read, and the tracker says so.
  assert.ok(per.lower.unsure + per.lower.lost >= per.lower.fits / 2, `lower face covered: ${per.lower.tracking} of ${per.lower.fits} fits called tracking`);
  // The panel says so in its state and its message.
  assert.ok(states.some((s) => /^unsure: Unsure of the fit: the targets hold/.test(s) || /^lost: Face lost/.test(s)), `the panel never said unsure or lost (${states.join('; ')})`);
  assert.ok(!states.some((s) => /^(unsure|lost): Tracking/.test(s)), `the message said tracking while the state did not (${states.join('; ')})`);
  assert.equal(moved, 0, 'an unsure or lost fit moved the source');
  await screenshot(page, 'confidence-end', { fullPage: false });
  assert.deepEqual(errors, []);
});

// End-to-end tests of the page's video sources (www/js/tracking.js): the bundled clip tracked
// live by the package's Tracker, a video file placed with a box and tracked, the webcam (Chromium's
// fake device) with its face guide, and the error paths. Served from 127.0.0.1, driven in Debian's
// headless chromium through playwright-core. Needs www/pkg/ built with the Tracker
// (scripts/build-wasm.sh) and the default models (scripts/build-models.sh). Screenshots go to
// artifacts/tracking-*.png.
//
//   node --test tests/e2e/tracking.test.mjs

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import {
  ROOT,
  CHROMIUM,
  serveStatic,
  launchBrowser,
  haveChromium,
  screenshot,
  canvasStats,
  canvasDigest,
  readPts,
  fakeCameraFile,
  FAKE_CAMERA_ARGS,
  landmarkError,
  cameraBrowser,
} from './lib.mjs';

// FACEMIMIC_WWW serves another folder laid out like www/ (for developing the page).
const WWW = path.resolve(ROOT, process.env.FACEMIMIC_WWW || 'www');
const CLIP = JSON.parse(fs.readFileSync(path.join(WWW, 'media', 'spk07-clip.json'), 'utf8'));
const CLIP_VIDEO = path.join(WWW, 'media', CLIP.video);
const CLIP_FRAMES = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');
const AUTOPLAY = '--autoplay-policy=no-user-gesture-required';
const PANEL = '.trk-panel';
const PANEL_CANVAS = '.trk-panel canvas.trk-canvas';
const TARGETS = '.face-card.target canvas.face';

let server;
let browser;
let camBrowser;

before(async () => {
  assert.ok(haveChromium(), `chromium not found at ${CHROMIUM}: run scripts/setup.sh --browser`);
  const glue = path.join(WWW, 'pkg', 'facemimic_wasm.js');
  assert.ok(fs.existsSync(glue), 'www/pkg/facemimic.js is missing: run scripts/build-wasm.sh');
  assert.ok(
    /export class Tracker\b/.test(fs.readFileSync(glue, 'utf8')),
    'www/pkg/ has no Tracker: rebuild it with scripts/build-wasm.sh',
  );
  assert.ok(fs.existsSync(path.join(WWW, 'models', 'manifest.json')), 'www/models/ is missing: run scripts/build-models.sh');
  server = await serveStatic(WWW);
  browser = await launchBrowser([AUTOPLAY]);
});

after(async () => {
  await camBrowser?.close();
  await browser?.close();
  await server?.close();
});

/** A fresh page on the demo; page errors and requests off the origin are collected. */
async function openPage(t, b = browser, { width = 1440, height = 1600, dpr = 1, init = null } = {}) {
  const context = await b.newContext({ viewport: { width, height }, deviceScaleFactor: dpr });
  const page = await context.newPage();
  const errors = [];
  const offOrigin = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => {
    if (m.type() === 'error') errors.push(m.text());
  });
  page.on('request', (r) => {
    const u = r.url();
    if (!u.startsWith(server.url) && !u.startsWith('blob:') && !u.startsWith('data:')) offOrigin.push(u);
  });
  if (init) await page.addInitScript(init);
  t.after(() => context.close());
  await page.goto(server.url);
  await page.waitForSelector('body[data-ready="1"]', { timeout: 30_000 });
  return { page, errors, offOrigin };
}

async function chooseSource(page, kind) {
  const kinds = await page.$$eval('#source-kind option', (os) => os.map((o) => o.value));
  assert.ok(kinds.includes(kind), `the source menu offers ${kinds.join(', ')}, not ${kind}`);
  await page.selectOption('#source-kind', kind);
  await page.waitForSelector(PANEL);
}

const tracking = (page, fn, arg) => page.evaluate(fn, arg);

/** The tracker's log (frames fitted so far), without the landmarks unless asked. */
function getLog(page, withLandmarks = false) {
  return tracking(
    page,
    (withLandmarks) =>
      window.facemimicTracking.log.map((l) => ({ ...l, landmarks: withLandmarks ? l.landmarks : undefined })),
    withLandmarks,
  );
}

const normError = landmarkError;

/** Pixels of the panel canvas that differ from the raw frame drawn at the same place. */
function overlayDiff(page, mirrored = false) {
  return page.evaluate((mirrored) => {
    const src = window.facemimicTracking;
    const c = src.canvas;
    const raw = document.createElement('canvas');
    raw.width = c.width;
    raw.height = c.height;
    const g = raw.getContext('2d');
    g.fillStyle = '#101114';
    g.fillRect(0, 0, c.width, c.height);
    const W = src.work.width;
    const H = src.work.height;
    const s = Math.min(c.width / W, c.height / H);
    g.imageSmoothingQuality = 'high';
    if (mirrored) {
      g.translate(c.width, 0);
      g.scale(-1, 1);
    }
    g.drawImage(src.work, (c.width - W * s) / 2, (c.height - H * s) / 2, W * s, H * s);
    const a = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    const b = g.getImageData(0, 0, c.width, c.height).data;
    let differ = 0;
    let greenish = 0;
    for (let i = 0; i < a.length; i += 4) {
      const d = Math.abs(a[i] - b[i]) + Math.abs(a[i + 1] - b[i + 1]) + Math.abs(a[i + 2] - b[i + 2]);
      if (d > 60) {
        differ++;
        if (a[i + 1] > 170 && a[i + 1] > a[i] + 40) greenish++;
      }
    }
    return { differ, greenish, pixels: a.length / 4 };
  }, mirrored);
}

test('the bundled clip plays and is tracked live, driving the source and the targets', async (t) => {
  const { page, errors, offOrigin } = await openPage(t);
  await chooseSource(page, 'video-clip');

  // Fit results arrive, and the source parameters change with them.
  await page.waitForFunction(() => window.facemimicTracking?.log.length >= 5, null, { timeout: 30_000 });
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'tracking');
  // The bundled clip shows the bundled person: their model's AAM is fitted.
  assert.equal(await page.$eval('.trk-path', (e) => e.dataset.path), 'aam');
  const p1 = await tracking(page, () => JSON.stringify(window.facemimicTracking.paramsAt(0)));
  const target1 = await canvasDigest(page, TARGETS);
  const source1 = await canvasDigest(page, '.face-card.source canvas.face');
  await page.waitForTimeout(700);
  const p2 = await tracking(page, () => JSON.stringify(window.facemimicTracking.paramsAt(0)));
  assert.notEqual(p1, p2, 'the source parameters did not change while the clip played');
  assert.notEqual(await canvasDigest(page, TARGETS), target1, 'a target canvas did not change while the clip played');
  assert.notEqual(await canvasDigest(page, '.face-card.source canvas.face'), source1, 'the source canvas did not change');
  const video = await page.$eval('.trk-panel video', (v) => ({ paused: v.paused, time: v.currentTime }));
  assert.ok(!video.paused && video.time > 0, `the clip is not playing (${JSON.stringify(video)})`);

  // A whole pass of the clip: every fitted frame tracked (none lost), low error, accurate
  // against the frames' dlib landmarks.
  await page.waitForFunction(() => window.facemimicTracking.loops >= 1, null, { timeout: 30_000 });
  const log = (await getLog(page, true)).filter((l) => l.loop === 0);
  const n = CLIP.frames;
  const frames = new Set(log.map((l) => l.frame));
  assert.ok(log.length >= 0.4 * n, `only ${log.length} of the clip's ${n} frames were fitted in one pass`);
  assert.equal(log[0].frame, 0, 'the first fit is not the first frame');
  assert.ok([...frames].every((f) => f >= 0 && f < n), `frame numbers out of range: ${[...frames]}`);
  const lost = log.filter((l) => l.lost);
  assert.equal(lost.length, 0, `frames reported lost: ${lost.map((l) => l.frame).join(', ')}`);
  const meanErr = log.reduce((s, l) => s + l.error, 0) / log.length;
  const maxErr = Math.max(...log.map((l) => l.error));
  assert.ok(meanErr < 0.05 && maxErr < 0.08, `fit error (RMS grey) mean ${meanErr.toFixed(4)}, max ${maxErr.toFixed(4)}`);
  const ms = log.map((l) => l.ms).sort((a, b) => a - b);
  const acc = [];
  if (fs.existsSync(CLIP_FRAMES)) {
    for (const l of log) {
      const pts = path.join(CLIP_FRAMES, `${String(l.frame).padStart(6, '0')}.pts`);
      acc.push(normError(l.landmarks, readPts(pts)));
    }
    const meanAcc = acc.reduce((a, b) => a + b, 0) / acc.length;
    const maxAcc = Math.max(...acc);
    console.log(
      `# clip: ${log.length}/${n} frames fitted in one pass, fit error mean ${meanErr.toFixed(4)} max ${maxErr.toFixed(4)}, ` +
        `landmark error (of the eye-corner distance) mean ${meanAcc.toFixed(4)} max ${maxAcc.toFixed(4)}, ` +
        `ms per fit median ${ms[ms.length >> 1].toFixed(2)} (incl. the first, cold one: max ${ms[ms.length - 1].toFixed(1)})`,
    );
    assert.ok(meanAcc <= 0.05, `mean landmark error ${meanAcc.toFixed(4)} of the eye-corner distance (<= 0.05 wanted)`);
    assert.ok(maxAcc <= 0.1, `worst frame's landmark error ${maxAcc.toFixed(4)} (<= 0.1 wanted)`);
  } else {
    console.log(`# ${CLIP_FRAMES} is absent: landmark accuracy not checked`);
  }

  // The second pass restarted from the first frame's landmarks.
  await page.waitForFunction(() => window.facemimicTracking.log.some((l) => l.loop === 1), null, { timeout: 10_000 });
  const second = (await getLog(page)).filter((l) => l.loop === 1);
  assert.equal(second[0].frame, 0, 'the loop did not restart at frame 0');

  // The readouts show the tracking state and speed.
  const readouts = await page.$$eval('.trk-stats dd', (dds) => Object.fromEntries(dds.map((d) => [d.dataset.k, d.textContent])));
  assert.match(readouts.error, /^0\.\d{3}$/, `fit error readout: ${readouts.error}`);
  assert.deepEqual(await page.$$eval('.trk-stats dt', (ds) => ds.map((d) => d.textContent)), ['fit error', 'iterations', 'fits / s', 'ms / fit', 'lost · reinit']);
  assert.ok(Number(readouts.fps) > 5, `fits per second readout: ${readouts.fps}`);
  assert.ok(Number(readouts.ms) > 0, `ms per fit readout: ${readouts.ms}`);
  assert.match(readouts.lost, /^0 · \d+$/, `lost readout: ${readouts.lost}`);
  assert.equal(await page.$eval('.trk-state', (e) => e.dataset.state), 'tracking');

  // The mesh is drawn over the video: the panel differs from the raw frame along the mesh
  // lines, and only there (switching the mesh off leaves the raw frame).
  // Space pauses and plays the video (not the page's recorded track); then pause with the button.
  await page.evaluate(() => document.activeElement?.blur());
  await page.keyboard.press('Space');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'paused', 'Space did not pause the video');
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'video-clip', 'Space switched the source');
  await page.keyboard.press('Space');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'tracking', 'Space did not resume the video');
  await page.click('.trk-panel button:has-text("Pause")');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'paused');
  const on = await overlayDiff(page);
  assert.ok(on.differ > 300 && on.greenish > 200, `no mesh over the video: ${JSON.stringify(on)}`);
  assert.ok(on.differ < on.pixels * 0.08, `the overlay covers too much of the video: ${JSON.stringify(on)}`);
  const stats = await canvasStats(page, PANEL_CANVAS);
  assert.ok(stats.variance > 100, `the video panel looks blank: ${JSON.stringify(stats)}`);
  await screenshot(page, 'tracking-clip', { fullPage: false });
  await page.click('.trk-panel label:has-text("Mesh overlay")');
  const off = await overlayDiff(page);
  assert.ok(off.differ < 20, `with the mesh off the panel is not the raw frame: ${JSON.stringify(off)}`);
  await page.click('.trk-panel label:has-text("Mesh overlay")');

  // Re-start goes back to frame 0 and tracks again; choosing another source removes the panel.
  const before = (await getLog(page)).length;
  await page.click('.trk-panel button:has-text("Re-start")');
  await page.waitForFunction((k) => window.facemimicTracking.log.length > k + 3, before, { timeout: 10_000 });
  const restarted = (await getLog(page)).slice(before);
  assert.equal(restarted[0].frame, 0, 'Re-start did not go back to the first frame');
  await page.selectOption('#source-kind', 'sliders');
  assert.equal(await page.$(PANEL), null, 'the tracking panel stayed after switching to the sliders');
  assert.deepEqual(errors, []);
  assert.deepEqual(offOrigin, []);
});

test('a video file is placed with a box, then tracked; a file that is neither video nor image is refused by name', async (t) => {
  const { page, errors } = await openPage(t);
  await chooseSource(page, 'video-file');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'empty');
  const targetsBefore = await page.$$eval('.face-card.target', (c) => c.length);

  // A dropped non-video file: an error naming it; nothing else changes.
  await page.$eval(PANEL, (panel) => {
    const dt = new DataTransfer();
    dt.items.add(new File(['not a video'], 'notes.txt', { type: 'text/plain' }));
    for (const type of ['dragenter', 'dragover', 'drop']) {
      panel.dispatchEvent(new DragEvent(type, { dataTransfer: dt, bubbles: true, cancelable: true }));
    }
  });
  const toast = await page.waitForSelector('.toast.error');
  const text = await toast.textContent();
  assert.match(text, /notes\.txt/, `the error does not name the file: ${text}`);
  assert.match(text, /not a video or an image/, `the error does not say why: ${text}`);
  assert.equal(await page.$$eval('.face-card.target', (c) => c.length), targetsBefore, 'a target was added');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'empty');

  // A file named like a video that is not one: the browser cannot decode it; the error names it.
  await page.$eval(PANEL, (panel) => {
    const dt = new DataTransfer();
    dt.items.add(new File([new Uint8Array(4096).fill(7)], 'broken.webm', { type: 'video/webm' }));
    panel.dispatchEvent(new DragEvent('drop', { dataTransfer: dt, bubbles: true, cancelable: true }));
  });
  await page.waitForFunction(() => [...document.querySelectorAll('.toast.error')].some((e) => /broken\.webm/.test(e.textContent)), null, {
    timeout: 20_000,
  });
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'empty');

  // A real video through the file picker, with Auto-start off (the manual path; auto-starting
  // is tested below): shown paused on its first frame with the face found and its box.
  await page.click('.trk-panel label:has-text("Auto-start")');
  await page.setInputFiles('.trk-panel input[type="file"]', CLIP_VIDEO);
  await page.waitForSelector('.trk-panel[data-phase="placing"]', { timeout: 20_000 });
  const paused = await page.$eval('.trk-panel video', (v) => ({ paused: v.paused, time: v.currentTime }));
  assert.ok(paused.paused && paused.time === 0, `the video is not paused on its first frame: ${JSON.stringify(paused)}`);
  await screenshot(page, 'tracking-file-place', { fullPage: false });

  // Keyboard: the frame is focusable and the arrows move the box.
  const box0 = await tracking(page, () => ({ ...window.facemimicTracking.box }));
  await page.focus(PANEL_CANVAS);
  await page.keyboard.press('ArrowRight');
  await page.keyboard.press('Shift+ArrowDown');
  const box1 = await tracking(page, () => ({ ...window.facemimicTracking.box }));
  assert.ok(box1.x > box0.x && box1.y > box0.y, `arrow keys did not move the box: ${JSON.stringify([box0, box1])}`);

  // Drag the box onto the face (the clip's first-frame landmarks say where it is).
  const xs = CLIP.initLandmarks.filter((_, i) => i % 2 === 0);
  const ys = CLIP.initLandmarks.filter((_, i) => i % 2 === 1);
  const face = { cx: (Math.min(...xs) + Math.max(...xs)) / 2, cy: (Math.min(...ys) + Math.max(...ys)) / 2 };
  const rect = await page.$eval(PANEL_CANVAS, (c) => {
    const r = c.getBoundingClientRect();
    return { left: r.left, top: r.top, width: r.width, height: r.height };
  });
  const toPage = (x, y) => [rect.left + (x / CLIP.width) * rect.width, rect.top + (y / CLIP.height) * rect.height];
  const [ax, ay] = toPage(box1.x + box1.w / 2, box1.y + box1.h / 2);
  const [bx, by] = toPage(face.cx, face.cy);
  await page.mouse.move(ax, ay);
  await page.mouse.down();
  await page.mouse.move((ax + bx) / 2, (ay + by) / 2, { steps: 4 });
  await page.mouse.move(bx, by, { steps: 4 });
  await page.mouse.up();
  const box2 = await tracking(page, () => ({ ...window.facemimicTracking.box }));
  assert.ok(
    Math.abs(box2.x + box2.w / 2 - face.cx) < 4 && Math.abs(box2.y + box2.h / 2 - face.cy) < 4,
    `dragging did not move the box onto the face: ${JSON.stringify({ box2, face })}`,
  );
  // ...and its corner handle resizes it (keeping the mean shape's proportions).
  const [hx, hy] = toPage(box2.x + box2.w, box2.y + box2.h);
  await page.mouse.move(hx, hy);
  await page.mouse.down();
  await page.mouse.move(hx + 12, hy + 12, { steps: 3 });
  await page.mouse.up();
  const box3 = await tracking(page, () => ({ ...window.facemimicTracking.box }));
  assert.ok(box3.h > box2.h * 1.02, `the corner did not resize the box: ${JSON.stringify([box2, box3])}`);
  assert.ok(Math.abs(box3.w / box3.h - box2.w / box2.h) < 1e-6, 'resizing changed the proportions');
  // Back to the face's size (the face's own box), then start.
  await page.evaluate((f) => {
    const s = window.facemimicTracking;
    const h = f.h;
    const w = h / s.boxAspect;
    s.box = { x: f.cx - w / 2, y: f.cy - h / 2, w, h };
    s.draw();
  }, { ...face, h: Math.max(...ys) - Math.min(...ys) });

  await page.click('.trk-panel button:has-text("Start tracking")');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'tracking');
  await page.waitForFunction(() => window.facemimicTracking.log.length >= 30, null, { timeout: 30_000 });
  const log = await getLog(page, true);
  const lost = log.filter((l) => l.lost).length;
  const meanErr = log.reduce((s, l) => s + l.error, 0) / log.length;
  let acc = null;
  if (fs.existsSync(CLIP_FRAMES)) {
    const errs = log
      .filter((l) => !l.lost)
      .map((l) => normError(l.landmarks, readPts(path.join(CLIP_FRAMES, `${String(Math.min(CLIP.frames - 1, l.frame)).padStart(6, '0')}.pts`))));
    acc = errs.reduce((a, b) => a + b, 0) / errs.length;
  }
  console.log(`# file from a box: ${log.length} fits, ${lost} lost, fit error mean ${meanErr.toFixed(4)}, landmark error mean ${acc?.toFixed(4)}`);
  assert.equal(lost, 0, 'frames lost tracking the file from the placed box');
  assert.ok(meanErr < 0.06, `fit error mean ${meanErr}`);
  if (acc !== null) assert.ok(acc < 0.08, `landmark error from the box: ${acc}`);
  await screenshot(page, 'tracking-file', { fullPage: false });
  // At its end the file loops back to where tracking began and keeps tracking.
  await page.waitForFunction(() => window.facemimicTracking.log.filter((l) => l.loop === 1).length >= 5, null, { timeout: 20_000 });
  const again = (await getLog(page)).filter((l) => l.loop === 1);
  assert.equal(again[0].frame, 0, 'the file did not loop back to the frame tracking began on');
  assert.equal(again.filter((l) => l.lost).length, 0, 'frames lost after the file looped');
  assert.deepEqual(errors.filter((e) => !/broken\.webm|notes\.txt/.test(e)), []);
});

test('the webcam starts with a face guide (fake camera: no face) and reports its state', async (t) => {
  camBrowser = await launchBrowser(FAKE_CAMERA_ARGS);
  const { page, errors } = await openPage(t, camBrowser);
  await chooseSource(page, 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="placing"]', { timeout: 20_000 });
  // The live picture with the guide is drawn and keeps changing (the fake camera animates).
  await page.waitForFunction(() => window.facemimicTracking.frameNo > 6, null, { timeout: 10_000 });
  const d1 = await canvasDigest(page, PANEL_CANVAS);
  await page.waitForTimeout(400);
  assert.notEqual(await canvasDigest(page, PANEL_CANVAS), d1, 'the webcam picture does not update');
  const stats = await canvasStats(page, PANEL_CANVAS, 0.9);
  assert.ok(stats.distinct > 20, `the webcam panel looks blank: ${JSON.stringify(stats)}`);
  assert.equal(await page.$eval('.trk-state', (e) => e.textContent), 'looking for a face');
  await page.waitForTimeout(1500);
  // No face in the fake picture: auto-start must not have fired.
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'placing', 'auto-start fired without a face');
  await screenshot(page, 'tracking-webcam-guide', { fullPage: false });

  // Start by hand: the tracker runs and reports a state (the face is lost: there is none).
  await page.click('.trk-panel button:has-text("Start")');
  await page.waitForFunction(() => window.facemimicTracking.fits >= 5, null, { timeout: 10_000 });
  const state = await page.$eval('.trk-state', (e) => e.dataset.state);
  assert.ok(['tracking', 'lost', 'reinit', 'placing'].includes(state), `state ${state}`);
  await screenshot(page, 'tracking-webcam-started', { fullPage: false });
  // Re-start brings the guide back (as does a long loss: 40 lost frames, which a slow machine
  // may already have reached).
  if ((await page.getAttribute(PANEL, 'data-phase')) === 'tracking') await page.click('.trk-panel button:has-text("Re-start")');
  assert.equal(await page.getAttribute(PANEL, 'data-phase'), 'placing');
  // The camera going away (unplugged, access withdrawn) is explained; Try again reopens it.
  await page.evaluate(() => window.facemimicTracking.stream.getVideoTracks()[0].dispatchEvent(new Event('ended')));
  assert.equal(await page.getAttribute(PANEL, 'data-state'), 'error');
  assert.match(await page.$eval('.trk-placeholder', (e) => e.textContent), /camera stopped/);
  await page.click('.trk-placeholder button:has-text("Try again")');
  await page.waitForSelector('.trk-panel[data-phase="placing"]', { timeout: 20_000 });
  // Switching away stops the camera.
  await page.selectOption('#source-kind', 'sliders');
  const live = await page.evaluate(() => window.facemimicTracking);
  assert.equal(live, null);
  assert.deepEqual(errors, []);
});

/**
 * A fake camera with a face: spk07's clip frames (the JPEGs in data/grid) with the face in the
 * webcam guide of a 640x480 picture (tests/e2e/lib.mjs `fakeCameraFile`); null when the frames
 * are absent.
 */
async function faceCamera(t) {
  if (!fs.existsSync(CLIP_FRAMES)) return null;
  return fakeCameraFile(t, CLIP_FRAMES, { name: 'face-camera' });
}

test('the webcam auto-starts on a face in the guide and tracks it live', async (t) => {
  const file = await faceCamera(t);
  if (!file) {
    t.skip(`${CLIP_FRAMES} is absent`);
    return;
  }
  const b = await cameraBrowser(t, file);
  const { page, errors } = await openPage(t, b);
  await chooseSource(page, 'webcam');
  // Nobody presses Start: the face in the guide is found and tracking starts by itself.
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 20_000 });
  await page.waitForFunction(() => window.facemimicTracking.log.length >= 40, null, { timeout: 30_000 });
  const log = await getLog(page);
  const lost = log.filter((l) => l.lost).length;
  const meanErr = log.reduce((s, l) => s + l.error, 0) / log.length;
  console.log(`# face camera: auto-started, ${log.length} fits, ${lost} lost, fit error mean ${meanErr.toFixed(4)}`);
  assert.equal(lost, 0, 'frames lost tracking the face camera');
  // The page gives the follower the work canvas as it is (640x480 here): its landmark passes cost
  // the same at any face size, so it does not resample (the AAM tracker's own choice of scale is
  // checked in tests/integration/track_policy.rs and crates/cli/tests/integration/cli.rs).
  const scale = await tracking(page, () => window.facemimicTracking.tracker.scale);
  assert.equal(scale, 1, 'the follower resampled the frame');
  assert.ok(meanErr < 0.06, `fit error mean ${meanErr}`);
  assert.equal(await page.$eval('.trk-state', (e) => e.dataset.state), 'tracking');
  // The source face follows: its parameters change, it stays centred (pose re-centred).
  const p1 = await tracking(page, () => JSON.stringify(window.facemimicTracking.paramsAt(0)));
  await page.waitForTimeout(500);
  assert.notEqual(await tracking(page, () => JSON.stringify(window.facemimicTracking.paramsAt(0))), p1);
  const on = await overlayDiff(page, true);
  assert.ok(on.differ > 300 && on.greenish > 200, `no mesh over the webcam picture: ${JSON.stringify(on)}`);
  // The bundled source model is not this person's own: the face is followed by its landmarks
  // (the package's Tracker.follower, the core's policy), and the panel says so and offers "Create a face".
  assert.equal(await page.$eval('.trk-path', (e) => e.dataset.path), 'landmarks');
  assert.match(await page.$eval('.trk-path', (e) => e.textContent), /Following landmarks/);
  assert.equal(await page.$eval('.trk-path button', (e) => e.textContent), 'Create a face');
  assert.equal(await tracking(page, () => window.facemimicTracking.tracker.path), 'landmarks');
  // Its readout is the face mesh's (no AAM is fitted): the score, the passes, frames a second.
  const stats = await page.$$eval('.trk-stats div', (ds) => Object.fromEntries(ds.map((d) => [d.querySelector('dd').dataset.k, [d.querySelector('dt').textContent, d.querySelector('dd').textContent]])));
  assert.deepEqual([stats.error[0], stats.iterations[0], stats.fps[0], stats.ms[0]], ['face score', 'mesh passes', 'frames / s', 'ms / frame']);
  assert.match(stats.error[1], /^(0\.[5-9]\d\d|1\.000)$/, `face score readout: ${stats.error[1]}`);
  assert.match(stats.iterations[1], /^[12]$/, `mesh passes readout: ${stats.iterations[1]}`);
  await screenshot(page, 'tracking-webcam-face', { fullPage: false });
  assert.deepEqual(errors, []);
});

test('webcam errors: a denied permission and a missing camera are explained', async (t) => {
  for (const [name, expect] of [
    ['NotAllowedError', /permission was denied/i],
    ['NotFoundError', /no camera was found/i],
  ]) {
    const { page, errors } = await openPage(t, browser, {
      init: `navigator.mediaDevices.getUserMedia = () => Promise.reject(new DOMException('test', '${name}'));`,
    });
    await chooseSource(page, 'webcam');
    await page.waitForSelector('.trk-panel[data-state="error"]', { timeout: 10_000 });
    const msg = await page.$eval('.trk-msg', (e) => e.textContent);
    assert.match(msg, expect, `${name}: ${msg}`);
    const toast = await page.$eval('.toast.error', (e) => e.textContent);
    assert.match(toast, expect);
    if (name === 'NotAllowedError') await screenshot(page, 'tracking-webcam-denied', { fullPage: false });
    // The page keeps running: another source still works.
    await page.selectOption('#source-kind', 'sliders');
    assert.equal(await page.$(PANEL), null);
    assert.deepEqual(errors, []);
  }
});

test('the tracking panel fits a phone screen', async (t) => {
  const { page, errors } = await openPage(t, browser, { width: 390, height: 844, dpr: 2 });
  await chooseSource(page, 'video-clip');
  await page.waitForFunction(() => window.facemimicTracking?.log.length >= 10, null, { timeout: 30_000 });
  const layout = await page.evaluate(() => {
    const p = document.querySelector('.trk-panel').getBoundingClientRect();
    const c = document.querySelector('.trk-panel canvas').getBoundingClientRect();
    return { scroll: document.documentElement.scrollWidth, vw: innerWidth, panel: [p.left, p.right], canvas: [c.left, c.right, c.width] };
  });
  assert.ok(layout.scroll <= layout.vw, `the page scrolls sideways: ${JSON.stringify(layout)}`);
  assert.ok(layout.panel[0] >= 0 && layout.panel[1] <= layout.vw, `the panel overflows: ${JSON.stringify(layout)}`);
  assert.ok(layout.canvas[2] > 0.7 * layout.vw, `the video is too small on a phone: ${JSON.stringify(layout)}`);
  await page.$eval(PANEL, (p) => p.scrollIntoView());
  await screenshot(page, 'tracking-phone', { fullPage: false });
  assert.deepEqual(errors, []);
});

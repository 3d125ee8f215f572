// The page's flow, issue 33 part 4, item 2: the transport (Play, the scrubber, the counter)
// shows only what drives the source. The recorded track: its Play and "12 / 75"; the sliders
// and the webcam (a fake camera playing spk07's unseen GRID clip, committed data): no Play, no
// track counter, a line saying what drives the source; a video file and the bundled clip: the
// video's own Play / Pause, scrubber and time. Switching sources switches it. Screenshots:
// artifacts/flow-transport-*.png.
//
//   node --test --test-concurrency=1 tests/e2e/flow_transport.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { ROOT, screenshot, openPage, pageSuite } from './lib.mjs';

const WWW = path.join(ROOT, 'www');
const CLIP = JSON.parse(fs.readFileSync(path.join(WWW, 'media', 'spk07-clip.json'), 'utf8'));
const CLIP_VIDEO = path.join(WWW, 'media', CLIP.video);
const CAMERA_CLIP = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');

const suite = pageSuite(WWW, { camera: { frames: CAMERA_CLIP, name: 'flow-transport' } });

/** What the transport bar shows (only what is visible counts). */
function transport(page) {
  return page.evaluate(() => {
    const $ = (id) => document.getElementById(id);
    const seen = (e) => Boolean(e && e.checkVisibility());
    const note = $('transport-note');
    return {
      what: document.querySelector('.transport').dataset.transport,
      kind: $('source-kind').value,
      play: seen($('play')),
      scrub: seen($('scrub')),
      counter: seen($('frame-counter')) ? $('frame-counter').textContent : null,
      state: $('play').dataset.state,
      label: $('play').textContent.trim(),
      note: seen(note) ? note.textContent : null,
    };
  });
}

const NOTHING = { play: false, scrub: false, counter: null };
const pick = (t, keys) => Object.fromEntries(keys.map((k) => [k, t[k]]));

test('the transport shows only what drives the source: the track, nothing for the sliders or the webcam, the video for a file or the clip', async (t) => {
  const { page, errors } = await openPage(t, suite.browser, suite.server, { context: { viewport: { width: 1440, height: 1300 } } });

  // The recorded track (the page opens playing it): its Play and frame counter.
  let s = await transport(page);
  assert.equal(s.what, 'track');
  assert.ok(s.play && s.scrub, `the track's Play and scrubber: ${JSON.stringify(s)}`);
  assert.match(s.counter, /^\d+ \/ \d+$/);
  assert.equal(s.state, 'playing');
  assert.equal(s.note, null);

  // The sliders: nothing of a track.
  await page.selectOption('#source-kind', 'sliders');
  s = await transport(page);
  assert.deepEqual({ what: s.what, ...pick(s, Object.keys(NOTHING)) }, { what: 'none', ...NOTHING }, JSON.stringify(s));
  assert.match(s.note, /sliders/i);
  assert.equal(await page.isDisabled('#play'), true);

  // The webcam: no Play, no counter; a line says it is live. Tracking starts by itself.
  await page.selectOption('#source-kind', 'webcam');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 60_000 });
  s = await transport(page);
  assert.deepEqual({ what: s.what, ...pick(s, Object.keys(NOTHING)) }, { what: 'none', ...NOTHING }, JSON.stringify(s));
  assert.equal(s.note, 'Live from the webcam');
  await page.waitForFunction(() => window.facemimicTracking.log.length >= 10, null, { timeout: 30_000 });
  await screenshot(page, 'flow-transport-webcam', { fullPage: false });
  await page.locator('.transport').screenshot({ path: path.join(ROOT, 'artifacts', 'flow-transport-webcam-bar.png') });
  // Space is the webcam panel's (pause / go on), never the track's.
  await page.evaluate(() => document.activeElement?.blur());
  await page.keyboard.press('Space');
  assert.equal(await page.getAttribute('.trk-panel', 'data-phase'), 'paused');
  assert.equal((await transport(page)).what, 'none');
  await page.keyboard.press('Space');
  assert.equal(await page.getAttribute('.trk-panel', 'data-phase'), 'tracking');

  // Back to the track: its transport again.
  await page.selectOption('#source-kind', 'track');
  s = await transport(page);
  assert.equal(s.what, 'track');
  assert.match(s.counter, /^\d+ \/ \d+$/);

  // A video file: nothing until it is open, then the video's Play / Pause, scrubber and time.
  await page.selectOption('#source-kind', 'video-file');
  await page.waitForSelector('.trk-panel[data-phase="empty"]');
  s = await transport(page);
  assert.deepEqual({ what: s.what, ...pick(s, Object.keys(NOTHING)) }, { what: 'none', ...NOTHING }, JSON.stringify(s));
  assert.match(s.note, /drop a video/i);
  await page.setInputFiles('.trk-panel input[type="file"]', CLIP_VIDEO);
  await page.waitForSelector('.trk-panel[data-phase="tracking"]', { timeout: 30_000 });
  await page.waitForFunction(() => document.querySelector('.transport').dataset.transport === 'video');
  s = await transport(page);
  assert.ok(s.play && s.scrub, JSON.stringify(s));
  const duration = CLIP.frames / (CLIP.fps || 25);
  const m = /^0:(\d\d\.\d) \/ 0:(\d\d\.\d)$/.exec(s.counter);
  assert.ok(m, `the video's time: ${s.counter}`);
  assert.ok(Math.abs(Number(m[2]) - duration) < 0.3, `the video lasts ${m[2]} s, the clip ${duration} s`);
  assert.deepEqual([s.state, s.label], ['playing', 'Pause']);
  assert.equal(s.note, null);
  const c0 = s.counter;
  await page.waitForTimeout(600);
  assert.notEqual((await transport(page)).counter, c0, 'the counter follows the video');

  // Pause: the video and its tracking pause; the track is not touched.
  await page.click('#play');
  await page.waitForSelector('.trk-panel[data-phase="paused"]');
  s = await transport(page);
  assert.deepEqual([s.what, s.kind, s.state, s.label], ['video', 'video-file', 'paused', 'Play']);
  assert.equal(await page.$eval('.trk-panel video', (v) => v.paused), true);
  // The scrubber moves the video; paused, the frame there is fitted (the source follows it).
  const fits = await page.evaluate(() => window.facemimicTracking.fits);
  await page.$eval('#scrub', (el) => {
    el.value = '1';
    el.dispatchEvent(new Event('input', { bubbles: true }));
  });
  await page.waitForFunction(() => Math.abs(document.querySelector('.trk-panel video').currentTime - 1) < 0.05);
  await page.waitForFunction((n) => window.facemimicTracking.fits > n, fits);
  await page.waitForFunction(() => /^0:01\.0 \//.test(document.getElementById('frame-counter').textContent));
  assert.equal((await transport(page)).kind, 'video-file', 'the scrubber switched the source');
  await screenshot(page, 'flow-transport-video', { fullPage: false });
  await page.locator('.transport').screenshot({ path: path.join(ROOT, 'artifacts', 'flow-transport-video-bar.png') });
  await page.click('#play');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]');
  assert.equal((await transport(page)).state, 'playing');
  // Space is the video's Play / Pause as well (never the track's while a video drives the source).
  await page.evaluate(() => document.activeElement?.blur());
  await page.keyboard.press('Space');
  await page.waitForSelector('.trk-panel[data-phase="paused"]');
  assert.deepEqual([(await transport(page)).state, (await transport(page)).kind], ['paused', 'video-file']);
  await page.keyboard.press('Space');
  await page.waitForSelector('.trk-panel[data-phase="tracking"]');

  // The bundled clip: a video too.
  await page.selectOption('#source-kind', 'video-clip');
  await page.waitForFunction(() => document.querySelector('.transport').dataset.transport === 'video', null, { timeout: 30_000 });
  s = await transport(page);
  assert.match(s.counter, /^0:\d\d\.\d \/ 0:\d\d\.\d$/);

  // And the track once more: frames, playing.
  await page.selectOption('#source-kind', 'track');
  s = await transport(page);
  assert.deepEqual([s.what, s.state], ['track', 'playing']);
  assert.match(s.counter, /^\d+ \/ \d+$/);
  assert.deepEqual(errors, []);
});

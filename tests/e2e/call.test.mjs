// The call page (www/call.html) end to end: two headless Chromium pages, each with a fake camera
// (spk07's unseen GRID clip at 640x480) and a fake microphone (a 440 Hz tone), joined through the
// demo server's signalling endpoint (node scripts/serve.mjs, a child process).
//
//   connect, see (the remote picture has frames and is not black) and hear (the remote audio
//   carries energy); privacy: every video track ever given to the RTCPeerConnection is the avatar
//   canvas's (checked by wrapping the WebRTC API in the page, not by asking the page);
//   the experimenter's controls: switch identity mid-call with no renegotiation, set the other
//   side's gain, expression gain per region and head motion; garbage over the data channel does
//   not hurt the other page;
//   the per-frame CSV log; the peer's camera lost (their avatar holds, marked); a reload rejoins;
//   a server restart is survived (the call carries on; the signalling comes back with back-off);
//   the peer leaves; the copy-paste exchange without a server; bad links are explained.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import { launchBrowser, haveChromium, screenshot, serveStatic, ROOT, pkg } from './lib.mjs';
import { fakeMedia, startDemoServer, status, waitCall, remotePicture, meanAbs, twoPages } from '../../scripts/lib/call.mjs';
import path from 'node:path';

/** Sets the input `selector` of `page` to `value` as the user would: an `input` event follows. */
function setInput(page, selector, value) {
  return page.$eval(selector, (el, v) => {
    el.value = v;
    el.dispatchEvent(new Event('input'));
  }, value);
}

const HAVE_PKG = fs.existsSync(path.join(ROOT, 'www', 'pkg', 'facemimic_bg.wasm')) && fs.existsSync(path.join(ROOT, 'www', 'models', 'manifest.json'));
const skip = !haveChromium() ? 'chromium is absent' : !HAVE_PKG ? 'www/pkg or www/models is missing (scripts/build-wasm.sh, scripts/build-models.sh)' : false;

const cleanups = [];
let browser;
let server;
let a;
let b;
let room;
const errors = [];

/** Record every track the page gives to an RTCPeerConnection (the privacy check's own view). */
function spyOnWebRTC() {
  const seen = [];
  window.__sentTracks = seen;
  const note = (t) => t && seen.push({ kind: t.kind, canvas: Boolean(t.canvas), label: t.label, id: t.id });
  const P = RTCPeerConnection.prototype;
  const addTrack = P.addTrack;
  P.addTrack = function (track, ...s) {
    note(track);
    return addTrack.call(this, track, ...s);
  };
  const addTransceiver = P.addTransceiver;
  P.addTransceiver = function (t, ...r) {
    if (typeof t !== 'string') note(t);
    return addTransceiver.call(this, t, ...r);
  };
  const replaceTrack = RTCRtpSender.prototype.replaceTrack;
  RTCRtpSender.prototype.replaceTrack = function (t) {
    note(t);
    return replaceTrack.call(this, t);
  };
  const createDataChannel = P.createDataChannel;
  window.__channels = [];
  P.createDataChannel = function (...args) {
    const dc = createDataChannel.apply(this, args);
    window.__channels.push(dc);
    return dc;
  };
}

const watch = (page, label) => {
  page.on('pageerror', (e) => errors.push(`${label}: ${e.message}`));
};

async function open(url, label) {
  const ctx = await browser.newContext({ viewport: { width: 1360, height: 900 } });
  await ctx.addInitScript(spyOnWebRTC);
  const page = await ctx.newPage();
  watch(page, label);
  await page.goto(url);
  return page;
}

before(async () => {
  if (skip) return;
  const args = await fakeMedia((fn) => cleanups.push(fn));
  browser = await launchBrowser(args);
  server = await startDemoServer({ env: { FACEMIMIC_SIGNAL_HEARTBEAT_MS: '2000' } });
});

after(async () => {
  await browser?.close();
  await server?.stop();
  for (const fn of cleanups) fn();
});

test('two pages connect; each sees the other\'s avatar (frames, not black) and hears their microphone; only the canvas is sent', { skip }, async () => {
  a = await open(`${server.url}call.html?autojoin=1&avatar=spk02`, 'A');
  await waitCall(a, () => window.facemimicCall.inviteUrl);
  const s0 = await status(a);
  assert.equal(s0.state, 'waiting');
  room = s0.room;
  assert.match(room, /^[A-Za-z0-9_-]{32}$/);
  assert.equal(new URL(s0.inviteUrl).searchParams.get('room'), room);
  b = await open(`${s0.inviteUrl}&autojoin=1&avatar=spk03`, 'B');
  for (const p of [a, b]) await waitCall(p, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 30, 45000);
  await a.waitForTimeout(2000);
  for (const [p, peer] of [[a, 'spk03'], [b, 'spk02']]) {
    const s = await status(p);
    assert.equal(s.sentVideo, 'canvas');
    assert.equal(s.method, pkg().methods().find((m) => m.isDefault).name, "the avatar is cloned with the core's default method");
    assert.deepEqual([s.settings.mouth, s.settings.eyes, s.settings.brows], [1, 1, 1]);
    assert.equal(s.peer.avatar, peer);
    assert.equal(s.peer.camera, 'ok', 'the peer tracks its camera');
    assert.ok(s.remoteFps >= 5, `remote fps ${s.remoteFps}`);
    assert.ok(Number.isFinite(s.latencyMs) && s.latencyMs > 0 && s.latencyMs < 1000, `latency ${s.latencyMs}`);
    const pic = await remotePicture(p);
    assert.equal(pic.width, 640);
    assert.equal(pic.height, 480);
    assert.ok(pic.mean > 30 && pic.variance > 200, `the remote picture is not blank: mean ${pic.mean.toFixed(1)}, variance ${pic.variance.toFixed(0)}`);
    // Hearing: the remote audio track is live and carries the tone's energy.
    const live = await p.evaluate(() => document.getElementById('remote').srcObject.getAudioTracks().map((t) => t.readyState));
    assert.deepEqual(live, ['live']);
    const e0 = s.audio.energy;
    await p.waitForTimeout(1500);
    const s2 = await status(p);
    assert.ok(s2.audio.sending, 'this page sends its microphone');
    assert.ok(s2.audio.energy > e0 && s2.audio.level > 0.01, `audio energy ${e0} -> ${s2.audio.energy}, level ${s2.audio.level}`);
    // Privacy, by the WebRTC API's own record: the only video track given was the canvas's.
    const sent = await p.evaluate(() => window.__sentTracks);
    const video = sent.filter((t) => t.kind === 'video');
    assert.ok(video.length >= 1);
    assert.ok(video.every((t) => t.canvas), `video tracks sent: ${JSON.stringify(video)}`);
    assert.ok(sent.filter((t) => t.kind === 'audio').length >= 1, 'the microphone is sent');
    // The webcam is open, and stays in the page.
    const cam = await p.evaluate(() => window.facemimicTracking?.stream?.getVideoTracks().map((t) => t.id) ?? []);
    assert.equal(cam.length, 1);
    assert.ok(!video.some((t) => t.id === cam[0]));
    // The bundled source model is not the caller's own face: the core's policy follows them by
    // their landmarks (as the main page does), not by fitting another person's AAM.
    assert.equal(await p.evaluate(() => window.facemimicTracking?.tracker?.path), 'landmarks');
  }
  // The status object is read-only.
  const kept = await a.evaluate(() => {
    try {
      window.facemimicCall.state = 'hacked';
    } catch {
      // strict mode throws; either way it must not change
    }
    return window.facemimicCall.state;
  });
  assert.equal(kept, 'connected');
  await screenshot(a, 'call-connected', { fullPage: false });
});

test('identity switch mid-call (no renegotiation); the experimenter sets the other side; garbage over the data channel is ignored', { skip }, async () => {
  const before = await status(b);
  const negA = (await status(a)).negotiations;
  const pic0 = await remotePicture(b);
  await a.selectOption('#avatar-model', 'b:spk05.fmm');
  await waitCall(b, () => window.facemimicCall.peer.avatar === 'spk05', 10000);
  await b.waitForTimeout(1500);
  const pic1 = await remotePicture(b);
  const diff = meanAbs(pic0.pixels, pic1.pixels);
  assert.ok(diff > 8, `B's picture of A changed with the identity: mean difference ${diff.toFixed(1)}`);
  const afterA = await status(a);
  const afterB = await status(b);
  assert.equal(afterA.negotiations, negA, 'A did not renegotiate');
  assert.equal(afterB.negotiations, before.negotiations, 'B did not renegotiate');
  assert.equal(afterB.state, 'connected');
  assert.equal(afterA.avatar, 'spk05');

  // B (the experimenter) sets A's gain, head motion and avatar through the data channel.
  await setInput(b, '#peer-gain', '0.5');
  await setInput(b, '#peer-head', '0.2');
  await waitCall(a, () => window.facemimicCall.settings.gain === 0.5 && window.facemimicCall.settings.head === 0.2, 5000);
  // ... and A's expression gain per region (0..3), beside the gain; B sees them in A's status.
  await setInput(b, '#peer-mouth', '3');
  await setInput(b, '#peer-eyes', '0');
  await setInput(b, '#peer-brows', '2.5');
  await waitCall(a, () => {
    const s = window.facemimicCall.settings;
    return s.mouth === 3 && s.eyes === 0 && s.brows === 2.5 && s.gain === 0.5;
  }, 5000);
  assert.deepEqual(await a.$$eval('#mouth, #eyes, #brows', (els) => els.map((e) => e.value)), ['3', '0', '2.5'], "A's own sliders show them");
  await waitCall(b, () => window.facemimicCall.peer.mouth === 3 && window.facemimicCall.peer.eyes === 0 && window.facemimicCall.peer.brows === 2.5, 5000);
  assert.equal(await b.textContent('#peer-mouth-out'), '3.00');
  // ... and its style (0..1: the avatar's own range to the full motion).
  await setInput(b, '#peer-style', '0.25');
  await waitCall(a, () => window.facemimicCall.settings.style === 0.25, 5000);
  await waitCall(b, () => window.facemimicCall.peer.style === 0.25, 5000);
  assert.equal(await a.inputValue('#style'), '0.25', "A's own style slider shows it");
  await b.selectOption('#peer-avatar', 'b:spk06.fmm');
  await waitCall(a, () => window.facemimicCall.avatar === 'spk06', 5000);
  assert.equal((await status(a)).negotiations, negA);
  // A refuses once "Let the other side set mine" is off.
  await a.uncheck('#allow-remote');
  await setInput(b, '#peer-gain', '2');
  await setInput(b, '#peer-mouth', '1');
  await a.waitForTimeout(800);
  assert.equal((await status(a)).settings.gain, 0.5);
  assert.equal((await status(a)).settings.mouth, 3, 'a refused region gain was applied');
  await a.check('#allow-remote');

  // Garbage from B's page straight into the data channel.
  const r0 = (await status(a)).rejectedMessages;
  const sent = await b.evaluate(() => {
    const dc = window.__channels.find((c) => c.readyState === 'open');
    const bad = [
      'not json',
      '{"t":"set","gain":1e9}',
      '{"t":"set","gain":"1"}',
      '{"t":"set","mouth":3.5}',
      '{"t":"set","eyes":-1}',
      '{"t":"set","brows":"2"}',
      '{"t":"set","gain":1,"mouth":1e9}',
      '{"t":"set","avatar":"../../etc/passwd"}',
      '{"t":"set"}',
      '{"t":"status","camera":"<img src=x onerror=alert(1)>"}',
      '{"t":"status","camera":"ok","pipelineMs":-5}',
      '{"__proto__":{"polluted":true},"t":"nope"}',
      '[1,2,3]',
      'null',
      'x'.repeat(60000),
    ];
    for (const m of bad) dc.send(m);
    dc.send(new Uint8Array([0, 1, 2, 255]).buffer);
    return bad.length + 1;
  });
  await waitCall(a, () => window.facemimicCall.rejectedMessages >= 16, 5000);
  const s = await status(a);
  assert.equal(s.rejectedMessages - r0, sent);
  assert.equal(s.settings.gain, 0.5, 'no bad message changed a setting');
  assert.deepEqual([s.settings.mouth, s.settings.eyes, s.settings.brows], [3, 0, 2.5], 'no bad message changed a region gain');
  assert.equal(s.avatar, 'spk06');
  assert.equal(await a.evaluate(() => ({}).polluted), undefined);
  await a.waitForTimeout(1000);
  assert.equal((await status(a)).state, 'connected');
  assert.ok((await status(b)).remoteFps > 0);

  // Back to the defaults, and A's own controls.
  await setInput(a, '#gain', '1');
  await setInput(a, '#head', '1');
  for (const r of ['mouth', 'eyes', 'brows']) await setInput(a, `#${r}`, '1');
  await waitCall(b, () => ['gain', 'head', 'mouth', 'eyes', 'brows'].every((k) => window.facemimicCall.peer[k] === 1), 5000);
});

test('the per-frame log downloads as CSV: timestamps, source and target parameters, pose, lost flag, settings', { skip }, async () => {
  const [download] = await Promise.all([a.waitForEvent('download'), a.click('#download-log')]);
  const file = await download.path();
  const lines = fs.readFileSync(file, 'utf8').trim().split('\n');
  const head = lines[0].split(',');
  for (const c of ['wall_ms', 'frame', 'capture_ms', 'render_ms', 'lost', 'gain', 'head_motion', 'avatar', 'fit_scale', 'sent_scale', 'sent_rotation', 'mouth_gain', 'eyes_gain', 'brows_gain', 'style', 'src_shape_1', 'src_app_1', 'tgt_shape_1', 'tgt_app_1']) {
    assert.ok(head.includes(c), `column ${c}`);
  }
  assert.ok(lines.length > 100, `${lines.length - 1} rows`);
  const rows = lines.slice(1).map((l) => l.split(','));
  const col = (name) => head.indexOf(name);
  const wall = rows.map((r) => Number(r[col('wall_ms')]));
  for (let i = 1; i < wall.length; i++) assert.ok(wall[i] >= wall[i - 1], 'rows in time order');
  assert.ok(rows.every((r) => r[col('lost')] === '0' || r[col('lost')] === '1'));
  const avatars = new Set(rows.map((r) => r[col('avatar')]));
  for (const n of ['"spk02"', '"spk05"', '"spk06"']) assert.ok(avatars.has(n), `avatar ${n} in the log (${[...avatars]})`);
  const gains = new Set(rows.map((r) => r[col('gain')]));
  assert.ok(gains.has('0.5') && gains.has('1'), `gains logged: ${[...gains]}`);
  const mouths = new Set(rows.map((r) => r[col('mouth_gain')]));
  assert.ok(mouths.has('3') && mouths.has('1'), `mouth gains logged: ${[...mouths]}`);
  const good = rows.filter((r) => r[col('lost')] === '0');
  assert.ok(good.length > 50);
  for (const r of good.slice(-20)) {
    for (const c of ['src_shape_1', 'tgt_shape_1', 'sent_scale', 'fit_scale', 'render_ms']) assert.ok(Number.isFinite(Number(r[col(c)])) && r[col(c)] !== '', `${c} = ${r[col(c)]}`);
  }
  // Head motion 0.2 pulls the sent pose towards its mean: sent rotation varies less than fitted.
  const spread = (name, rs) => {
    const v = rs.map((r) => Number(r[col(name)]));
    const m = v.reduce((x, y) => x + y, 0) / v.length;
    return Math.sqrt(v.reduce((x, y) => x + (y - m) ** 2, 0) / v.length);
  };
  const damped = good.filter((r) => r[col('head_motion')] === '0.2');
  assert.ok(damped.length > 10, `${damped.length} frames at head motion 0.2`);
  assert.ok(spread('sent_tx', damped) < spread('fit_tx', damped), 'damped head motion');
});

test("the peer's camera is lost: their avatar holds its last frame, marked", { skip }, async () => {
  await b.evaluate(() => {
    const t = window.facemimicTracking.stream.getVideoTracks()[0];
    t.stop();
    t.dispatchEvent(new Event('ended'));
  });
  await waitCall(a, () => window.facemimicCall.state === 'camera-lost', 10000);
  assert.equal(await a.isVisible('#remote-badge'), true);
  assert.match(await a.textContent('#remote-badge'), /camera lost/);
  assert.match(await a.textContent('#status-text'), /camera is lost/);
  const pic = await remotePicture(a);
  assert.ok(pic.variance > 200, 'the last frame is still shown');
  await screenshot(a, 'call-camera-lost', { fullPage: false });
});

test('a reload rejoins the room; the call comes back', { skip }, async () => {
  await b.reload();
  await waitCall(b, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 10, 45000);
  assert.equal((await status(b)).room, room);
  await waitCall(a, () => window.facemimicCall.state === 'connected', 20000);
  await waitCall(a, () => window.facemimicCall.peer.camera === 'ok', 20000); // B's camera is back
});

test('a server restart is survived: the call carries on, the signalling reconnects with back-off and the room still works', { skip }, async () => {
  const port = server.port;
  await server.stop();
  await waitCall(a, () => window.facemimicCall.signal === 'reconnecting', 10000);
  await a.waitForTimeout(5000);
  const down = await status(a);
  assert.equal(down.state, 'connected', 'media flows without the server');
  assert.ok(down.remoteFps > 0);
  assert.match(await a.textContent('#status-text'), /signalling server is away/);
  const d = down.signalDelays;
  assert.ok(d.length >= 3, `retries while down: ${d}`);
  assert.ok(d[d.length - 1] > d[0] * 2, `the delays grow: ${d}`);
  server = await startDemoServer({ port, env: { FACEMIMIC_SIGNAL_HEARTBEAT_MS: '2000' } });
  for (const p of [a, b]) await waitCall(p, () => window.facemimicCall.signal === 'open' && window.facemimicCall.signalReconnects >= 1, 30000);
  for (const p of [a, b]) assert.equal((await status(p)).state, 'connected');
  // The room is known to the restarted server: a reload joins it again.
  await b.reload();
  await waitCall(b, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 10, 45000);
  await waitCall(a, () => window.facemimicCall.state === 'connected', 20000);
});

test('the peer leaves: the other side is told; a guessed room and a bad avatar name are explained', { skip }, async () => {
  await b.close();
  await waitCall(a, () => window.facemimicCall.state === 'peer-left', 15000);
  assert.match(await a.textContent('#status-text'), /other side left/);
  await screenshot(a, 'call-peer-left', { fullPage: false });

  const guessed = Buffer.from(crypto.getRandomValues(new Uint8Array(24))).toString('base64url');
  const c = await open(`${server.url}call.html?room=${guessed}&autojoin=1&avatar=nobody`, 'C');
  await c.waitForSelector('.toast.error');
  const toasts = await c.$$eval('.toast', (els) => els.map((e) => e.textContent));
  assert.ok(toasts.some((t) => /No bundled avatar named nobody/.test(t)), toasts.join(' | '));
  await c.waitForFunction(() => [...document.querySelectorAll('.toast')].some((e) => /does not exist/.test(e.textContent)), null, { timeout: 10000 });
  assert.notEqual((await status(c)).state, 'connected');
  await c.close();
  await a.close();
});

test('without a server: the connection text is copied and pasted by hand; bad text is explained', { skip }, async () => {
  const stat = await serveStatic('www');
  try {
    const p = await open(`${stat.url}call.html`, 'P');
    const q = await open(`${stat.url}call.html`, 'Q');
    // A static host has no signalling server: starting a room says so, and what to do instead.
    await p.click('#start-call');
    await p.waitForFunction(() => [...document.querySelectorAll('.toast.error')].some((e) => /No signalling server answers here.*Without a server/.test(e.textContent)), null, { timeout: 15000 });
    assert.equal((await status(p)).state, 'idle');
    await p.click('#manual summary');
    await q.click('#manual summary');
    // Bad text first.
    await q.fill('#manual-in', 'hello');
    await q.click('#make-answer');
    await q.waitForSelector('.toast.error');
    assert.match(await q.textContent('.toast.error'), /not facemimic connection text/);
    await p.click('#make-offer');
    await p.waitForFunction(() => document.getElementById('manual-out').value.startsWith('facemimic-call-1:'), null, { timeout: 15000 });
    const offer = await p.inputValue('#manual-out');
    await q.fill('#manual-in', offer);
    await q.click('#make-answer');
    await q.waitForFunction(() => document.getElementById('manual-out').value.startsWith('facemimic-call-1:'), null, { timeout: 15000 });
    const answer = await q.inputValue('#manual-out');
    await p.fill('#manual-in', offer); // an offer where an answer is expected
    await p.click('#accept-answer');
    await p.waitForFunction(() => [...document.querySelectorAll('.toast.error')].some((e) => /an answer is expected/.test(e.textContent)), null, { timeout: 5000 });
    await p.fill('#manual-in', answer);
    await p.click('#accept-answer');
    for (const x of [p, q]) await waitCall(x, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 10, 30000);
    assert.equal((await status(p)).sentVideo, 'canvas');
    const pic = await remotePicture(q);
    assert.ok(pic.variance > 200);
    // The connection itself needed no signalling: one attempt, from "Start a call", refused.
    assert.ok(stat.requests.filter((r) => r.startsWith('/signal')).length <= 1, stat.requests.filter((r) => r.startsWith('/signal')).join(' '));
    await p.close();
    await q.close();
  } finally {
    await stat.close();
  }
  assert.deepEqual(errors, [], 'no uncaught error in any page');
});

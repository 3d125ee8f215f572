// The call's latency and frame rate (a script, not a test; issue 19's "Measures"): two headless
// Chromium pages in a call through the demo server, each with a fake camera (spk07's unseen GRID
// clip as a 640x480 MJPEG) and a fake microphone, both sending, in bench mode (`?bench=1`: each
// avatar frame carries its camera frame's capture time, stamped in 24 black / white blocks along
// its bottom edge, read back by the receiver at display time; one machine, one clock).
//
//   node scripts/bench/call.mjs [--seconds 30] [--warmup 10] [--out artifacts/call-bench.json]
//
// Per receiving page: capture-to-display latency over every frame measured (median, p90), the
// breakdown (the sender's camera capture -> avatar drawn = track + clone + render; its encode
// time per frame; transport = half the round trip; the receiver's jitter buffer and decode time
// per frame; the rest = canvas capture, packetisation, pacing and display), and the frames
// presented per second (requestVideoFrameCallback).

import fs from 'node:fs';
import path from 'node:path';
import { ROOT } from '../lib/browser.mjs';
import { status, waitCall, twoPages } from '../lib/call.mjs';
import { arg, runCall } from './call-run.mjs';

const seconds = Number(arg('seconds', 30));
const warmup = Number(arg('warmup', 10));
const out = path.resolve(ROOT, arg('out', 'artifacts/call-bench.json'));
if (!(seconds > 0) || !(warmup >= 0)) {
  console.error('call bench: --seconds must be positive, --warmup not negative');
  process.exit(2);
}

const q = (arr, p) => {
  const s = arr.filter(Number.isFinite).sort((a, b) => a - b);
  return s.length ? s[Math.min(s.length - 1, Math.floor(p * s.length))] : null;
};
const r1 = (x) => (x === null || x === undefined ? null : Math.round(x * 10) / 10);

await runCall('call bench', { media: 'bench' }, async ({ browser, server }) => {
  const { a, b } = await twoPages(browser, server, { extra: '&bench=1' });
  const pages = { A: a, B: b };
  for (const p of Object.values(pages)) await waitCall(p, () => window.facemimicCall.state === 'connected' && window.facemimicCall.latencySource === 'stamp', 60000);
  await a.waitForTimeout(warmup * 1000);
  const acc = {};
  for (const [k, p] of Object.entries(pages)) {
    const s = await status(p);
    acc[k] = { lat: [], parts: [], count0: s.latencyCount, lastCount: s.latencyCount, frames0: s.remoteFrames, sent0: s.framesSent, t0: Date.now(), camera: await p.evaluate(() => window.facemimicTracking?.stream?.getVideoTracks()[0]?.getSettings()) };
  }
  const end = Date.now() + seconds * 1000;
  while (Date.now() < end) {
    await a.waitForTimeout(1000);
    for (const [k, p] of Object.entries(pages)) {
      const s = await status(p);
      const x = acc[k];
      const fresh = Math.min(s.latencyCount - x.lastCount, s.recentLatencies.length);
      if (fresh > 0) x.lat.push(...s.recentLatencies.slice(-fresh));
      x.lastCount = s.latencyCount;
      x.parts.push(s.breakdown);
      x.last = s;
    }
  }
  const summary = { seconds, warmup, canvas: '640x480', pages: {} };
  for (const [k, x] of Object.entries(acc)) {
    const med = (f) => q(x.parts.map(f).filter((v) => typeof v === 'number'), 0.5);
    const total = q(x.lat, 0.5);
    const parts = {
      trackCloneRenderMs: med((p) => p.peerPipelineMs),
      encodeMs: med((p) => p.peerEncodeMs),
      transportMs: med((p) => (typeof p.rttMs === 'number' ? p.rttMs / 2 : null)),
      jitterBufferMs: med((p) => p.jitterBufferMs),
      decodeMs: med((p) => p.decodeMs),
    };
    const known = Object.values(parts).reduce((s, v) => s + (v ?? 0), 0);
    const secs = (Date.now() - x.t0) / 1000;
    summary.pages[k] = {
      framesMeasured: x.lat.length,
      latencyMedianMs: r1(total),
      latencyP90Ms: r1(q(x.lat, 0.9)),
      latencyMaxMs: r1(q(x.lat, 1)),
      breakdownMedianMs: { ...Object.fromEntries(Object.entries(parts).map(([n, v]) => [n, r1(v)])), restMs: r1(total - known) },
      receiverFps: r1((x.last.remoteFrames - x.frames0) / secs),
      senderAvatarFps: r1((x.last.framesSent - x.sent0) / secs),
      received: `${x.last.breakdown.frameWidth}x${x.last.breakdown.frameHeight}`,
      codec: `${x.last.breakdown.encoder} -> ${x.last.breakdown.decoder}`,
      qualityLimitation: x.last.breakdown.qualityLimitation,
      camera: x.camera,
      latencySource: x.last.latencySource,
    };
  }
  console.log(JSON.stringify(summary, null, 2));
  fs.mkdirSync(path.dirname(out), { recursive: true });
  fs.writeFileSync(out, JSON.stringify(summary, null, 1));
});

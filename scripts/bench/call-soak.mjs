// The call soak (a script, not a test; issue 19's "Measures"): two headless Chromium pages in a
// call through the demo server (node scripts/serve.mjs, a child process), each with a fake
// camera (spk07's unseen GRID clip at 640x480, looped) and a fake microphone (a tone), for
// --minutes (default 30). Every --every seconds, on each page, after a forced garbage collection
// (DevTools HeapProfiler.collectGarbage): the JS heap in use, the wasm memory, the connection
// state, the frames presented. The remote video's presented frames are timed in the page
// (requestVideoFrameCallback): the longest gap and the gaps over 200 ms after the first minute.
//
//   node scripts/bench/call-soak.mjs [--minutes 30] [--every 30] [--gc every|ends] [--out artifacts/call-soak.json] [--snapshots]
//
// --gc ends forces the garbage collection only for the sample at 1 minute and the last one (the
// heap growth is measured between those two; the samples between read the heap as it is), so the
// collections themselves cannot cause the stalls measured.
//
// A forced collection's sample reads the live heap as the least of three collections' readings
// (liveHeap: performance.memory's figure, and V8's plus Blink's heaps as DevTools counts them);
// the others read performance.memory as it is.
//
// --snapshots also writes a heap snapshot of each page at one minute (before the stall counters
// start) and after the last sample (artifacts/heap-A-first.heapsnapshot, ...) and prints what grew
// between them, by constructor (scripts/bench/heap-diff.mjs).
//
// Prints one line per sample and a JSON summary: heap and wasm growth after the first minute
// (last sample over the one at 1 minute), longest stall after the first minute, connection drops
// (a sample not "connected", a renegotiation, a signalling reconnection), receiver fps.

import fs from 'node:fs';
import path from 'node:path';
import { ROOT } from '../lib/browser.mjs';
import { summarise, diff, report } from './heap-diff.mjs';
import { status, waitCall, twoPages } from '../lib/call.mjs';
import { arg, runCall } from './call-run.mjs';

const minutes = Number(arg('minutes', 30));
const every = Number(arg('every', 30));
const out = path.resolve(ROOT, arg('out', 'artifacts/call-soak.json'));
const gcMode = arg('gc', 'every');
const snapshots = process.argv.includes('--snapshots');
if (!(minutes > 1) || !(every > 0) || !['every', 'ends'].includes(gcMode)) {
  console.error('call-soak: --minutes must be over 1, --every positive, --gc every or ends');
  process.exit(2);
}

const t0 = Date.now();
const samples = [];

/**
 * The page's live JS heap after forced collections: the least of three readings of
 * performance.memory.usedJSHeapSize, each taken right after a collection (`heap`), and the same
 * for V8's and Blink's heaps as DevTools' Runtime.getHeapUsage counts them (`v8Blink`, a smaller
 * figure: it leaves out what V8 keeps outside its object spaces). The page keeps drawing (about
 * 0.7 MB of garbage a second at 30 fps), so a single reading counts whatever it allocated since
 * the collection; one taken a second or two later, on a busy machine, counted up to a megabyte.
 */
async function liveHeap(session) {
  const least = { heap: Infinity, v8Blink: Infinity };
  for (let i = 0; i < 3; i++) {
    await session.send('HeapProfiler.collectGarbage');
    const { result } = await session.send('Runtime.evaluate', { expression: 'performance.memory.usedJSHeapSize', returnByValue: true });
    const { usedSize, embedderHeapUsedSize = 0 } = await session.send('Runtime.getHeapUsage');
    least.heap = Math.min(least.heap, result.value);
    least.v8Blink = Math.min(least.v8Blink, usedSize + embedderHeapUsedSize);
  }
  return least;
}

/** Where page `k`'s heap snapshot `which` ('first', 'last') goes. */
const snapshotFile = (k, which) => path.join(path.dirname(out), `heap-${k}-${which}.heapsnapshot`);

/** Write a heap snapshot of the page behind `session` to `file`. */
async function takeSnapshot(session, file) {
  fs.mkdirSync(path.dirname(file), { recursive: true });
  const chunks = [];
  const onChunk = (e) => chunks.push(e.chunk);
  session.on('HeapProfiler.addHeapSnapshotChunk', onChunk);
  await session.send('HeapProfiler.takeHeapSnapshot', { reportProgress: false });
  session.off('HeapProfiler.addHeapSnapshotChunk', onChunk);
  fs.writeFileSync(file, chunks.join(''));
}

/** In the page: time the remote video's presented frames. */
function timeFrames() {
  const v = document.getElementById('remote');
  const w = { frames: 0, last: 0, maxGap: 0, gaps200: 0, since: performance.now(), events: [] };
  window.__soak = w;
  let lastPresented;
  const cb = (now, meta) => {
    // Callbacks may be missed on a busy main thread: presentedFrames counts what was shown, and
    // a gap spanning n presented frames counts as n gaps of its mean length.
    const inc = lastPresented !== undefined && meta.presentedFrames > lastPresented ? meta.presentedFrames - lastPresented : 1;
    lastPresented = meta.presentedFrames;
    if (w.last) {
      const gap = (now - w.last) / inc;
      if (gap > w.maxGap) w.maxGap = gap;
      if (gap > 200) {
        w.gaps200 += inc;
        if (w.events.length < 2000) w.events.push({ at: performance.timeOrigin + now, ms: gap, span: now - w.last, inc });
      }
    }
    w.last = now;
    w.frames += inc;
    v.requestVideoFrameCallback(cb);
  };
  v.requestVideoFrameCallback(cb);
  window.__soakReset = () => Object.assign(w, { frames: 0, maxGap: 0, gaps200: 0, since: performance.now(), events: [] });
}

await runCall('call-soak', { media: 'soak', browserArgs: ['--enable-precise-memory-info'] }, async ({ browser, server }) => {
  const { a, b } = await twoPages(browser, server);
  for (const p of [a, b]) await waitCall(p, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 30, 60000);
  const pages = { A: a, B: b };
  const cdp = {};
  for (const [k, p] of Object.entries(pages)) {
    cdp[k] = await p.context().newCDPSession(p);
    await p.evaluate(timeFrames);
  }
  const base = {};
  for (const [k, p] of Object.entries(pages)) base[k] = await status(p);
  let reset = false;
  let firstGcDone = false;
  const end = t0 + minutes * 60000;
  for (;;) {
    const elapsed = (Date.now() - t0) / 1000;
    if (!reset && elapsed >= 60) {
      // The first snapshots before the counters start (a snapshot pauses the page for a second).
      if (snapshots) for (const k of Object.keys(pages)) await takeSnapshot(cdp[k], snapshotFile(k, 'first'));
      for (const p of Object.values(pages)) await p.evaluate(() => window.__soakReset());
      reset = true;
    }
    const row = { t: Math.round(elapsed) };
    const lastSample = Date.now() + every * 1000 > end;
    row.gc = gcMode === 'every' || (reset && !firstGcDone) || lastSample;
    if (reset && row.gc) firstGcDone = true;
    for (const [k, p] of Object.entries(pages)) {
      const live = row.gc ? await liveHeap(cdp[k]) : null;
      const s = await status(p);
      const m = await p.evaluate(() => ({ heap: performance.memory.usedJSHeapSize, soak: { ...window.__soak, events: undefined, now: performance.now() } }));
      if (live !== null) [m.heap, m.v8Blink] = [live.heap, live.v8Blink];
      const secs = (m.soak.now - m.soak.since) / 1000;
      row[k] = {
        state: s.state,
        connection: s.connection,
        signal: s.signal,
        negotiations: s.negotiations,
        signalReconnects: s.signalReconnects,
        heap: m.heap,
        v8Blink: m.v8Blink ?? null,
        wasm: s.wasmBytes,
        remoteFps: s.remoteFps,
        meanFps: secs > 0 ? m.soak.frames / secs : 0,
        maxGap: m.soak.maxGap,
        gaps200: m.soak.gaps200,
        latencyMs: s.latencyMs,
        framesSent: s.framesSent,
        camera: s.camera,
      };
    }
    samples.push(row);
    const f = (x) => `${(x / 1048576).toFixed(2)} MB`;
    console.log(
      `t=${row.t}s${row.gc ? ' (gc)' : ''} ` +
        Object.entries(row)
          .filter(([k]) => k === 'A' || k === 'B')
          .map(([k, r]) => `${k}: ${r.state} heap ${f(r.heap)} wasm ${f(r.wasm)} fps ${r.remoteFps} (mean ${r.meanFps.toFixed(1)}) maxGap ${r.maxGap.toFixed(0)} ms gaps>200 ${r.gaps200} lat ${r.latencyMs?.toFixed(0)} ms`)
          .join(' | '),
    );
    if (Date.now() >= end) break;
    await new Promise((r) => setTimeout(r, Math.min(every * 1000, Math.max(0, end - Date.now()))));
  }
  const first = samples.find((r) => r.t >= 60 && r.gc) || samples[0];
  const last = samples[samples.length - 1];
  const summary = { minutes, gc: gcMode, samples: samples.length, pages: {} };
  // The heap's trend after the first minute (least squares over the samples): a leak shows as a
  // slope; single samples move by about a megabyte either way (WebRTC's and the page's garbage).
  const trend = (k) => {
    const pts = samples.filter((r) => r.t >= first.t && r.gc).map((r) => [r.t / 60, r[k].heap]);
    if (pts.length < 3) return { heapTrendKBPerMin: null, heapTrendPctPer30Min: null };
    const n = pts.length;
    const mx = pts.reduce((s, p) => s + p[0], 0) / n;
    const my = pts.reduce((s, p) => s + p[1], 0) / n;
    const den = pts.reduce((s, p) => s + (p[0] - mx) ** 2, 0);
    const slope = den > 0 ? pts.reduce((s, p) => s + (p[0] - mx) * (p[1] - my), 0) / den : 0; // bytes a minute
    return { heapTrendKBPerMin: slope / 1024, heapTrendPctPer30Min: ((slope * 30) / my) * 100 };
  };
  for (const k of ['A', 'B']) {
    const drops = samples.filter((r) => r[k].connection !== 'connected').length;
    summary.pages[k] = {
      heapAt1MinMB: first[k].heap / 1048576,
      heapEndMB: last[k].heap / 1048576,
      heapGrowthPct: ((last[k].heap - first[k].heap) / first[k].heap) * 100,
      v8BlinkAt1MinMB: first[k].v8Blink / 1048576,
      v8BlinkEndMB: last[k].v8Blink / 1048576,
      v8BlinkGrowthPct: ((last[k].v8Blink - first[k].v8Blink) / first[k].v8Blink) * 100,
      ...trend(k),
      heapMaxGrowthPct: Math.max(...samples.filter((r) => r.t >= first.t && r.gc).map((r) => ((r[k].heap - first[k].heap) / first[k].heap) * 100)),
      wasmAt1MinMB: first[k].wasm / 1048576,
      wasmEndMB: last[k].wasm / 1048576,
      wasmGrowthPct: ((last[k].wasm - first[k].wasm) / first[k].wasm) * 100,
      longestStallAfter1MinMs: last[k].maxGap,
      stallsOver200MsAfter1Min: last[k].gaps200,
      receiverFpsMean: last[k].meanFps,
      samplesNotConnected: drops,
      renegotiations: last[k].negotiations - base[k].negotiations,
      signalReconnects: last[k].signalReconnects - base[k].signalReconnects,
      framesSent: last[k].framesSent,
    };
  }
  // Where each stall came from. A receiver's gap over 200 ms (wall-clock interval [at - span, at])
  // is the sender's when the sender drew no avatar frame for most of it (its drawGaps, shifted by
  // the receiver's median latency): "face lost" when the sender's tracker lost the face within
  // the pause, "sender slow" otherwise; a gap the receiver saw while missing callbacks (inc > 1)
  // is "receiver busy"; the rest is "transport" (encode, network, jitter buffer, decode).
  for (const [k, other] of [['A', 'B'], ['B', 'A']]) {
    const events = await pages[k].evaluate(() => window.__soak.events);
    const gaps = await pages[other].evaluate(() => window.facemimicCall.drawGaps);
    const lat = last[k].latencyMs ?? 0;
    const causes = { faceLost: 0, senderSlow: 0, receiverBusy: 0, transport: 0 };
    const worst = { faceLost: 0, senderSlow: 0, receiverBusy: 0, transport: 0 };
    for (const e of events) {
      const [s0, s1] = [e.at - e.span, e.at];
      let best = null;
      let bestOverlap = 0;
      for (const g of gaps) {
        const [g0, g1] = [g.at - g.ms + lat, g.at + lat];
        const o = Math.min(s1, g1) - Math.max(s0, g0);
        if (o > bestOverlap) [best, bestOverlap] = [g, o];
      }
      const cause = best && bestOverlap >= 0.5 * e.span ? (best.lost > 0 ? 'faceLost' : 'senderSlow') : e.inc > 1 ? 'receiverBusy' : 'transport';
      causes[cause]++;
      worst[cause] = Math.max(worst[cause], e.ms);
    }
    summary.pages[k].stallCauses = { counts: causes, longestMs: worst, senderDrawGapsOver150Ms: gaps.length };
  }
  console.log(JSON.stringify(summary, null, 2));
  if (snapshots) {
    // The last snapshots after every figure is read (they pause each page).
    for (const k of ['A', 'B']) await takeSnapshot(cdp[k], snapshotFile(k, 'last'));
    for (const k of ['A', 'B']) {
      const read = (w) => summarise(fs.readFileSync(snapshotFile(k, w), 'utf8'));
      console.log(`page ${k}, live objects from the snapshot at 1 minute to the last:\n${report(diff(read('first'), read('last')))}`);
    }
  }
  fs.mkdirSync(path.dirname(out), { recursive: true });
  fs.writeFileSync(out, JSON.stringify({ summary, samples }, null, 1));
  console.log(`call-soak: samples and summary in ${path.relative(ROOT, out)}`);
});

// facemimic in-browser benchmark: the whole frame (source + N targets at 360x288) split by stage,
// with the chosen rasteriser (?raster=, default scanline: the page's default and the headline) and then the other one.
// Then tracking: the time per fit of the bundled clip with the source model, and what a lost
// frame costs while the page's finder worker searches (www/bench-tracking.js).
// Prints a JSON summary into <pre id="result"> (data-done="1" when finished) for headless runs
// (scripts/bench/page.mjs).
import init, { Model, Cloner, version, methods } from './pkg/facemimic.js';
import { benchFinder, benchTracking, fetchOk, summary } from './bench-tracking.js';

const MODELS = './models/';
const W = 360;
const H = 288;
const q = new URLSearchParams(location.search);
const int = (name, dflt, min, max) => {
  const v = Number.parseInt(q.get(name) ?? '', 10);
  return Number.isFinite(v) ? Math.min(max, Math.max(min, v)) : dflt;
};
const FRAMES = int('frames', 300, 1, 100000);
const WARMUP = int('warmup', 30, 0, 10000);
const TARGETS = int('targets', 4, 0, 16);
// The method: ?method=NAME, or the core's default (from methods(), once the module is loaded).
let METHOD = q.get('method');
const MESH = q.get('mesh') === '1';
const RASTERS = ['tiny-skia', 'scanline'];
const RASTER = q.get('raster') || 'scanline';
const OTHER = RASTERS.find((r) => r !== RASTER);
// The face finder's runs (0 skips it): `find` on a 640x480 frame and `landmarks` given its box.
const FINDER_RUNS = int('finder', 20, 0, 1000);
// Frames of the composited run (0 skips it): the source and the targets each composited into its
// picture in a 640x480 canvas, follow-pose on (the head moves in the picture), as the page shows
// them by default.
const COMPOSITE_FRAMES = int('composite', 300, 0, 100000);
const CW = 640;
const CH = 480;
// Passes over the bundled clip for the tracking figures (0 skips them).
const TRACK_PASSES = int('track', 6, 0, 1000);
// Frames without a face in each pass of the lost-frame run (the face gone while a search runs).
const LOST_FRAMES = int('lost', 12, 1, 1000);

const $ = (id) => document.getElementById(id);
const status = (text) => { $('status').textContent = text; };

const bytes = async (file) => new Uint8Array(await (await fetchOk(MODELS + file)).arrayBuffer());

function canvas(label, w = W, h = H) {
  const fig = document.createElement('figure');
  const c = document.createElement('canvas');
  c.width = w;
  c.height = h;
  if (w !== W) c.className = 'wide';
  const cap = document.createElement('figcaption');
  cap.textContent = label;
  fig.append(c, cap);
  $('faces').append(fig);
  return c.getContext('2d');
}

async function main() {
  await init();
  METHOD ||= methods().find((m) => m.isDefault).name;
  const manifest = await (await fetchOk(MODELS + 'manifest.json')).json();
  const trackFile = typeof manifest.track === 'string' ? manifest.track : manifest.track.file;
  const track = await (await fetchOk(MODELS + trackFile)).json();
  if (!Array.isArray(track) || track.length === 0) throw new Error(`${trackFile}: empty track`);
  const source = Model.fromBytes(await bytes(manifest.source));
  const names = [...manifest.targets, ...manifest.library.filter((t) => !manifest.targets.includes(t))];
  if (names.length < TARGETS) throw new Error(`only ${names.length} target models available`);
  const cloner = new Cloner(source);
  const targetNames = [];
  for (const file of names.slice(0, TARGETS)) {
    const m = Model.fromBytes(await bytes(file));
    cloner.addTarget(m);
    targetNames.push(m.name);
    m.free();
  }
  cloner.setMethod(METHOD);
  const sourceCtx = canvas(`source ${source.name}`);
  const targetCtx = targetNames.map((n) => canvas(`target ${n}`));
  if (!RASTERS.includes(RASTER)) throw new Error(`raster must be tiny-skia or scanline, got ${RASTER}`);
  let options;
  const frame = (i) => {
    const t0 = performance.now();
    cloner.setSourceParams(track[i % track.length]);
    cloner.update();
    cloner.renderSource(sourceCtx, options);
    for (let k = 0; k < targetCtx.length; k++) cloner.renderTarget(k, targetCtx[k], options);
    const t1 = performance.now();
    return [t1 - t0, cloner.timings()];
  };

  // The whole-frame run with one rasteriser: per-stage summaries.
  const measure = async (raster) => {
    options = { background: '#202024', mesh: MESH, raster };
    const stages = { map: [], synth: [], raster: [], blit: [], other: [], total: [] };
    status(`${raster}: warming up (${WARMUP} frames)...`);
    await new Promise((r) => setTimeout(r, 0));
    for (let i = 0; i < WARMUP; i++) frame(i);
    status(`${raster}: running ${FRAMES} frames...`);
    await new Promise((r) => setTimeout(r, 0));
    // In chunks, yielding between them so the page stays responsive; only frame() is timed.
    for (let i = 0; i < FRAMES; ) {
      const end = Math.min(FRAMES, i + 50);
      for (; i < end; i++) {
        const [total, t] = frame(WARMUP + i);
        stages.map.push(t.mapMs);
        stages.synth.push(t.synthMs);
        stages.raster.push(t.rasterMs);
        stages.blit.push(t.blitMs);
        stages.total.push(total);
        // Everything outside the four stages: parameter passing, API calls, JS.
        stages.other.push(Math.max(0, total - t.mapMs - t.synthMs - t.rasterMs - t.blitMs));
      }
      await new Promise((r) => setTimeout(r, 0));
    }

    return Object.fromEntries(Object.entries(stages).map(([k, v]) => [k, summary(v)]));
  };
  const s = await measure(RASTER);
  const o = await measure(OTHER);

  // The two rasterisers on the same face, interleaved call by call so that both see the same
  // machine load: raster ms per face (clear + triangle warp) for target 0.
  const rasterCompare = {};
  if (targetCtx.length > 0) {
    status('comparing rasterisers...');
    await new Promise((r) => setTimeout(r, 0));
    const modes = RASTERS;
    const samples = { 'tiny-skia': [], scanline: [] };
    const opts = Object.fromEntries(modes.map((m) => [m, { background: '#202024', raster: m }]));
    for (let i = 0; i < Math.max(60, Math.min(FRAMES, 400)); i++) {
      cloner.setSourceParams(track[i % track.length]);
      cloner.update();
      for (const m of i % 2 ? modes : [...modes].reverse()) {
        const before = cloner.timings().rasterMs;
        cloner.renderTarget(0, targetCtx[0], opts[m]);
        samples[m].push(cloner.timings().rasterMs - before);
      }
    }
    for (const m of modes) rasterCompare[m] = summary(samples[m]);
  }
  // The composited run: the page's default view at 640x480 with follow-pose on, with the
  // headline rasteriser; then the compositing cost per face beyond the face alone, interleaved
  // call by call on target 0 (raster ms: the stage that holds both warps).
  let composite = null;
  if (COMPOSITE_FRAMES > 0 && targetCtx.length > 0) {
    const srcCtx = canvas(`source ${source.name} (640x480)`, CW, CH);
    const ctxs = targetNames.map((n) => canvas(`${n} composited (640x480)`, CW, CH));
    cloner.setFollowPose(true);
    const opts = { background: '#202024', raster: RASTER, composite: true };
    const faceOpts = { background: '#202024', raster: RASTER };
    const totals = [];
    const stages = { map: [], synth: [], raster: [], blit: [] };
    const run = (i) => {
      const t0 = performance.now();
      cloner.setSourceParams(track[i % track.length]);
      cloner.update(); // resets the stage timings: after the renders they are this frame's
      cloner.renderSource(srcCtx, faceOpts);
      for (let k = 0; k < ctxs.length; k++) cloner.renderTarget(k, ctxs[k], opts);
      return [performance.now() - t0, cloner.timings()];
    };
    status(`composited: warming up (${WARMUP} frames)...`);
    await new Promise((r) => setTimeout(r, 0));
    for (let i = 0; i < WARMUP; i++) run(i);
    status(`composited: running ${COMPOSITE_FRAMES} frames...`);
    for (let i = 0; i < COMPOSITE_FRAMES; ) {
      const end = Math.min(COMPOSITE_FRAMES, i + 50);
      for (; i < end; i++) {
        const [total, t] = run(WARMUP + i);
        totals.push(total);
        for (const k of Object.keys(stages)) stages[k].push(t[`${k}Ms`]);
      }
      await new Promise((r) => setTimeout(r, 0));
    }
    const per = { composite: [], face: [] };
    for (let i = 0; i < Math.max(60, Math.min(COMPOSITE_FRAMES, 300)); i++) {
      cloner.setSourceParams(track[i % track.length]);
      cloner.update();
      for (const m of i % 2 ? ['composite', 'face'] : ['face', 'composite']) {
        const before = cloner.timings().rasterMs;
        cloner.renderTarget(0, ctxs[0], m === 'composite' ? opts : faceOpts);
        per[m].push(cloner.timings().rasterMs - before);
      }
    }
    cloner.setFollowPose(false);
    const total = summary(totals);
    composite = {
      canvas: `${CW}x${CH}`,
      faces: 1 + ctxs.length,
      raster: RASTER,
      followPose: true,
      frames: COMPOSITE_FRAMES,
      ms: { ...Object.fromEntries(Object.entries(stages).map(([k, v]) => [k, summary(v)])), total },
      fps: { fromMean: Math.round(1000 / total.mean), fromMedian: Math.round(1000 / total.median) },
      perFaceRasterMs: { composite: summary(per.composite), faceOnly: summary(per.face) },
      extraPerFaceMs: Math.round((summary(per.composite).median - summary(per.face).median) * 1000) / 1000,
    };
  }
  const finder = FINDER_RUNS > 0 ? await benchFinder({ runs: FINDER_RUNS, status }) : null;
  const tracking = TRACK_PASSES > 0 ? await benchTracking(source, { passes: TRACK_PASSES, lost: LOST_FRAMES, status }) : null;
  const result = {
    facemimic: version(),
    userAgent: navigator.userAgent,
    hardwareConcurrency: navigator.hardwareConcurrency,
    canvas: `${W}x${H}`,
    faces: 1 + targetNames.length,
    source: source.name,
    targets: targetNames,
    method: METHOD,
    mesh: MESH,
    raster: RASTER,
    frames: FRAMES,
    warmup: WARMUP,
    trackFrames: track.length,
    ms: s,
    rasterPerFaceMs: rasterCompare,
    fps: {
      fromMean: Math.round(1000 / s.total.mean),
      fromMedian: Math.round(1000 / s.total.median),
    },
    // The same whole-frame run with the other rasteriser.
    other: {
      raster: OTHER,
      ms: o,
      fps: { fromMean: Math.round(1000 / o.total.mean), fromMedian: Math.round(1000 / o.total.median) },
    },
    composite,
    finder,
    tracking,
  };
  const tbody = $('table').querySelector('tbody');
  for (const k of ['map', 'synth', 'raster', 'blit', 'other', 'total']) {
    const tr = document.createElement('tr');
    for (const v of [k, s[k].mean, s[k].median, s[k].p95]) {
      const td = document.createElement('td');
      td.textContent = typeof v === 'number' ? v.toFixed(3) : v;
      tr.append(td);
    }
    tbody.append(tr);
  }
  $('table').hidden = false;
  status(`${result.faces} faces at ${W}x${H}, ${RASTER}: ${s.total.mean.toFixed(2)} ms per frame (mean), ` +
    `${result.fps.fromMean} fps; median ${s.total.median.toFixed(2)} ms, ${result.fps.fromMedian} fps ` +
    `(${OTHER}: median ${o.total.median.toFixed(2)} ms, ${result.other.fps.fromMedian} fps)` +
    (composite ? `; composited (source + ${composite.faces - 1} at ${composite.canvas}, follow-pose): ` +
      `median ${composite.ms.total.median.toFixed(2)} ms, ${composite.fps.fromMedian} fps, ` +
      `${composite.extraPerFaceMs.toFixed(2)} ms a face beyond the face alone` : '') +
    (finder ? `; face finder on ${finder.frame}: find ${finder.findMs.median.toFixed(1)} ms, ` +
      `landmarks ${finder.landmarksMs.median.toFixed(1)} ms (median)` : '') +
    (tracking ? `; tracking: ${tracking.trackedMs.median.toFixed(2)} ms a fit, a lost frame ` +
      `${tracking.lostMs.median.toFixed(2)} ms (medians; means: ${tracking.lostOverTracked}x)` : ''));
  $('result').textContent = JSON.stringify(result, null, 2);
  $('result').dataset.done = '1';
}

main().catch((e) => {
  status(`error: ${e.message}`);
  $('result').textContent = JSON.stringify({ error: e.message });
  $('result').dataset.done = '1';
  console.error(e);
});

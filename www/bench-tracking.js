// The in-browser benchmark's face finder and tracking measures (www/bench.js runs them after the
// frame's): the finder on a webcam-sized frame, and the time per fit of the bundled clip with
// the source model, and what a lost frame costs (see benchTracking); and the helpers both
// modules use.
import { FaceFinder, Tracker } from './pkg/facemimic.js';

/** `fetch` that rejects on an HTTP error. */
export async function fetchOk(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r;
}
/** Mean, median, 95th percentile, min and max of `values` (ms, rounded to 1 us). */
export function summary(values) {
  const s = [...values].sort((a, b) => a - b);
  const at = (p) => s[Math.min(s.length - 1, Math.floor(p * s.length))];
  const mean = s.reduce((a, b) => a + b, 0) / s.length;
  const median = s.length % 2 ? s[(s.length - 1) / 2] : 0.5 * (s[s.length / 2 - 1] + s[s.length / 2]);
  const r = (x) => Math.round(x * 1000) / 1000;
  return { mean: r(mean), median: r(median), p95: r(at(0.95)), min: r(s[0]), max: r(s[s.length - 1]) };
}

// A 640x480 webcam-sized frame: the bundled clip's first frame (spk07, 360x288) scaled 1.5x and
// centred on black, as in the native benchmark (benches/find.rs, which uses a GRID frame too).
async function webcamFrame() {
  const video = document.createElement('video');
  video.muted = true;
  video.src = './media/spk07-clip.webm';
  await new Promise((resolve, reject) => {
    video.onloadeddata = resolve;
    video.onerror = () => reject(new Error('media/spk07-clip.webm: cannot decode'));
  });
  const c = document.createElement('canvas');
  c.width = 640;
  c.height = 480;
  const ctx = c.getContext('2d', { willReadFrequently: true });
  ctx.fillStyle = '#000';
  ctx.fillRect(0, 0, 640, 480);
  const [w, h] = [video.videoWidth * 1.5, video.videoHeight * 1.5];
  ctx.drawImage(video, (640 - w) / 2, (480 - h) / 2, w, h);
  return ctx.getImageData(0, 0, 640, 480);
}

// The face finder in wasm on one frame: `find` (detector + landmark passes) and `landmarks`
// (one landmark-net pass given the found box), each run FINDER_RUNS times after one warm-up.
export async function benchFinder({ runs: FINDER_RUNS, status }) {
  status(`face finder: ${FINDER_RUNS} runs...`);
  await new Promise((r) => setTimeout(r, 0));
  const img = await webcamFrame();
  const finder = new FaceFinder();
  try {
    const first = finder.find(img.data, img.width, img.height);
    if (first.length === 0) throw new Error('face finder: no face in the benchmark frame');
    const box = first[0].box;
    finder.landmarks(img.data, img.width, img.height, box);
    const find = [];
    const marks = [];
    for (let i = 0; i < FINDER_RUNS; i++) {
      let t = performance.now();
      finder.find(img.data, img.width, img.height);
      find.push(performance.now() - t);
      t = performance.now();
      finder.landmarks(img.data, img.width, img.height, box);
      marks.push(performance.now() - t);
      if (i % 5 === 4) await new Promise((r) => setTimeout(r, 0));
    }
    const r = (x) => Math.round(x);
    return {
      frame: `${img.width}x${img.height}`,
      faces: first.length,
      box: { x: r(box.x), y: r(box.y), width: r(box.width), height: r(box.height) },
      runs: FINDER_RUNS,
      findMs: summary(find),
      landmarksMs: summary(marks),
    };
  } finally {
    finder.free();
  }
}

/** The bundled clip's frames (spk07, 360x288) as ImageData at their own size (the tracker chooses
 *  its fit scale and resamples itself, as for the page), and its first frame's landmarks. */
async function clipFrames() {
  const info = await (await fetchOk('./media/spk07-clip.json')).json();
  const video = document.createElement('video');
  video.muted = true;
  video.src = `./media/${info.video}`;
  await new Promise((resolve, reject) => {
    video.onloadeddata = resolve;
    video.onerror = () => reject(new Error(`media/${info.video}: cannot decode`));
  });
  const init = Float32Array.from(info.initLandmarks);
  const c = document.createElement('canvas');
  c.width = video.videoWidth;
  c.height = video.videoHeight;
  const ctx = c.getContext('2d', { willReadFrequently: true });
  ctx.imageSmoothingQuality = 'medium';
  const frames = [];
  for (let i = 0; i < info.frames; i++) {
    video.currentTime = (i + 0.5) / info.fps;
    await new Promise((r) => { video.onseeked = r; });
    ctx.drawImage(video, 0, 0, c.width, c.height);
    frames.push(ctx.getImageData(0, 0, c.width, c.height));
  }
  return { frames, init };
}

// Tracking as the page's sources do (`Tracker` with faces offered by the finder worker,
// `expectOffers(true)`), on the bundled clip at the page's fit scale:
// - tracked: TRACK_PASSES passes over the clip, each started from its first frame's landmarks
//   (the first, cold fit of a pass not counted): ms per `track()` call;
// - lost: 2 x TRACK_PASSES passes each track frames 0-29, then LOST_FRAMES frames where the face
//   is gone (black frames, or the face covered by a random texture, alternately; the tracker wants
//   faces and the page's worker is searching, nothing offered yet), then the clip again from
//   frame 30 (the face back where it was, still nothing offered): ms per lost frame against the
//   tracked frames of the same passes, and the frames until the face is tracked again without
//   the finder's help.
export async function benchTracking(source, { passes: TRACK_PASSES, lost: LOST_FRAMES, status }) {
  status(`tracking: decoding the clip...`);
  const fit = Tracker.fromModel(source);
  try {
    fit.expectOffers(true);
    const { frames, init } = await clipFrames();
    const { width, height } = frames[0];
    const black = new ImageData(width, height);
    for (let i = 3; i < black.data.length; i += 4) black.data[i] = 255;
    // The face covered (a hand, an object): the clip's frames with the face's box, 30% larger,
    // painted over with a coarse random texture (the same in every run).
    let seed = 1;
    const rnd = () => ((seed = (Math.imul(seed, 1103515245) + 12345) >>> 0) >>> 16) & 255;
    let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
    for (let i = 0; i < init.length; i += 2) {
      x0 = Math.min(x0, init[i]);
      x1 = Math.max(x1, init[i]);
      y0 = Math.min(y0, init[i + 1]);
      y1 = Math.max(y1, init[i + 1]);
    }
    const [cx, cy, hw, hh] = [(x0 + x1) / 2, (y0 + y1) / 2, 0.65 * (x1 - x0), 0.65 * (y1 - y0)];
    const covered = frames.map((f) => {
      const c = new OffscreenCanvas(width, height);
      const g = c.getContext('2d', { willReadFrequently: true });
      g.putImageData(f, 0, 0);
      for (let y = Math.round(cy - hh); y < cy + hh; y += 6) {
        for (let x = Math.round(cx - hw); x < cx + hw; x += 6) {
          g.fillStyle = `rgb(${rnd()},${rnd()},${rnd()})`;
          g.fillRect(x, y, 6, 6);
        }
      }
      return g.getImageData(0, 0, width, height);
    });
    const track = (im) => {
      const t = performance.now();
      const r = fit.track(im.data, im.width, im.height);
      return [performance.now() - t, r];
    };
    status(`tracking: ${TRACK_PASSES} passes over the clip...`);
    await new Promise((r) => setTimeout(r, 0));
    const tracked = [];
    let lostTracking = 0;
    let iterations = 0;
    for (let p = 0; p < TRACK_PASSES; p++) {
      fit.startFromLandmarks(init);
      track(frames[0]);
      for (let i = 1; i < frames.length; i++) {
        const [ms, r] = track(frames[i]);
        tracked.push(ms);
        iterations += r.iterations;
        if (r.lost) lostTracking++;
      }
      await new Promise((r) => setTimeout(r, 0));
    }
    status(`tracking: lost frames...`);
    await new Promise((r) => setTimeout(r, 0));
    const lost = { black: [], covered: [] };
    const around = []; // the tracked frames of the same passes (same machine load)
    const back = []; // frames from the face's return to its first tracked frame
    let wanted = 0;
    let notLost = 0;
    for (let p = 0; p < 2 * TRACK_PASSES; p++) {
      const kind = p % 2 ? 'covered' : 'black';
      fit.startFromLandmarks(init);
      track(frames[0]);
      for (let i = 1; i < 30; i++) around.push(track(frames[i])[0]);
      for (let i = 0; i < LOST_FRAMES; i++) {
        const [ms, r] = track(kind === 'black' ? black : covered[(30 + i) % frames.length]);
        if (!r.lost) {
          notLost++;
          continue;
        }
        lost[kind].push(ms);
        if (fit.wantsFaces) wanted++;
      }
      let found = -1;
      for (let i = 30; i < frames.length; i++) {
        const [ms, r] = track(frames[i]);
        if (!r.lost) {
          if (found < 0) found = i - 30;
          around.push(ms);
        }
      }
      back.push(found);
      await new Promise((r) => setTimeout(r, 0));
    }
    const t = summary(tracked);
    const all = [...lost.black, ...lost.covered];
    const l = summary(all);
    const a = summary(around);
    return {
      clip: `${frames.length} frames at ${width}x${height} (fit scale ${fit.scale.toFixed(3)})`,
      passes: TRACK_PASSES,
      trackedMs: t,
      fitsPerSecond: Math.round(1000 / t.median),
      iterationsPerFit: Math.round((10 * iterations) / tracked.length) / 10,
      lostWhileTracking: lostTracking,
      lostFrames: LOST_FRAMES,
      lostMs: l,
      lostBlackMs: summary(lost.black),
      lostCoveredMs: summary(lost.covered),
      notLost,
      trackedAroundMs: a,
      lostOverTracked: Math.round((100 * l.mean) / a.mean) / 100,
      lostOverTrackedMedian: Math.round((100 * l.median) / a.median) / 100,
      wantsFacesWhileLost: wanted / all.length,
      framesToTrackAgain: back,
    };
  } finally {
    fit.free();
  }
}

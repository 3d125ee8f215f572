// A Web Worker running the package's face finder and model builder off the page's main thread,
// so the page keeps drawing. Messages in (pixel buffers transferred):
//   { id, options }             build with buildModel (frames without landmarks get the finder's)
//   { id, find: { rgba, width, height }, minScore }   the most confident face in one frame
// Messages out: for a build, { id, type: "progress", stage, done, total, skipped } then either
// { id, type: "done", bytes, info, skipped, ms } (the .fmm file, transferred) or
// { id, type: "error", message }; for a search, { id, type: "found", face: { landmarks, score,
// spread } | null, ms } or { id, type: "error", message }.
// Cancelling a build is terminating the worker: a model only ever leaves the worker complete.
import init, * as fm from '../pkg/facemimic.js';

const ready = init();

self.onmessage = async (e) => {
  const { id, options, find, minScore } = e.data || {};
  try {
    await ready;
    const t0 = performance.now();
    if (find) {
      // The landmarks buildModel would place itself (the finder's, averaged with the mirror).
      const f = fm.enrolFace(find.rgba, find.width, find.height, minScore ?? 0);
      const face = f ? { landmarks: f.landmarks, score: f.score, spread: f.spread } : null;
      self.postMessage({ id, type: 'found', face, ms: performance.now() - t0 });
      return;
    }
    let skipped = [];
    const model = fm.buildModel(options, (p) => {
      skipped = p.skipped;
      self.postMessage({ id, type: 'progress', stage: p.stage, done: p.done, total: p.total, skipped });
    });
    const bytes = model.toBytes();
    const info = model.info();
    model.free();
    self.postMessage({ id, type: 'done', bytes, info, skipped, ms: performance.now() - t0 }, [bytes.buffer]);
  } catch (err) {
    self.postMessage({ id, type: 'error', message: err && err.message ? err.message : String(err) });
  }
};

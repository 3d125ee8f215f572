// A Web Worker running the package's model builder off the page's main thread, so the page keeps
// drawing (one per build; faces in sampled frames are found by finder-worker.js). Messages in
// (pixel buffers transferred): { id, options }: build with buildModel (frames without landmarks
// get the finder's). Messages out: { id, type: "progress", stage, done, total, skipped, rejected } then
// either { id, type: "done", bytes, info, skipped, rejected, ms } (the .fmm file, transferred) or
// { id, type: "error", message }.
// Cancelling a build is terminating the worker: a model only ever leaves the worker complete.
import init, * as fm from '../pkg/facemimic.js';

const ready = init();

self.onmessage = async (e) => {
  const { id, options } = e.data || {};
  try {
    await ready;
    const t0 = performance.now();
    let skipped = [];
    let rejected = [];
    const model = fm.buildModel(options, (p) => {
      skipped = p.skipped;
      rejected = p.rejected ?? [];
      self.postMessage({ id, type: 'progress', stage: p.stage, done: p.done, total: p.total, skipped, rejected });
    });
    const bytes = model.toBytes();
    const info = model.info();
    model.free();
    self.postMessage({ id, type: 'done', bytes, info, skipped, rejected, ms: performance.now() - t0 }, [bytes.buffer]);
  } catch (err) {
    self.postMessage({ id, type: 'error', message: err && err.message ? err.message : String(err) });
  }
};

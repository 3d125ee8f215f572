// A Web Worker that builds a model with the package's `buildModel`, off the page's main thread
// so the page keeps drawing. Messages in: { id, options } (options as for buildModel; pixel
// buffers transferred). Messages out: { id, type: "progress", done, total }, then either
// { id, type: "done", bytes } (the .fmm file, transferred) or { id, type: "error", message }.
// Cancelling is terminating the worker: the model only ever leaves the worker complete.
import init, * as fm from '../pkg/facemimic.js';

const ready = init();

self.onmessage = async (e) => {
  const { id, options } = e.data || {};
  try {
    await ready;
    const t0 = performance.now();
    const model = fm.buildModel(options, (p) => {
      self.postMessage({ id, type: 'progress', done: p.done, total: p.total });
    });
    const bytes = model.toBytes();
    const info = model.info();
    model.free();
    self.postMessage({ id, type: 'done', bytes, info, ms: performance.now() - t0 }, [bytes.buffer]);
  } catch (err) {
    self.postMessage({ id, type: 'error', message: err && err.message ? err.message : String(err) });
  }
};

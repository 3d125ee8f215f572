// The page's side of www/js/build-worker.js: build a model in a worker, with progress and
// cancelling (one worker per build, terminated when the build ends or is cancelled). Faces in
// sampled frames are found by the page's finder worker (finder-client.js).

let nextId = 1;
const WORKER_URL = new URL('./build-worker.js', import.meta.url);

function startWorker() {
  try {
    return new Worker(WORKER_URL, { type: 'module' });
  } catch (e) {
    throw new Error(`cannot start a worker: ${e.message || e}`);
  }
}

/**
 * Builds a model off the main thread. `options` as for the package's buildModel (frames with
 * rgba buffers: they are transferred to the worker and unusable here afterwards; frames without
 * landmarks get the face finder's). `onProgress(done, total, stage, skipped)`. Resolves to
 * { bytes, info, skipped, rejected, ms } (`skipped`: indices of frames without a confident
 * face; `rejected`: [{ frame, reason }] the quality checks did not build from); rejects
 * with an Error (its message names the problem; "cancelled" when `signal` aborted it).
 */
export function buildInWorker(options, { onProgress, signal } = {}) {
  return new Promise((resolve, reject) => {
    if (signal?.aborted) {
      reject(new Error('cancelled'));
      return;
    }
    let worker;
    try {
      worker = startWorker();
    } catch (e) {
      reject(e);
      return;
    }
    const id = nextId++;
    const finish = () => {
      worker.terminate();
      signal?.removeEventListener('abort', abort);
    };
    const abort = () => {
      finish();
      reject(new Error('cancelled'));
    };
    signal?.addEventListener('abort', abort);
    worker.onmessage = (e) => {
      const m = e.data;
      if (m.id !== id) return;
      if (m.type === 'progress') onProgress?.(m.done, m.total, m.stage, m.skipped);
      else if (m.type === 'done') {
        finish();
        resolve({ bytes: new Uint8Array(m.bytes), info: m.info, skipped: m.skipped, rejected: m.rejected ?? [], ms: m.ms });
      } else if (m.type === 'error') {
        finish();
        reject(new Error(m.message));
      }
    };
    worker.onerror = (e) => {
      finish();
      reject(new Error(`the build worker failed: ${e.message || 'script error'}`));
    };
    const transfer = [];
    for (const f of options.frames || []) if (f?.rgba?.buffer instanceof ArrayBuffer) transfer.push(f.rgba.buffer);
    worker.postMessage({ id, options }, [...new Set(transfer)]);
  });
}

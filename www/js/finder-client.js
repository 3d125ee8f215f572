// The page's side of www/js/finder-worker.js: find the faces in a frame off the main thread.
// One worker for the page, made on the first request (the finder's weights load then, never on
// the page's first load); one request at a time per caller is the expected use (`busy`).

let worker = null;
let nextId = 1;
const pending = new Map();

function fail(reason) {
  for (const { reject } of pending.values()) reject(new Error(reason));
  pending.clear();
  worker?.terminate();
  worker = null;
}

function getWorker() {
  if (worker) return worker;
  worker = new Worker(new URL('./finder-worker.js', import.meta.url), { type: 'module' });
  worker.onmessage = (e) => {
    const m = e.data || {};
    const p = pending.get(m.id);
    if (!p) return;
    pending.delete(m.id);
    if (m.error) p.reject(new Error(m.error));
    else p.resolve({ faces: m.faces, ms: m.ms });
  };
  worker.onerror = (e) => fail(`the face finder failed: ${e.message || 'script error'}`);
  return worker;
}

/**
 * The faces in an RGBA frame (`ImageData`, or `{ data, width, height }`; its buffer is copied),
 * most confident first: resolves to `{ faces: [{ box: { x, y, width, height }, score,
 * landmarks: Float32Array(136) }], ms }` in the frame's pixels.
 */
export function findFaces(image) {
  return new Promise((resolve, reject) => {
    let w;
    try {
      w = getWorker();
    } catch (e) {
      reject(new Error(`cannot start the face finder: ${e.message || e}`));
      return;
    }
    const id = nextId++;
    pending.set(id, { resolve, reject });
    const data = new Uint8Array(image.data).buffer; // a copy: the caller keeps its frame
    w.postMessage({ id, data, width: image.width, height: image.height }, [data]);
  });
}

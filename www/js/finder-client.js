// The page's side of www/js/finder-worker.js: find faces off the main thread, for the tracking
// sources (`findFaces`: every face in a frame) and for the enrolment (`enrolFace`: the face a
// model would be built from). One worker for the page, made on the first request (the finder's
// weights load then, never on the page's first load), so the nets and the wasm are in memory
// once. One request is in the worker at a time; the others wait here, searches for tracking
// before enrolment's (a lost face is found again without waiting behind sampled frames), so a
// request waits at most for one search under way. Each caller is expected to keep one request
// at a time (tracking.js `findBusy`, enrol.js samples the next frame when a search is done).

let worker = null;
let nextId = 1;
let inFlight = null; // the request the worker is on: { id, resolve, reject, ... }
const waiting = { find: [], enrol: [] };

function fail(reason) {
  const all = [...(inFlight ? [inFlight] : []), ...waiting.find, ...waiting.enrol];
  inFlight = null;
  waiting.find = [];
  waiting.enrol = [];
  worker?.terminate();
  worker = null;
  for (const r of all) r.reject(new Error(reason));
}

function getWorker() {
  if (worker) return worker;
  worker = new Worker(new URL('./finder-worker.js', import.meta.url), { type: 'module' });
  worker.onmessage = (e) => {
    const m = e.data || {};
    const r = inFlight;
    if (!r || r.id !== m.id) return;
    inFlight = null;
    if (m.error) r.reject(new Error(m.error));
    else if (r.kind === 'enrol') r.resolve(m.face ? { ...m.face, ms: m.ms } : null);
    else r.resolve({ faces: m.faces, ms: m.ms });
    pump();
  };
  worker.onerror = (e) => fail(`the face finder failed: ${e.message || 'script error'}`);
  return worker;
}

/** Sends the next waiting request when the worker is free (tracking's first). */
function pump() {
  if (inFlight) return;
  const r = waiting.find.shift() ?? waiting.enrol.shift();
  if (!r) return;
  let w;
  try {
    w = getWorker();
  } catch (e) {
    r.reject(new Error(`cannot start the face finder: ${e.message || e}`));
    pump();
    return;
  }
  inFlight = r;
  const { id, kind, data, width, height, minScore } = r;
  r.data = null;
  w.postMessage({ id, kind, data, width, height, minScore }, [data]);
}

function request(kind, image, extra = {}) {
  return new Promise((resolve, reject) => {
    const data = new Uint8Array(image.data ?? image.rgba).buffer; // a copy (the constructor copies): the caller keeps its frame
    waiting[kind].push({ id: nextId++, kind, data, width: image.width, height: image.height, resolve, reject, ...extra });
    pump();
  });
}

/**
 * The faces in an RGBA frame (`ImageData`, or `{ data, width, height }`; its buffer is copied),
 * most confident first: resolves to `{ faces: [{ box: { x, y, width, height }, score,
 * landmarks: Float32Array(136) }], ms }` in the frame's pixels (`ms`: the search in the worker).
 */
export function findFaces(image) {
  return request('find', image);
}

/**
 * The face a model would be built from in an RGBA frame (`{ rgba, width, height }` or
 * `ImageData`; copied): the most confident face scoring at least `minScore`, its landmarks
 * averaged with a pass on the mirrored image (the package's `enrolFace`). Resolves to
 * `{ landmarks: Float32Array(136), score, spread, ms }` or null when there is none.
 */
export function enrolFace(frame, minScore = 0) {
  return request('enrol', frame, { minScore });
}

/** Requests not yet answered (waiting or under way), for the tests and the console. */
export function pendingSearches() {
  return (inFlight ? 1 : 0) + waiting.find.length + waiting.enrol.length;
}

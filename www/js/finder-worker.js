// The page's one face-finder Web Worker (one copy of the finder's nets and of the wasm), serving
// both the tracking sources and the enrolment, so finding faces (tens to hundreds of
// milliseconds a frame) never stalls the page's drawing. Messages in: { id, kind: "find" |
// "enrol", data (RGBA ArrayBuffer, transferred), width, height, minScore? }. Messages out:
//   find:  { id, faces: [{ box, score, landmarks (Float32Array, transferred) }], ms }
//   enrol: { id, face: { landmarks, score, spread, reason } | null, ms }   (the package's FaceFinder.enrol:
//          the face buildModel would use, its points averaged with a pass on the mirror)
//   or { id, error }.
import init, { FaceFinder } from '../pkg/facemimic.js';

let finder = null;
const ready = init().then(() => {
  finder = new FaceFinder();
});

self.onmessage = async (e) => {
  const { id, kind, data, width, height, minScore } = e.data || {};
  try {
    await ready;
    const rgba = new Uint8Array(data);
    const t0 = performance.now();
    if (kind === 'enrol') {
      const f = finder.enrol(rgba, width, height, minScore ?? 0);
      const face = f ? { landmarks: f.landmarks, score: f.score, spread: f.spread, reason: f.reason ?? null } : null;
      self.postMessage({ id, face, ms: performance.now() - t0 }, face ? [face.landmarks.buffer] : []);
      return;
    }
    const found = finder.find(rgba, width, height);
    const ms = performance.now() - t0;
    const faces = found.map((f) => ({ box: { ...f.box }, score: f.score, landmarks: f.landmarks }));
    self.postMessage({ id, faces, ms }, faces.map((f) => f.landmarks.buffer));
  } catch (err) {
    self.postMessage({ id, error: err && err.message ? err.message : String(err) });
  }
};

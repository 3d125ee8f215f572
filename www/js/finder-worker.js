// A Web Worker running the package's FaceFinder, so finding faces (a few hundred milliseconds
// for a 640x480 frame) never stalls the page's drawing. Messages in: { id, data (RGBA
// ArrayBuffer, transferred), width, height }. Messages out: { id, faces: [{ box, score,
// landmarks (Float32Array, transferred) }], ms } or { id, error }.
import init, { FaceFinder } from '../pkg/facemimic.js';

let finder = null;
const ready = init().then(() => {
  finder = new FaceFinder();
});

self.onmessage = async (e) => {
  const { id, data, width, height } = e.data || {};
  try {
    await ready;
    const t0 = performance.now();
    const found = finder.find(new Uint8Array(data), width, height);
    const ms = performance.now() - t0;
    const faces = found.map((f) => ({ box: { ...f.box }, score: f.score, landmarks: f.landmarks }));
    self.postMessage({ id, faces, ms }, faces.map((f) => f.landmarks.buffer));
  } catch (err) {
    self.postMessage({ id, error: err && err.message ? err.message : String(err) });
  }
};

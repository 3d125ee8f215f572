// facemimic-faces: where the default faces are. Each face is a URL beside this module (a
// file: URL in Node), which facemimic's `loadModel` / `Model.load` reads in a page, a worker
// or Node. Bundlers (Vite, webpack 5, Rollup) see the literal `new URL(..., import.meta.url)`
// and copy each file they meet.

/** The source face (GRID speaker 7), the one the recorded track drives. */
export const source = new URL("./spk07.fmm", import.meta.url);

/** Every face by name: the source and four targets. */
export const faces = Object.freeze({
  spk07: source,
  spk02: new URL("./spk02.fmm", import.meta.url),
  spk03: new URL("./spk03.fmm", import.meta.url),
  spk06: new URL("./spk06.fmm", import.meta.url),
  spk10: new URL("./spk10.fmm", import.meta.url),
});

/** The four target faces, in the demo's order. */
export const targets = Object.freeze([faces.spk02, faces.spk03, faces.spk06, faces.spk10]);

/** Speaker 7's unseen clip as source parameters, 75 frames at `track.fps`, to drive the
 *  source without a camera: `[{ pose, shape, appearance }, ...]` (JSON). */
export const track = Object.freeze({
  url: new URL("./spk07-track.json", import.meta.url),
  fps: 25,
});

/** The attribution these faces need wherever they are shown (CC BY 4.0). */
export const credits =
  "Faces built from the GRID audio-visual corpus (Cooke, Barker, Cunningham & Shao, 2006), CC BY 4.0";

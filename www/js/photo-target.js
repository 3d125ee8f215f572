// Photo targets: a photo dropped on the targets (the "Add a target" card or a target card) or
// chosen with "Add a photo target…" becomes a target made from that one picture (the package's
// `Model.fromPhoto`: the photo's face is the model's base, the photo its backdrop; with no modes
// of its own, a method that maps into them substitutes the source's expression onto it instead,
// the expressive method clones it as any target). The face's 68 landmarks come from a
// `.pts` file dropped or chosen with the photo (same name), else from the page's face finder
// (finder-client.js, the worker the photo and video sources use); with several faces the user
// picks one in a small dialog that reuses the tracking panel's placement step (placement.js).
// Every failure is an Error whose message says why (no face found, the face is too small, the
// image does not decode…); the caller names the file.

import { findFaces } from './finder-client.js';
import { Placement } from './placement.js';
import { drawFrame } from './face-draw.js';
import { parsePts } from './enrol.js';
import { looksLikeImage } from './media.js';


/** Whether a file is a landmark file (`.pts`). */
export function isPts(file) {
  return /\.pts$/i.test(file.name || '');
}

/** The files split into photos (each with its `.pts` when one of the same name is there), the
 *  `.pts` files that go with no photo, and the rest. */
export function splitPhotos(files) {
  const pts = new Map();
  for (const f of files) if (isPts(f)) pts.set(stem(f.name), f);
  const photos = [];
  const rest = [];
  for (const f of files) {
    if (isPts(f)) continue;
    if (looksLikeImage(f)) {
      const p = pts.get(stem(f.name)) ?? null;
      pts.delete(stem(f.name));
      photos.push({ file: f, pts: p });
    } else rest.push(f);
  }
  return { photos, loosePts: [...pts.values()], rest };
}

/** A file name without its extension. */
export function stem(name) {
  return String(name || 'photo').replace(/\.[^.]+$/, '') || 'photo';
}

/** A bitmap drawn at `scale` into a new canvas: `{ canvas, width, height, scale }`. */
function drawn(bmp, scale) {
  const width = Math.max(1, Math.round(bmp.width * scale));
  const height = Math.max(1, Math.round(bmp.height * scale));
  const canvas = document.createElement('canvas');
  canvas.width = width;
  canvas.height = height;
  const g = canvas.getContext('2d', { willReadFrequently: true });
  g.imageSmoothingQuality = 'high';
  g.drawImage(bmp, 0, 0, width, height);
  return { canvas, g, width, height, scale };
}

/** Points (pixel centres on integers) of a picture scaled by `k`. */
function rescale(pts, k) {
  const out = new Float32Array(pts.length);
  for (let i = 0; i < pts.length; i++) out[i] = (pts[i] + 0.5) * k - 0.5;
  return out;
}

/**
 * Makes a photo target from `file` (an image) and `ptsFile` (its landmarks, or null).
 * `choose(canvas, faces, fileName)` is asked when the finder sees several faces and resolves to
 * the index of the face to use, or null (cancelled). `onStatus(text)` hears progress.
 * Resolves to `{ model, name, faces }` or null when cancelled; rejects with the reason.
 */
export async function photoTarget(fm, file, ptsFile, { choose, onStatus = () => {} } = {}) {
  if (typeof fm.Model?.fromPhoto !== 'function') throw new Error('this build of the package cannot make photo targets');
  // The core's policy: the picture kept at most maxSide on its longer side, faces searched in a
  // copy at most findSide (the tracking panel's work frame).
  const { maxSide, findSide } = fm.policy().photo;
  let bmp;
  try {
    bmp = await createImageBitmap(file);
  } catch (e) {
    throw new Error(`the image could not be decoded (${e?.message || e})`);
  }
  try {
    if (!bmp.width || !bmp.height) throw new Error('the image is empty');
    const full = drawn(bmp, Math.min(1, maxSide / Math.max(bmp.width, bmp.height)));
    let landmarks;
    let faces = 1;
    if (ptsFile) {
      let pts;
      try {
        pts = parsePts(await ptsFile.text());
      } catch (e) {
        throw new Error(`${ptsFile.name}: ${e.message || e}`);
      }
      landmarks = rescale(pts, full.scale);
    } else {
      onStatus(`Looking for the face in ${file.name}…`);
      const find = drawn(bmp, Math.min(1, findSide / Math.max(bmp.width, bmp.height)));
      const found = (await findFaces(find.g.getImageData(0, 0, find.width, find.height))).faces;
      faces = found.length;
      if (!found.length) throw new Error('no face was found in it (a photo target needs one face seen from the front)');
      let pick = 0;
      if (found.length > 1) {
        pick = choose ? await choose(find.canvas, found, file.name) : 0;
        if (pick === null || pick === undefined) return null;
      }
      landmarks = rescale(found[pick].landmarks, full.scale / find.scale);
    }
    const rgba = full.g.getImageData(0, 0, full.width, full.height).data;
    const name = stem(file.name);
    const model = fm.Model.fromPhoto(name, rgba, full.width, full.height, landmarks);
    return { model, name, faces };
  } finally {
    bmp.close?.();
  }
}

/**
 * The face picker: the photo (`picture`, a canvas) with the faces found, the most confident
 * selected; a click (or Tab) selects another, "Use this face" (or Enter) resolves to its index,
 * Cancel (or Escape) to null. One dialog for the page, made on first use.
 */
export function chooseFace(picture, faces, fileName) {
  const d = pickerDialog();
  const placement = new Placement(faces[0].landmarks);
  placement.setFaces(faces);
  const { canvas, title, hint, use } = d.els;
  title.textContent = `Which face in ${fileName}?`;
  canvas.style.aspectRatio = `${picture.width} / ${picture.height}`;
  const say = () => {
    hint.textContent = `${faces.length} faces were found. Click one (or press Tab) to choose it, then use it as the target.`;
    use.textContent = `Use face ${placement.selected + 1}`;
  };
  let view = null;
  const draw = () => {
    view = drawFrame(canvas, picture);
    if (view) placement.draw(view.g, view.map, view.s, view.lw, view.dpr);
  };
  const toFrame = (e) => {
    const r = canvas.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    // drawFrame letterboxes the picture: undo its offset and scale.
    const X = (e.clientX - r.left) * dpr;
    const Y = (e.clientY - r.top) * dpr;
    const [ox, oy] = view ? view.map(0, 0) : [0, 0];
    const s = view ? view.s : 1;
    return { x: (X - ox) / s, y: (Y - oy) / s };
  };
  return new Promise((resolve) => {
    const ac = new AbortController();
    const on = (el, type, fn) => el.addEventListener(type, fn, { signal: ac.signal });
    const finish = (value) => {
      ac.abort();
      if (d.open) d.close();
      resolve(value);
    };
    on(canvas, 'pointerdown', (e) => {
      const p = toFrame(e);
      const hit = placement.hit(p, 0);
      if (hit.startsWith('face:')) placement.select(Number(hit.slice(5)));
      say();
      draw();
    });
    on(canvas, 'pointermove', (e) => {
      canvas.style.cursor = placement.hit(toFrame(e), 0).startsWith('face:') ? 'pointer' : 'default';
    });
    on(d, 'keydown', (e) => {
      if (e.key === 'Tab' && e.target === canvas && placement.key(e, 0, picture.width, picture.height)) {
        e.preventDefault();
        say();
        draw();
      } else if (e.key === 'Enter' && e.target === canvas) {
        e.preventDefault();
        finish(placement.selected);
      }
    });
    on(use, 'click', () => finish(placement.selected));
    on(d.els.cancel, 'click', () => finish(null));
    on(d, 'cancel', () => finish(null));
    on(d, 'close', () => finish(null));
    say();
    d.showModal();
    canvas.focus({ preventScroll: true });
    requestAnimationFrame(draw);
  });
}

let dialog = null;

function pickerDialog() {
  if (dialog) return dialog;
  const el = (tag, props = {}, ...children) => {
    const e = Object.assign(document.createElement(tag), props);
    e.append(...children);
    return e;
  };
  const title = el('h2', { id: 'photo-pick-title' });
  const hint = el('p', { className: 'hint' });
  const canvas = el('canvas', { className: 'photo-pick-view', tabIndex: 0 });
  canvas.setAttribute('role', 'img');
  canvas.setAttribute('aria-label', 'The photo with the faces found; Tab chooses another face, Enter uses it');
  const use = el('button', { type: 'button', className: 'btn primary', id: 'photo-pick-use' });
  const cancel = el('button', { type: 'button', className: 'btn', textContent: 'Cancel' });
  dialog = el('dialog', { className: 'photo-pick', id: 'photo-pick' }, title, hint, canvas, el('div', { className: 'row buttons' }, use, cancel));
  dialog.setAttribute('aria-labelledby', 'photo-pick-title');
  dialog.els = { title, hint, canvas, use, cancel };
  document.body.append(dialog);
  return dialog;
}

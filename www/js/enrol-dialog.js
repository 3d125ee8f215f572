// The "Create a face" dialog's view (www/js/enrol.js is the enrolment itself): its DOM, the
// preview of a built model and the thumbnails of the frames a build would use. Nothing here
// samples, finds or builds: the dialog's buttons and drops call the `actions` it is given.

import { Inspector } from './inspector.js';
import { download, safeName } from './store.js';

/** An element with its properties set and its children appended. */
function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  Object.assign(e, props);
  e.append(...children);
  return e;
}

/**
 * The dialog (appended to the page, closed): returns `{ dialog, els }`. `actions`: `webcam()`,
 * `addFiles(files)` (chosen or dropped), `build()`, `cancel()`, `closed()` (the dialog closed),
 * `result()` (the last build's `{ bytes, name }`, or null), `useAsSource(result)`,
 * `addAsTarget(result)`.
 */
export function enrolDialog(actions) {
  const d = el('dialog', { id: 'enrol', className: 'enrol' });
  d.setAttribute('aria-labelledby', 'enrol-title');
  const $ = el;
  const e = {
    webcam: $('button', { type: 'button', className: 'btn', textContent: 'Webcam' }),
    photos: $('button', { type: 'button', className: 'btn', textContent: 'Photos or video…' }),
    file: $('input', { type: 'file', multiple: true, accept: 'image/*,video/*,.pts', hidden: true }),
    guide: $('p', { className: 'hint enrol-guide', role: 'status' }),
    checklist: $('ul', { className: 'enrol-checklist' }),
    video: $('video', { muted: true, playsInline: true, className: 'enrol-video', hidden: true }),
    status: $('p', { className: 'enrol-status', role: 'status' }),
    coverage: $('meter', { min: 0, max: 1, value: 0, className: 'enrol-coverage' }),
    name: $('input', { type: 'text', value: 'My face', maxLength: 80, className: 'enrol-name' }),
    refine: $('input', { type: 'checkbox', className: 'enrol-refine' }),
    build: $('button', { type: 'button', className: 'btn primary', textContent: 'Build', disabled: true }),
    cancel: $('button', { type: 'button', className: 'btn', textContent: 'Cancel' }),
    progress: $('progress', { max: 1, value: 0, hidden: true, className: 'enrol-progress' }),
    done: $('div', { className: 'enrol-done', hidden: true }),
    preview: $('section', { className: 'enrol-preview', hidden: true }),
    strip: $('div', { className: 'enrol-strip' }),
  };
  e.checklist.setAttribute('aria-label', 'Expressions the frames kept show');
  Object.assign(e.checklist.style, { display: 'flex', flexWrap: 'wrap', gap: '6px', listStyle: 'none', padding: '0', margin: '4px 0 8px' });
  e.strip.setAttribute('aria-label', 'The frames the model will be built from, with their landmarks');
  e.coverage.setAttribute('aria-label', 'Expression coverage');
  e.name.setAttribute('aria-label', 'Name of the new face');
  e.webcam.addEventListener('click', () => actions.webcam());
  e.photos.addEventListener('click', () => {
    e.file.value = '';
    e.file.click();
  });
  e.file.addEventListener('change', () => actions.addFiles([...e.file.files]));
  e.build.addEventListener('click', () => actions.build());
  e.cancel.addEventListener('click', () => actions.cancel());
  // Closing ends the capture; a search under way finishes in the worker and is dropped
  // (sampleFrom checks the session).
  d.addEventListener('close', () => actions.closed());
  d.addEventListener('dragover', (ev) => {
    ev.preventDefault();
    ev.stopPropagation();
  });
  d.addEventListener('drop', (ev) => {
    ev.preventDefault();
    ev.stopPropagation();
    if (ev.dataTransfer?.files?.length) actions.addFiles([...ev.dataTransfer.files]);
  });
  const use = (label, fn) => {
    const b = $('button', { type: 'button', className: 'btn', textContent: label });
    b.addEventListener('click', () => {
      const r = actions.result();
      if (r) fn(r);
    });
    return b;
  };
  e.done.append(
    use('Use as source', (r) => { actions.useAsSource(r); d.close(); }),
    use('Add as target', (r) => { actions.addAsTarget(r); d.close(); }),
    use('Download .fmm', (r) => download(r.bytes, `${safeName(r.name)}.fmm`)),
  );
  d.append(
    $('h2', { id: 'enrol-title', textContent: 'Create a face' }),
    $('p', {
      className: 'hint',
      // Touch screens cannot drop files: say how to choose them there.
      textContent: matchMedia('(pointer: coarse)').matches
        ? 'Use the camera, a video, or about 20 photos of one person (choose them with "Photos or video…"; a .pts landmark file chosen with a photo is used). Everything stays on this device.'
        : 'Use the webcam, a video, or about 20 photos of one person (drop them here; a .pts landmark file beside a photo is used when given). Everything stays in this browser.',
    }),
    $('div', { className: 'row buttons' }, e.webcam, e.photos, e.file),
    e.guide,
    e.checklist,
    e.video,
    $('div', { className: 'row' }, $('span', { textContent: 'Coverage' }), e.coverage),
    e.strip,
    e.status,
    e.preview,
    e.done,
    $('div', { className: 'row' }, $('label', { textContent: 'Name' }), e.name),
    $('label', { className: 'row hint', title: 'Fits the new model to its own frames and rebuilds it from the fitted landmarks. Measured on a webcam clip, it tracks unseen frames worse, so it is off by default.' }, e.refine, ' Refine (slower; measured to track worse)'),
    e.progress,
    $('div', { className: 'row buttons' }, e.build, e.cancel),
  );
  document.body.append(d);
  return { dialog: d, els: e };
}

/**
 * The preview of a built model in `host` (the Inspector's look, paper Fig. 1): mean face, one
 * mode animated as base + k sigma sin(t), shape or appearance, a mode picked from the bars.
 * `page`: { fm, hidpi, faceOptions } (see Enrolment). Returns its `Inspector`.
 */
export function enrolPreview(host, page) {
  const $ = el;
  host.setAttribute('aria-labelledby', 'enrol-preview-title');
  const canvas = (label) => {
    const c = $('canvas', { className: 'face small' });
    c.setAttribute('role', 'img');
    c.setAttribute('aria-label', label);
    return c;
  };
  const els = {
    mean: canvas('Mean face of the new model'),
    mode: canvas('The chosen mode of the new model, animated'),
    caption: $('figcaption'),
    bars: $('div', { className: 'bars' }),
    kind: $('fieldset', { className: 'segmented small' }),
  };
  els.bars.setAttribute('role', 'radiogroup');
  els.bars.setAttribute('aria-label', 'Modes of the new model by share of variance');
  const radio = (value, label, checked) => $('label', {}, $('input', { type: 'radio', name: 'enrol-kind', value, checked }), $('span', { textContent: label }));
  els.kind.append($('legend', { className: 'visually-hidden', textContent: 'Mode kind' }), radio('shape', 'Shape', true), radio('appearance', 'Appearance', false));
  host.append(
    $('h3', { id: 'enrol-preview-title', textContent: 'Preview' }),
    $('div', { className: 'enrol-preview-body' },
      $('div', { className: 'inspect-views' },
        $('figure', {}, els.mean, $('figcaption', { textContent: 'Mean' })),
        $('figure', {}, els.mode, els.caption)),
      $('div', { className: 'enrol-preview-modes' },
        els.kind,
        els.bars,
        $('p', { className: 'hint bars-caption', textContent: 'Each mode\'s share of the variance; pick one to animate it.' }))),
  );
  for (const c of [els.mean, els.mode]) page.hidpi?.watch(c);
  return new Inspector(page.fm, els, page.faceOptions ?? {});
}

/**
 * Thumbnails (`H` px square canvases) of the frames `pick` of `candidates` (a build would use
 * them), each cropped about its face with its landmarks.
 */
export function faceThumbs(candidates, pick, H = 56) {
  return pick.map((i) => {
    const c = candidates[i];
    // Crop around the face (landmark box + 30%), scaled to H pixels high.
    let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
    for (let k = 0; k < c.landmarks.length; k += 2) {
      x0 = Math.min(x0, c.landmarks[k]); x1 = Math.max(x1, c.landmarks[k]);
      y0 = Math.min(y0, c.landmarks[k + 1]); y1 = Math.max(y1, c.landmarks[k + 1]);
    }
    const side = Math.max(x1 - x0, y1 - y0) * 1.3;
    const [cx, cy] = [(x0 + x1) / 2, (y0 + y1) / 2];
    const k = H / side;
    const canvas = document.createElement('canvas');
    canvas.width = H;
    canvas.height = H;
    const g = canvas.getContext('2d');
    if (!c.thumb) {
      // The frame once as a canvas (drawn again only if the crop changes: never).
      const img = new ImageData(new Uint8ClampedArray(c.rgba.buffer, c.rgba.byteOffset, c.rgba.length), c.width, c.height);
      c.thumb = new OffscreenCanvas(c.width, c.height);
      c.thumb.getContext('2d').putImageData(img, 0, 0);
    }
    g.drawImage(c.thumb, cx - side / 2, cy - side / 2, side, side, 0, 0, H, H);
    g.fillStyle = '#7cc4ff';
    for (let j = 0; j < c.landmarks.length; j += 2) {
      g.fillRect((c.landmarks[j] - cx + side / 2) * k - 0.5, (c.landmarks[j + 1] - cy + side / 2) * k - 0.5, 1.2, 1.2);
    }
    return canvas;
  });
}

/** The expressions the guide asks for: the core's names (`expressionCoverage`'s `missing`),
 *  the count's key, the checklist's label and the guide's ask. */
export const EXPRESSIONS = [
  ['smile', 'smile', 'Smile', 'now smile'],
  ['mouth-open', 'mouthOpen', 'Mouth open', 'open your mouth wide'],
  ['brows', 'brows', 'Eyebrows up', 'raise your eyebrows'],
  ['eyes-closed', 'eyesClosed', 'Eyes closed', 'close your eyes for a moment'],
  ['turn-left', 'turnLeft', 'Look left', 'look a little left'],
  ['turn-right', 'turnRight', 'Look right', 'look a little right'],
];

/** Fills the checklist `ul` from `counts` (expressionCoverage's counts, or empty): an item a
 *  tick and the number of frames showing it, or an empty box. */
export function drawChecklist(ul, counts) {
  ul.replaceChildren(...EXPRESSIONS.map(([name, key, label]) => {
    const n = counts?.[key] || 0;
    const li = el('li', { textContent: `${n ? '\u2713' : '\u25CB'} ${label}${n ? ` (${n})` : ''}` });
    li.dataset.expression = name;
    li.dataset.done = n ? '1' : '0';
    Object.assign(li.style, {
      padding: '2px 9px', borderRadius: '999px', fontSize: '12.5px',
      border: `1px solid ${n ? 'rgba(107, 220, 154, 0.7)' : 'rgba(255, 255, 255, 0.22)'}`,
      color: n ? 'var(--ok, #6bdc9a)' : 'inherit', background: n ? 'rgba(107, 220, 154, 0.1)' : 'transparent',
    });
    return li;
  }));
}

// Recording and snapshots: the faces as shown (source, then targets) side by side in one canvas,
// as a PNG (each face rendered afresh at 480 px) or a WebM video (the page's canvases, copied
// every frame while recording), offered as downloads.

import { composite, fileName, WebmRecorder, addDownload, webmType } from './recorder.js';
import { notify, message } from './toasts.js';
import { app, $, FACE_BG } from './page-state.js';

/** The record and snapshot buttons (recording is off where the browser cannot encode WebM). */
export function wireCapture() {
  $('record').addEventListener('click', toggleRecording);
  $('snapshot').addEventListener('click', snapshot);
  if (!webmType()) {
    $('record').disabled = true;
    $('record').title = 'This browser cannot record WebM video';
  }
}

/** The options the faces are drawn with: the source's, and the targets' (composited unless "Face only"). */
export function renderOptions() {
  const face = { background: FACE_BG, mesh: app.settings.mesh, raster: app.settings.fast ? 'scanline' : 'tiny-skia' };
  return { face, target: { ...face, composite: !app.settings.faceOnly, keepWhole: app.settings.keepWhole !== false } };
}

/** The faces to record, as shown: source then targets. `crisp`: render each afresh at the tile
 *  size (with the options the page draws them with). */
function recordTiles(crisp = false) {
  const { face, target } = renderOptions();
  return [app.source, ...app.targets].map((e) => {
    const isSource = e === app.source;
    const index = app.targets.indexOf(e);
    return {
      canvas: e.canvas,
      label: isSource ? `${e.name} (source)` : e.name,
      render: crisp
        ? (w, h) =>
            isSource ? app.cloner.renderSourceImageData(w, h, face) : app.cloner.renderTargetImageData(index, w, h, target)
        : null,
    };
  });
}

const compositeCanvas = document.createElement('canvas');

/** Video tiles at the page canvases' own height (no rescaling), even, within 240..720 px. */
function videoTileHeight() {
  const h = app.source.canvas.height;
  return Math.max(240, Math.min(720, h - (h & 1)));
}

/** A PNG of every face, downloaded. */
async function snapshot() {
  try {
    // 480 device px per face, rendered at that size (not scaled up from the page's canvases).
    const crisp = typeof app.cloner.renderTargetImageData === 'function';
    composite(compositeCanvas, recordTiles(crisp), 480);
  } catch (e) {
    notify('error', 'Snapshot failed', message(e));
    return;
  }
  const blob = await new Promise((resolve) => compositeCanvas.toBlob(resolve, 'image/png'));
  if (!blob) {
    notify('error', 'Snapshot failed', 'the browser could not encode a PNG');
    return;
  }
  const name = fileName('png');
  const a = addDownload($('downloads'), blob, name, name);
  a.click();
}

/** Starts a WebM recording, or stops it and offers the file. */
async function toggleRecording() {
  const btn = $('record');
  if (app.recorder) {
    const rec = app.recorder;
    app.recorder = null;
    btn.dataset.state = 'idle';
    btn.querySelector('.label').textContent = 'Record WebM';
    btn.classList.remove('recording');
    try {
      const blob = await rec.stop();
      const name = fileName('webm');
      addDownload($('downloads'), blob, name, `${name} (${rec.seconds.toFixed(1)} s)`).click();
    } catch (e) {
      notify('error', 'Recording failed', message(e));
    }
    return;
  }
  try {
    app.recordTileH = videoTileHeight();
    composite(compositeCanvas, recordTiles(), app.recordTileH);
    app.recorder = new WebmRecorder(compositeCanvas, 30);
    app.recorder.start();
  } catch (e) {
    app.recorder = null;
    notify('error', 'Cannot record', message(e));
    return;
  }
  btn.dataset.state = 'recording';
  btn.querySelector('.label').textContent = 'Stop recording';
  btn.classList.add('recording');
  app.dirty = true;
}
/** While recording: the faces of this frame into the video's canvas. */
export function recordFrame() {
  if (app.recorder) composite(compositeCanvas, recordTiles(), app.recordTileH);
}

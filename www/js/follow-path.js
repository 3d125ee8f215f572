// Which path follows a live face (issue 20, item 6), and the line that says so in the tracking
// panel.
//
//   "aam"        the source model's AAM is fitted to every frame (the package's `Tracker`): for a
//                person's own model (Create a face, Your models, a model file dropped on the
//                source) and for the bundled clip, which shows the bundled person
//   "landmarks"  anyone is followed at once with the bundled source model (the package's
//                `Follower`): the face finder's landmarks, smoothed, read as expression relative
//                to the person's own neutral face and mapped onto the model's shape modes; the
//                appearance stays the model's. The panel says so and offers "Create a face".
//
// The `Follower` has the `Tracker`'s calls and convention (start, offerFaces, wantsFaces,
// `track(data, width, height, dt)` on the frame at its own size returning landmarks and poses in
// its pixels with `placed`, the head re-centred about the same kind of anchor, the counters), so
// tracking.js drives either the same way.

/** "landmarks" when a live source (webcam, video file) drives a bundled source model. */
export function followPath(ctx, mode) {
  if (mode === 'clip') return 'aam';
  if (typeof ctx.wasm?.Follower !== 'function') return 'aam';
  const own = typeof ctx.sourceIsOwn === 'function' ? ctx.sourceIsOwn() : true;
  return own ? 'aam' : 'landmarks';
}

/** A `Follower` for `model`, with faces offered from the page's finder worker. */
export function makeFollower(wasm, model) {
  const follower = wasm.Follower.fromModel(model);
  follower.expectOffers(true);
  return follower;
}

/**
 * The panel's line saying which path is in use; `createFace` (optional) opens "Create a face".
 * Returns the element (a `<p class="trk-path" data-path>`).
 */
export function pathNotice(path, createFace) {
  const p = document.createElement('p');
  p.className = 'trk-path';
  p.dataset.path = path;
  if (path === 'landmarks') {
    p.append('Following landmarks with the bundled face — create your own face for a closer match. ');
    if (typeof createFace === 'function') {
      const b = document.createElement('button');
      b.type = 'button';
      b.className = 'btn trk-create';
      b.textContent = 'Create a face';
      b.addEventListener('click', () => createFace());
      p.append(b);
    }
  } else {
    p.textContent = 'Fitting the source model (AAM).';
  }
  return p;
}

// Which path follows a live face (issue 20, item 6), and the line that says so in the tracking
// panel. The choice is the core's tracking policy (the package's `Tracker.kindFor`,
// `facemimic::fit::tracker_for`); the page only says whose face the source model is.
//
//   "aam"        the source model's AAM is fitted to every frame: for a person's own model
//                (Create a face, Your models, a model file dropped on the source) and for the
//                bundled clip, which shows the bundled person
//   "landmarks"  anyone is followed at once with the bundled source model: the face finder's
//                landmarks, smoothed, read as expression relative to the person's own neutral
//                face and mapped onto the model's shape modes; the change of appearance (teeth,
//                creases, lids) observed against the person's own neutral drives the expressive
//                method (the core's FaceTracker::observed).
//                The panel says so and offers "Create a face".
//
// Both are the package's one `Tracker` class (`Tracker.fromModel` / `Tracker.follower`), with
// the same calls and convention (start, offerFaces, wantsFaces, `track(data, width, height, dt)`
// on the frame at its own size returning landmarks and poses in its pixels with `placed`, the
// head re-centred about the core's pose anchor, the counters), so tracking.js drives either the
// same way.

/**
 * The path the core's policy chooses for the source model: "landmarks" when a live source
 * (webcam, video file) drives someone else's (a bundled) model, else "aam". `model`: the source
 * model (default: the context's).
 */
export function followPath(ctx, mode, model = ctx.sourceModel?.() ?? ctx.source?.model) {
  // The bundled clip shows the bundled person: the model is theirs.
  const own = mode === 'clip' || (typeof ctx.sourceIsOwn === 'function' ? ctx.sourceIsOwn() : true);
  const T = ctx.wasm?.Tracker;
  if (typeof T?.kindFor !== 'function' || !model) return 'aam';
  return T.kindFor(model, own);
}

/** The package's `Tracker` of `path` for `model`, with faces offered from the page's finder worker. */
export function makeTracker(wasm, model, path) {
  const T = wasm.Tracker;
  const tracker = path === 'landmarks' ? T.follower(model) : T.fromModel(model);
  tracker.expectOffers(true);
  return tracker;
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

// The output view: one avatar alone, nothing else, for OBS's window capture or a browser source
// (docs/obs.md). It draws nothing by itself: the page that feeds it (www/js/output-feed.js: the
// main page or the call page) renders the avatar with its cloner after each of its own frames
// and calls `present()`, which copies it into the view's canvas with one drawImage. So the view
// shows the page's frames at the page's frame rate.
//
// Two homes: a pop-out window (www/output.html, started by www/js/output.js) and the main page
// itself in output mode (`index.html?output=NAME`, www/js/output-page.js), for a browser source.
// The canvas has the chosen size (`configure`); the window may have any shape: the canvas is
// scaled to fit it, centred, on the surround colour (the key colour, or black around a
// picture). The cursor hides after a moment without moving; a double-click toggles full screen.

const IDLE_MS = 1500;

/** The view's look (put once into its document): no chrome, no scrollbars, the canvas fitted. */
const CSS = `
.fm-output { position: fixed; inset: 0; margin: 0; display: grid; place-items: center; overflow: hidden; background: #000; }
.fm-output > canvas { display: block; width: 100vw; height: 100vh; object-fit: contain; }
.fm-output > canvas:not([data-drawn]) { visibility: hidden; }
.fm-output.idle, .fm-output.idle * { cursor: none; }
.fm-output > .notice {
  position: fixed; inset: 0; display: grid; place-items: center; padding: 24px;
  background: rgba(12, 13, 16, 0.88); color: #e6e7eb; text-align: center;
  font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
}
.fm-output > .notice[hidden] { display: none; }
.fm-output strong { display: block; font-size: 18px; font-weight: 600; margin-bottom: 6px; }
.fm-output p { margin: 0 auto; max-width: 44ch; color: #b6bac4; }
.fm-output a { color: #7cc4ff; }
html.fm-output-mode, html.fm-output-mode body { overflow: hidden; }
body.fm-output-mode > :not(.fm-output) { display: none !important; }
`;

/** A view's elements, made in `doc` and appended to its body (when the page has none). */
export function outputRoot(doc) {
  const root = doc.createElement('div');
  root.innerHTML = '<canvas role="img" aria-label="The avatar"></canvas><div class="notice" role="status" aria-live="polite" hidden><div><strong></strong><p></p></div></div>';
  doc.body.append(root);
  return root;
}

/**
 * The view in `root` (an element holding a `canvas` and a `.notice` with a `strong` and a `p`,
 * as `outputRoot` makes):
 * `{ configure, present, disconnect, notice, frames, fps() }`. `page`: where a link in a notice
 * leads (the page to press Pop out on).
 */
export function outputView(root, { page = './' } = {}) {
  const doc = root.ownerDocument;
  if (!doc.getElementById('fm-output-css')) {
    const style = doc.createElement('style');
    style.id = 'fm-output-css';
    style.textContent = CSS;
    doc.head.append(style);
  }
  root.classList.add('fm-output');
  const canvas = root.querySelector('canvas');
  const ctx = canvas.getContext('2d', { alpha: false });
  const box = root.querySelector('.notice');
  const times = []; // present times of the last second (performance clock)
  let frames = 0;
  let connected = true;
  let name = '';

  /** A message over the view (what a capture of it shows): `text`, strings and nodes. */
  function notice(title, text) {
    box.querySelector('strong').textContent = title;
    box.querySelector('p').replaceChildren(...text);
    box.hidden = false;
    root.dataset.state = 'disconnected';
  }
  const link = () => {
    const a = doc.createElement('a');
    a.href = page;
    a.textContent = 'the facemimic page';
    return a;
  };

  const view = {
    notice,
    link,
    /** The output's size (device pixels), surround colour, window title and avatar name. */
    configure({ width, height, surround, title, name: avatar }) {
      if (canvas.width !== width || canvas.height !== height) {
        canvas.width = width;
        canvas.height = height;
        delete canvas.dataset.drawn;
      }
      root.style.background = surround;
      doc.documentElement.style.background = surround;
      doc.title = title;
      name = avatar;
      canvas.setAttribute('aria-label', `${avatar}, the avatar`);
      root.dataset.size = `${width}x${height}`;
    },
    /** One frame: the part (sx, sy, sw, sh) of `image` (a canvas of the page) fills the canvas. */
    present(image, sx, sy, sw, sh) {
      ctx.drawImage(image, sx, sy, sw, sh, 0, 0, canvas.width, canvas.height);
      frames++;
      const now = performance.now();
      times.push(now);
      while (now - times[0] > 1000) times.shift();
      root.dataset.frames = String(frames);
      if (!canvas.dataset.drawn) canvas.dataset.drawn = '1';
      if (!connected) {
        connected = true;
        box.hidden = true;
      }
      root.dataset.state = 'live';
    },
    /** Not fed any more: said in the view itself. `gone`: the avatar itself left the page. */
    disconnect(reason, gone = false) {
      if (!connected) return;
      connected = false;
      const advice = gone ? [' Close this window, or pop out another avatar on ', link(), '.'] : [' Press Pop out on ', link(), ' again: the avatar comes back in this window.'];
      notice(`${name || 'The avatar'}: not connected`, [reason, ...advice]);
    },
    get connected() {
      return connected;
    },
    /** Frames presented so far, and in the last second. */
    get frames() {
      return frames;
    },
    fps() {
      const now = performance.now();
      while (times.length && now - times[0] > 1000) times.shift();
      return times.length;
    },
  };

  // No chrome: the cursor hides when it rests; a double-click toggles full screen.
  let idleTimer = 0;
  const awake = () => {
    root.classList.remove('idle');
    clearTimeout(idleTimer);
    idleTimer = setTimeout(() => root.classList.add('idle'), IDLE_MS);
  };
  root.addEventListener('pointermove', awake);
  root.addEventListener('pointerdown', awake);
  awake();
  root.addEventListener('dblclick', () => {
    if (doc.fullscreenElement) doc.exitFullscreen?.();
    else root.requestFullscreen?.().catch(() => {});
  });
  return view;
}

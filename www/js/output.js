// The pop-out output window (www/output.html): the view (www/js/output-view.js), found by the
// page that opened it (its opener) as `window.facemimicOutput`; it checks that the page still
// feeds it and says so plainly when it does not (closed, reloaded, gone elsewhere).

import { outputView } from './output-view.js';

const CHECK_MS = 500;
const params = new URLSearchParams(location.search);
const page = params.get('from') === 'call' ? 'call.html' : './';
const root = document.getElementById('view');
const view = outputView(root, { page });
window.facemimicOutput = view;

/** Whether the page that opened this window still feeds it. */
function fed() {
  try {
    const o = window.opener;
    return !!o && !o.closed && !!o.facemimicOutputs?.feeds(window);
  } catch {
    return false; // the opener went to another origin
  }
}

if (!window.opener) {
  view.notice('facemimic output view', ['This window shows one avatar of ', view.link(), ": open it there, with an avatar's Pop out button."]);
} else {
  root.dataset.state = 'live';
  setInterval(() => {
    if (view.connected && !fed()) view.disconnect('The facemimic page that fed this window was closed or reloaded.');
  }, CHECK_MS);
  try {
    window.opener.facemimicOutputs?.hello(window); // the page draws a frame now, even when paused
  } catch {
    // checked again by the interval
  }
}

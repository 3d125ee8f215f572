// What the call scripts (call.mjs, call-soak.mjs) share: their command-line options and the
// browser, fake media and demo server a call runs in.

import { launchBrowser } from '../lib/browser.mjs';
import { fakeMedia, startDemoServer } from '../lib/call.mjs';

/** The value after `--name` on the command line, else `def`. */
export const arg = (name, def) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : def;
};

/**
 * Start a browser with a fake camera and microphone (files named after `media`) and the demo
 * server, run `body({ browser, server })`, then close them both and exit: 0, or 1 after printing
 * the error under `label` if `body` threw.
 */
export async function runCall(label, { media, browserArgs = [] }, body) {
  const cleanups = [];
  const args = await fakeMedia((fn) => cleanups.push(fn), media);
  const browser = await launchBrowser([...args, ...browserArgs]);
  const server = await startDemoServer();
  let exitCode = 0;
  try {
    await body({ browser, server });
  } catch (e) {
    console.error(`${label}: ${e.stack || e}`);
    exitCode = 1;
  } finally {
    await browser.close();
    await server.stop();
    for (const fn of cleanups) fn();
  }
  process.exit(exitCode);
}

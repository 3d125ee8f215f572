// The page's flow, issue 33 part 4, item 4: the two sides of a call start with different
// avatars. Two headless Chromium pages with fake cameras (scripts/lib/call.mjs: spk07's unseen
// GRID clip) join one room through the demo server's signalling: with no avatar asked for, the
// first side takes the first default target and the second side the next one, from the start
// (the first side never sees the second as its own avatar); a reload keeps them apart; the
// experimenter can still choose any avatar, the same as the other side's too. When the first side
// chose the second's default, the second takes the first default that is not theirs.
//
//   node --test --test-concurrency=1 tests/e2e/flow_call.test.mjs

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { launchBrowser, haveChromium, screenshot, ROOT } from './lib.mjs';
import { fakeMedia, startDemoServer, status, waitCall } from '../../scripts/lib/call.mjs';

const HAVE_PKG = fs.existsSync(path.join(ROOT, 'www', 'pkg', 'facemimic_bg.wasm')) && fs.existsSync(path.join(ROOT, 'www', 'models', 'manifest.json'));
const skip = !haveChromium() ? 'chromium is absent' : !HAVE_PKG ? 'www/pkg or www/models is missing (scripts/build-wasm.sh, scripts/build-models.sh)' : false;
const MANIFEST = HAVE_PKG ? JSON.parse(fs.readFileSync(path.join(ROOT, 'www', 'models', 'manifest.json'), 'utf8')) : { targets: [] };
const [FIRST, SECOND] = MANIFEST.targets.map((f) => f.replace(/\.fmm$/, ''));

const cleanups = [];
let browser;
let server;
const errors = [];

before(async () => {
  if (skip) return;
  browser = await launchBrowser(await fakeMedia((fn) => cleanups.push(fn), 'flow-call'));
  server = await startDemoServer();
});

after(async () => {
  await browser?.close();
  await server?.stop();
  for (const fn of cleanups) fn();
});

/** Every avatar name the other side's status has named, in order (recorded in the page). */
function recordPeerAvatars() {
  window.__peerAvatars = [];
  setInterval(() => {
    const a = window.facemimicCall?.peer?.avatar;
    const seen = window.__peerAvatars;
    if (a && seen[seen.length - 1] !== a) seen.push(a);
  }, 20);
}

async function open(url, label) {
  const ctx = await browser.newContext({ viewport: { width: 1360, height: 900 } });
  cleanups.push(() => ctx.close().catch(() => {}));
  await ctx.addInitScript(recordPeerAvatars);
  const page = await ctx.newPage();
  page.on('pageerror', (e) => errors.push(`${label}: ${e.message}`));
  await page.goto(url);
  return page;
}

/** A joins a new room with `query`, B opens A's invite link (autojoin) with `queryB`; both connected. */
async function pair(query = '', queryB = '') {
  const a = await open(`${server.url}call.html?autojoin=1${query}`, 'A');
  await waitCall(a, () => window.facemimicCall.inviteUrl);
  const invite = await a.evaluate(() => window.facemimicCall.inviteUrl);
  const b = await open(`${invite}&autojoin=1${queryB}`, 'B');
  for (const p of [a, b]) await waitCall(p, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 10, 60_000);
  return { a, b };
}

/** Both pages closed (their cameras and trackers stop: the machine is small). */
const hangUp = (...pages) => Promise.all(pages.map((p) => p.context().close()));

/** Each side's avatar and the avatar it sees on the other side. */
async function avatars(a, b) {
  const [sa, sb] = [await status(a), await status(b)];
  return { a: sa.avatar, b: sb.avatar, aSees: sa.peer.avatar, bSees: sb.peer.avatar };
}

/** Waits until the statuses have crossed (each side names the other's current avatar). */
const settled = (a, b) =>
  Promise.all([a, b].map((p) => waitCall(p, () => window.facemimicCall.peer.avatar && window.facemimicCall.peer.at > 0, 20_000))).then(() =>
    a.waitForTimeout(2500),
  );

test('the second side to join starts with a different default avatar; a reload keeps them apart; the experimenter may still choose any', { skip }, async () => {
  const { a, b } = await pair();
  await settled(a, b);
  assert.deepEqual(await avatars(a, b), { a: FIRST, b: SECOND, aSees: SECOND, bSees: FIRST });
  // From the start: the first side never saw the second with its own avatar.
  assert.deepEqual(await a.evaluate(() => window.__peerAvatars), [SECOND]);
  assert.equal(await a.$eval('#avatar-model', (s) => s.value), `b:${FIRST}.fmm`);
  assert.equal(await b.$eval('#avatar-model', (s) => s.value), `b:${SECOND}.fmm`);
  await screenshot(b, 'flow-call-second-side', { fullPage: false });

  // A reload of the second side: back in the room, still apart.
  await b.reload();
  await waitCall(b, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 10, 60_000);
  await settled(a, b);
  assert.deepEqual(await avatars(a, b), { a: FIRST, b: SECOND, aSees: SECOND, bSees: FIRST });

  // The experimenter chooses: the second side may look like the first; nobody moves off it.
  await b.selectOption('#avatar-model', `b:${FIRST}.fmm`);
  await settled(a, b);
  assert.deepEqual(await avatars(a, b), { a: FIRST, b: FIRST, aSees: FIRST, bSees: FIRST });
  // ... and sets the other side from here (the experimenter's "Appears as").
  await a.selectOption('#peer-avatar', 'b:spk05.fmm');
  await waitCall(b, () => window.facemimicCall.avatar === 'spk05');
  await settled(a, b);
  assert.deepEqual(await avatars(a, b), { a: FIRST, b: 'spk05', aSees: 'spk05', bSees: FIRST });
  await hangUp(a, b);
  assert.deepEqual(errors, []);
});

test("the first side chose the second side's default: the second takes the first default that is not theirs", { skip }, async () => {
  const { a, b } = await pair(`&avatar=${SECOND}`);
  await settled(a, b);
  assert.deepEqual(await avatars(a, b), { a: SECOND, b: FIRST, aSees: FIRST, bSees: SECOND });
  await hangUp(a, b);
  // Both sides chose the same: they stay so.
  const { a: c, b: d } = await pair(`&avatar=${FIRST}`, `&avatar=${FIRST}`);
  await settled(c, d);
  assert.deepEqual(await avatars(c, d), { a: FIRST, b: FIRST, aSees: FIRST, bSees: FIRST });
  await hangUp(c, d);
  assert.deepEqual(errors, []);
});

// The condition schedule on the call page, end to end: two headless Chromium pages in a call
// (fake cameras, the demo server's signalling; scripts/lib/call.mjs), page A the experimenter's.
//
//   a short schedule (3 conditions of D = 4 s) switches both sides at the durations, every setting
//   and the avatar of each; page B is blind all along (no condition name anywhere in its DOM, no
//   setting, value or avatar name on its screen, its own avatar covered) and A's panel shows the
//   condition, the countdown and the progress; each switch is in the frame logs (A's: the
//   condition's number, name, both sides' settings, the time; B's: the number); both sides come
//   back to their settings at the end; a reload of B mid-condition (B comes back blind, in the
//   condition); Stop; "Participant view" on A; bad files and text are explained by their code and
//   the page goes on; Save writes what Load reads.
// The schedule's logic alone: tests/e2e/call_schedule.test.mjs.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import path from 'node:path';
import { launchBrowser, haveChromium, screenshot, ROOT } from './lib.mjs';
import { fakeMedia, startDemoServer, status, waitCall, twoPages } from '../../scripts/lib/call.mjs';
import { parseSchedule, serialiseSchedule } from '../../www/js/call-schedule.js';

const HAVE_PKG = fs.existsSync(path.join(ROOT, 'www', 'pkg', 'facemimic_bg.wasm')) && fs.existsSync(path.join(ROOT, 'www', 'models', 'manifest.json'));
const skip = !haveChromium() ? 'chromium is absent' : !HAVE_PKG ? 'www/pkg or www/models is missing (scripts/build-wasm.sh, scripts/build-models.sh)' : false;

/**
 * Each condition's length, in seconds. The loop below looks at both pages within each condition,
 * so a condition must outlast a loaded 2-core machine's slowest look: at 2 s (with two
 * screenshots in the loop, now taken in the long condition of the next test), CI once reached
 * the third condition's wait after it had gone.
 */
const D = 4;
/** The schedule's whole length as the panel writes it (m:ss). */
const TOTAL = `${Math.floor((3 * D) / 60)}:${String((3 * D) % 60).padStart(2, '0')}`;
const SCHEDULE = {
  version: 1,
  name: 'e2e-three-conditions',
  conditions: [
    { name: 'cond-alpha', duration: D, local: { gain: 0.5 }, remote: { head: 0.2, avatar: 'spk05' } },
    { name: 'cond-beta', duration: D, both: { gain: 1.5 }, remote: { mouth: 2 } },
    { name: 'cond-gamma', duration: D, local: { avatar: 'spk06', style: 0.5 }, remote: { gain: 0.25, eyes: 0 } },
  ],
};
/** What each side is set to in each condition (the settings before it are all 1; A is spk02, B spk03). */
const ONE = { gain: 1, head: 1, mouth: 1, eyes: 1, brows: 1, style: 1 };
const EXPECT = [
  { a: { ...ONE, gain: 0.5 }, aAvatar: 'spk02', b: { ...ONE, head: 0.2 }, bAvatar: 'spk05' },
  { a: { ...ONE, gain: 1.5 }, aAvatar: 'spk02', b: { ...ONE, gain: 1.5, mouth: 2 }, bAvatar: 'spk03' },
  { a: { ...ONE, style: 0.5 }, aAvatar: 'spk06', b: { ...ONE, gain: 0.25, eyes: 0 }, bAvatar: 'spk03' },
];
const NAMES = [SCHEDULE.name, ...SCHEDULE.conditions.map((c) => c.name)];

const cleanups = [];
const errors = [];
let browser;
let server;
let a;
let b;

before(async () => {
  if (skip) return;
  const args = await fakeMedia((fn) => cleanups.push(fn), 'call-schedule');
  browser = await launchBrowser(args);
  server = await startDemoServer({ env: { FACEMIMIC_SIGNAL_HEARTBEAT_MS: '2000' } });
});

after(async () => {
  await browser?.close();
  await server?.stop();
  for (const fn of cleanups) fn();
});

/**
 * What a participant could learn from page B: every text in its DOM, and what is on its screen.
 * Runs in the page; with `want` (settings and an avatar), false until B is set to them, so the
 * view is read in the same look as the settings it is checked against.
 */
function viewInPage(want) {
  if (want && !(Object.entries(want.settings).every(([k, v]) => window.facemimicCall.settings[k] === v) && window.facemimicCall.avatar === want.avatar)) return false;
  const visible = (id) => {
    const el = document.getElementById(id);
    return Boolean(el && el.offsetParent !== null && getComputedStyle(el).visibility !== 'hidden');
  };
  return {
    blind: document.body.classList.contains('blind'),
    html: document.documentElement.outerHTML,
    text: document.body.innerText,
    outputs: [...document.querySelectorAll('output[id$="-out"]')].map((o) => o.textContent), // the settings' values
    shown: Object.fromEntries(['gain', 'head', 'avatar-model', 'peer-gain', 'peer-avatar', 'schedule-group', 'download-log', 'allow-remote', 'blind-note'].map((id) => [id, visible(id)])),
    cover: getComputedStyle(document.querySelector('.self-cover')).display !== 'none',
    settings: { ...window.facemimicCall.settings },
    schedule: window.facemimicCall.schedule,
    popOut: [...document.querySelectorAll('.self .output-menu')].some((e) => e.offsetParent !== null), // the avatar in a window of its own
  };
}

/** Page B's view now. */
function participantView(page) {
  return page.evaluate(viewInPage, null);
}

/** Page B's view once it is set to `want` ({ settings, avatar }), waiting at most `timeout` ms. */
async function participantViewWhenSet(page, want, timeout) {
  return (await page.waitForFunction(viewInPage, want, { timeout, polling: 50 })).jsonValue();
}

function assertBlind(v, label) {
  assert.ok(v.blind, `${label}: page B is blind`);
  for (const n of NAMES) assert.ok(!v.html.includes(n), `${label}: "${n}" is nowhere in page B's DOM`);
  assert.ok(!/spk\d\d/.test(v.text), `${label}: no avatar name on page B's screen: ${v.text.match(/.{0,40}spk\d\d.{0,40}/)?.[0]}`);
  assert.ok(!/condition|schedule/i.test(v.text), `${label}: no word of a schedule on page B's screen`);
  assert.ok(v.outputs.every((o) => o === '–'), `${label}: no setting's value, even hidden: ${v.outputs}`);
  for (const [id, shown] of Object.entries(v.shown)) assert.equal(shown, id === 'blind-note', `${label}: #${id} ${shown ? 'shown' : 'hidden'}`);
  assert.ok(v.cover, `${label}: B's own avatar is covered`);
  assert.ok(!v.popOut, `${label}: no pop-out of B's own avatar`);
}

const settingsOf = (s) => Object.fromEntries(Object.keys(ONE).map((k) => [k, s.settings[k]]));

/** Sets the schedule box of `page` and presses Load. */
async function loadText(page, text) {
  await page.fill('#schedule-text', text);
  await page.click('#schedule-load');
}

test(`a schedule of 3 conditions of ${D} s switches both sides; the other page is blind; every switch is logged`, { skip }, async (t) => {
  ({ a, b } = await twoPages(browser, server, { onPage: (p, label) => p.on('pageerror', (e) => errors.push(`${label}: ${e.message}`)) }));
  for (const p of [a, b]) await waitCall(p, () => window.facemimicCall.state === 'connected' && window.facemimicCall.remoteFrames > 20, 45000);
  await waitCall(a, () => window.facemimicCall.peer.avatar === 'spk03', 10000);

  await loadText(a, JSON.stringify(SCHEDULE, null, 2));
  assert.equal(await a.textContent('#schedule-summary'), `3 conditions, ${TOTAL} in all · e2e-three-conditions`);
  assert.equal(await a.locator('#schedule-list li').count(), 3);
  assert.equal(await a.isHidden('#schedule-error'), true);
  assert.equal(await b.evaluate(() => document.body.classList.contains('blind')), false, 'B sees its controls before the schedule');

  await a.click('#schedule-start');
  const seen = [];
  for (let k = 0; k < 3; k++) {
    const want = EXPECT[k];
    await waitCall(a, `window.facemimicCall.schedule.number === ${k + 1}`, D * 1000 + 1000).catch(async (e) => {
      throw new Error(`condition ${k + 1} never seen on A, whose schedule is ${JSON.stringify((await status(a)).schedule)} (${e.message})`);
    });
    // A's page, in one look once the other page reports the condition: its settings, and the
    // experimenter's view (the condition, its name, the time left, what each side gets).
    const va = await (
      await a.waitForFunction(
        ([n, avatar]) => {
          const $ = (id) => document.getElementById(id);
          const s = window.facemimicCall;
          if ($('schedule-remote-state').textContent !== 'applied' || $('schedule-cond').textContent !== `Condition ${n} of 3` || s.avatar !== avatar) return false;
          return {
            number: s.schedule.number,
            settings: { ...s.settings },
            name: $('schedule-name').textContent,
            left: $('schedule-left').textContent,
            total: $('schedule-total').textContent,
            remote: $('schedule-remote').textContent,
            current: document.querySelector('#schedule-list li.current b')?.textContent,
            shown: $('schedule-now').offsetParent !== null,
          };
        },
        [k + 1, want.aAvatar],
        { timeout: D * 1000 - 100, polling: 50 },
      )
    ).jsonValue();
    assert.equal(va.number, k + 1);
    assert.deepEqual(settingsOf(va), want.a, `A's settings in condition ${k + 1}`);
    assert.equal(va.name, SCHEDULE.conditions[k].name);
    assert.equal(va.current, SCHEDULE.conditions[k].name);
    assert.match(va.left, new RegExp(`^0:0[0-${D}]$`));
    assert.match(va.total, new RegExp(`^0:\\d\\d of ${TOTAL}$`));
    assert.match(va.remote, new RegExp(want.bAvatar));
    assert.ok(va.shown);
    // B, set by A's page over the data channel (settings at once, the avatar once loaded), shows
    // nothing of it: its view is read in the same look as the settings it is checked against.
    const vb = await participantViewWhenSet(b, { settings: want.b, avatar: want.bAvatar }, D * 1000 - 100).catch(async (e) => {
      const [sa, sb] = [await status(a), await status(b)];
      throw new Error(`condition ${k + 1}: B has ${JSON.stringify(sb.settings)} as ${sb.avatar}; A is in ${JSON.stringify(sa.schedule)} (${e.message})`);
    });
    assert.deepEqual(settingsOf(vb), want.b, `B's settings in condition ${k + 1}`);
    assert.equal(vb.schedule.state, 'blind');
    assertBlind(vb, `condition ${k + 1}`);
    seen.push(k + 1);
  }
  assert.deepEqual(seen, [1, 2, 3]);

  // The end: both sides back to where they were; B sees its controls again.
  await waitCall(a, () => window.facemimicCall.schedule.state === 'ended', 5000);
  await waitCall(b, () => !document.body.classList.contains('blind'), 5000);
  await waitCall(b, () => window.facemimicCall.avatar === 'spk03' && window.facemimicCall.settings.head === 1, 5000);
  await waitCall(a, () => window.facemimicCall.avatar === 'spk02', 5000);
  assert.deepEqual(settingsOf(await status(a)), ONE);
  assert.deepEqual(settingsOf(await status(b)), ONE);
  assert.equal(await a.textContent('#schedule-cond'), 'Schedule over');
  assert.equal(await b.isVisible('#gain'), true);

  // A's log of the switches: start, the three conditions, the end, with names, values and times.
  const sw = (await status(a)).switches;
  assert.deepEqual(sw.map((e) => [e.event, e.condition, e.name]), [['start', 0, 'e2e-three-conditions'], ['switch', 1, 'cond-alpha'], ['switch', 2, 'cond-beta'], ['switch', 3, 'cond-gamma'], ['end', 0, 'e2e-three-conditions']]);
  const [, s1, s2, s3, end] = sw;
  for (const [i, e] of [s1, s2, s3].entries()) {
    assert.equal(e.duration, D);
    assert.ok(Math.abs(e.planned - s1.planned - D * 1000 * i) < 1, `condition ${i + 1} planned at +${e.planned - s1.planned} ms`);
    // On time but for the main thread's other work (a frame's tracking, this loaded machine).
    assert.ok(e.wall - e.planned >= -1 && e.wall - e.planned < 1000, `condition ${i + 1} switched ${(e.wall - e.planned).toFixed(0)} ms after its time`);
    assert.deepEqual(Object.fromEntries(Object.keys(ONE).map((k) => [k, e.remote[k]])), EXPECT[i].b);
    assert.equal(e.remote.avatar, EXPECT[i].bAvatar);
    assert.equal(e.local.avatar, EXPECT[i].aAvatar);
    assert.equal(e.local.gain, EXPECT[i].a.gain);
  }
  t.diagnostic(`A switched ${[s1, s2, s3].map((e) => (e.wall - e.planned).toFixed(1)).join(', ')} ms after the planned times; the end ${(end.wall - s1.planned - 3 * D * 1000).toFixed(1)} ms after`);
  assert.ok(end.wall - s1.planned >= 3 * D * 1000 - 10 && end.wall - s1.planned < 3 * D * 1000 + 1000, `the end ${end.wall - s1.planned} ms after the start`);
  assert.deepEqual([end.local.avatar, end.remote.avatar, end.remote.head], ['spk02', 'spk03', 1]);
  // B's log: what it was set to, by number only (never the name).
  const bsw = (await status(b)).switches;
  assert.deepEqual(bsw.map((e) => [e.event, e.condition, e.name]), [['applied', 1, ''], ['applied', 2, ''], ['applied', 3, ''], ['applied', 0, '']]);
  assert.equal(bsw[0].local.head, 0.2);
  t.diagnostic(`B applied each condition ${bsw.slice(0, 3).map((e, i) => (e.wall - [s1, s2, s3][i].wall).toFixed(1)).join(', ')} ms after A switched (one machine, one clock)`);
  assert.equal(bsw[0].local.avatar, 'spk05');

  // The downloads: A's frames carry their condition's number and name; the switches as CSV.
  const csv = async (page, id) => {
    const [d] = await Promise.all([page.waitForEvent('download'), page.click(id)]);
    return fs.readFileSync(await d.path(), 'utf8').trim().split('\n').map((l) => l.match(/("(?:[^"\\]|\\.)*"|[^,]*)(,|$)/g).map((c) => c.replace(/,$/, '')));
  };
  const frames = await csv(a, '#download-log');
  const col = (rows, name) => rows[0].indexOf(name);
  const byCond = (rows, n) => rows.slice(1).filter((r) => r[col(rows, 'condition')] === String(n));
  for (const n of [1, 2, 3]) {
    const rows = byCond(frames, n);
    assert.ok(rows.length >= 10, `A: ${rows.length} frames in condition ${n}`);
    assert.ok(rows.every((r) => r[col(frames, 'condition_name')] === `"${SCHEDULE.conditions[n - 1].name}"`));
    assert.ok(rows.every((r) => Number(r[col(frames, 'gain')]) === EXPECT[n - 1].a.gain), `A's gain in condition ${n}`);
  }
  assert.ok(byCond(frames, 3).some((r) => r[col(frames, 'avatar')] === '"spk06"'), 'A appears as spk06 in condition 3');
  assert.ok(frames.slice(1).some((r) => r[col(frames, 'condition')] === ''), 'frames outside the schedule have no condition');
  const switches = await csv(a, '#download-switches');
  assert.deepEqual(switches.slice(1).map((r) => r[1]), ['start', 'switch', 'switch', 'switch', 'end']);
  assert.equal(switches[2][col(switches, 'condition_name')], '"cond-alpha"');
  assert.equal(switches[2][col(switches, 'remote_head_motion')], '0.2');
  assert.equal(switches[2][col(switches, 'remote_avatar')], '"spk05"');
  assert.equal(switches[4][col(switches, 'local_avatar')], '"spk06"');
  const bFrames = await csv(b, '#download-log');
  const b1 = byCond(bFrames, 1);
  assert.ok(b1.length >= 10 && b1.every((r) => r[col(bFrames, 'head_motion')] === '0.2' && r[col(bFrames, 'condition_name')] === ''), "B's frames in condition 1: head motion 0.2, no name");
  assert.ok(b1.some((r) => r[col(bFrames, 'avatar')] === '"spk05"'));
  assert.ok(byCond(bFrames, 3).length >= 10);
});

test('Stop brings both sides back at once; "Participant view" hides the experimenter\'s panel on its own page', { skip }, async () => {
  await loadText(a, JSON.stringify({ name: 'long-one', duration: 30, conditions: [{ name: 'cond-long', remote: { head: 0, avatar: 'spk01' }, local: { brows: 3 } }, { name: 'cond-never' }] }));
  await a.click('#schedule-start');
  await waitCall(b, () => window.facemimicCall.avatar === 'spk01' && window.facemimicCall.settings.head === 0, 5000);
  await waitCall(a, () => window.facemimicCall.settings.brows === 3, 5000);
  assert.equal(await a.isDisabled('#gain'), true, "A's own controls are the schedule's while it runs");
  assert.equal(await a.isDisabled('#peer-gain'), true);
  assertBlind(await participantView(b), 'a long condition');
  // The screenshots, in a condition long enough for both: the experimenter's panel scrolled to
  // the schedule (the page itself at its top), and the participant's page.
  await a.evaluate(() => {
    const panel = document.getElementById('controls');
    panel.scrollTop += document.getElementById('schedule-group').getBoundingClientRect().top - panel.getBoundingClientRect().top;
    window.scrollTo(0, 0);
  });
  await screenshot(a, 'call-schedule-experimenter', { fullPage: false });
  await screenshot(b, 'call-schedule-participant', { fullPage: true });
  // B reloads mid-condition: it comes back blind, and A's page sets it to the condition again.
  await b.reload();
  await waitCall(b, () => window.facemimicCall.state === 'connected', 45000);
  await waitCall(b, () => window.facemimicCall.avatar === 'spk01' && window.facemimicCall.settings.head === 0, 10000);
  assertBlind(await participantView(b), 'after a reload');
  await a.waitForFunction(() => document.getElementById('schedule-remote-state').textContent === 'applied', null, { timeout: 5000 });
  // A participant at A's screen: nothing of the schedule, no value, no name.
  await a.click('#schedule-blind');
  const va = await participantView(a);
  assert.ok(va.blind);
  assert.ok(!/spk\d\d|cond-long|condition|schedule/i.test(va.text), `A's screen in participant view: ${va.text.slice(0, 300)}`);
  assert.equal(va.shown['schedule-group'], false);
  assert.equal(va.shown['blind-note'], true);
  await screenshot(a, 'call-schedule-participant-view', { fullPage: true });
  assert.equal((await status(b)).schedule.state, 'blind', 'B stays blind');
  await a.keyboard.press('Control+Shift+E');
  assert.equal(await a.isVisible('#schedule-group'), true, 'Ctrl+Shift+E brings the panel back');
  assert.match(await a.textContent('#schedule-left'), /^0:[0-3]\d$/);
  await a.click('#schedule-stop');
  await waitCall(b, () => window.facemimicCall.avatar === 'spk03' && window.facemimicCall.settings.head === 1 && !document.body.classList.contains('blind'), 5000);
  await waitCall(a, () => window.facemimicCall.settings.brows === 1, 5000);
  assert.equal(await a.isDisabled('#gain'), false);
  const sw = (await status(a)).switches.slice(-3);
  assert.deepEqual(sw.map((e) => [e.event, e.condition, e.name]), [['start', 0, 'long-one'], ['switch', 1, 'cond-long'], ['stop', 1, 'cond-long']]);
  assert.ok(sw[2].wall - sw[1].wall < 30000);
  assert.equal(await a.textContent('#schedule-cond'), 'Schedule stopped');
});

test('bad schedules are explained by their code and message; the page goes on; Save writes what Load reads', { skip }, async () => {
  const file = (name, content) => ({ name, mimeType: 'application/json', buffer: Buffer.isBuffer(content) ? content : Buffer.from(content) });
  const cases = [
    ['text', 'not json at all', 'not-json', /not JSON/],
    ['text', '', 'not-json', /empty/],
    ['file', file('picture.json', Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0, 0, 0, 13])), 'not-json', /not JSON/],
    ['file', file('big.json', Buffer.alloc(1_000_001, 32)), 'too-large', /big.json is 1000001 bytes/],
    ['file', file('keys.json', '{"conditions": [{"duration": 2, "remote": {"gian": 1}}]}'), 'unknown-key', /unknown key "gian" \(did you mean "gain"\?/],
    ['file', file('zero.json', '[{"duration": 0}]'), 'bad-duration', /Condition 1: the duration is 0/],
    ['file', file('negative.json', '[{"duration": 2}, {"name": "neg", "duration": -5}]'), 'bad-duration', /Condition 2 \("neg"\): the duration is -5/],
    ['text', '[{"duration": "sixty"}]', 'bad-duration', /"sixty", not a number/],
    ['text', '[{"duration": 2, "remote": {"avatar": "nobody"}}]', 'bad-avatar', /remote.avatar is "nobody", an unknown avatar \(a bundled avatar's name: spk01/],
    ['text', '[{"duration": 2, "local": {"avatar": ""}}]', 'bad-avatar', /local.avatar is missing/],
    ['text', '[{"duration": 2, "both": {"gain": 9}}]', 'out-of-range', /both.gain is 9, outside 0..2.5/],
    ['text', '[{"duration": 2, "remote": {"style": "1"}}]', 'bad-value', /remote.style is "1", not a number/],
  ];
  for (const [how, input, code, why] of cases) {
    if (how === 'text') await loadText(a, input);
    else await a.setInputFiles('#schedule-file', input);
    await a.waitForFunction((c) => document.getElementById('schedule-error').dataset.code === c && !document.getElementById('schedule-error').hidden, code, { timeout: 5000 });
    const shown = await a.textContent('#schedule-error');
    assert.match(shown, new RegExp(`^${code} `), shown);
    assert.match(shown, why, shown);
    assert.equal(await a.textContent('#schedule-summary'), 'No schedule loaded.');
    assert.equal(await a.isDisabled('#schedule-start'), true, 'nothing to start after a bad schedule');
    await a.evaluate(() => {
      document.getElementById('schedule-error').dataset.code = '';
    });
  }
  const toasts = await a.$$eval('.toast.error', (els) => els.map((e) => e.textContent));
  assert.ok(toasts.some((t) => /Schedule not loaded.*\[bad-avatar\]/.test(t)), toasts.join(' | '));
  // The page goes on: a good file loads and runs; the call is still up.
  const crossed = { version: 1, duration: 1, cross: { factors: { 'remote.gain': [0.5, 1], 'local.head': [0, 1] }, seed: 5 } };
  await a.setInputFiles('#schedule-file', file('crossed.json', JSON.stringify(crossed)));
  await a.waitForFunction(() => document.getElementById('schedule-error').hidden, null, { timeout: 5000 });
  assert.match(await a.textContent('#schedule-summary'), /^4 conditions, 0:04 in all · remote.gain × local.head, fully crossed, shuffled \(seed 5\)$/);
  const [d] = await Promise.all([a.waitForEvent('download'), a.click('#schedule-save')]);
  const saved = fs.readFileSync(await d.path(), 'utf8');
  const avatars = ['spk01', 'spk02', 'spk03', 'spk04', 'spk05', 'spk06', 'spk07', 'spk08', 'spk09', 'spk10'];
  const want = parseSchedule(crossed, { avatars });
  assert.equal(saved, serialiseSchedule(want), 'Save writes the crossed conditions out, in their order');
  assert.deepEqual(parseSchedule(saved, { avatars }).conditions, want.conditions);
  await a.click('#schedule-start');
  await waitCall(a, () => window.facemimicCall.schedule.state === 'ended', 10000);
  await waitCall(b, () => !document.body.classList.contains('blind'), 5000);
  const sw = (await status(a)).switches.filter((e) => e.event === 'switch').slice(-4);
  assert.deepEqual(sw.map((e) => e.name), want.conditions.map((c) => c.name));
  assert.equal((await status(a)).state, 'connected');
  assert.equal((await status(b)).state, 'connected');
  // A page opened with ?blind=1 is blind from the start.
  const ctx = await browser.newContext({ viewport: { width: 1360, height: 900 } });
  const c = await ctx.newPage();
  c.on('pageerror', (e) => errors.push(`C: ${e.message}`));
  await c.goto(`${server.url}call.html?blind=1&avatar=spk04`);
  await waitCall(c, () => window.facemimicCall.framesSent > 0, 30000);
  const vc = await participantView(c);
  assert.ok(vc.blind && !vc.shown.gain && !vc.shown['schedule-group'] && vc.shown['blind-note'] && !/spk\d\d/.test(vc.text));
  await ctx.close();
  assert.deepEqual(errors, [], 'no uncaught error in any page');
});

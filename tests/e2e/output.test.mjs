// End-to-end tests of the output view (www/output.html, www/js/output-*.js): one avatar alone in
// a pop-out window at a chosen size, on its picture or on a key colour, fed by the main page's
// (or the call page's) frame loop; and the main page's output mode (`?output=NAME`) for a
// browser source. docs/obs.md is the guide; its frame rates are the ones this file prints.
//
//   node --test --test-concurrency=1 tests/e2e/output.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { screenshot } from './lib.mjs';
import { pageTests } from './page-lib.mjs';

const { suite, open } = pageTests();

const VIEW = '.fm-output';
const CANVAS = '.fm-output canvas';

/** Opens the output view by clicking `selector` on the main page; returns the pop-out, drawn. */
async function popOut(page, selector) {
  const [pop] = await Promise.all([page.waitForEvent('popup'), page.click(selector)]);
  await pop.waitForSelector(`${CANVAS}[data-drawn]`, { timeout: 15_000 });
  return pop;
}

/**
 * What the output canvas shows: its size, and over its middle (the middle `frac` of each side,
 * where the face is) the share of pixels far from `bg` ([r, g, b]), the luminance variance and
 * a digest; over a border strip, the largest distance from `bg`.
 */
async function look(pop, bg, frac = 0.3) {
  return pop.$eval(
    CANVAS,
    (c, [bg, frac]) => {
      const g = c.getContext('2d');
      const w = c.width;
      const h = c.height;
      const far = (d, i) => Math.max(Math.abs(d[i] - bg[0]), Math.abs(d[i + 1] - bg[1]), Math.abs(d[i + 2] - bg[2]));
      const cw = Math.round(w * frac);
      const ch = Math.round(h * frac);
      const mid = g.getImageData(Math.round((w - cw) / 2), Math.round((h - ch) / 2), cw, ch).data;
      let away = 0;
      let s = 0;
      let s2 = 0;
      let hash = 2166136261 >>> 0;
      for (let i = 0; i < mid.length; i += 4) {
        if (far(mid, i) > 60) away++;
        const l = 0.299 * mid[i] + 0.587 * mid[i + 1] + 0.114 * mid[i + 2];
        s += l;
        s2 += l * l;
        hash = Math.imul(hash ^ mid[i] ^ (mid[i + 1] << 8) ^ (mid[i + 2] << 16), 16777619) >>> 0;
      }
      const n = mid.length / 4;
      let border = 0;
      const strip = Math.max(2, Math.round(Math.min(w, h) * 0.04));
      for (const [x, y, sw, sh] of [[0, 0, w, strip], [0, h - strip, w, strip], [0, 0, strip, h], [w - strip, 0, strip, h]]) {
        const d = g.getImageData(x, y, sw, sh).data;
        for (let i = 0; i < d.length; i += 4) border = Math.max(border, far(d, i));
      }
      return { width: w, height: h, away: away / n, variance: s2 / n - (s / n) ** 2, digest: hash.toString(16), border };
    },
    [bg, frac],
  );
}

/** Main-page frames and the output's presented frames, read at one moment (from the main page). */
const counts = (page) =>
  page.evaluate(() => {
    const o = window.facemimicOutputs.outputs[0];
    return { main: Number(document.body.dataset.frames), output: o.win.facemimicOutput.frames, at: performance.now() };
  });

/** Over `ms`: the main page's and the output's frame rates, and the share of the main page's
 *  frames the output got. */
async function pace(page, ms) {
  const a = await counts(page);
  await page.waitForTimeout(ms);
  const b = await counts(page);
  const s = (b.at - a.at) / 1000;
  const main = b.main - a.main;
  const output = b.output - a.output;
  return { mainFps: main / s, outputFps: output / s, share: output / Math.max(1, main), main };
}

test('a target card pops the avatar out in its picture at 1280x720, fed at the page frame rate; it closes and opens again', async (t) => {
  const { page, errors } = await open(t);
  assert.equal(await page.locator('.face-card.target').count(), suite.manifest.targets.length, 'four targets composited on the page');
  const name = await page.locator('.face-card.target >> nth=1 >> .name').textContent();
  const pop = await popOut(page, `.face-card.target >> nth=1 >> [data-action="popout"]`);
  const popErrors = [];
  pop.on('pageerror', (e) => popErrors.push(String(e)));
  assert.equal(await pop.title(), `${name} · facemimic output`, 'the window title names the avatar');
  assert.equal(await page.getAttribute(`.face-card.target >> nth=1 >> [data-action="popout"]`, 'aria-pressed'), 'true');

  // The chosen size (the default preset) and the avatar in its picture: varied, not black.
  const first = await look(pop, [0, 0, 0]);
  assert.equal(`${first.width}x${first.height}`, '1280x720');
  assert.ok(first.away > 0.9 && first.variance > 60, `the middle of the output is not a face in its picture: ${JSON.stringify(first)}`);
  assert.ok(first.border > 30, 'the picture fills the output to its edges');
  // No chrome: the canvas fills the window, nothing scrolls, nothing else is in it.
  const chrome = await pop.evaluate(() => ({
    scroll: document.documentElement.scrollWidth - innerWidth + document.documentElement.scrollHeight - innerHeight,
    others: [...document.body.querySelectorAll('*')].filter((e) => e.offsetParent !== null && !e.closest('.fm-output')).length,
    box: document.querySelector('.fm-output canvas').getBoundingClientRect().toJSON(),
    inner: [innerWidth, innerHeight],
  }));
  assert.equal(chrome.scroll, 0, 'the output window scrolls');
  assert.equal(chrome.others, 0);
  assert.deepEqual([chrome.box.width, chrome.box.height], chrome.inner);

  // Fed every frame the main page draws while the track plays: the avatar moves, and the
  // output's frames keep pace with the page's (a share, not a wall-clock rate).
  await pop.waitForTimeout(300);
  const p = await pace(page, 4000);
  t.diagnostic(`picture 1280x720: main page ${p.mainFps.toFixed(1)} fps, output ${p.outputFps.toFixed(1)} fps (${(100 * p.share).toFixed(1)}% of the page's ${p.main} frames)`);
  assert.ok(p.main > 10, `the main page drew only ${p.main} frames in 4 s`);
  assert.ok(p.share >= 0.9, `the output got ${(100 * p.share).toFixed(1)}% of the page's frames`);
  const later = await look(pop, [0, 0, 0]);
  assert.notEqual(later.digest, first.digest, 'the avatar does not move in the output');
  await screenshot(pop, 'output-picture', { fullPage: false });

  // Closed: the page stops feeding it; the panel's button opens it again, fed again.
  await pop.close();
  await page.waitForFunction(() => window.facemimicOutputs.open === 0, null, { timeout: 5000 });
  assert.equal(await page.getAttribute(`.face-card.target >> nth=1 >> [data-action="popout"]`, 'aria-pressed'), 'false');
  await page.selectOption('#output-target', { label: name });
  const again = await popOut(page, '#output-open');
  assert.equal(await again.title(), `${name} · facemimic output`);
  const q = await pace(page, 1500);
  assert.ok(q.share >= 0.9, `reopened, the output got ${(100 * q.share).toFixed(1)}% of the page's frames`);
  await page.locator('#h-output').scrollIntoViewIfNeeded();
  await screenshot(page, 'output-main-page', { fullPage: false });
  assert.deepEqual(errors, [], 'main page errors');
  assert.deepEqual(popErrors, [], 'output window errors');
});

test('the key colour: a custom size, the face alone on the chosen colour; the pop-out says when its page is gone', async (t) => {
  const { page, errors } = await open(t);
  await page.selectOption('#output-size', 'custom');
  await page.fill('#output-width', '960');
  await page.fill('#output-height', '540');
  await page.press('#output-height', 'Tab');
  await page.check('input[name="output-bg"][value="key"]', { force: true });
  assert.equal(await page.inputValue('#output-key'), '#00ff00', 'green is the default key colour');
  const pop = await popOut(page, `.face-card.target >> nth=0 >> [data-action="popout"]`);
  const green = await look(pop, [0, 255, 0]);
  assert.equal(`${green.width}x${green.height}`, '960x540');
  assert.ok(green.away > 0.95 && green.variance > 60, `no face in the middle of the output: ${JSON.stringify(green)}`);
  assert.ok(green.border <= 2, `the edges are not the key colour (off by ${green.border})`);
  // The window around the canvas is the key colour too (any window shape: OBS crops it).
  assert.equal(await pop.evaluate(() => getComputedStyle(document.querySelector('.fm-output')).backgroundColor), 'rgb(0, 255, 0)');
  await pop.setViewportSize({ width: 700, height: 700 });
  const box = await pop.$eval(CANVAS, (c) => c.getBoundingClientRect().toJSON());
  assert.deepEqual([box.width, box.height], [700, 700], 'the canvas box fills the window (object-fit keeps its aspect)');
  await screenshot(pop, 'output-key-resized', { fullPage: false });
  await pop.setViewportSize({ width: 960, height: 540 });
  const p = await pace(page, 3000);
  t.diagnostic(`key colour 960x540: main page ${p.mainFps.toFixed(1)} fps, output ${p.outputFps.toFixed(1)} fps (${(100 * p.share).toFixed(1)}%)`);
  assert.ok(p.share >= 0.9, `the output got ${(100 * p.share).toFixed(1)}% of the page's frames`);
  assert.notEqual((await look(pop, [0, 255, 0])).digest, green.digest, 'the face does not move');
  await screenshot(pop, 'output-key', { fullPage: false });

  // Another key colour, live: the open output follows.
  await page.$eval('#output-key', (el) => {
    el.value = '#ff00ff';
    el.dispatchEvent(new Event('input', { bubbles: true }));
  });
  await pop.waitForFunction(() => getComputedStyle(document.querySelector('.fm-output')).backgroundColor === 'rgb(255, 0, 255)');
  await page.waitForTimeout(300);
  assert.ok((await look(pop, [255, 0, 255])).border <= 2, 'the new key colour is not around the face');

  // The page goes: the output says so in its own window.
  assert.deepEqual(errors, []);
  await page.close();
  await pop.waitForSelector('.fm-output .notice:not([hidden])', { timeout: 5000 });
  assert.match(await pop.textContent('.fm-output .notice'), /not connected.*closed or reloaded/s);
  await screenshot(pop, 'output-disconnected', { fullPage: false });
});

test('output mode (?output=NAME): the page shows only that avatar, at the size and key colour asked, for a browser source', async (t) => {
  const { page, errors } = await open(t, { width: 720, height: 720 });
  const name = suite.manifest.targets[2].replace(/\.fmm$/, '');
  await page.goto(new URL(`?output=${name}&size=720x720&background=key&key=0000ff`, page.url()).href);
  await page.waitForSelector(`${CANVAS}[data-drawn]`, { timeout: 30_000 });
  assert.equal(await page.title(), `${name} · facemimic output`);
  const blue = await look(page, [0, 0, 255]);
  assert.equal(`${blue.width}x${blue.height}`, '720x720');
  assert.ok(blue.away > 0.95 && blue.border <= 2, `not the face alone on blue: ${JSON.stringify(blue)}`);
  const ui = await page.evaluate(() => ({
    shown: [...document.querySelectorAll('header, main, footer, .card, button')].filter((e) => e.getClientRects().length > 0).length,
    scroll: document.documentElement.scrollHeight - innerHeight,
  }));
  assert.deepEqual(ui, { shown: 0, scroll: 0 }, 'the page shows UI around the output');
  await page.waitForFunction((n) => Number(document.querySelector('.fm-output').dataset.frames) > n + 10, Number(await page.getAttribute(VIEW, 'data-frames')));
  assert.notEqual((await look(page, [0, 0, 255])).digest, blue.digest, 'the face does not move');
  await screenshot(page, 'output-mode', { fullPage: false });
  assert.deepEqual(errors, []);
});

test('the call page pops out the local avatar', async (t) => {
  const context = await suite.browser.newContext({ viewport: { width: 1280, height: 900 } });
  t.after(() => context.close());
  const page = await context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.goto(`${suite.server.url}call.html`);
  await page.waitForSelector('.self .output-open', { timeout: 30_000 });
  await page.waitForFunction(() => /\w/.test(document.getElementById('self-name').textContent), null, { timeout: 30_000 });
  const name = (await page.textContent('#self-name')).trim();
  const pop = await popOut(page, '.self .output-open');
  assert.equal(await pop.title(), `${name} · facemimic output`);
  const s = await look(pop, [0, 0, 0]);
  assert.ok(s.away > 0.9 && s.variance > 60, `the call's output shows no avatar: ${JSON.stringify(s)}`);
  assert.ok(await page.$eval('.self .output-open', (b) => b.classList.contains('on')));
  await screenshot(pop, 'output-call', { fullPage: false });
  await page.locator('.self').scrollIntoViewIfNeeded();
  await screenshot(page, 'output-call-page', { fullPage: false });
  assert.deepEqual(errors, []);
});

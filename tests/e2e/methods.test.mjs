// End-to-end tests of the demo page's cloning methods and settings (www/js/controls.js): the
// method radios and the compare view's canvases are the package's `methods()` (the core's one
// list), the default is the core's (expressive), every method draws a different face, and the
// expressive method's region gains and style reach the stage and the compare view. Headless
// chromium through playwright-core, as page.test.mjs; needs www/pkg/ and www/models/.
//
//   node --test --test-concurrency=1 tests/e2e/methods.test.mjs

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { screenshot, canvasPixels, meanAbsDiff, pkg } from './lib.mjs';
import { TARGETS, pageTests, assertFace, pause, setSlider } from './page-lib.mjs';

const { open } = pageTests();

test('moving a slider pauses the track and changes the targets; so does the method', async (t) => {
  const { page, errors, frames } = await open(t);
  await frames(2);
  await setSlider(page, 'p-shape-0', 0);
  await frames(2);
  assert.equal(await page.getAttribute('#play', 'data-state'), 'paused', 'the slider paused playback');
  assert.equal(await page.$eval('#source-kind', (s) => s.value), 'sliders');
  const before = await canvasPixels(page, `${TARGETS} >> nth=0`);
  await setSlider(page, 'p-shape-0', 2.5);
  await frames(2);
  const moved = await canvasPixels(page, `${TARGETS} >> nth=0`);
  assert.ok(meanAbsDiff(before, moved) > 0.5, `target did not change with the slider (${meanAbsDiff(before, moved)})`);
  // The source follows the sliders too.
  assert.match(await page.$eval('#p-shape-0 + output', (o) => o.value), /^\+2\.50σ$/);

  // Method: substitute differs from the default (expressive) for the same expression.
  await page.click('label:has(input[value="substitute"])');
  await frames(2);
  const substituted = await canvasPixels(page, `${TARGETS} >> nth=0`);
  assert.ok(meanAbsDiff(moved, substituted) > 0.2, `method change did not change the target (${meanAbsDiff(moved, substituted)})`);
  await page.click('label:has(input[value="map"])');
  await frames(2);
  const mapped = await canvasPixels(page, `${TARGETS} >> nth=0`);
  assert.ok(meanAbsDiff(mapped, substituted) > 0.2, 'map and substitute look the same');
  await screenshot(page, 'page-slider-substitute-vs-map');

  // Gain 0 gives the target's reference face: different again.
  await setSlider(page, 'gain', 0);
  await frames(2);
  const zero = await canvasPixels(page, `${TARGETS} >> nth=0`);
  assert.ok(meanAbsDiff(zero, mapped) > 0.2, 'gain 0 did not change the target');
  assert.equal(await page.$eval('#gain-out', (o) => o.value), '0.00');

  // Reset restores the defaults: the method is the core's default (methods()' isDefault).
  await page.click('#reset');
  await frames(1);
  assert.equal(await page.$eval('input[name=method]:checked', (r) => r.value), pkg().methods().find((m) => m.isDefault).name);
  assert.equal(await page.$eval('#gain', (r) => r.value), '1');
  assert.equal(await page.$eval('#p-shape-0', (r) => r.value), '0');
  assert.deepEqual(errors, []);
});

test('the compare view shows every method on one target, each a different face', async (t) => {
  const { page, errors, frames } = await open(t);
  await page.check('#compare-on');
  await page.selectOption('#compare-target', '1');
  await frames(3);
  await pause(page);
  // An expressive frame: mouth mode pushed so the methods visibly differ.
  await setSlider(page, 'p-shape-0', 2.5);
  await setSlider(page, 'p-shape-1', -2);
  await frames(2);
  const names = pkg().methods().map((m) => m.name);
  assert.deepEqual(names, ['substitute', 'map', 'map-residual', 'expressive']);
  const ids = await page.$$eval('#compare-grid canvas', (cs) => cs.map((c) => c.id));
  assert.deepEqual(ids, names.map((n) => `cmp-${n}`), 'one compare canvas per method, in the list\'s order');
  const px = [];
  for (const id of ids) {
    await assertFace(page, `#${id}`, id);
    px.push(await canvasPixels(page, `#${id}`));
  }
  assert.ok(meanAbsDiff(px[0], px[1]) > 0.2, 'substitute = map');
  assert.ok(meanAbsDiff(px[0], px[2]) > 0.2, 'substitute = map-residual');
  assert.ok(meanAbsDiff(px[2], px[3]) > 0.2, 'map-residual = expressive');
  assert.ok(meanAbsDiff(px[0], px[3]) > 0.2, 'substitute = expressive');
  const name = await page.textContent('#compare-name');
  assert.equal(name, await page.textContent('.face-card.target >> nth=1 >> .name'));
  await page.locator('#compare').scrollIntoViewIfNeeded();
  await screenshot(page, 'page-compare');
  assert.deepEqual(errors, []);
});

test("the method control is the package's methods(), expressive by default; its region gains and style change the faces", async (t) => {
  const list = pkg().methods();
  const def = list.find((m) => m.isDefault);
  assert.equal(list.length, 4);
  assert.equal(def?.name, 'expressive', 'the core default');
  const { page, errors, frames } = await open(t);
  await frames(2);
  const radios = await page.$$eval('input[name=method]', (rs) =>
    rs.map((r) => ({ name: r.value, checked: r.checked, label: r.nextElementSibling.textContent, title: r.parentElement.title })),
  );
  assert.deepEqual(radios.map((r) => r.name), list.map((m) => m.name));
  assert.deepEqual(radios.map((r) => r.label), list.map((m) => m.label));
  assert.deepEqual(radios.map((r) => r.title), list.map((m) => m.description), 'the descriptions as tooltips');
  assert.deepEqual(radios.filter((r) => r.checked).map((r) => r.name), ['expressive']);
  assert.match(await page.textContent('#method-note'), new RegExp(def.label));
  // The expressive settings show with the expressive method only.
  assert.ok(await page.isVisible('#expressive-settings'));
  await page.click('label:has(input[value="map"])');
  assert.ok(!(await page.isVisible('#expressive-settings')), 'expressive settings shown for map');
  await page.click('label:has(input[value="expressive"])');
  assert.ok(await page.isVisible('#expressive-settings'));
  for (const id of ['gain-mouth', 'gain-eyes', 'gain-brows']) {
    assert.deepEqual(await page.$eval(`#${id}`, (r) => [r.min, r.max, r.step, r.value]), ['0', '3', '0.05', '1'], id);
  }
  assert.deepEqual(await page.$eval('#style', (r) => [r.min, r.max, r.value]), ['0', '1', '1']);

  // An open mouth (paused), the compare view on target 1: the mouth's gain changes the stage's
  // target and the compare view's expressive column (the same cloner options), and not the
  // other columns.
  await page.check('#compare-on');
  await page.selectOption('#compare-target', '0');
  await setSlider(page, 'p-shape-0', 2.5);
  await setSlider(page, 'p-shape-1', -2);
  await frames(2);
  const stage = () => canvasPixels(page, `${TARGETS} >> nth=0`);
  const cmp = (m) => canvasPixels(page, `#cmp-${m}`);
  const [t1, e1, m1] = [await stage(), await cmp('expressive'), await cmp('map')];
  await setSlider(page, 'gain-mouth', 3);
  await frames(2);
  assert.equal(await page.$eval('#gain-mouth-out', (o) => o.value), '3.00');
  const [t3, e3, m3] = [await stage(), await cmp('expressive'), await cmp('map')];
  const dStage = meanAbsDiff(t1, t3);
  const dCmp = meanAbsDiff(e1, e3);
  console.log(`# mouth gain 1 -> 3: stage target ${dStage.toFixed(3)}, compare (expressive) ${dCmp.toFixed(3)}, compare (map) ${meanAbsDiff(m1, m3).toFixed(3)} levels`);
  assert.ok(dStage > 0.2, `the mouth's gain did not change the target (${dStage})`);
  assert.ok(dCmp > 0.2, `the mouth's gain did not change the compare view's expressive face (${dCmp})`);
  assert.ok(meanAbsDiff(m1, m3) < 0.01, 'the mouth gain changed the map column');
  await setSlider(page, 'gain-mouth', 0);
  await frames(2);
  assert.ok(meanAbsDiff(t1, await stage()) > 0.2, 'mouth gain 0 looks as 1');
  // Style 0 (the target's own range) differs from 1 (the source's full motion).
  await setSlider(page, 'gain-mouth', 1);
  await setSlider(page, 'style', 0);
  await frames(2);
  assert.ok(meanAbsDiff(t1, await stage()) > 0.2, 'style 0 looks as style 1');
  await screenshot(page, 'page-expressive-settings', { fullPage: false });
  // Reset: the region gains and the style back to 1.
  await page.click('#reset');
  await frames(1);
  for (const id of ['gain-mouth', 'gain-eyes', 'gain-brows', 'style']) assert.equal(await page.$eval(`#${id}`, (r) => r.value), '1', id);
  assert.equal(await page.$eval('input[name=method]:checked', (r) => r.value), 'expressive');
  assert.deepEqual(errors, []);
});

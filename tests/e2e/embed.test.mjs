// End-to-end test of the npm package: `npm pack` in pkg/, install the tarball into a fresh
// folder (offline: the package has no dependencies), serve examples/embed/ with that installed
// package and two default models on 127.0.0.1, and check in headless Chromium that the target
// canvas shows a face that changes when the source's parameters change. Also imports the
// installed package in Node and loads a model with it.
//   node --test tests/e2e/embed.test.mjs      (after scripts/build-wasm.sh and scripts/build-models.sh)
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { pathToFileURL } from 'node:url';
import {
  ROOT, serveStatic, launchBrowser, haveChromium, screenshot, canvasStats, canvasPixels, meanAbsDiff,
} from './lib.mjs';

const PKG = path.join(ROOT, 'pkg');
const MODELS = path.join(ROOT, 'www', 'models');
const SOURCE = 'spk07.fmm';
const TARGET = 'spk02.fmm';

function packAndInstall() {
  for (const [file, how] of [
    [path.join(PKG, 'package.json'), 'scripts/build-wasm.sh'],
    [path.join(PKG, 'facemimic_bg.wasm'), 'scripts/build-wasm.sh'],
    [path.join(MODELS, SOURCE), 'scripts/build-models.sh'],
    [path.join(MODELS, TARGET), 'scripts/build-models.sh'],
  ]) {
    assert.ok(fs.existsSync(file), `${path.relative(ROOT, file)} is missing: run ${how}`);
  }
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'facemimic-embed-'));
  const packed = JSON.parse(
    execFileSync('npm', ['pack', '--json', '--pack-destination', tmp], { cwd: PKG, encoding: 'utf8' }),
  );
  const tgz = path.join(tmp, packed[0].filename);
  const files = packed[0].files.map((f) => f.path).sort();
  const site = path.join(tmp, 'site');
  fs.mkdirSync(path.join(site, 'models'), { recursive: true });
  fs.writeFileSync(path.join(site, 'package.json'), '{ "private": true, "type": "module" }\n');
  execFileSync('npm', ['install', '--offline', '--no-audit', '--no-fund', '--loglevel=error', tgz], {
    cwd: site,
    encoding: 'utf8',
  });
  for (const f of ['index.html', 'main.js']) {
    fs.copyFileSync(path.join(ROOT, 'examples', 'embed', f), path.join(site, f));
  }
  for (const f of [SOURCE, TARGET]) fs.copyFileSync(path.join(MODELS, f), path.join(site, 'models', f));
  return { tmp, site, tgz, files };
}

test('the packed npm package installs, and the embed example drives a target from a source', async (t) => {
  if (!haveChromium()) {
    t.skip('chromium not installed (scripts/setup.sh --browser)');
    return;
  }
  const { tmp, site, files } = packAndInstall();
  try {
    // The tarball holds what an npm user needs, and nothing from the build tree.
    for (const f of ['package.json', 'facemimic.js', 'facemimic.d.ts', 'facemimic_bg.wasm', 'README.md',
      'LICENSE-MIT', 'LICENSE-APACHE', 'LICENSE-mediapipe']) {
      assert.ok(files.includes(f), `tarball lacks ${f} (has ${files.join(', ')})`);
    }
    const installed = path.join(site, 'node_modules', 'facemimic');
    const manifest = JSON.parse(fs.readFileSync(path.join(installed, 'package.json'), 'utf8'));
    assert.equal(manifest.name, 'facemimic');
    assert.equal(manifest.type, 'module');
    assert.equal(manifest.exports['.'].types, './facemimic.d.ts');
    // The entry's declarations re-export the generated ones (facemimic_wasm.d.ts).
    const dts = ['facemimic.d.ts', 'facemimic_wasm.d.ts']
      .map((f) => fs.readFileSync(path.join(installed, f), 'utf8')).join('\n');
    for (const name of ['class Model', 'class Cloner', 'function renderMode', 'interface ModelInfo', 'type Method',
      'class FacemimicError', 'function loadModel', 'type FrameSource']) {
      assert.ok(dts.includes(name), `the declarations lack ${name}`);
    }

    // The installed package works in Node too: resolve it by name, load a model, clone a frame.
    const script = `
      import fs from 'node:fs';
      import init, { Model, Cloner, version } from 'facemimic';
      await init({ module_or_path: fs.readFileSync('node_modules/facemimic/facemimic_bg.wasm') });
      const s = Model.fromBytes(fs.readFileSync('models/${SOURCE}'));
      const c = new Cloner(s);
      c.addTarget(Model.fromBytes(fs.readFileSync('models/${TARGET}')));
      c.update();
      let bad = '';
      try { Model.fromBytes(new Uint8Array([1, 2, 3])); } catch (e) { bad = e.message; }
      console.log(JSON.stringify({ version: version(), name: s.name, targets: c.targetCount,
        landmarks: c.targetLandmarks(0).length, bad }));`;
    fs.writeFileSync(path.join(site, 'node-check.mjs'), script);
    const out = JSON.parse(execFileSync(process.execPath, ['node-check.mjs'], { cwd: site, encoding: 'utf8' }));
    assert.equal(out.name, 'spk07');
    assert.equal(out.targets, 1);
    assert.equal(out.landmarks, 136);
    assert.match(out.bad, /^model file: /);

    // The page, served from the folder the tarball was installed into.
    const server = await serveStatic(site);
    const browser = await launchBrowser();
    try {
      const page = await browser.newPage({ viewport: { width: 900, height: 700 } });
      const errors = [];
      page.on('pageerror', (e) => errors.push(e.message));
      page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
      await page.goto(server.url);
      await page.waitForSelector('#status[data-state]', { timeout: 30000 });
      const state = await page.getAttribute('#status', 'data-state');
      const text = await page.textContent('#status');
      assert.equal(state, 'ready', `page status: ${text}`);
      assert.match(text, /spk07 drives spk02/);

      for (const id of ['#source', '#target']) {
        const s = await canvasStats(page, id);
        assert.ok(s.width > 0 && s.height > 0, `${id} has no size`);
        assert.ok(s.variance > 150 && s.distinct > 300, `${id} shows no face: ${JSON.stringify(s)}`);
      }
      // The corner is background, the centre face.
      const corner = await page.$eval('#target', (c) => Array.from(c.getContext('2d').getImageData(0, 0, 1, 1).data));
      assert.deepEqual(corner, [0x20, 0x20, 0x24, 255]);
      await screenshot(page, 'embed-rest');

      // Moving the source's first shape mode changes the target.
      const before = await canvasPixels(page, '#target');
      await page.fill('#mode', '2.5');
      await page.waitForFunction(() => document.getElementById('mode-value').textContent === '2.5');
      const after = await canvasPixels(page, '#target');
      const d = meanAbsDiff(before, after);
      assert.ok(d > 0.5, `target barely changed when the source moved (mean abs diff ${d.toFixed(3)})`);
      const s = await canvasStats(page, '#target');
      assert.ok(s.variance > 150, `target after the change shows no face: ${JSON.stringify(s)}`);
      await screenshot(page, 'embed-moved');

      // Animation keeps drawing.
      await page.check('#animate');
      const a0 = await canvasPixels(page, '#target');
      await page.waitForTimeout(400);
      const a1 = await canvasPixels(page, '#target');
      assert.ok(meanAbsDiff(a0, a1) > 0.1, 'animation does not change the target');
      assert.deepEqual(errors, [], `page errors: ${errors.join('; ')}`);
    } finally {
      await browser.close();
      await server.close();
    }
  } finally {
    fs.rmSync(tmp, { recursive: true, force: true });
  }
});

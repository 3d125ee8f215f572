// The npm packages as a user gets them: `npm pack` of pkg/ (facemimic) and pkg-faces/
// (facemimic-faces), installed from the tarballs into a fresh folder (offline: they have no
// dependencies), and the npm README's quick starts run as written:
//  - in Node (init() reading the wasm from disk, faces read from disk, raw RGBA out);
//  - in a Vite app, on Vite's dev server (with the README's vite.config.js) and from `vite build`,
//    in headless Chromium;
//  - the declarations type-check a user's calls under tsc (strict, lib ES2022 + DOM, no
//    skipLibCheck) and reject wrong ones;
//  - frames from ImageData, ImageBitmap, a canvas, an OffscreenCanvas, a VideoFrame, a video
//    element and raw RGBA give the same pixels; a module worker initialises; bad input (a 404, an
//    HTML answer, another file type, a detached buffer, a video with no frame, a freed object,
//    NaN) throws the documented codes.
//   node --test tests/e2e/npm.test.mjs   (after scripts/build-wasm.sh and scripts/build-faces.sh)
import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFile, execFileSync, spawn } from 'node:child_process';
import { promisify } from 'node:util';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import net from 'node:net';
import { ROOT, serveStatic, launchBrowser, haveChromium, screenshot, canvasStats, canvasPixels, meanAbsDiff } from './lib.mjs';

const MAX_TARBALL = 6e6;
const VITE = path.join(ROOT, 'node_modules', 'vite', 'bin', 'vite.js');
const TSC = path.join(ROOT, 'node_modules', 'typescript', 'bin', 'tsc');
const FIXTURES = path.join(ROOT, 'tests', 'e2e', 'npm-app');
let tmp;
let app;
const packed = {};

/** The README's fenced block: the first ```lang block whose text matches `match`. */
function readmeBlock(lang, match) {
  const readme = fs.readFileSync(path.join(ROOT, 'npm', 'README.md'), 'utf8');
  const re = new RegExp('```' + lang + '\\n([\\s\\S]*?)```', 'g');
  for (const m of readme.matchAll(re)) if (match.test(m[1])) return m[1];
  throw new Error(`npm/README.md has no ${lang} block matching ${match}`);
}

function run(cmd, args, cwd) {
  return execFileSync(cmd, args, { cwd, encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
}

before(() => {
  for (const [file, how] of [['pkg/facemimic_bg.wasm', 'scripts/build-wasm.sh'], ['pkg-faces/spk07.fmm', 'scripts/build-faces.sh']]) {
    assert.ok(fs.existsSync(path.join(ROOT, file)), `${file} is missing: run ${how}`);
  }
  tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'facemimic-npm-'));
  for (const dir of ['pkg', 'pkg-faces']) {
    const [info] = JSON.parse(run('npm', ['pack', '--json', '--pack-destination', tmp], path.join(ROOT, dir)));
    packed[info.name] = { file: path.join(tmp, info.filename), size: info.size, unpacked: info.unpackedSize, files: info.files.map((f) => f.path) };
  }
  app = path.join(tmp, 'app');
  fs.mkdirSync(app);
  fs.writeFileSync(path.join(app, 'package.json'), '{ "private": true, "type": "module" }\n');
  run('npm', ['install', '--offline', '--no-audit', '--no-fund', '--loglevel=error',
    packed.facemimic.file, packed['facemimic-faces'].file], app);
});

after(() => {
  if (tmp) fs.rmSync(tmp, { recursive: true, force: true });
});

test('the tarballs hold what a user needs, each within 6 MB', () => {
  const main = packed.facemimic;
  for (const f of ['package.json', 'facemimic.js', 'facemimic.d.ts', 'facemimic_wasm.js', 'facemimic_wasm.d.ts',
    'facemimic_bg.wasm', 'README.md', 'LICENSE-MIT', 'LICENSE-APACHE', 'LICENSE-mediapipe']) {
    assert.ok(main.files.includes(f), `facemimic lacks ${f}`);
  }
  const faces = packed['facemimic-faces'];
  for (const f of ['package.json', 'index.js', 'index.d.ts', 'README.md', 'NOTICE-GRID.md', 'spk07-track.json',
    'spk07.fmm', 'spk02.fmm', 'spk03.fmm', 'spk06.fmm', 'spk10.fmm']) {
    assert.ok(faces.files.includes(f), `facemimic-faces lacks ${f}`);
  }
  for (const [name, p] of Object.entries(packed)) {
    console.log(`# ${name}: tarball ${(p.size / 1e6).toFixed(3)} MB, unpacked ${(p.unpacked / 1e6).toFixed(3)} MB, ${p.files.length} files`);
    assert.ok(p.size <= MAX_TARBALL, `${name} tarball is ${p.size} bytes`);
  }
  const manifest = JSON.parse(fs.readFileSync(path.join(app, 'node_modules', 'facemimic', 'package.json'), 'utf8'));
  for (const key of ['name', 'version', 'description', 'license', 'repository', 'homepage', 'keywords', 'files', 'exports', 'types']) {
    assert.ok(manifest[key], `package.json lacks ${key}`);
  }
  assert.equal(manifest.exports['.'].types, './facemimic.d.ts');
  assert.doesNotMatch(fs.readFileSync(path.join(app, 'node_modules', 'facemimic', 'facemimic_wasm.d.ts'), 'utf8'), /Symbol\.dispose/);
});

test("the README's Node quick start runs as written, from the tarballs", () => {
  fs.writeFileSync(path.join(app, 'node-quick-start.mjs'), readmeBlock('js', /^\/\/ quick start: Node/));
  const out = run(process.execPath, ['node-quick-start.mjs'], app);
  assert.match(out, /target\.ppm: spk07 drives spk02/);
  const ppm = fs.readFileSync(path.join(app, 'target.ppm'));
  const header = 'P6 360 288 255\n';
  assert.equal(ppm.subarray(0, header.length).toString(), header);
  const rgb = ppm.subarray(header.length);
  assert.equal(rgb.length, 360 * 288 * 3);
  let sum = 0;
  let sq = 0;
  for (const v of rgb) { sum += v; sq += v * v; }
  const mean = sum / rgb.length;
  const variance = sq / rgb.length - mean * mean;
  assert.ok(variance > 300, `the rendered picture is flat (variance ${variance.toFixed(1)})`);
});

test('in Node, bad input throws the documented codes', async () => {
  const site = path.join(tmp, 'site');
  fs.mkdirSync(site, { recursive: true });
  fs.writeFileSync(path.join(site, 'index.html'), '<!doctype html><title>a page</title>');
  fs.writeFileSync(path.join(site, 'page.fmm'), '<!doctype html><title>a page served for a model</title>');
  const server = await serveStatic(site);
  try {
    const script = `
      import init, { Model, Cloner, loadModel, initialised, FacemimicError } from 'facemimic';
      import { source, faces } from 'facemimic-faces';
      const code = async (f) => { try { await f(); return 'none'; } catch (e) { return (e instanceof FacemimicError) ? e.code : 'plain ' + e; } };
      const out = {};
      out.beforeInit = await code(() => new Cloner());
      out.initialisedBefore = initialised();
      await init();
      out.initialisedAfter = initialised();
      out.secondInit = await code(() => init());
      const m = await loadModel(source);
      out.notFound = await code(() => loadModel('${server.url}missing.fmm'));
      out.html = await code(() => loadModel('${server.url}'));
      out.htmlBody = await code(() => loadModel('${server.url}page.fmm'));
      out.otherType = await code(() => loadModel(new TextEncoder().encode('PK\\u0003\\u0004 a zip file').buffer));
      const gone = new ArrayBuffer(32); const view = new Uint8Array(gone, 8); structuredClone(gone, { transfer: [gone] });
      out.detached = await code(() => loadModel(gone));
      out.detachedView = await code(() => loadModel(view));
      out.noFile = await code(() => loadModel('no/such/face.fmm'));
      const t = await Model.load(faces.spk03);
      const c = new Cloner(m);
      out.nan = await code(() => c.setSourceParams({ ...m.baseParams(), shape: [NaN] }));
      out.badFrame = await code(() => Model.fromPhoto('x', { data: new Uint8Array(12), width: 2, height: 2 }, new Float32Array(136)));
      out.nodeCanvas = await code(() => c.renderTargetImageData(0, 8, 8));
      t.free();
      out.freed = await code(() => t.info());
      out.freedArg = await code(() => c.addTarget(t));
      console.log(JSON.stringify(out));`;
    fs.writeFileSync(path.join(app, 'node-bad.mjs'), script);
    // Asynchronously: the server answering the child runs in this process.
    const { stdout } = await promisify(execFile)(process.execPath, ['node-bad.mjs'], { cwd: app });
    const out = JSON.parse(stdout);
    assert.deepEqual(out, {
      beforeInit: 'not-initialised', initialisedBefore: false, initialisedAfter: true, secondInit: 'none',
      notFound: 'fetch-failed', html: 'bad-model', htmlBody: 'bad-model', otherType: 'bad-model',
      detached: 'detached-buffer', detachedView: 'detached-buffer', noFile: 'fetch-failed', nan: 'bad-params',
      badFrame: 'bad-frame', nodeCanvas: 'bad-argument', freed: 'freed', freedArg: 'freed',
    });
  } finally {
    await server.close();
  }
});

test('the declarations type-check a user\'s calls (tsc strict, lib ES2022 + DOM, no skipLibCheck)', () => {
  for (const f of ['check.ts', 'tsconfig.json']) fs.copyFileSync(path.join(FIXTURES, f), path.join(app, f));
  try {
    run(process.execPath, [TSC, '-p', 'tsconfig.json'], app);
  } catch (e) {
    assert.fail(`tsc failed:\n${e.stdout}${e.stderr}`);
  }
});

async function freePort() {
  return new Promise((resolve) => {
    const s = net.createServer();
    s.listen(0, '127.0.0.1', () => { const { port } = s.address(); s.close(() => resolve(port)); });
  });
}

/** Vite's dev server in `dir`, resolved once it prints its URL. Colour is off, and escape codes are
 * stripped anyway (a CI terminal may force colour, which splits the port with escapes); the
 * server is killed if it does not start, so no child outlives the test. */
async function viteDev(dir) {
  const port = await freePort();
  const env = { ...process.env, NO_COLOR: '1', FORCE_COLOR: '0' };
  const child = spawn(process.execPath, [VITE, '--host', '127.0.0.1', '--port', String(port), '--strictPort'],
    { cwd: dir, env, stdio: ['ignore', 'pipe', 'pipe'] });
  let log = '';
  const plain = () => log.replace(/\x1b\[[0-9;]*[A-Za-z]/g, '');
  try {
    await new Promise((resolve, reject) => {
      const timer = setTimeout(() => reject(new Error(`vite did not start:\n${plain()}`)), 60000);
      const on = (d) => { log += d; if (plain().includes(`127.0.0.1:${port}`)) { clearTimeout(timer); resolve(); } };
      child.stdout.on('data', on);
      child.stderr.on('data', on);
      child.on('exit', (c) => { clearTimeout(timer); reject(new Error(`vite exited ${c}:\n${plain()}`)); });
    });
  } catch (e) {
    child.kill();
    throw e;
  }
  return { url: `http://127.0.0.1:${port}/`, close: () => child.kill(), log: plain };
}

/** The quick start's page: both canvases show faces, and the target moves. */
async function checkQuickStart(browser, url, name) {
  const page = await browser.newPage({ viewport: { width: 800, height: 400 } });
  const errors = [];
  page.on('pageerror', (e) => errors.push(e.message));
  // Every failed request is named (a browser asks for /favicon.ico, which the app has not).
  page.on('response', (r) => r.status() >= 400 && !r.url().endsWith('/favicon.ico') && errors.push(`${r.status()} ${r.url()}`));
  await page.goto(url);
  await page.waitForFunction(() => {
    const c = document.querySelector('#target');
    const d = c.getContext('2d').getImageData(c.width / 2, c.height / 2, 1, 1).data;
    return d[3] > 0 && (d[0] + d[1] + d[2]) > 0;
  }, null, { timeout: 60000 }).catch(() => {});
  for (const id of ['#source', '#target']) {
    const s = await canvasStats(page, id);
    assert.ok(s.variance > 150 && s.distinct > 300, `${name}: ${id} shows no face: ${JSON.stringify(s)}; errors: ${errors.join('; ')}`);
  }
  const a = await canvasPixels(page, '#target');
  await page.waitForTimeout(500);
  const b = await canvasPixels(page, '#target');
  assert.ok(meanAbsDiff(a, b) > 0.1, `${name}: the target does not move`);
  await screenshot(page, `npm-${name}`);
  assert.deepEqual(errors, [], `${name}: page errors`);
  await page.close();
}

test("the README's page quick start runs in a Vite app (dev server and build); frames, worker and errors in the browser", async (t) => {
  if (!haveChromium()) {
    t.skip('chromium not installed (scripts/setup.sh --browser)');
    return;
  }
  const html = readmeBlock('html', /<canvas id="target"/);
  fs.writeFileSync(path.join(app, 'index.html'), `<!doctype html>\n<meta charset="utf-8">\n${html}`);
  fs.writeFileSync(path.join(app, 'main.js'), readmeBlock('js', /^\/\/ quick start: browser/));
  fs.writeFileSync(path.join(app, 'vite.config.js'), readmeBlock('js', /optimizeDeps/));
  for (const f of ['frames.html', 'frames.js', 'worker.js']) fs.copyFileSync(path.join(FIXTURES, f), path.join(app, f));

  const browser = await launchBrowser();
  try {
    const dev = await viteDev(app);
    try {
      await checkQuickStart(browser, dev.url, 'vite-dev');
      const page = await browser.newPage();
      const errors = [];
      page.on('pageerror', (e) => errors.push(e.message));
      await page.goto(`${dev.url}frames.html`);
      await page.waitForFunction(() => window.result, null, { timeout: 90000 });
      const r = await page.evaluate(() => window.result);
      assert.equal(r.error, undefined, `frames page: ${r.error}`);
      assert.equal(r.beforeInit, 'not-initialised');
      for (const [kind, same] of Object.entries(r.same)) assert.ok(same, `${kind}: toFrame's pixels differ from the ImageData's`);
      for (const [kind, n] of Object.entries(r.faces)) assert.equal(n, r.rawCall, `${kind}: ${n} faces, raw RGBA ${r.rawCall}`);
      assert.ok(r.rawCall >= 1, 'no face found in the rendered target');
      assert.equal(r.videoFrame, 360);
      assert.ok(r.tracked, 'tracking a playing video element failed');
      assert.equal(r.idleVideo, 'frame-unavailable');
      assert.equal(r.idleTrack, 'frame-unavailable');
      assert.equal(r.notAFrame, 'bad-frame');
      assert.equal(r.wrongSize, 'bad-frame');
      assert.ok(['fetch-failed', 'bad-model'].includes(r.missing), `missing model: ${r.missing}`);
      assert.equal(r.html, 'bad-model');
      assert.equal(r.otherType, 'bad-model');
      assert.equal(r.detached, 'detached-buffer');
      assert.equal(r.freed, 'freed');
      assert.equal(r.freedArg, 'freed');
      assert.equal(r.nan, 'bad-params');
      assert.ok(r.worker.ok, `worker: ${JSON.stringify(r.worker)}`);
      assert.equal(r.worker.bytes, 64 * 48 * 4);
      assert.deepEqual(errors, []);
      await page.close();
    } finally {
      dev.close();
    }

    run(process.execPath, [VITE, 'build', '--logLevel', 'warn'], app);
    const server = await serveStatic(path.join(app, 'dist'));
    try {
      await checkQuickStart(browser, server.url, 'vite-build');
    } finally {
      await server.close();
    }
  } finally {
    await browser.close();
  }
});

// The npm package's builder against the native one: `buildModel` (wasm, in Node) and
// `facemimic build` (native CLI) build from the same RGBA frames and the same landmarks and
// must give the same model within float tolerance (every header field exact, every float within
// 1e-3 relative). Also: selection, progress, cancelling, and bad input throwing clear Errors
// without breaking the module.
//   node --test tests/e2e/build.test.mjs   (after scripts/build-wasm.sh and scripts/build-models.sh,
//   which builds target/release/facemimic)
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import { pathToFileURL } from 'node:url';
import { ROOT, readPts } from './lib.mjs';

const PKG = path.join(ROOT, 'pkg');
const CLI = path.join(process.env.CARGO_TARGET_DIR || path.join(ROOT, 'target'), 'release', 'facemimic');
const CLIP = path.join(ROOT, 'data', 'grid', 'spk02_brbk7n');

async function loadPackage() {
  for (const [file, how] of [
    [path.join(PKG, 'facemimic.js'), 'scripts/build-wasm.sh'],
    [CLI, 'cargo build --release (scripts/build-models.sh does)'],
  ]) {
    assert.ok(fs.existsSync(file), `${path.relative(ROOT, file)} is missing: run ${how}`);
  }
  const fm = await import(pathToFileURL(path.join(PKG, 'facemimic.js')).href);
  fm.initSync({ module: fs.readFileSync(path.join(PKG, 'facemimic_bg.wasm')) });
  return fm;
}

// --- PNG writing (RGBA8, no filter) ------------------------------------------------------
const CRC_TABLE = Array.from({ length: 256 }, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});
function crc32(buf) {
  let c = 0xffffffff;
  for (const b of buf) c = CRC_TABLE[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}
function chunk(type, data) {
  const head = Buffer.alloc(8);
  head.writeUInt32BE(data.length, 0);
  head.write(type, 4, 'ascii');
  const crc = Buffer.alloc(4);
  crc.writeUInt32BE(crc32(Buffer.concat([head.subarray(4), data])), 0);
  return Buffer.concat([head, data, crc]);
}
function png(rgba, width, height) {
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr.set([8, 6, 0, 0, 0], 8);
  const raw = Buffer.alloc((width * 4 + 1) * height);
  for (let y = 0; y < height; y++) {
    raw.set(rgba.subarray(y * width * 4, (y + 1) * width * 4), y * (width * 4 + 1) + 1);
  }
  return Buffer.concat([
    Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]),
    chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(raw)),
    chunk('IEND', Buffer.alloc(0)),
  ]);
}

/** Deterministic textured frames (360x288) with GRID spk02's real landmarks: the builder needs
 *  no real face to be compared, only identical inputs on both sides. */
function makeFrames(count) {
  const stems = fs.readdirSync(CLIP).filter((f) => f.endsWith('.pts')).sort().slice(0, count);
  const [W, H] = [360, 288];
  let seed = 0x9e3779b9;
  const rand = () => {
    seed ^= seed << 13; seed >>>= 0;
    seed ^= seed >>> 17;
    seed ^= seed << 5; seed >>>= 0;
    return seed / 4294967296;
  };
  return stems.map((pts, i) => {
    const rgba = new Uint8Array(W * H * 4);
    for (let y = 0; y < H; y++) {
      for (let x = 0; x < W; x++) {
        const k = (y * W + x) * 4;
        rgba[k] = 128 + 90 * Math.sin(x / 9 + i) * Math.cos(y / 13);
        rgba[k + 1] = 100 + 80 * Math.sin((x + y) / 17 - i / 3);
        rgba[k + 2] = Math.floor(60 + 120 * rand());
        rgba[k + 3] = 255;
      }
    }
    return { name: pts.replace('.pts', ''), rgba, width: W, height: H, landmarks: Float32Array.from(readPts(path.join(CLIP, pts))) };
  });
}

/** Compares two .fmm files: header integers and names exact, floats within `tol` relative. */
function compareModels(a, b, tol = 1e-3) {
  assert.equal(a.length, b.length, 'file lengths differ');
  const dv = (x) => new DataView(x.buffer, x.byteOffset, x.byteLength);
  const [da, db] = [dv(a), dv(b)];
  for (const off of [0, 4, 8, 12, 16, 20, 24, 28, 32, 36, 40, 44, 48, 52, 56, 60, 64, 68, 72, 76, 96, 100, 104, 108]) {
    assert.equal(da.getUint32(off, true), db.getUint32(off, true), `header word at ${off} differs`);
  }
  const close = (x, y) => Math.abs(x - y) <= tol * Math.max(1, Math.abs(x), Math.abs(y));
  for (let off = 80; off < 96; off += 4) {
    assert.ok(close(da.getFloat32(off, true), db.getFloat32(off, true)), `pose at ${off}`);
  }
  const names = da.getUint32(72, true) + da.getUint32(76, true);
  const start = 112 + names + ((4 - ((112 + names) % 4)) % 4);
  assert.ok(Buffer.from(a.subarray(112, 112 + names)).equals(Buffer.from(b.subarray(112, 112 + names))), 'names differ');
  let worst = 0;
  let differing = 0;
  for (let off = start; off < a.length - 4; off += 4) {
    if (da.getUint32(off, true) === db.getUint32(off, true)) continue;
    differing++;
    const [x, y] = [da.getFloat32(off, true), db.getFloat32(off, true)];
    assert.ok(Number.isFinite(x) && Number.isFinite(y), `non-finite value at ${off}`);
    worst = Math.max(worst, Math.abs(x - y) / Math.max(1, Math.abs(x), Math.abs(y)));
  }
  assert.ok(worst <= tol, `largest relative difference ${worst} (tolerance ${tol})`);
  // With the compact (quantised) appearance storage both sides write the same levels unless a
  // value sits on a rounding boundary: a handful of differing words at most.
  assert.ok(differing <= 16, `${differing} words differ`);
  return { values: (a.length - 4 - start) / 4, differing, worst };
}

test('buildModel in wasm gives the native builder\'s model', async () => {
  const fm = await loadPackage();
  const frames = makeFrames(12);
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'facemimic-build-'));
  try {
    for (const f of frames) {
      fs.writeFileSync(path.join(dir, `${f.name}.png`), png(f.rgba, f.width, f.height));
      fs.copyFileSync(path.join(CLIP, `${f.name}.pts`), path.join(dir, `${f.name}.pts`));
    }
    const nativeFile = path.join(dir, 'native.fmm');
    execFileSync(CLI, ['build', '--name', 'same', '--out', nativeFile, ...frames.map((f) => path.join(dir, `${f.name}.png`))], {
      stdio: ['ignore', 'ignore', 'pipe'],
    });
    const seen = [];
    const t0 = performance.now();
    const model = fm.buildModel(
      { frames: frames.map(({ rgba, width, height }) => ({ rgba, width, height })), landmarks: frames.map((f) => f.landmarks), name: 'same' },
      (p) => { seen.push(p.done); },
    );
    const ms = performance.now() - t0;
    const info = model.info();
    assert.equal(info.fingerprint, 'f33469e7338a4632', 'built in the canonical frame');
    assert.deepEqual(seen, Array.from({ length: frames.length + 2 }, (_, i) => i + 1), 'progress steps');
    const r = compareModels(fs.readFileSync(nativeFile), model.toBytes());
    console.log(`wasm vs native: ${r.values} values, ${r.differing} not bit-identical, largest relative difference ${r.worst.toExponential(2)}; wasm build of ${frames.length} frames ${ms.toFixed(0)} ms (Node)`);
    model.free();
  } finally {
    fs.rmSync(dir, { recursive: true, force: true });
  }
});

test('selection, cancelling and bad input', async () => {
  const fm = await loadPackage();
  const frames = makeFrames(10);
  const shapes = frames.map((f) => f.landmarks);
  const pick = fm.selectVaried(shapes, 4);
  assert.equal(pick.length, 4);
  assert.equal(new Set(pick).size, 4, 'distinct frames');
  const c4 = fm.shapeCoverage(shapes, pick);
  const c1 = fm.shapeCoverage(shapes, pick.slice(0, 1));
  assert.ok(c4 > c1 && c4 <= 1 && c1 >= 0, `coverage ${c1} -> ${c4}`);
  assert.equal(fm.shapeCoverage(shapes, Uint32Array.from(shapes.keys())), 1);

  const base = () => ({ frames: frames.map(({ rgba, width, height, landmarks }) => ({ rgba, width, height, landmarks })), name: 'x' });
  // select keeps that many frames
  const m = fm.buildModel({ ...base(), select: 5 });
  // 5 frames' deviations and their mirror images (symmetric shape modes) span at most 8 dimensions
  assert.ok(m.info().shapeModes <= 8, `${m.info().shapeModes} shape modes from 5 frames`);
  m.free();
  // cancelled half way
  assert.throws(() => fm.buildModel(base(), (p) => p.done < 4), (e) => e.code === "cancelled" && /^FacemimicError: cancelled$/.test(String(e)));
  // ... also while the finder searches frames given without landmarks; progress names the stage
  // and the frames skipped so far.
  const seen = [];
  assert.throws(() => fm.buildModel({ ...base(), frames: base().frames.map((f, i) => ({ ...f, landmarks: i < 5 ? f.landmarks : null })) }, (p) => {
    seen.push(`${p.stage} ${p.done}/${p.total} [${p.skipped}]`);
    return p.done < 2;
  }), (e) => e.code === "cancelled" && /^FacemimicError: cancelled$/.test(String(e)));
  assert.deepEqual(seen, ['landmarks 1/5 [5]', 'landmarks 2/5 [5,6]']);
  // bad input: clear messages, and the module keeps working afterwards
  const cases = [
    [{ ...base(), frames: [] }, /at least 2/],
    [{ ...base(), frames: base().frames.slice(0, 1) }, /at least 2/],
    // No landmarks: the face finder looks for faces; these textured frames have none.
    [{ ...base(), frames: base().frames.map((f) => ({ ...f, landmarks: undefined })) }, /a usable face in 0 of 10 frames, at least 2 are needed; no confident face in frames 0, 1, 2, 3/],
    [{ ...base(), frames: base().frames.map((f, i) => ({ ...f, landmarks: i < 3 ? f.landmarks : undefined })), minFrames: 8 }, /a usable face in 3 of 10 frames, at least 8 are needed; no confident face in frames 3, 4/],
    [{ ...base(), minScore: 2 }, /minScore/],
    [{ ...base(), minFrames: 1 }, /minFrames/],
    [{ ...base(), frames: base().frames.map((f, i) => (i === 3 ? { ...f, width: 100 } : f)) }, /frames\[3\]\.rgba has/],
    [{ ...base(), frames: base().frames.map((f, i) => (i === 2 ? { ...f, landmarks: f.landmarks.slice(0, 10) } : f)) }, /landmarks/],
    [{ ...base(), frames: base().frames.map((f, i) => (i === 2 ? { ...f, landmarks: f.landmarks.map(() => NaN) } : f)) }, /non-finite/],
    [{ ...base(), name: '' }, /name/],
    [{ ...base(), reference: 99 }, /reference/],
    [{ ...base(), select: 1 }, /select/],
    [{ ...base(), frames: 'nope' }, /frames/],
    [null, /options object/],
  ];
  for (const [opts, want] of cases) {
    assert.throws(() => fm.buildModel(opts), want);
  }
  assert.throws(() => fm.buildModel({ ...base(), refine: 7 }), /refine/);
  // One round of refinement: progress counts both builds and the fits.
  const steps = [];
  const refined = fm.buildModel({ ...base(), refine: 1 }, (p) => { steps.push(p.total); });
  assert.equal(steps[0], 2 * (frames.length + 2) + frames.length);
  assert.equal(steps.length, steps[0]);
  refined.free();
  assert.throws(() => fm.buildModel(base(), 42), /onProgress/);
  assert.throws(() => fm.buildModel(base(), () => { throw new Error('boom'); }), /onProgress threw: boom/);
  const ok = fm.buildModel({ ...base(), reference: 2 });
  assert.equal(ok.info().reference, 'frame2');
  ok.free();
  // "rest": the frame most at rest (mostAtRest) is the reference.
  const rest = fm.mostAtRest(shapes);
  assert.ok(Number.isInteger(rest) && rest >= 0 && rest < shapes.length, `mostAtRest ${rest}`);
  const atRest = fm.buildModel({ ...base(), reference: 'rest' });
  assert.equal(atRest.info().reference, `frame${rest}`);
  atRest.free();
  assert.throws(() => fm.buildModel({ ...base(), reference: 'smile' }), /reference/);
  assert.throws(() => fm.mostAtRest([]), /no faces/);
  assert.throws(() => fm.mostAtRest([shapes[0].slice(0, 10)]), /68/);
});

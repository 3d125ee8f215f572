// Tracking speed of the wasm package under Node on franck-dev2 (research data: never shipped).
//
//   cargo run --release --example fit_eval -- dump-franck2          # -> target/fit-bench/
//   cargo build --release --lib --target wasm32-unknown-unknown
//   wasm-bindgen --target nodejs --out-dir target/fit-bench/pkg \
//       target/wasm32-unknown-unknown/release/facemimic.wasm
//   node scripts/fit-bench-wasm.cjs [target/fit-bench]
//
// Times only the `track` loop (pre-decoded RGBA frames, results converted to JS objects
// included), three passes over the 300 frames from frame 3800's landmarks; wall and CPU time.
'use strict';
const fs = require('fs');
const path = require('path');

const dir = path.resolve(process.argv[2] || 'target/fit-bench');
// wasm-bindgen's nodejs output is CommonJS; inside this repository (`"type": "module"`) its
// folder needs its own package.json to say so.
const pkgJson = path.join(dir, 'pkg', 'package.json');
if (!fs.existsSync(pkgJson)) fs.writeFileSync(pkgJson, '{"type": "commonjs"}\n');
const { Tracker } = require(path.join(dir, 'pkg', 'facemimic.js'));
const [width, height] = fs.readFileSync(path.join(dir, 'size.txt'), 'utf8').trim().split(' ').map(Number);
const init = Float32Array.from(
  fs.readFileSync(path.join(dir, 'init.txt'), 'utf8').trim().split(/\s+/).map(Number));
const frames = [];
for (let i = 3800; i < 4100; i++) frames.push(new Uint8Array(fs.readFileSync(path.join(dir, `${i}.rgba`))));
const tracker = new Tracker(fs.readFileSync(path.join(dir, 'model.fmm')));
for (let run = 0; run < 3; run++) {
  tracker.startFromLandmarks(init);
  let iterations = 0;
  let lost = 0;
  const t0 = process.hrtime.bigint();
  const c0 = process.cpuUsage();
  for (const f of frames) {
    const r = tracker.track(f, width, height);
    iterations += r.iterations;
    if (r.lost) lost++;
  }
  const ms = Number(process.hrtime.bigint() - t0) / 1e6;
  const cpu = process.cpuUsage(c0);
  const cpuMs = (cpu.user + cpu.system) / 1e3;
  const n = frames.length;
  console.log(`franck-dev2 run ${run}: ${n} frames, ${(n / ms * 1e3).toFixed(1)} fits/s wall ` +
    `(${(ms / n).toFixed(3)} ms), ${(n / cpuMs * 1e3).toFixed(1)} fits/s CPU, ` +
    `mean ${(iterations / n).toFixed(2)} iterations, lost ${lost}`);
}

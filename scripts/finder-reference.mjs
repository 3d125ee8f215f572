#!/usr/bin/env node
// Writes the reference outputs the finder's layer tests compare against: the face-api.js nets,
// run by TensorFlow.js (CPU backend) on fixed inputs, from the same tfjs weight manifests that
// scripts/convert-weights.mjs converts.
//
// Usage: node scripts/finder-reference.mjs FACE_API_PACKAGE_DIR
//   FACE_API_PACKAGE_DIR: the untarred `npm pack @vladmandic/face-api@1.7.15` (its `package/`).
// Reads tests/data/finder/*.rgb (raw RGB8 net inputs cut from GRID frames, see
// tests/data/finder/README.md) and writes tests/data/finder/*.json.
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { createRequire } from 'node:module';

const pkg = process.argv[2];
if (!pkg) {
  console.error('usage: node scripts/finder-reference.mjs FACE_API_PACKAGE_DIR');
  process.exit(2);
}
// The node build of face-api, with @tensorflow/tfjs and @tensorflow/tfjs-backend-wasm 4.22.0
// installed in that package directory (`npm i --no-save @tensorflow/tfjs@4.22.0
// @tensorflow/tfjs-backend-wasm@4.22.0`); the CPU backend runs the nets.
const faceapi = createRequire(join(pkg, 'package.json'))('./dist/face-api.node-wasm.js');
const { tf } = faceapi;
await tf.setBackend('cpu');
await tf.ready();

function weightMap(name) {
  const manifest = JSON.parse(readFileSync(join(pkg, 'model', `${name}-weights_manifest.json`), 'utf8'));
  const specs = manifest.flatMap((g) => g.weights);
  const all = Buffer.concat(manifest.flatMap((g) => g.paths.map((p) => readFileSync(join(pkg, 'model', p)))));
  return tf.io.decodeWeights(all.buffer.slice(all.byteOffset, all.byteOffset + all.length), specs);
}

function rgb(file, size) {
  const bytes = readFileSync(join('tests/data/finder', file));
  if (bytes.length !== size * size * 3) throw new Error(`${file}: ${bytes.length} bytes`);
  return tf.tensor3d(Float32Array.from(bytes), [size, size, 3], 'float32');
}

const round = (a) => Array.from(a, (v) => Number(v.toPrecision(7)));
const save = async (file, out) => {
  writeFileSync(join('tests/data/finder', file), `${JSON.stringify({ shape: out.shape, data: round(await out.data()) })}\n`);
  console.log(file, out.shape);
};

const det = new faceapi.TinyFaceDetector();
det.loadFromWeightMap(weightMap('tiny_face_detector_model'));
await save('grid-detector-160.json', det.forwardInput(await faceapi.toNetInput(rgb('grid-detector-160.rgb', 160)), 160));

const lm = new faceapi.FaceLandmark68Net();
lm.loadFromWeightMap(weightMap('face_landmark_68_model'));
for (const name of ['grid-landmark-a-112', 'grid-landmark-b-112']) {
  await save(`${name}.json`, lm.runNet(await faceapi.toNetInput(rgb(`${name}.rgb`, 112))));
}

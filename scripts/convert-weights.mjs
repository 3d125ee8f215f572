#!/usr/bin/env node
// Converts the face-api.js tfjs weight manifests (tiny face detector, 68-point landmark net)
// into the small binary read by src/find/weights.rs (format described there and in
// data/weights/README.md).
//
// Usage: node scripts/convert-weights.mjs MODEL_DIR [OUT_DIR]
//   MODEL_DIR: the `model/` directory of the npm package @vladmandic/face-api@1.7.15
//              (`npm pack @vladmandic/face-api@1.7.15` in a scratch directory, then untar).
//   OUT_DIR:   defaults to data/weights.
//
// The tensors keep their uint8 quantisation (value = min + scale * q), so the files are as
// small as the originals; float32 tensors (none in 1.7.15) are stored as float32.
import { readFileSync, writeFileSync, mkdirSync } from 'node:fs';
import { join } from 'node:path';

const NETS = [
  ['tiny_face_detector_model', 'tiny_face_detector.fmw'],
  ['face_landmark_68_model', 'face_landmark_68.fmw'],
];

function convert(modelDir, name) {
  const manifest = JSON.parse(readFileSync(join(modelDir, `${name}-weights_manifest.json`), 'utf8'));
  const chunks = [];
  const push = (buf) => chunks.push(Buffer.from(buf));
  const u32 = (v) => { const b = Buffer.alloc(4); b.writeUInt32LE(v); push(b); };
  const f32 = (v) => { const b = Buffer.alloc(4); b.writeFloatLE(v); push(b); };
  let tensors = [];
  for (const group of manifest) {
    const data = Buffer.concat(group.paths.map((p) => readFileSync(join(modelDir, p))));
    let offset = 0;
    for (const w of group.weights) {
      const count = w.shape.reduce((a, b) => a * b, 1);
      const q = w.quantization;
      if (w.dtype !== 'float32') throw new Error(`${w.name}: dtype ${w.dtype} not supported`);
      let bytes;
      if (q) {
        if (q.dtype !== 'uint8') throw new Error(`${w.name}: quantisation ${q.dtype} not supported`);
        bytes = data.subarray(offset, offset + count);
      } else {
        bytes = data.subarray(offset, offset + 4 * count);
      }
      offset += bytes.length;
      tensors.push({ name: w.name, shape: w.shape, q, bytes });
    }
    if (offset !== data.length) throw new Error(`${name}: ${data.length - offset} bytes left over`);
  }
  push(Buffer.from('FMW1', 'ascii'));
  u32(tensors.length);
  for (const t of tensors) {
    const nameBytes = Buffer.from(t.name, 'utf8');
    u32(nameBytes.length);
    push(nameBytes);
    u32(t.shape.length);
    t.shape.forEach(u32);
    if (t.q) {
      u32(1);
      f32(t.q.scale);
      f32(t.q.min);
    } else {
      u32(0);
    }
    push(t.bytes);
  }
  return { bytes: Buffer.concat(chunks), tensors };
}

const [modelDir, outDir = 'data/weights'] = process.argv.slice(2);
if (!modelDir) {
  console.error('usage: node scripts/convert-weights.mjs MODEL_DIR [OUT_DIR]');
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
for (const [name, out] of NETS) {
  const { bytes, tensors } = convert(modelDir, name);
  writeFileSync(join(outDir, out), bytes);
  console.log(`${out}: ${tensors.length} tensors, ${bytes.length} bytes`);
}

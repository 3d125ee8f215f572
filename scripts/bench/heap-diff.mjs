// What grew between two V8 heap snapshots (.heapsnapshot files, as DevTools or the call soak's
// --snapshots write them): live objects summed by kind and constructor name, the largest growths
// first. A leak shows as a constructor whose count and size climb between the snapshots.
//
//   node scripts/bench/heap-diff.mjs before.heapsnapshot after.heapsnapshot [--top 25]

import fs from 'node:fs';
import { pathToFileURL } from 'node:url';

/** Sum the snapshot's nodes by "type name": count and self size. */
export function summarise(text) {
  const snap = JSON.parse(text);
  const meta = snap.snapshot.meta;
  const fields = meta.node_fields;
  const stride = fields.length;
  const [iType, iName, iSize] = ['type', 'name', 'self_size'].map((f) => fields.indexOf(f));
  const types = meta.node_types[0];
  const nodes = snap.nodes;
  const strings = snap.strings;
  const groups = new Map();
  let total = 0;
  for (let i = 0; i < nodes.length; i += stride) {
    const type = types[nodes[i + iType]];
    // Strings and numbers are grouped by kind alone (their "names" are their values).
    const name = ['string', 'number', 'concatenated string', 'sliced string'].includes(type) ? '' : strings[nodes[i + iName]];
    const key = `${type} ${name.length > 60 ? `${name.slice(0, 57)}...` : name}`;
    const g = groups.get(key) || { count: 0, size: 0 };
    g.count++;
    g.size += nodes[i + iSize];
    total += nodes[i + iSize];
    groups.set(key, g);
  }
  return { groups, total };
}

/** The groups that grew most from `a` to `b` (summaries from `summarise`). */
export function diff(a, b, top = 25) {
  const keys = new Set([...a.groups.keys(), ...b.groups.keys()]);
  const rows = [];
  for (const k of keys) {
    const x = a.groups.get(k) || { count: 0, size: 0 };
    const y = b.groups.get(k) || { count: 0, size: 0 };
    rows.push({ key: k, dCount: y.count - x.count, dSize: y.size - x.size, size: y.size });
  }
  rows.sort((p, q) => Math.abs(q.dSize) - Math.abs(p.dSize));
  return { totalBefore: a.total, totalAfter: b.total, rows: rows.slice(0, top) };
}

/** The diff as text lines. */
export function report(d) {
  const kb = (x) => `${(x / 1024).toFixed(1)} KB`;
  const lines = [`heap: ${kb(d.totalBefore)} -> ${kb(d.totalAfter)} (${(((d.totalAfter - d.totalBefore) / d.totalBefore) * 100).toFixed(2)}%)`];
  for (const r of d.rows) lines.push(`${r.dSize >= 0 ? '+' : ''}${kb(r.dSize).padStart(10)} ${(r.dCount >= 0 ? '+' : '') + r.dCount}`.padEnd(24) + ` ${r.key}`);
  return lines.join('\n');
}

if (process.argv[1] && import.meta.url === pathToFileURL(process.argv[1]).href) {
  const [fa, fb] = process.argv.slice(2).filter((s) => !s.startsWith('--'));
  const i = process.argv.indexOf('--top');
  if (!fa || !fb) {
    console.error('heap-diff: node scripts/bench/heap-diff.mjs before.heapsnapshot after.heapsnapshot [--top 25]');
    process.exit(2);
  }
  const d = diff(summarise(fs.readFileSync(fa, 'utf8')), summarise(fs.readFileSync(fb, 'utf8')), i > 0 ? Number(process.argv[i + 1]) : 25);
  console.log(report(d));
}

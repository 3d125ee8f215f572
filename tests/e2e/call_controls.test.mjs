// The call page's DOM-free modules, under Node: head-motion damping, the checks on data channel
// messages, the per-frame log and its CSV, the connection text of the copy-paste exchange and
// the ICE server list. (The page drives them in tests/e2e/call.test.mjs.)

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { parseControl, FrameLog, clampSettings, MAX_CONTROL_BYTES } from '../../www/js/call-controls.js';
import { pkg } from './lib.mjs';
import { encodeDescription, decodeDescription, parseIceServers } from '../../www/js/call-peer.js';

const AVATARS = ['spk02', 'spk03'];

test('head-motion damping scales the deviation from the running mean (the core\'s pose anchor)', () => {
  const fm = pkg();
  const damper = () => new fm.PoseDamper(2); // the package's class over the core's pose anchor
  const d = damper();
  const still = { scale: 2, rotation: 0.1, tx: 100, ty: 50 };
  // A steady pose: the mean is the pose; any factor gives it back.
  for (let t = 0; t < 10000; t += 33) d.apply(still, t, 0.3);
  const same = d.apply(still, 10033, 0.3);
  for (const k of Object.keys(still)) assert.ok(Math.abs(same[k] - still[k]) < 1e-4, k); // f32
  // A sudden move of 20 px: factor 0 keeps the head at the mean, 1 follows, 0.5 goes half way.
  const moved = { ...still, tx: 120 };
  const d0 = damper();
  const d5 = damper();
  const d1 = damper();
  for (let t = 0; t < 10000; t += 33) {
    d0.apply(still, t, 0);
    d5.apply(still, t, 0.5);
    d1.apply(still, t, 1);
  }
  const t = 10033;
  assert.ok(Math.abs(d0.apply(moved, t, 0).tx - 100) < 0.5);
  assert.ok(Math.abs(d5.apply(moved, t, 0.5).tx - 110) < 0.5);
  assert.equal(d1.apply(moved, t, 1).tx, 120);
  // Rotation wraps: a mean near pi and a pose near -pi are close.
  const w = damper();
  w.apply({ ...still, rotation: 3.1 }, 0, 0.5);
  const r = w.apply({ ...still, rotation: -3.1 }, 33, 0.5).rotation;
  assert.ok(Math.abs(Math.atan2(Math.sin(r - 3.1), Math.cos(r - 3.1))) < 0.1, `rotation ${r}`);
  // Scale is damped in log space: stays positive at any factor.
  const s = damper();
  s.apply(still, 0, 1.5);
  assert.ok(s.apply({ ...still, scale: 0.1 }, 33, 1.5).scale > 0);
});

test('data channel messages: only well-formed ones pass, with only their known fields', () => {
  const none = { gain: undefined, head: undefined, mouth: undefined, eyes: undefined, brows: undefined, style: undefined, avatar: undefined, condition: undefined };
  assert.deepEqual(parseControl('{"t":"set","gain":0.5}', AVATARS).msg, { t: 'set', ...none, gain: 0.5 });
  // The expression gain per region: mouth, eyes, brows, each 0..3.
  assert.deepEqual(parseControl('{"t":"set","mouth":3,"eyes":0,"brows":1.25}', AVATARS).msg, { t: 'set', ...none, mouth: 3, eyes: 0, brows: 1.25 });
  // The expressive method's style, 0..1.
  assert.deepEqual(parseControl('{"t":"set","style":0.25}', AVATARS).msg, { t: 'set', ...none, style: 0.25 });
  assert.match(parseControl('{"t":"set","style":1.5}', AVATARS).error, /style is outside 0..1/);
  assert.match(parseControl('{"t":"set","style":"0"}', AVATARS).error, /style is not a number/);
  assert.deepEqual(parseControl('{"t":"set","eyes":2}', AVATARS).msg, { t: 'set', ...none, eyes: 2 });
  const rs = parseControl('{"t":"status","camera":"ok","gain":1,"head":1,"mouth":2,"eyes":0.5,"brows":3}', AVATARS).msg;
  assert.deepEqual([rs.mouth, rs.eyes, rs.brows], [2, 0.5, 3]);
  assert.equal(parseControl('{"t":"set","avatar":"spk03","extra":"x"}', AVATARS).msg.avatar, 'spk03');
  assert.equal(parseControl('{"t":"set","avatar":"spk03","extra":"x"}', AVATARS).msg.extra, undefined);
  const st = parseControl('{"t":"status","camera":"face-lost","pipelineMs":31.5,"avatar":"spk02"}', AVATARS).msg;
  assert.equal(st.camera, 'face-lost');
  assert.equal(st.pipelineMs, 31.5);
  assert.deepEqual(parseControl('{"t":"bye","x":1}', AVATARS).msg, { t: 'bye' });
  // A schedule's condition number rides on a set (for the other side's log) and comes back in
  // the status; a page running a schedule says so (blind), so the other hides the conditions.
  assert.equal(parseControl('{"t":"set","gain":1,"condition":3}', AVATARS).msg.condition, 3);
  const sb = parseControl('{"t":"status","camera":"ok","blind":true,"condition":2}', AVATARS).msg;
  assert.deepEqual([sb.blind, sb.condition], [true, 2]);
  assert.equal(parseControl('{"t":"status","camera":"ok"}', AVATARS).msg.blind, false);
  const bad = [
    [42, /not text/],
    ['x'.repeat(MAX_CONTROL_BYTES + 1), /longer/],
    ['{', /not JSON/],
    ['null', /not an object/],
    ['[1]', /not an object/],
    ['{"t":"set"}', /changes nothing/],
    ['{"t":"set","gain":3}', /outside/],
    ['{"t":"set","gain":-0.1}', /outside/],
    ['{"t":"set","gain":"1"}', /not a number/],
    ['{"t":"set","gain":null}', /not a number/],
    ['{"t":"set","head":1e999}', /not a number/],
    ['{"t":"set","mouth":3.01}', /mouth is outside 0..3/],
    ['{"t":"set","eyes":-0.1}', /eyes is outside 0..3/],
    ['{"t":"set","brows":"1"}', /brows is not a number/],
    ['{"t":"set","mouth":null}', /mouth is not a number/],
    ['{"t":"set","gain":1,"brows":1e9}', /brows is outside/],
    ['{"t":"status","camera":"ok","mouth":4}', /mouth is outside/],
    ['{"t":"set","avatar":"spk99"}', /not a bundled model/],
    ['{"t":"set","avatar":{"toString":"spk02"}}', /not a bundled model/],
    ['{"t":"status","camera":"on fire"}', /camera state/],
    ['{"t":"status","camera":"ok","encodeMs":-1}', /outside/],
    ['{"t":"launch"}', /unknown kind/],
    ['{"t":"set","gain":1,"condition":1.5}', /condition is not a whole number/],
    ['{"t":"set","gain":1,"condition":-1}', /condition is outside/],
    ['{"t":"set","condition":2}', /changes nothing/],
    ['{"t":"status","camera":"ok","condition":"2"}', /condition is not a number/],
    ['{"t":"status","camera":"ok","blind":"yes"}', /blind is not true or false/],
    ['{"__proto__":{"t":"set"}}', /unknown kind/],
  ];
  for (const [m, why] of bad) {
    const r = parseControl(m, AVATARS);
    assert.equal(r.msg, undefined, String(m).slice(0, 40));
    assert.match(r.error, why, String(m).slice(0, 40));
  }
  assert.deepEqual(clampSettings({ gain: 9, head: -1 }), { gain: 2.5, head: 0, mouth: 1, eyes: 1, brows: 1, style: 1 });
  assert.deepEqual(clampSettings({ gain: 1, head: 1, mouth: 4, eyes: -1, brows: 2.5, style: 3 }), { gain: 1, head: 1, mouth: 3, eyes: 0, brows: 2.5, style: 1 });
});

test('the frame log: a fixed ring, CSV with named columns, oldest row first', () => {
  const log = new FrameLog({ shapeModes: 2, appearanceModes: 3, targetShape: 2, targetAppearance: 1, capacity: 4 });
  const bytes = log.data.byteLength;
  for (let i = 0; i < 6; i++) {
    log.push({
      wall: 1000 + i,
      frame: i,
      captureMs: 1764000000000.25 + i,
      renderMs: i % 2 ? NaN : 12.5,
      lost: i % 2 === 1,
      gain: 1,
      head: 0.5,
      mouth: 2,
      eyes: 1,
      brows: i / 4,
      avatar: i < 3 ? 'spk02' : 'spk03',
      fitPose: { scale: 1, rotation: 0, tx: i, ty: 0 },
      sentPose: i % 2 ? null : { scale: 1, rotation: 0, tx: i / 2, ty: 0 },
      src: { shape: [0.1, 0.2], appearance: [1, 2, 3] },
      tgt: i % 2 ? null : { shape: [0.3, 0.4], appearance: [5] },
    });
  }
  assert.equal(log.length, 4);
  assert.equal(log.data.byteLength, bytes, 'no growth');
  const lines = log.toCSV().trim().split('\n');
  assert.equal(lines.length, 5);
  const head = lines[0].split(',');
  assert.deepEqual(head.slice(0, 8), ['wall_ms', 'frame', 'capture_ms', 'render_ms', 'lost', 'gain', 'head_motion', 'avatar']);
  assert.deepEqual(head.slice(-8), ['src_shape_1', 'src_shape_2', 'src_app_1', 'src_app_2', 'src_app_3', 'tgt_shape_1', 'tgt_shape_2', 'tgt_app_1']);
  const rows = lines.slice(1).map((l) => l.split(','));
  assert.deepEqual(rows.map((r) => r[1]), ['2', '3', '4', '5'], 'oldest first');
  assert.equal(rows[0][0], '1002.000');
  assert.equal(rows[0][2], '1764000000002.250', 'wall-clock times keep their milliseconds');
  assert.equal(rows[0][3], '12.5');
  assert.deepEqual(rows.map((r) => r[4]), ['0', '1', '0', '1']);
  assert.deepEqual(rows.map((r) => r[7]), ['"spk02"', '"spk03"', '"spk03"', '"spk03"']);
  assert.equal(rows[1][3], '', 'no render time for a lost frame');
  assert.equal(rows[1][head.indexOf('tgt_shape_1')], '');
  assert.equal(rows[0][head.indexOf('tgt_shape_2')], '0.4');
  assert.equal(rows[0][head.indexOf('sent_tx')], '1');
  assert.deepEqual(head.slice(16, 19), ['mouth_gain', 'eyes_gain', 'brows_gain']);
  assert.deepEqual(rows.map((r) => r[head.indexOf('mouth_gain')]), ['2', '2', '2', '2']);
  assert.deepEqual(rows.map((r) => r[head.indexOf('brows_gain')]), ['0.5', '0.75', '1', '1.25']);
  assert.deepEqual(head.slice(19, 22), ['style', 'condition', 'condition_name']);
  // A target with more modes widens the columns and keeps the rows (a schedule switches avatars).
  log.ensure(2, 3, 5, 1);
  assert.ok(log.columns.includes('tgt_shape_5'));
  assert.equal(log.length, 4);
  const wide = log.toCSV().trim().split('\n');
  const wideHead = wide[0].split(',');
  assert.deepEqual(wide.slice(1).map((l) => l.split(',')[1]), ['2', '3', '4', '5'], 'the rows are kept, in order');
  assert.equal(wide[1].split(',')[wideHead.indexOf('tgt_shape_2')], '0.4');
  assert.equal(wide[1].split(',')[wideHead.indexOf('tgt_shape_5')], '');
  assert.equal(wide[1].split(',')[wideHead.indexOf('src_app_3')], '3');
  // Another source (other mode counts) starts the log again.
  log.ensure(4, 3, 5, 1);
  assert.equal(log.length, 0);
});

test('connection text: round trip, and every kind of bad paste explained', () => {
  const offer = { type: 'offer', sdp: 'v=0\r\no=- 1 2 IN IP4 127.0.0.1\r\ns=é\r\n' };
  const text = encodeDescription(offer);
  assert.match(text, /^facemimic-call-1:/);
  assert.deepEqual(decodeDescription(text, 'offer'), offer);
  assert.deepEqual(decodeDescription(`  ${text.slice(0, 30)}\n${text.slice(30)}  `, 'offer'), offer, 'whitespace from a mail client');
  assert.throws(() => decodeDescription('', 'offer'), /paste the connection text/);
  assert.throws(() => decodeDescription('v=0 hello', 'offer'), /not facemimic connection text/);
  assert.throws(() => decodeDescription('facemimic-call-1:%%%', 'offer'), /damaged/);
  assert.throws(() => decodeDescription(`facemimic-call-1:${btoa('{"type":"pranswer","sdp":"v=0"}')}`), /no offer or answer/);
  assert.throws(() => decodeDescription(`facemimic-call-1:${btoa('{"type":"offer","sdp":"x"}')}`), /no offer or answer/);
  assert.throws(() => decodeDescription(text, 'answer'), /an answer is expected/);
});

test('ICE servers: none by default; a list of stun/turn URLs, checked', () => {
  assert.deepEqual(parseIceServers(''), []);
  assert.deepEqual(parseIceServers('[{"urls":"stun:stun.example.org:3478"}]'), [{ urls: ['stun:stun.example.org:3478'] }]);
  assert.deepEqual(parseIceServers('[{"urls":["turn:t.example.org"],"username":"u","credential":"c","x":1}]'), [{ urls: ['turn:t.example.org'], username: 'u', credential: 'c' }]);
  assert.throws(() => parseIceServers('stun:x'), /not JSON/);
  assert.throws(() => parseIceServers('{"urls":"stun:x"}'), /must be a JSON list/);
  assert.throws(() => parseIceServers('[{"urls":"http://x"}]'), /ICE server 1 needs urls/);
  assert.throws(() => parseIceServers('[{}]'), /ICE server 1/);
});

// The call's condition schedule without a browser (www/js/call-schedule.js, and the frame log's
// switch rows in www/js/call-controls.js): parsing and every kind of bad input (a stable code, a
// message naming the problem, never another exception), the fully crossed generator and its
// seeded shuffle, writing back, the values each side gets, and the clock that switches. The page
// runs it in tests/e2e/call_schedule_page.test.mjs.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { parseSchedule, serialiseSchedule, crossConditions, resolveCondition, ScheduleRunner, ScheduleError, seededRandom, describeSide, formatClock, totalSeconds, exampleSchedule, LIMITS } from '../../www/js/call-schedule.js';
import { FrameLog, EVENT_COLUMNS } from '../../www/js/call-controls.js';

const AVATARS = ['spk01', 'spk02', 'spk05', 'spk07'];
const parse = (v) => parseSchedule(v, { avatars: AVATARS });

/** The ScheduleError `fn` throws (anything else fails the test). */
function error(fn) {
  try {
    fn();
  } catch (e) {
    assert.ok(e instanceof ScheduleError, `a ScheduleError, not ${e?.name}: ${e?.message}`);
    assert.equal(typeof e.code, 'string');
    assert.ok(e.message.length > 10);
    return e;
  }
  assert.fail('no error');
}

test('a schedule: conditions with a duration and any of the settings per side; a list alone; a duration for all', () => {
  const s = parse(`{
    "version": 1, "name": "pilot", "comment": "two conditions",
    "conditions": [
      {"name": "damped", "duration": 60, "remote": {"head": 0.25, "avatar": "spk05.fmm"}},
      {"duration": 30.5, "both": {"gain": 1.5, "mouth": 3, "eyes": 0, "brows": 2, "style": 0.5}, "local": {"avatar": "spk02"}, "comment": "x"}
    ]}`);
  assert.deepEqual(s, {
    version: 1,
    name: 'pilot',
    comment: 'two conditions',
    conditions: [
      { name: 'damped', duration: 60, remote: { head: 0.25, avatar: 'spk05' } },
      { comment: 'x', duration: 30.5, both: { gain: 1.5, mouth: 3, eyes: 0, brows: 2, style: 0.5 }, local: { avatar: 'spk02' } },
    ],
  });
  assert.equal(totalSeconds(s), 90.5);
  // A bare list of conditions; a top-level duration for those without one; a BOM.
  const l = parse('\uFEFF[{"duration": 2}, {"remote": {"gain": 0}, "duration": 3}]');
  assert.deepEqual(l.conditions.map((c) => c.duration), [2, 3]);
  assert.deepEqual(parse({ duration: 60, conditions: [{}, { duration: 5 }, { remote: { gain: 2.5 } }] }).conditions.map((c) => c.duration), [60, 5, 60]);
  // The ranges' ends are in range.
  parse({ duration: 1, conditions: [{ both: { gain: 0, head: 0, mouth: 0, eyes: 0, brows: 0, style: 0 } }, { both: { gain: 2.5, head: 1.5, mouth: 3, eyes: 3, brows: 3, style: 1 } }] });
  // An empty side is dropped; a condition setting nothing keeps the settings before the schedule.
  assert.deepEqual(parse([{ duration: 1, remote: {} }]).conditions[0], { duration: 1 });
});

test('bad schedules: a stable code, the place, and a message naming the problem', () => {
  const cases = [
    // not JSON
    ['{', 'not-json', '', /not JSON.*line 1, column 2/],
    ['', 'not-json', '', /empty/],
    ['   \n ', 'not-json', '', /empty/],
    ['\u0000\u0001PNG\u0002', 'not-json', '', /not JSON/],
    ["{'conditions': []}", 'not-json', '', /not JSON/],
    ['{"conditions": [{"duration": 60,}]}', 'not-json', '', /not JSON/],
    [42, 'bad-schedule', '', /The schedule is 42: it must be an object/],
    ['x'.repeat(LIMITS.bytes + 1), 'too-large', '', /at most/],
    // the shape
    ['"a schedule"', 'bad-schedule', '', /must be an object/],
    ['null', 'bad-schedule', '', /null.*must be an object/],
    ['{}', 'bad-schedule', 'conditions', /conditions are missing/],
    ['{"conditions": {}}', 'bad-schedule', 'conditions', /must be a list/],
    ['[]', 'bad-schedule', 'conditions', /no conditions/],
    ['[7]', 'bad-schedule', 'conditions[0]', /Condition 1 is 7/],
    ['{"version": 2, "conditions": [{"duration": 1}]}', 'bad-schedule', 'version', /version is 2/],
    ['[{"duration": 1, "remote": 0.5}]', 'bad-schedule', 'conditions[0].remote', /remote is 0.5: it must be an object/],
    ['[{"duration": 1, "name": 5}]', 'bad-schedule', 'conditions[0].name', /name is 5: it must be text/],
    [[{ duration: 1, name: 'n'.repeat(81) }], 'bad-schedule', 'conditions[0].name', /81 characters/],
    [{ conditions: [{ duration: 1 }], cross: { factors: { 'remote.gain': [1] } } }, 'bad-schedule', '', /both "conditions" and "cross"/],
    [Array.from({ length: LIMITS.conditions + 1 }, () => ({ duration: 1 })), 'bad-schedule', 'conditions', /2001 conditions/],
    // unknown keys, with the known ones (and a near one)
    ['{"conditons": []}', 'unknown-key', 'conditons', /unknown key "conditons" \(did you mean "conditions"\?/],
    ['[{"duration": 1, "remote": {"gian": 1}}]', 'unknown-key', 'conditions[0].remote.gian', /Condition 1, remote: unknown key "gian" \(did you mean "gain"\? known: gain, head, mouth, eyes, brows, style, avatar\)/],
    ['[{"name": "x", "duration": 1, "both": {"gain": 1}, "other": {}}]', 'unknown-key', 'conditions[0].other', /Condition 1 \("x"\): unknown key "other"/],
    ['[{"duration": 1, "__proto__": {"gain": 1}}]', 'unknown-key', 'conditions[0].__proto__', /unknown key "__proto__"/],
    ['[{"duration": 1, "remote": {"Gain": 1}}]', 'unknown-key', 'conditions[0].remote.Gain', /did you mean "gain"/],
    // durations: missing, zero, negative, not numbers, too long
    ['[{"remote": {"gain": 1}}]', 'bad-duration', 'conditions[0].duration', /duration is missing/],
    ['[{"duration": 0}]', 'bad-duration', 'conditions[0].duration', /duration is 0: it must be a number of seconds above 0/],
    ['[{"duration": 1}, {"duration": -60}]', 'bad-duration', 'conditions[1].duration', /Condition 2: the duration is -60/],
    ['[{"duration": "60"}]', 'bad-duration', 'conditions[0].duration', /duration is "60", not a number/],
    ['[{"duration": null}]', 'bad-duration', 'conditions[0].duration', /duration is null, not a number/],
    ['[{"duration": [60]}]', 'bad-duration', 'conditions[0].duration', /duration is a list, not a number/],
    [[{ duration: Infinity }], 'bad-duration', 'conditions[0].duration', /not a number/],
    [[{ duration: NaN }], 'bad-duration', 'conditions[0].duration', /not a number/],
    ['[{"duration": 0.01}]', 'bad-duration', 'conditions[0].duration', /0.01 s/],
    ['[{"duration": 1e6}]', 'bad-duration', 'conditions[0].duration', /at most|86400/],
    ['{"duration": -1, "conditions": [{}]}', 'bad-duration', 'duration', /The schedule: the duration is -1/],
    // values: not numbers, out of the controls' ranges
    ['[{"duration": 1, "local": {"gain": "1"}}]', 'bad-value', 'conditions[0].local.gain', /local.gain is "1", not a number: the expression gain is a number in 0..2.5/],
    ['[{"duration": 1, "both": {"head": null}}]', 'bad-value', 'conditions[0].both.head', /both.head is null, not a number/],
    ['[{"duration": 1, "remote": {"style": true}}]', 'bad-value', 'conditions[0].remote.style', /remote.style is true, not a number/],
    ['[{"duration": 1, "remote": {"gain": 2.6}}]', 'out-of-range', 'conditions[0].remote.gain', /remote.gain is 2.6, outside 0..2.5 \(the expression gain's range\)/],
    ['[{"duration": 1, "remote": {"head": -0.1}}]', 'out-of-range', 'conditions[0].remote.head', /outside 0..1.5 \(the head motion's range\)/],
    ['[{"duration": 1, "local": {"mouth": 3.5}}]', 'out-of-range', 'conditions[0].local.mouth', /outside 0..3/],
    ['[{"duration": 1, "local": {"eyes": -1}}]', 'out-of-range', 'conditions[0].local.eyes', /outside 0..3/],
    ['[{"duration": 1, "local": {"brows": 1e9}}]', 'out-of-range', 'conditions[0].local.brows', /outside 0..3/],
    ['[{"duration": 1, "both": {"style": 1.01}}]', 'out-of-range', 'conditions[0].both.style', /outside 0..1 \(the style's range\)/],
    // avatars: unknown or missing
    ['[{"duration": 1, "remote": {"avatar": "spk99"}}]', 'bad-avatar', 'conditions[0].remote.avatar', /remote.avatar is "spk99", an unknown avatar \(a bundled avatar's name: spk01, spk02, spk05, spk07\)/],
    ['[{"duration": 1, "remote": {"avatar": "../../etc/passwd"}}]', 'bad-avatar', 'conditions[0].remote.avatar', /unknown avatar/],
    ['[{"duration": 1, "local": {"avatar": ""}}]', 'bad-avatar', 'conditions[0].local.avatar', /local.avatar is missing/],
    ['[{"duration": 1, "local": {"avatar": null}}]', 'bad-avatar', 'conditions[0].local.avatar', /is missing/],
    ['[{"duration": 1, "both": {"avatar": 5}}]', 'bad-avatar', 'conditions[0].both.avatar', /both.avatar is 5: it must be a bundled avatar's name/],
  ];
  for (const [input, code, path, why] of cases) {
    const e = error(() => parse(input));
    const label = String(typeof input === 'string' ? input : JSON.stringify(input)).slice(0, 60);
    assert.equal(e.code, code, `${label}: ${e.message}`);
    assert.equal(e.path, path, `${label}: path`);
    assert.match(e.message, why, label);
  }
  // No avatar list: any avatar is unknown (the page always gives its bundled ones).
  assert.equal(error(() => parseSchedule('[{"duration": 1, "remote": {"avatar": "spk02"}}]')).code, 'bad-avatar');
});

test('any input ends in a schedule or a ScheduleError, never another exception', () => {
  const rand = seededRandom(12345);
  const pick = (a) => a[Math.floor(rand() * a.length)];
  const good = serialiseSchedule(parse({ duration: 2, conditions: [{ name: 'a, "b": c', remote: { gain: 0.5, avatar: 'spk05' } }, { both: { head: 0 } }] }));
  const values = [0, -1, 1e309, 'x', '', null, true, [], {}, [1], { gain: 1 }, 'spk05', 0.5, 99];
  let schedules = 0;
  for (let i = 0; i < 3000; i++) {
    let input;
    if (i % 2) {
      // Damaged text: characters dropped, doubled or replaced.
      const chars = [...good];
      for (let k = 0; k < 1 + Math.floor(rand() * 4); k++) {
        const at = Math.floor(rand() * chars.length);
        const op = Math.floor(rand() * 3);
        if (op === 0) chars.splice(at, 1);
        else if (op === 1) chars.splice(at, 0, chars[at]);
        else chars[at] = pick(['{', '}', '[', ']', ',', ':', '"', '0', '-', 'e', ' ', '\u0000']);
      }
      input = chars.join('');
    } else {
      // Random structures with the schema's own keys.
      const side = () => Object.fromEntries(Array.from({ length: Math.floor(rand() * 3) }, () => [pick(['gain', 'head', 'mouth', 'eyes', 'brows', 'style', 'avatar', 'x']), pick(values)]));
      const cond = () => Object.fromEntries(Array.from({ length: Math.floor(rand() * 4) }, () => [pick(['name', 'duration', 'both', 'local', 'remote', 'comment']), rand() < 0.5 ? side() : pick(values)]));
      input = rand() < 0.2 ? pick(values) : { duration: pick([undefined, 1, 0, 'x']), conditions: rand() < 0.9 ? Array.from({ length: Math.floor(rand() * 3) }, cond) : pick(values) };
    }
    try {
      parse(input);
      schedules++;
    } catch (e) {
      assert.ok(e instanceof ScheduleError && e.code, `${JSON.stringify(input)?.slice(0, 80)} threw ${e?.name}: ${e?.message}`);
    }
  }
  assert.ok(schedules > 0, 'some inputs were schedules');
});

test('fully crossed: every combination once, the first factor slowest; a seeded shuffle per block', () => {
  const factors = { 'remote.head': [1, 0.25], 'remote.gain': [1, 0.5, 0], 'local.avatar': ['spk02', 'spk05'] };
  const { conditions, seed } = crossConditions(factors, { duration: 60, avatars: AVATARS });
  assert.equal(seed, undefined, 'not shuffled');
  assert.equal(conditions.length, 12);
  assert.deepEqual(conditions[0], { name: 'remote.head=1 · remote.gain=1 · local.avatar=spk02', duration: 60, remote: { head: 1, gain: 1 }, local: { avatar: 'spk02' } });
  assert.deepEqual(conditions[1].local, { avatar: 'spk05' }, 'the last factor varies fastest');
  assert.deepEqual(conditions[11].remote, { head: 0.25, gain: 0 });
  const key = (c) => JSON.stringify([c.remote, c.local]);
  assert.equal(new Set(conditions.map(key)).size, 12, 'all combinations, each once');
  // Shuffled with a seed: the same seed gives the same order, another seed another; a permutation.
  const a = crossConditions(factors, { duration: 60, shuffle: true, seed: 7, avatars: AVATARS });
  const b = crossConditions(factors, { duration: 60, seed: 7, avatars: AVATARS }); // a seed implies shuffle
  const c = crossConditions(factors, { duration: 60, seed: 8, avatars: AVATARS });
  assert.equal(a.seed, 7);
  assert.deepEqual(a.conditions, b.conditions);
  assert.notDeepEqual(a.conditions.map(key), c.conditions.map(key));
  assert.notDeepEqual(a.conditions.map(key), conditions.map(key));
  assert.deepEqual([...a.conditions.map(key)].sort(), [...conditions.map(key)].sort());
  // Blocks: each repetition is every combination once, shuffled on its own.
  const r = crossConditions({ 'both.gain': [0, 1, 2] }, { duration: 1, repeat: 3, seed: 1, avatars: AVATARS });
  assert.equal(r.conditions.length, 9);
  assert.match(r.conditions[0].name, /^gain=\d$/, 'factors all on one side: named without it');
  const blocks = [0, 3, 6].map((i) => r.conditions.slice(i, i + 3).map((x) => x.both.gain));
  for (const bl of blocks) assert.deepEqual([...bl].sort(), [0, 1, 2]);
  assert.ok(new Set(blocks.map(String)).size > 1, `blocks differ: ${blocks.join(' | ')}`);
  // No seed given: one is drawn, and reported, so the order can be had again.
  const d = crossConditions(factors, { duration: 60, shuffle: true, avatars: AVATARS });
  assert.ok(Number.isInteger(d.seed));
  assert.deepEqual(crossConditions(factors, { duration: 60, seed: d.seed, avatars: AVATARS }).conditions, d.conditions);

  // The page's example: head motion x expression x identity, one minute each, shuffled (seed 1).
  const ex = parse(exampleSchedule(['spk01', 'spk05']));
  assert.equal(ex.conditions.length, 8);
  assert.equal(totalSeconds(ex), 480);
  assert.equal(ex.seed, 1);

  // In a file: "cross" with a top-level duration; the name says how it was made.
  const s = parse({ duration: 60, cross: { factors, seed: 3 } });
  assert.equal(s.conditions.length, 12);
  assert.equal(s.seed, 3);
  assert.match(s.name, /remote.head × remote.gain × local.avatar, fully crossed, shuffled \(seed 3\)/);
  assert.deepEqual(parse(serialiseSchedule(s)).conditions, s.conditions, 'saved: the conditions in the order run');

  const bad = [
    [{ duration: 60, cross: { factors: { 'remote.hed': [1] } } }, 'unknown-key', /unknown factor "remote.hed"/],
    [{ duration: 60, cross: { factors: { 'them.head': [1] } } }, 'unknown-key', /unknown factor/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1] }, shufle: true } }, 'unknown-key', /did you mean "shuffle"/],
    [{ duration: 60, cross: { factors: {} } }, 'bad-schedule', /factors is an object: it must be an object like/],
    [{ duration: 60, cross: { factors: { 'remote.head': [] } } }, 'bad-schedule', /list of 1 to 50 levels/],
    [{ duration: 60, cross: { factors: { 'remote.head': 1 } } }, 'bad-schedule', /list of 1 to 50 levels/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1, 2] } } }, 'out-of-range', /factor "remote.head": level 2 is 2, outside 0..1.5/],
    [{ duration: 60, cross: { factors: { 'remote.avatar': ['spk02', 'nobody'] } } }, 'bad-avatar', /level 2 is "nobody", an unknown avatar/],
    [{ duration: 60, cross: { factors: { 'remote.gain': ['1'] } } }, 'bad-value', /level 1 is "1", not a number/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1] }, shuffle: false, seed: 4 } }, 'bad-schedule', /seed is given but shuffle is false/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1] }, seed: -1 } }, 'bad-schedule', /seed is -1/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1] }, seed: 1.5 } }, 'bad-schedule', /seed is 1.5/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1] }, shuffle: 'yes' } }, 'bad-schedule', /shuffle is "yes"/],
    [{ duration: 60, cross: { factors: { 'remote.head': [1] }, repeat: 0 } }, 'bad-schedule', /repeat is 0/],
    [{ duration: 60, cross: { factors: Object.fromEntries(['gain', 'head', 'mouth', 'eyes'].map((k) => [`remote.${k}`, Array.from({ length: 10 }, (_, i) => i / 10)])) } }, 'bad-schedule', /10000 conditions \(at most 2000\)/],
    [{ cross: { factors: { 'remote.head': [1] } } }, 'bad-duration', /duration is missing/],
    [{ duration: 60, cross: [1] }, 'bad-schedule', /cross is a list/],
  ];
  for (const [input, code, why] of bad) {
    const e = error(() => parse(input));
    assert.equal(e.code, code, `${JSON.stringify(input)}: ${e.message}`);
    assert.match(e.message, why);
  }
});

test('written back as JSON, one condition a line, read back the same (strings with commas, colons and quotes too)', () => {
  const s = parse({ name: 'a: "b", c', comment: 'é ✓', conditions: [{ name: 'x, y: {z}', duration: 1.5, both: { gain: 0.5 }, local: { avatar: 'spk01', style: 0 }, remote: { head: 1.25 } }, { duration: 2 }] });
  const text = serialiseSchedule(s);
  assert.deepEqual(parse(text), s);
  const lines = text.trim().split('\n');
  assert.equal(lines[0], '{');
  assert.equal(lines[1], '  "version": 1,');
  assert.equal(lines[5], '    {"name": "x, y: {z}", "duration": 1.5, "both": {"gain": 0.5}, "local": {"style": 0, "avatar": "spk01"}, "remote": {"head": 1.25}},', 'the settings in their order');
  assert.equal(lines[6], '    {"duration": 2}');
});

test('what each side gets: the settings before the schedule, then "both", then its own side', () => {
  const baseline = { local: { gain: 1, head: 1, mouth: 1, eyes: 1, brows: 1, style: 1, avatar: 'spk02' }, remote: { gain: 0.8, head: 1, mouth: 1, eyes: 1, brows: 1, style: 0.5, avatar: 'spk01' } };
  const v = resolveCondition({ duration: 1, both: { gain: 2, head: 0 }, remote: { head: 0.5, avatar: 'spk05' } }, baseline);
  assert.deepEqual(v.local, { gain: 2, head: 0, mouth: 1, eyes: 1, brows: 1, style: 1, avatar: 'spk02' });
  assert.deepEqual(v.remote, { gain: 2, head: 0.5, mouth: 1, eyes: 1, brows: 1, style: 0.5, avatar: 'spk05' });
  assert.deepEqual(resolveCondition({ duration: 1 }, baseline), baseline, 'a condition setting nothing: the baseline');
  assert.equal(describeSide(v.remote), 'gain 2 · head 0.5 · mouth 1 · eyes 1 · brows 1 · style 0.5 · spk05');
  assert.equal(describeSide({ head: 0.25, avatar: 'spk05' }), 'head 0.25 · spk05');
  assert.deepEqual([formatClock(0), formatClock(1), formatClock(59001), formatClock(61000), formatClock(3600000)], ['0:00', '0:01', '1:00', '1:01', '1:00:00']);
});

test('the clock: switches at the durations, without drift, however late the ticks; skipped conditions named; stop', () => {
  const s = parse([{ name: 'a', duration: 2 }, { name: 'b', duration: 2 }, { name: 'c', duration: 1.5 }]);
  const r = new ScheduleRunner(s);
  assert.equal(r.totalMs, 5500);
  assert.deepEqual(r.start(1000), { type: 'switch', index: 0, from: -1, skipped: [], plannedAt: 1000 });
  assert.equal(r.tick(1500), null);
  let st = r.status(1500);
  assert.deepEqual([st.state, st.number, st.count, st.condition.name, st.remainingMs, st.conditionProgress, st.progress], ['running', 1, 3, 'a', 1500, 0.25, 500 / 5500]);
  assert.equal(r.untilNext(1500), 1500);
  assert.equal(r.tick(2999), null);
  // A late tick: the switch is reported with the time it was planned for.
  assert.deepEqual(r.tick(3040), { type: 'switch', index: 1, from: 0, skipped: [], plannedAt: 3000 });
  st = r.status(3040);
  assert.equal(st.remainingMs, 1960, 'the next switch is still at 5000: no drift');
  assert.equal(r.untilNext(3040), 1960);
  // A tick far too late (a frozen tab): the conditions it missed are named.
  assert.deepEqual(r.tick(6600), { type: 'end', from: 1, skipped: [2] });
  assert.equal(r.state, 'ended');
  assert.equal(r.tick(7000), null);
  assert.equal(r.status(9000).progress, 1);
  // Skipping into a condition; stopping.
  const q = new ScheduleRunner(s);
  q.start(0);
  assert.deepEqual(q.tick(4100), { type: 'switch', index: 2, from: 0, skipped: [1], plannedAt: 4000 });
  assert.deepEqual(q.stop(4200), { type: 'stop', index: 2 });
  assert.equal(q.state, 'stopped');
  assert.equal(q.tick(9000), null);
  assert.equal(q.stop(9000), null);
  assert.equal(q.status(9999).elapsedMs, 4200, 'the clock stops with it');
  assert.equal(q.untilNext(9999), null);
  // Boundaries: condition i starts exactly at the sum of the durations before it.
  const z = new ScheduleRunner(parse([{ duration: 0.1 }, { duration: 0.2 }, { duration: 0.3 }]));
  assert.deepEqual([0, 99, 100, 299, 300, 599, 600].map((t) => z.indexAt(t)), [0, 0, 1, 1, 2, 2, 3]);
});

test("the frame log: each frame's condition, and a row per switch with both sides' settings", () => {
  const log = new FrameLog({ shapeModes: 1, appearanceModes: 1, targetShape: 1, targetAppearance: 1, capacity: 8 });
  const frame = (i, condition, conditionName) => log.push({ wall: 1000 + i, frame: i, captureMs: 990 + i, renderMs: 10, lost: false, gain: 1, head: 1, avatar: 'spk02', condition, conditionName, src: { shape: [0], appearance: [0] } });
  frame(0);
  frame(1, 1, 'damped, "slow"');
  frame(2, 2, 'b');
  frame(3, 2); // the other side's log: the number only
  const lines = log.toCSV().trim().split('\n');
  const head = lines[0].split(',');
  const col = (r, c) => lines[r].split(',')[head.indexOf(c)];
  assert.deepEqual([1, 2, 3, 4].map((r) => col(r, 'condition')), ['', '1', '2', '2']);
  assert.match(lines[2], /,1,"damped, \\"slow\\"",/, 'the name quoted as a CSV text cell');
  assert.equal(col(3, 'condition_name'), '"b"');
  assert.equal(col(4, 'condition_name'), '');
  const values = { gain: 0.5, head: 0.25, mouth: 1, eyes: 1, brows: 1, style: 1, avatar: 'spk05' };
  log.event({ wall: 1764000000000.5, event: 'start', condition: 0, name: 'pilot', duration: 4, local: { ...values, gain: 1 }, remote: values });
  log.event({ wall: 1764000000001.25, event: 'switch', condition: 1, name: 'damped, "slow"', planned: 1764000000001, duration: 2, local: values, remote: { ...values, avatar: 'spk01' } });
  log.event({ wall: 1764000000003, event: 'applied', condition: 2, name: '', local: { gain: 2, head: 0 } });
  const ev = log.eventsCSV().trim().split('\n');
  assert.equal(ev[0], EVENT_COLUMNS.join(','));
  assert.deepEqual(EVENT_COLUMNS.slice(0, 8), ['wall_ms', 'event', 'condition', 'condition_name', 'planned_ms', 'duration_s', 'local_gain', 'local_head_motion']);
  assert.ok(EVENT_COLUMNS.includes('remote_avatar') && EVENT_COLUMNS.includes('remote_brows_gain'));
  const row = (i) => Object.fromEntries(ev[i].match(/("(?:[^"\\]|\\.)*"|[^,]*)(,|$)/g).map((c, k) => [EVENT_COLUMNS[k], c.replace(/,$/, '')]));
  assert.deepEqual([row(1).event, row(1).condition, row(1).condition_name, row(1).duration_s, row(1).local_gain], ['start', '0', '"pilot"', '4', '1']);
  const sw = row(2);
  assert.deepEqual([sw.wall_ms, sw.event, sw.condition, sw.planned_ms, sw.local_gain, sw.local_head_motion, sw.local_avatar, sw.remote_avatar], ['1764000000001.250', 'switch', '1', '1764000000001.000', '0.5', '0.25', '"spk05"', '"spk01"']);
  assert.equal(sw.condition_name, '"damped, \\"slow\\""');
  assert.deepEqual([row(3).event, row(3).condition, row(3).local_gain, row(3).local_head_motion, row(3).remote_gain], ['applied', '2', '2', '0', '']);
  // The switches are kept beside the frames: a new source's log starts its frames again, not them.
  log.ensure(3, 1, 1, 1);
  assert.equal(log.length, 0);
  assert.equal(log.events.length, 3);
});

// The call's condition schedule, without DOM: a list of conditions, each with a duration and any
// of the per-side settings (expression gain, head motion, the expression gain per region, style)
// and the apparent identity (avatar), for this page ("local"), the other page ("remote") or both;
// checked, generated fully crossed from factors, written back as JSON, and run by a clock the
// page ticks. The page's wiring is call-schedule-ui.js; the schema is in docs/call.md, "The
// condition schedule".
//
// Every problem is a ScheduleError with a stable `code`, a `path` into the JSON (e.g.
// `conditions[2].remote.gain`) and a message that names it: nothing here throws anything else,
// whatever the input.

import { GAIN_RANGE, HEAD_RANGE, REGION_RANGE, STYLE_RANGE, SETTINGS } from './call-controls.js';

export const SCHEDULE_VERSION = 1;
/** Who a condition's settings are for: both pages, this page (running the schedule), the other. */
export const SIDES = ['both', 'local', 'remote'];
/** What a side may set: the settings of call-controls.js and the avatar (a bundled model's name). */
export const KEYS = [...SETTINGS, 'avatar'];
export const RANGES = { gain: GAIN_RANGE, head: HEAD_RANGE, mouth: REGION_RANGE, eyes: REGION_RANGE, brows: REGION_RANGE, style: STYLE_RANGE };
const LABELS = { gain: 'expression gain', head: 'head motion', mouth: 'mouth gain', eyes: 'eyes gain', brows: 'brows gain', style: 'style' };
export const LIMITS = { bytes: 1_000_000, conditions: 2000, minDuration: 0.1, maxDuration: 86400, name: 80, comment: 2000, factors: 8, levels: 50, repeat: 100 };
const TOP_KEYS = ['version', 'name', 'comment', 'duration', 'conditions', 'cross'];
const CONDITION_KEYS = ['name', 'comment', 'duration', ...SIDES];
const CROSS_KEYS = ['factors', 'shuffle', 'seed', 'repeat'];

/** Error codes: not-json, too-large, bad-schedule, unknown-key, bad-duration, bad-value, out-of-range, bad-avatar. */
export class ScheduleError extends Error {
  constructor(code, message, path = '') {
    super(message);
    this.name = 'ScheduleError';
    this.code = code;
    this.path = path;
  }
}

const isObject = (v) => v !== null && typeof v === 'object' && !Array.isArray(v);
const show = (v) => (typeof v === 'string' ? JSON.stringify(v.length > 40 ? `${v.slice(0, 40)}…` : v) : Array.isArray(v) ? 'a list' : v === null ? 'null' : typeof v === 'object' ? 'an object' : String(v));
const fmt = (x) => String(+x.toFixed(3));

/** Edit distance (for "did you mean"). */
function distance(a, b) {
  const d = Array.from({ length: b.length + 1 }, (_, j) => j);
  for (let i = 1; i <= a.length; i++) {
    let prev = d[0];
    d[0] = i;
    for (let j = 1; j <= b.length; j++) {
      const cur = d[j];
      d[j] = Math.min(d[j] + 1, d[j - 1] + 1, prev + (a[i - 1] === b[j - 1] ? 0 : 1));
      prev = cur;
    }
  }
  return d[b.length];
}

function checkKeys(obj, known, where, path) {
  for (const k of Object.keys(obj)) {
    if (known.includes(k)) continue;
    const near = known.find((n) => distance(k.toLowerCase(), n) <= 2);
    const hint = near ? `did you mean "${near}"? ` : '';
    throw new ScheduleError('unknown-key', `${where}: unknown key "${k.slice(0, 40)}" (${hint}known: ${known.join(', ')})`, path ? `${path}.${k}` : k);
  }
}

function checkString(v, max, where, path) {
  if (v === undefined) return undefined;
  if (typeof v !== 'string') throw new ScheduleError('bad-schedule', `${where} is ${show(v)}: it must be text`, path);
  if (v.length > max) throw new ScheduleError('bad-schedule', `${where} is ${v.length} characters long (at most ${max})`, path);
  return v;
}

function checkDuration(v, where, path) {
  const range = `a number of seconds above 0 (${LIMITS.minDuration} to ${LIMITS.maxDuration})`;
  if (v === undefined) throw new ScheduleError('bad-duration', `${where}: the duration is missing: give ${range}, or one "duration" at the top for all`, path);
  if (typeof v !== 'number' || !Number.isFinite(v)) throw new ScheduleError('bad-duration', `${where}: the duration is ${show(v)}, not a number: it must be ${range}`, path);
  if (v < LIMITS.minDuration || v > LIMITS.maxDuration) throw new ScheduleError('bad-duration', `${where}: the duration is ${v}${v > 0 ? ' s' : ''}: it must be ${range}`, path);
  return v;
}

/** One setting's value, checked: a number in its control's range, or a bundled avatar's name.
 *  `where`: the condition (or factor level); `label`: the setting as the file names it. */
function checkValue(key, v, avatars, where, label, path) {
  if (key === 'avatar') {
    const known = `a bundled avatar's name: ${[...avatars].sort().join(', ')}`;
    if (v === undefined || v === null || (typeof v === 'string' && !v.trim())) throw new ScheduleError('bad-avatar', `${where}: ${label} is missing (${known})`, path);
    if (typeof v !== 'string') throw new ScheduleError('bad-avatar', `${where}: ${label} is ${show(v)}: it must be ${known}`, path);
    const name = v.trim().replace(/\.fmm$/i, '');
    if (!avatars.includes(name)) throw new ScheduleError('bad-avatar', `${where}: ${label} is ${show(v)}, an unknown avatar (${known})`, path);
    return name;
  }
  const [lo, hi] = RANGES[key];
  if (typeof v !== 'number' || !Number.isFinite(v)) throw new ScheduleError('bad-value', `${where}: ${label} is ${show(v)}, not a number: the ${LABELS[key]} is a number in ${lo}..${hi}`, path);
  if (v < lo || v > hi) throw new ScheduleError('out-of-range', `${where}: ${label} is ${v}, outside ${lo}..${hi} (the ${LABELS[key]}'s range)`, path);
  return v;
}

function checkSide(side, v, avatars, where, path) {
  if (v === undefined) return undefined;
  if (!isObject(v)) throw new ScheduleError('bad-schedule', `${where}: ${side} is ${show(v)}: it must be an object of settings (${KEYS.join(', ')})`, path);
  checkKeys(v, KEYS, `${where}, ${side}`, path);
  const out = {};
  for (const k of KEYS) if (k in v) out[k] = checkValue(k, v[k], avatars, where, `${side}.${k}`, `${path}.${k}`);
  return Object.keys(out).length ? out : undefined;
}

function checkCondition(c, i, avatars, defaultDuration) {
  const path = `conditions[${i}]`;
  const label = `Condition ${i + 1}`;
  if (!isObject(c)) throw new ScheduleError('bad-schedule', `${label} is ${show(c)}: a condition is an object ({"duration": 60, "remote": {"head": 0.5}})`, path);
  const name = checkString(c.name, LIMITS.name, `${label}: the name`, `${path}.name`);
  const where = name ? `${label} ("${name}")` : label;
  checkKeys(c, CONDITION_KEYS, where, path);
  const out = {};
  if (name !== undefined) out.name = name;
  const comment = checkString(c.comment, LIMITS.comment, `${where}: the comment`, `${path}.comment`);
  if (comment !== undefined) out.comment = comment;
  out.duration = checkDuration('duration' in c ? c.duration : defaultDuration, where, `${path}.duration`);
  for (const side of SIDES) {
    const s = checkSide(side, c[side], avatars, where, `${path}.${side}`);
    if (s) out[side] = s;
  }
  return out;
}

/** A seeded generator of numbers in [0, 1) (mulberry32): the same seed, the same shuffle. */
export function seededRandom(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

function randomSeed() {
  const c = globalThis.crypto;
  return c?.getRandomValues ? c.getRandomValues(new Uint32Array(1))[0] : Math.floor(Math.random() * 2 ** 32);
}

/**
 * A fully crossed list of conditions: every combination of the factors' levels, the first factor
 * varying slowest. `factors`: { "side.setting": [levels] } (side: both, local or remote; setting:
 * one of KEYS). `repeat` blocks of them; `shuffle` (implied by a `seed`) shuffles each block with
 * a seeded generator. Returns { conditions, seed } (the seed used, drawn when none is given).
 * Checked: a bad factor or level throws a ScheduleError.
 */
export function crossConditions(factors, { duration, shuffle, seed, repeat = 1, avatars = [] } = {}) {
  const p = 'cross';
  if (!isObject(factors) || !Object.keys(factors).length) throw new ScheduleError('bad-schedule', `cross: factors is ${show(factors)}: it must be an object like {"remote.head": [1, 0.2]}`, `${p}.factors`);
  const names = Object.keys(factors);
  if (names.length > LIMITS.factors) throw new ScheduleError('bad-schedule', `cross: ${names.length} factors (at most ${LIMITS.factors})`, `${p}.factors`);
  const levels = names.map((f) => {
    const fp = `${p}.factors["${f}"]`;
    const [side, key, ...rest] = f.split('.');
    if (!SIDES.includes(side) || !KEYS.includes(key) || rest.length) {
      throw new ScheduleError('unknown-key', `cross: unknown factor "${f.slice(0, 40)}" (a factor is side.setting: side one of ${SIDES.join(', ')}; setting one of ${KEYS.join(', ')}; e.g. "remote.head")`, fp);
    }
    const ls = factors[f];
    if (!Array.isArray(ls) || !ls.length || ls.length > LIMITS.levels) throw new ScheduleError('bad-schedule', `cross: factor "${f}" is ${show(ls)}: it must be a list of 1 to ${LIMITS.levels} levels`, fp);
    return ls.map((v, j) => checkValue(key, v, avatars, `cross: factor "${f}"`, `level ${j + 1}`, `${fp}[${j}]`));
  });
  if (repeat !== undefined && (!Number.isInteger(repeat) || repeat < 1 || repeat > LIMITS.repeat)) throw new ScheduleError('bad-schedule', `cross: repeat is ${show(repeat)}: it must be a whole number 1..${LIMITS.repeat}`, `${p}.repeat`);
  if (seed !== undefined && (!Number.isInteger(seed) || seed < 0 || seed > 4294967295)) throw new ScheduleError('bad-schedule', `cross: seed is ${show(seed)}: it must be a whole number 0..4294967295`, `${p}.seed`);
  if (shuffle !== undefined && typeof shuffle !== 'boolean') throw new ScheduleError('bad-schedule', `cross: shuffle is ${show(shuffle)}: it must be true or false`, `${p}.shuffle`);
  if (shuffle === false && seed !== undefined) throw new ScheduleError('bad-schedule', 'cross: a seed is given but shuffle is false (drop one)', `${p}.seed`);
  const n = levels.reduce((m, l) => m * l.length, 1) * repeat;
  if (n > LIMITS.conditions) throw new ScheduleError('bad-schedule', `cross: ${n} conditions (at most ${LIMITS.conditions})`, `${p}.factors`);
  let block = [[]];
  for (const ls of levels) block = block.flatMap((combo) => ls.map((v) => [...combo, v]));
  const doShuffle = shuffle ?? seed !== undefined;
  const used = doShuffle ? (seed ?? randomSeed()) : undefined;
  const rand = doShuffle ? seededRandom(used) : null;
  // Conditions named by their levels ("head=0.25 · gain=0.5"), with the sides when they differ.
  const oneSide = new Set(names.map((f) => f.split('.')[0])).size === 1;
  const conditions = [];
  for (let r = 0; r < repeat; r++) {
    const order = block.map((_, i) => i);
    if (rand) {
      for (let i = order.length - 1; i > 0; i--) {
        const j = Math.floor(rand() * (i + 1));
        [order[i], order[j]] = [order[j], order[i]];
      }
    }
    for (const i of order) {
      const c = { name: names.map((f, k) => `${oneSide ? f.split('.')[1] : f}=${block[i][k]}`).join(' · ').slice(0, LIMITS.name), duration };
      names.forEach((f, k) => {
        const [side, key] = f.split('.');
        (c[side] ??= {})[key] = block[i][k];
      });
      conditions.push(c);
    }
  }
  return { conditions, seed: used };
}

function parseJSON(text) {
  if (typeof text !== 'string') throw new ScheduleError('not-json', `The schedule is ${show(text)}, not JSON text`);
  if (text.length > LIMITS.bytes) throw new ScheduleError('too-large', `The schedule is ${text.length} characters long (at most ${LIMITS.bytes}): is it the right file?`);
  const t = text.replace(/^\uFEFF/, '');
  if (!t.trim()) throw new ScheduleError('not-json', 'The schedule is empty: paste its JSON or open a .json file');
  try {
    return JSON.parse(t);
  } catch (e) {
    const m = /position (\d+)/.exec(e.message);
    let where = '';
    if (m) {
      const before = t.slice(0, Number(m[1])).split('\n');
      where = ` (line ${before.length}, column ${before[before.length - 1].length + 1})`;
    }
    throw new ScheduleError('not-json', `The schedule is not JSON: ${e.message.replace(/\s*\(line \d+ column \d+\)/, '')}${where}`);
  }
}

/**
 * A schedule from JSON text (or a value already parsed), checked. `avatars`: the names an avatar
 * may take (the bundled models). Returns { version, name?, comment?, conditions: [{ name?,
 * comment?, duration, both?, local?, remote? }], seed? } (a `cross` expanded into its
 * conditions); throws a ScheduleError.
 */
export function parseSchedule(input, { avatars = [] } = {}) {
  const v = typeof input === 'string' ? parseJSON(input) : input;
  const top = Array.isArray(v) ? { conditions: v } : v;
  if (!isObject(top)) throw new ScheduleError('bad-schedule', `The schedule is ${show(v)}: it must be an object with "conditions" (a list) or "cross", or a list of conditions`);
  checkKeys(top, TOP_KEYS, 'The schedule', '');
  if (top.version !== undefined && top.version !== SCHEDULE_VERSION) throw new ScheduleError('bad-schedule', `The schedule's version is ${show(top.version)}: this page reads version ${SCHEDULE_VERSION}`, 'version');
  const out = { version: SCHEDULE_VERSION };
  const name = checkString(top.name, LIMITS.name, "The schedule's name", 'name');
  if (name !== undefined) out.name = name;
  const comment = checkString(top.comment, LIMITS.comment, "The schedule's comment", 'comment');
  if (comment !== undefined) out.comment = comment;
  const duration = top.duration === undefined ? undefined : checkDuration(top.duration, 'The schedule', 'duration');
  if (top.conditions !== undefined && top.cross !== undefined) throw new ScheduleError('bad-schedule', 'The schedule has both "conditions" and "cross": give one of them');
  let list = top.conditions;
  if (top.cross !== undefined) {
    if (!isObject(top.cross)) throw new ScheduleError('bad-schedule', `cross is ${show(top.cross)}: it must be an object ({"factors": {...}, "shuffle": true, "seed": 7})`, 'cross');
    checkKeys(top.cross, CROSS_KEYS, 'cross', 'cross');
    if (duration === undefined) checkDuration(undefined, 'cross', 'duration');
    const { conditions, seed } = crossConditions(top.cross.factors, { ...top.cross, duration, avatars });
    list = conditions;
    if (seed !== undefined) out.seed = seed;
    if (out.name === undefined) out.name = `${Object.keys(top.cross.factors).join(' × ')}, fully crossed${seed !== undefined ? `, shuffled (seed ${seed})` : ''}`.slice(0, LIMITS.name);
  }
  if (!Array.isArray(list)) throw new ScheduleError('bad-schedule', `The schedule's conditions are ${list === undefined ? 'missing' : show(list)}: "conditions" must be a list (or give "cross")`, 'conditions');
  if (!list.length) throw new ScheduleError('bad-schedule', 'The schedule has no conditions', 'conditions');
  if (list.length > LIMITS.conditions) throw new ScheduleError('bad-schedule', `The schedule has ${list.length} conditions (at most ${LIMITS.conditions})`, 'conditions');
  out.conditions = list.map((c, i) => checkCondition(c, i, avatars, duration));
  return out;
}

/** A value as JSON on one line, with a space after each colon and comma (outside strings). */
const oneLine = (v) => (isObject(v) ? `{${Object.entries(v).map(([k, x]) => `${JSON.stringify(k)}: ${oneLine(x)}`).join(', ')}}` : JSON.stringify(v));

/** A schedule as JSON text (version 1, one condition a line), which parseSchedule reads back. */
export function serialiseSchedule(s) {
  const head = { version: SCHEDULE_VERSION };
  if (s.name !== undefined) head.name = s.name;
  if (s.comment !== undefined) head.comment = s.comment;
  const lines = Object.entries(head).map(([k, v]) => `  ${JSON.stringify(k)}: ${JSON.stringify(v)},`);
  const conds = s.conditions.map((c) => `    ${oneLine(Object.fromEntries(CONDITION_KEYS.filter((k) => c[k] !== undefined).map((k) => [k, c[k]])))}`);
  return `{\n${lines.join('\n')}\n  "conditions": [\n${conds.join(',\n')}\n  ]\n}\n`;
}

/** An example: three factors of two levels, fully crossed, shuffled with a seed, one minute each. */
export function exampleSchedule([a = 'spk02', b = 'spk05'] = []) {
  return `{
  "version": 1,
  "name": "Head motion x expression x identity, 1 min each",
  "duration": 60,
  "cross": {
    "factors": {
      "remote.head": [1, 0.25],
      "remote.gain": [1, 0.5],
      "remote.avatar": [${JSON.stringify(a)}, ${JSON.stringify(b)}]
    },
    "shuffle": true,
    "seed": 1
  }
}
`;
}

/** The schedule's length, seconds. */
export const totalSeconds = (s) => s.conditions.reduce((t, c) => t + c.duration, 0);

/**
 * What each side is set to in a condition: its baseline (the settings when the schedule started),
 * then `both`, then its own side. `baseline`: { local, remote }, each { gain, head, mouth, eyes,
 * brows, style, avatar? }. Returns { local, remote }.
 */
export function resolveCondition(c, baseline) {
  const side = (s) => ({ ...baseline[s], ...(c.both || {}), ...(c[s] || {}) });
  return { local: side('local'), remote: side('remote') };
}

/** One side's settings in a line: "gain 0.5 · head 0.2 · spk05". */
export function describeSide(values) {
  const parts = [];
  for (const k of KEYS) {
    if (values[k] === undefined || values[k] === null) continue;
    parts.push(k === 'avatar' ? values[k] : `${k} ${fmt(values[k])}`);
  }
  return parts.join(' · ');
}

/** Milliseconds as m:ss (h:mm:ss from an hour). */
export function formatClock(ms) {
  const s = Math.max(0, Math.ceil(ms / 1000));
  const h = Math.floor(s / 3600);
  const m = Math.floor((s % 3600) / 60);
  const ss = String(s % 60).padStart(2, '0');
  return h ? `${h}:${String(m).padStart(2, '0')}:${ss}` : `${m}:${ss}`;
}

/**
 * Runs a schedule against a clock the caller gives (ms; performance.now() in the page): condition
 * i starts at start + the durations before it, however late the ticks come, so the schedule does
 * not drift. `tick(now)` returns what happened since the last tick, or null:
 *   { type: "switch", index, from, skipped: [indices whose time passed unseen], plannedAt }
 *   { type: "end", from, skipped }
 * `stop(now)` returns { type: "stop", index } while running. No timers, no DOM.
 */
export class ScheduleRunner {
  constructor(schedule) {
    this.schedule = schedule;
    this.starts = [];
    let t = 0;
    for (const c of schedule.conditions) {
      this.starts.push(t);
      t += c.duration * 1000;
    }
    this.totalMs = t;
    this.state = 'ready'; // running, ended, stopped
    this.index = -1;
    this.t0 = null;
  }

  get count() {
    return this.schedule.conditions.length;
  }

  start(now) {
    this.t0 = now;
    this.state = 'running';
    this.index = -1;
    return this.tick(now);
  }

  /** The condition at `elapsed` ms from the start (count: the schedule is over). */
  indexAt(elapsed) {
    if (elapsed >= this.totalMs) return this.count;
    let lo = 0;
    let hi = this.count - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (this.starts[mid] <= elapsed) lo = mid;
      else hi = mid - 1;
    }
    return lo;
  }

  tick(now) {
    if (this.state !== 'running') return null;
    const i = this.indexAt(now - this.t0);
    if (i === this.index) return null;
    const from = this.index;
    const skipped = [];
    for (let k = from + 1; k < i; k++) skipped.push(k);
    this.index = i;
    if (i >= this.count) {
      this.state = 'ended';
      return { type: 'end', from, skipped };
    }
    return { type: 'switch', index: i, from, skipped, plannedAt: this.t0 + this.starts[i] };
  }

  stop(now) {
    if (this.state !== 'running') return null;
    this.state = 'stopped';
    this.stoppedAt = now;
    return { type: 'stop', index: this.index };
  }

  /** Milliseconds to the next switch (or the end), for a timer; null when not running. */
  untilNext(now) {
    if (this.state !== 'running') return null;
    const next = this.index + 1 < this.count ? this.starts[this.index + 1] : this.totalMs;
    return Math.max(0, this.t0 + next - now);
  }

  /** Where the schedule is: the condition, its time left, the whole's progress (0..1). */
  status(now) {
    const running = this.state === 'running';
    const elapsed = this.t0 === null ? 0 : Math.min(this.totalMs, (running ? now : this.stoppedAt ?? now) - this.t0);
    const i = this.index;
    const c = i >= 0 && i < this.count ? this.schedule.conditions[i] : null;
    const inCond = c ? elapsed - this.starts[i] : 0;
    return {
      state: this.state,
      index: i,
      number: c ? i + 1 : 0,
      count: this.count,
      condition: c,
      elapsedMs: elapsed,
      totalMs: this.totalMs,
      remainingMs: c ? Math.max(0, c.duration * 1000 - inCond) : 0,
      conditionProgress: c ? Math.min(1, inCond / (c.duration * 1000)) : 0,
      progress: this.totalMs ? elapsed / this.totalMs : 0,
    };
  }
}

// The call's experimenter controls, without DOM: head-motion damping (the pose's deviation from
// its running mean, scaled: the package's PoseDamper, the core's pose anchor), the checks on
// every message that arrives over the data channel, and the per-frame log (a fixed-size ring of
// numbers, written out as CSV).
//
// Everything received from the other page is untrusted: `parseControl` returns a clean message
// or null (and why), so garbage over the data channel is counted and ignored, never thrown.

/** The limits of the per-side settings (the wasm `Cloner.setGain` takes 0..2.5 as well). */
export const GAIN_RANGE = [0, 2.5];
/** The expression gain per region (the expressive method's `Cloner.setRegionGains`), each 0..3. */
export const REGIONS = ['mouth', 'eyes', 'brows'];
export const REGION_RANGE = [0, 3];
/** The expressive method's style (`Cloner.setStyle`): 0 the avatar's own range, 1 the full motion. */
export const STYLE_RANGE = [0, 1];
/** Each side's settings, as its sliders (ids `gain`, `peer-gain`, ...) and messages name them. */
export const SETTINGS = ['gain', 'head', ...REGIONS, 'style'];
/** Head motion: 0 holds the head at its running mean, 1 leaves it, above 1 exaggerates. */
export const HEAD_RANGE = [0, 1.5];
/** Running mean of the pose: time constant in seconds. */
export const HEAD_TAU = 2;
/** A data channel message longer than this is dropped unread. */
export const MAX_CONTROL_BYTES = 4096;
/** A condition's number (1-based; 0: none) in a set or status message (call-schedule.js). */
export const CONDITION_RANGE = [0, 100000];
/** The condition switches the frame log keeps (a few an hour in a study). */
export const MAX_EVENTS = 10000;

const clamp = (x, [lo, hi]) => Math.min(hi, Math.max(lo, x));

const finite = (x) => typeof x === 'number' && Number.isFinite(x);

/**
 * A data channel message, checked. Returns `{ msg }` (a fresh object with only known fields) or
 * `{ error }`. Kinds (mouth, eyes, brows: the expression gain per region, REGION_RANGE; style:
 * STYLE_RANGE):
 *   {t:"set", gain?, head?, mouth?, eyes?, brows?, style?, avatar?, condition?}
 *                                        the experimenter sets this side's settings (condition: the
 *                                        schedule's condition number, for the log; 0 none)
 *   {t:"status", camera, pipelineMs?, encodeMs?, avatar?, gain?, head?, mouth?, eyes?, brows?, style?, blind?, condition?}
 *                                        the other side's state (blind: it runs a schedule, so
 *                                        this side hides the conditions; condition: the number
 *                                        it last applied)
 *   {t:"bye"}                            the other side hangs up
 * `avatars`: the names an "avatar" may take.
 */
export function parseControl(data, avatars) {
  if (typeof data !== 'string') return { error: 'not text' };
  if (data.length > MAX_CONTROL_BYTES) return { error: `longer than ${MAX_CONTROL_BYTES} bytes` };
  let m;
  try {
    m = JSON.parse(data);
  } catch {
    return { error: 'not JSON' };
  }
  if (!m || typeof m !== 'object' || Array.isArray(m)) return { error: 'not an object' };
  const num = (k, range) => {
    if (m[k] === undefined) return undefined;
    if (!finite(m[k])) throw new Error(`${k} is not a number`);
    if (range && (m[k] < range[0] || m[k] > range[1])) throw new Error(`${k} is outside ${range[0]}..${range[1]}`);
    return m[k];
  };
  const avatar = () => {
    if (m.avatar === undefined) return undefined;
    if (typeof m.avatar !== 'string' || !avatars.includes(m.avatar)) throw new Error('avatar is not a bundled model');
    return m.avatar;
  };
  const regions = () => Object.fromEntries(REGIONS.map((k) => [k, num(k, REGION_RANGE)]));
  const bool = (k) => {
    if (m[k] !== undefined && typeof m[k] !== 'boolean') throw new Error(`${k} is not true or false`);
    return m[k] === true;
  };
  const condition = () => {
    if (num('condition', CONDITION_RANGE) !== undefined && !Number.isInteger(m.condition)) throw new Error('condition is not a whole number');
    return m.condition;
  };
  try {
    if (m.t === 'set') {
      const out = { t: 'set', gain: num('gain', GAIN_RANGE), head: num('head', HEAD_RANGE), ...regions(), style: num('style', STYLE_RANGE), avatar: avatar() };
      if (Object.keys(out).every((k) => k === 't' || out[k] === undefined)) return { error: 'set changes nothing' };
      out.condition = condition();
      return { msg: out };
    }
    if (m.t === 'status') {
      if (!['ok', 'face-lost', 'camera-lost', 'starting'].includes(m.camera)) return { error: 'bad camera state' };
      const name = typeof m.avatar === 'string' ? m.avatar.slice(0, 80) : undefined;
      return {
        msg: {
          t: 'status',
          camera: m.camera,
          pipelineMs: num('pipelineMs', [0, 60000]),
          encodeMs: num('encodeMs', [0, 60000]),
          gain: num('gain', GAIN_RANGE),
          head: num('head', HEAD_RANGE),
          ...regions(),
          style: num('style', STYLE_RANGE),
          avatar: name,
          blind: bool('blind'),
          condition: condition(),
        },
      };
    }
    if (m.t === 'bye') return { msg: { t: 'bye' } };
  } catch (e) {
    return { error: e.message };
  }
  return { error: 'unknown kind' };
}

/** The settings (gain, head-motion factor, region gains, style; a region or style not given is 1), clamped into their ranges. */
export function clampSettings({ gain, head, mouth = 1, eyes = 1, brows = 1, style = 1 }) {
  const regions = { mouth: clamp(mouth, REGION_RANGE), eyes: clamp(eyes, REGION_RANGE), brows: clamp(brows, REGION_RANGE) };
  return { gain: clamp(gain, GAIN_RANGE), head: clamp(head, HEAD_RANGE), ...regions, style: clamp(style, STYLE_RANGE) };
}

/** The settings of one side in the switch log's columns (as the frame log names them). */
const EVENT_VALUES = [['gain', 'gain'], ['head', 'head_motion'], ...REGIONS.map((r) => [r, `${r}_gain`]), ['style', 'style'], ['avatar', 'avatar']];
/** The switch log's columns: when, what, which condition, then each side's settings. */
export const EVENT_COLUMNS = ['wall_ms', 'event', 'condition', 'condition_name', 'planned_ms', 'duration_s', ...['local', 'remote'].flatMap((side) => EVENT_VALUES.map(([, c]) => `${side}_${c}`))];

const csvText = (v) => (v === undefined || v === null ? '' : JSON.stringify(String(v)));
const csvNumber = (v) => (typeof v !== 'number' || Number.isNaN(v) ? '' : Number.isInteger(v) ? String(v) : String(+v.toPrecision(7)));

/**
 * The per-frame log: a ring of `capacity` rows of numbers (allocated once, so a long call does
 * not grow the page's memory), written out as CSV. Columns: time and frame, the pipeline's
 * timing, the lost flag, the settings, the pose (as fitted and as sent), the region gains, the
 * condition of a schedule (its number and name), the source's shape and appearance parameters
 * and the avatar's (the target's, as cloned). Beside the frames, the schedule's switches
 * (`event`, `eventsCSV`): one row each, with both sides' settings.
 */
export class FrameLog {
  constructor({ shapeModes, appearanceModes, targetShape, targetAppearance, capacity = 18000 }) {
    this.capacity = capacity;
    this.rows = 0; // written in all
    this.avatars = []; // names by index (the avatar column holds the index)
    this.conditionNames = []; // the same for the condition_name column
    this.events = []; // the schedule's switches, oldest first (at most MAX_EVENTS)
    this.layout(shapeModes, appearanceModes, targetShape, targetAppearance);
  }

  layout(ss, sa, ts, ta, keep = false) {
    const old = keep && this.rows ? { columns: this.columns, data: this.data } : null;
    this.dims = { ss, sa, ts, ta };
    const fixed = [
      'wall_ms', 'frame', 'capture_ms', 'render_ms', 'lost', 'gain', 'head_motion', 'avatar',
      'fit_scale', 'fit_rotation', 'fit_tx', 'fit_ty', 'sent_scale', 'sent_rotation', 'sent_tx', 'sent_ty',
      ...REGIONS.map((r) => `${r}_gain`),
      'style', 'condition', 'condition_name',
    ];
    this.fixed = fixed.length;
    const seq = (p, n) => Array.from({ length: n }, (_, i) => `${p}${i + 1}`);
    this.columns = [...fixed, ...seq('src_shape_', ss), ...seq('src_app_', sa), ...seq('tgt_shape_', ts), ...seq('tgt_app_', ta)];
    this.col = Object.fromEntries(this.columns.map((c, i) => [c, i]));
    this.data = new Float64Array(this.capacity * this.columns.length);
    if (!old) {
      this.rows = 0;
      return;
    }
    // Wider: the rows so far are kept, column by column (the new ones empty).
    const w = this.columns.length;
    const ow = old.columns.length;
    const from = this.columns.map((c) => old.columns.indexOf(c));
    for (let r = 0; r < Math.min(this.rows, this.capacity); r++) {
      for (let i = 0; i < w; i++) this.data[r * w + i] = from[i] < 0 ? NaN : old.data[r * ow + from[i]];
    }
  }

  /** A new source with other mode counts starts the log again (its columns change); an avatar
   *  with more modes widens it, keeping the rows (a schedule switches avatars mid-log). */
  ensure(ss, sa, ts, ta) {
    const d = this.dims;
    if (d.ss === ss && d.sa === sa && d.ts >= ts && d.ta >= ta) return;
    const sameSource = d.ss === ss && d.sa === sa;
    this.layout(ss, sa, Math.max(ts, d.ts), Math.max(ta, d.ta), sameSource);
  }

  avatarIndex(name) {
    let i = this.avatars.indexOf(name);
    if (i < 0) i = this.avatars.push(name) - 1;
    return i;
  }

  /** One row. `r`: { wall, frame, captureMs, renderMs, lost, gain, head, avatar, fitPose, sentPose, mouth, eyes, brows, style, condition, conditionName, src, tgt }. */
  push(r) {
    const w = this.columns.length;
    const o = (this.rows % this.capacity) * w;
    const d = this.data;
    const c = this.col;
    const { ss, sa, ts, ta } = this.dims;
    d.fill(NaN, o, o + w);
    const fixed = [r.wall, r.frame, r.captureMs, r.renderMs, r.lost ? 1 : 0, r.gain, r.head, this.avatarIndex(r.avatar)];
    for (let i = 0; i < fixed.length; i++) d[o + i] = fixed[i] ?? NaN;
    const pose = (p, at) => {
      if (!p) return;
      d[o + at] = p.scale;
      d[o + at + 1] = p.rotation;
      d[o + at + 2] = p.tx;
      d[o + at + 3] = p.ty;
    };
    pose(r.fitPose, c.fit_scale);
    pose(r.sentPose, c.sent_scale);
    for (const k of REGIONS) d[o + c[`${k}_gain`]] = r[k] ?? NaN;
    d[o + c.style] = r.style ?? NaN;
    if (r.condition) {
      d[o + c.condition] = r.condition;
      if (r.conditionName) {
        let i = this.conditionNames.indexOf(r.conditionName);
        if (i < 0) i = this.conditionNames.push(r.conditionName) - 1;
        d[o + c.condition_name] = i;
      }
    }
    const put = (arr, at, n) => {
      if (!arr) return;
      for (let i = 0; i < Math.min(n, arr.length); i++) d[o + at + i] = arr[i];
    };
    let at = this.fixed;
    put(r.src?.shape, at, ss);
    put(r.src?.appearance, (at += ss), sa);
    put(r.tgt?.shape, (at += sa), ts);
    put(r.tgt?.appearance, (at += ts), ta);
    this.rows++;
  }

  get length() {
    return Math.min(this.rows, this.capacity);
  }

  /** The log as CSV text (oldest row first); the avatar and condition_name columns by name. */
  toCSV() {
    const w = this.columns.length;
    const text = { [this.col.avatar]: this.avatars, [this.col.condition_name]: this.conditionNames };
    const lines = [this.columns.join(',')];
    const n = this.length;
    const first = this.rows - n;
    for (let k = 0; k < n; k++) {
      const o = ((first + k) % this.capacity) * w;
      const cells = new Array(w);
      for (let i = 0; i < w; i++) {
        const v = this.data[o + i];
        if (text[i]) cells[i] = Number.isNaN(v) ? '' : csvText(text[i][v] ?? '');
        else if (Number.isNaN(v)) cells[i] = '';
        else if (i === 0 || i === 2) cells[i] = v.toFixed(3); // wall-clock times, ms
        else cells[i] = csvNumber(v);
      }
      lines.push(cells.join(','));
    }
    return `${lines.join('\n')}\n`;
  }

  /**
   * A switch of the schedule: `e` { wall (ms, wall clock), event ("start", "switch", "skip",
   * "end", "stop" on the page running it; "applied" on the other), condition (number, 0 none),
   * name, planned (ms, wall clock), duration (s), local, remote (each side's settings: gain,
   * head, mouth, eyes, brows, style, avatar) }. Kept beside the frames, not in their ring.
   */
  event(e) {
    this.events.push({ ...e, local: e.local ? { ...e.local } : null, remote: e.remote ? { ...e.remote } : null });
    if (this.events.length > MAX_EVENTS) this.events.shift();
  }

  /** The switches as CSV (EVENT_COLUMNS), oldest first. */
  eventsCSV() {
    const side = (v) => EVENT_VALUES.map(([k]) => (k === 'avatar' ? csvText(v?.[k]) : csvNumber(v?.[k])));
    const lines = this.events.map((e) =>
      [typeof e.wall === 'number' ? e.wall.toFixed(3) : '', e.event, csvNumber(e.condition), csvText(e.name), typeof e.planned === 'number' ? e.planned.toFixed(3) : '', csvNumber(e.duration), ...side(e.local), ...side(e.remote)].join(','),
    );
    return `${[EVENT_COLUMNS.join(','), ...lines].join('\n')}\n`;
  }
}

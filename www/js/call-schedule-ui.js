// The condition schedule on the call page: load it (text, a .json file), save it, run it, and keep
// both participants blind. The schedule's logic (checks, crossing, the clock) is call-schedule.js,
// without DOM; this is its wiring.
//
// The page that runs a schedule is the experimenter's: its panel shows the condition, the time
// left and what each side is set to. At each switch it sets its own settings (and avatar) and
// sends the other page its own (a "set" over the data channel, with the condition's number only,
// for that page's log: never its name). Its status tells the other page it runs one ("blind"), and
// that page then shows no setting, no value and no avatar name, and covers its own avatar: its
// panel says only that a session is under way. "Participant view" (Ctrl+Shift+E to come back)
// does the same on the experimenter's page, when it is a participant's screen too. `?blind=1`
// keeps a page blind from the start.
//
// Each switch is logged in the frame log (`FrameLog.event`): the condition's number and name, both
// sides' settings, the time (wall clock) and the time planned; each frame carries its condition.

import { parseSchedule, serialiseSchedule, ScheduleRunner, ScheduleError, resolveCondition, describeSide, formatClock, totalSeconds, exampleSchedule, KEYS, LIMITS } from './call-schedule.js';
import { SETTINGS } from './call-controls.js';
import { notify } from './toasts.js';
import { download } from './call-view.js';

const $ = (id) => document.getElementById(id);
const STORE_KEY = 'facemimic-call-schedule';
/** The other side not yet in the condition after this long: send it again (a reload, a lost message). */
const RESEND_MS = 2000;
const TICK_MS = 250;
const wallNow = () => performance.timeOrigin + performance.now();
const stamp = () => new Date().toISOString().replace(/[:.]/g, '-');
const setText = (el, text) => {
  if (el.textContent !== text) el.textContent = text;
};

/** A side's settings in `el`, those the condition sets (`set`) marked; the rest are the baseline. */
function showValues(el, values, set) {
  const key = JSON.stringify([values, set]);
  if (el.dataset.key === key) return;
  el.dataset.key = key;
  if (!values) return el.replaceChildren('–');
  const parts = KEYS.filter((k) => values[k] !== undefined && values[k] !== null).map((k) => {
    const span = document.createElement('span');
    span.textContent = describeSide({ [k]: values[k] });
    if (set?.[k] !== undefined) span.className = 'set';
    return span;
  });
  el.replaceChildren(...parts.flatMap((p, i) => (i ? [' · ', p] : [p])));
}

export class SchedulePanel {
  /**
   * `call`: the page's state (avatar, peer, link); `view`: the CallView; `modelFor(key)`,
   * `setOwnSettings(s)`, `setAvatarKey(key)`: call.js's own; `forceBlind`: `?blind=1`.
   */
  constructor({ call, view, modelFor, setOwnSettings, setAvatarKey, forceBlind = false }) {
    Object.assign(this, { call, view, modelFor, setOwnSettings, setAvatarKey, forceBlind });
    this.schedule = null;
    this.runner = null;
    this.baseline = null;
    this.current = null; // { number, name, values: { local, remote }, set: what the condition sets }
    this.peerBlind = false; // the other page runs a schedule
    this.selfBlind = false; // "Participant view" on this page
    this.blind = false;
    this.peerCondition = 0; // the condition the other page says it is in
    this.applied = 0; // the condition the other page's schedule set this page to
    this.lastSent = 0;
    this.wire();
    this.applyBlind();
  }

  wire() {
    const text = $('schedule-text');
    try {
      text.value = localStorage.getItem(STORE_KEY) || '';
    } catch {
      // no storage: an empty box
    }
    if (text.value) this.load(text.value, { quiet: true });
    $('schedule-load').addEventListener('click', () => this.load(text.value));
    $('schedule-open').addEventListener('click', () => $('schedule-file').click());
    $('schedule-file').addEventListener('change', (e) => {
      const file = e.target.files?.[0];
      e.target.value = ''; // the same file may be chosen again
      if (file) this.openFile(file);
    });
    $('schedule-example').addEventListener('click', () => {
      text.value = exampleSchedule(this.avatars().filter((n, i, all) => i === 0 || i === all.length - 1));
      this.load(text.value);
    });
    $('schedule-save').addEventListener('click', () => this.save());
    $('schedule-start').addEventListener('click', () => this.start());
    $('schedule-stop').addEventListener('click', () => this.stop());
    $('schedule-blind').addEventListener('click', () => this.setSelfBlind(true));
    $('download-switches').addEventListener('click', () => download(`facemimic-call-switches-${stamp()}.csv`, this.call.avatar.log.eventsCSV(), 'text/csv'));
    addEventListener('keydown', (e) => {
      if (e.ctrlKey && e.shiftKey && e.code === 'KeyE') {
        e.preventDefault();
        this.setSelfBlind(!this.selfBlind);
      }
    });
  }

  /** The avatars a schedule may name: the bundled ones offered under "Appears as" (not the source). */
  avatars() {
    return [...$('peer-avatar').options].map((o) => o.textContent);
  }

  get running() {
    return this.runner?.state === 'running';
  }

  // -------------------------------------------------------------------------------------------
  // Loading and saving

  /** Check `text` and make it the schedule; a problem is shown (code and message), never thrown. */
  load(text, { quiet = false } = {}) {
    if (this.running) return false;
    try {
      this.schedule = parseSchedule(text, { avatars: this.avatars() });
    } catch (e) {
      this.schedule = null;
      this.showError(e, quiet);
      this.render();
      return false;
    }
    this.showError(null);
    try {
      localStorage.setItem(STORE_KEY, text);
    } catch {
      // not kept: fine
    }
    this.render();
    return true;
  }

  async openFile(file) {
    if (file.size > LIMITS.bytes) return this.showError(new ScheduleError('too-large', `${file.name} is ${file.size} bytes (a schedule is at most ${LIMITS.bytes}): is it the right file?`));
    let text;
    try {
      text = await file.text();
    } catch (e) {
      return this.showError(new ScheduleError('unreadable', `${file.name} could not be read (${e?.message || e})`));
    }
    $('schedule-text').value = text;
    if (this.load(text)) notify('info', 'Schedule loaded', `${file.name}: ${this.summary()}`);
  }

  save() {
    if (!this.running && !this.load($('schedule-text').value)) return;
    download(`facemimic-schedule-${stamp()}.json`, serialiseSchedule(this.schedule), 'application/json');
  }

  showError(e, quiet = false) {
    const box = $('schedule-error');
    if (!e) {
      box.hidden = true;
      box.replaceChildren();
      return;
    }
    const code = e instanceof ScheduleError ? e.code : 'internal';
    const msg = e?.message || String(e);
    const c = document.createElement('code');
    c.textContent = code;
    box.replaceChildren(c, ` ${msg}`);
    box.dataset.code = code;
    box.hidden = false;
    if (!quiet) notify('error', 'Schedule not loaded', `${msg} [${code}]`);
  }

  summary() {
    const s = this.schedule;
    const n = s.conditions.length;
    return `${n} condition${n === 1 ? '' : 's'}, ${formatClock(totalSeconds(s) * 1000)} in all${s.name ? ` · ${s.name}` : ''}`;
  }

  // -------------------------------------------------------------------------------------------
  // Running

  async start() {
    if (this.running || this.starting || !this.load($('schedule-text').value)) return;
    this.starting = true;
    try {
      await this.begin();
    } finally {
      this.starting = false;
      this.render();
    }
  }

  async begin() {
    const c = this.call;
    // This page's avatars first (a switch then need not wait for a model to load).
    const names = new Set(this.schedule.conditions.flatMap((k) => [k.both?.avatar, k.local?.avatar]).filter(Boolean));
    try {
      for (const n of names) await this.modelFor(`b:${n}.fmm`);
    } catch (e) {
      return this.showError(new ScheduleError('bad-avatar', `An avatar of the schedule could not be loaded: ${e?.message || e}`));
    }
    const p = c.peer;
    const num = (v) => (typeof v === 'number' ? v : 1);
    this.baseline = {
      local: { ...c.avatar.settings, avatar: c.avatar.target?.name },
      remote: { ...Object.fromEntries(SETTINGS.map((k) => [k, num(p[k])])), avatar: p.avatar ?? undefined },
      localKey: $('avatar-model').value,
    };
    if (c.link?.dc?.readyState !== 'open') notify('warning', 'The other side is not connected', 'its settings are sent when it is');
    this.runner = new ScheduleRunner(this.schedule);
    const now = performance.now();
    this.log('start', 0, this.schedule.name, this.baseline, { duration: totalSeconds(this.schedule) });
    this.lock(true);
    this.handle(this.runner.start(now));
    clearInterval(this.interval);
    this.interval = setInterval(() => this.tick(), TICK_MS);
    this.render();
    this.update();
  }

  stop() {
    const ev = this.runner?.stop(performance.now());
    if (ev) this.finish('stop', ev.index + 1);
  }

  tick() {
    if (!this.runner) return;
    const now = performance.now();
    this.handle(this.runner.tick(now));
    if (this.running && this.current && this.peerCondition !== this.current.number && this.call.link?.dc?.readyState === 'open' && now - this.lastSent > RESEND_MS) this.sendRemote();
    this.update();
  }

  /** What the runner says happened: a switch (after any skipped conditions) or the end. */
  handle(ev) {
    if (!ev) return;
    const at = wallNow(); // the switch, logged at this time (its effect: the frames after it)
    const conds = this.schedule.conditions;
    for (const k of ev.skipped) this.log('skip', k + 1, conds[k].name, resolveCondition(conds[k], this.baseline), { planned: this.runner.t0 + this.runner.starts[k], duration: conds[k].duration });
    if (ev.type === 'end') {
      this.finish('end', 0, at);
      return;
    }
    const c = conds[ev.index];
    const values = resolveCondition(c, this.baseline);
    this.current = { number: ev.index + 1, name: c.name ?? '', values, set: { both: c.both, local: c.local, remote: c.remote } };
    this.call.avatar.condition = { number: this.current.number, name: this.current.name };
    // This page's status says "blind" before the other page gets the condition (one ordered channel).
    const avatar = c.local?.avatar ?? c.both?.avatar;
    this.applyLocal(values.local, avatar ? `b:${avatar}.fmm` : this.baseline.localKey);
    this.sendRemote();
    this.log('switch', this.current.number, c.name, values, { planned: ev.plannedAt, duration: c.duration, at });
    clearTimeout(this.timer);
    this.timer = setTimeout(() => this.tick(), this.runner.untilNext(performance.now()) + 5);
    this.render();
  }

  /** The end of the schedule, or a stop: both sides back to their settings before it. */
  finish(kind, number, at = wallNow()) {
    clearInterval(this.interval);
    clearTimeout(this.timer);
    const b = this.baseline;
    this.current = null;
    this.call.avatar.condition = null;
    // The other page gets its settings back before this page's status lifts its blindness.
    this.sendRemote(b.remote, 0);
    this.applyLocal(b.local, b.localKey);
    this.log(kind, number, kind === 'stop' ? this.schedule.conditions[number - 1]?.name : this.schedule.name, b, { at });
    this.lock(false);
    this.render();
    this.update();
    if (!this.blind) notify('info', kind === 'end' ? 'The schedule is over' : 'The schedule was stopped', 'both sides are back to their settings before it');
  }

  applyLocal(v, want) {
    this.setOwnSettings(Object.fromEntries(SETTINGS.map((k) => [k, v[k]])));
    if (want && want !== $('avatar-model').value) this.setAvatarKey(want).catch((e) => notify('error', 'Could not change the avatar', e?.message || String(e)));
  }

  sendRemote(v = this.current?.values.remote, condition = this.current?.number ?? 0) {
    if (!v) return;
    const msg = { t: 'set', ...Object.fromEntries(SETTINGS.map((k) => [k, v[k]])), condition };
    if (v.avatar && this.avatars().includes(v.avatar)) msg.avatar = v.avatar;
    this.call.link?.sendControl(msg);
    this.lastSent = performance.now();
  }

  log(event, condition, name, values, { planned, duration, at = wallNow() } = {}) {
    this.call.avatar?.log?.event({
      wall: at,
      event,
      condition,
      name: name ?? '',
      planned: planned === undefined ? undefined : performance.timeOrigin + planned,
      duration,
      local: values?.local,
      remote: values?.remote,
    });
  }

  /** While running, the settings are the schedule's: this page's controls are off. */
  lock(on) {
    for (const id of ['avatar-model', ...SETTINGS]) $(id).disabled = on;
    for (const id of ['schedule-load', 'schedule-example', 'schedule-open', 'schedule-file', 'schedule-start']) $(id).disabled = on;
    $('schedule-text').readOnly = on;
    $('schedule-stop').disabled = !on;
    $('schedule-group').classList.toggle('running', on); // the editor folds away: the countdown in view
    this.view.locked = on;
    this.view.update();
  }

  // -------------------------------------------------------------------------------------------
  // The other side, and blindness

  /** A "set" from the other page: its schedule's condition number, for this page's log. */
  onSet(msg) {
    if (msg.condition === undefined) return;
    this.applied = msg.condition;
    this.call.avatar.condition = msg.condition ? { number: msg.condition, name: '' } : null;
    const local = Object.fromEntries([...SETTINGS, 'avatar'].map((k) => [k, msg[k]]));
    this.log('applied', msg.condition, '', { local });
    this.applyBlind();
  }

  onPeerStatus(msg) {
    this.peerCondition = msg.condition ?? 0;
    if (this.peerBlind !== msg.blind) {
      this.peerBlind = msg.blind;
      this.applyBlind();
    }
  }

  /** What this page's status tells the other: blind while a schedule runs here. */
  statusFields() {
    return { blind: this.running, condition: this.current?.number ?? this.applied };
  }

  setSelfBlind(on) {
    this.selfBlind = on;
    this.applyBlind();
    if (on) scrollTo(0, 0); // the participant sees the call from its top
  }

  /** Blind: `?blind=1`, the other page runs a schedule, "Participant view", or this page is still
   *  in a condition the other page set (its page reloaded before it set this one back). */
  applyBlind() {
    const on = this.forceBlind || this.peerBlind || this.selfBlind || this.applied !== 0;
    if (on === this.blind && document.body.classList.contains('blind') === on) return;
    this.blind = on;
    document.body.classList.toggle('blind', on);
    this.view.blind = on;
    if (this.call.avatar) this.view.ownSettings(this.call.avatar.settings);
    this.view.peerSettings(this.call.peer);
    this.view.selfName(this.view.selfNameText);
    this.view.update();
  }

  /** For `facemimicCall.schedule`: where the schedule is (a blind page: only that it is blind). */
  status() {
    if (!this.runner || (!this.running && (this.peerBlind || this.applied))) return { state: this.blind ? 'blind' : 'none', blind: this.blind, condition: this.applied };
    const s = this.runner.status(performance.now());
    return { state: s.state, blind: this.blind, number: s.number, count: s.count, name: s.condition?.name ?? null, remainingMs: s.remainingMs, elapsedMs: s.elapsedMs, totalMs: s.totalMs, peerCondition: this.peerCondition, values: this.current?.values ?? null };
  }

  // -------------------------------------------------------------------------------------------
  // The experimenter's view

  /** The list of conditions (built on load; marked at each switch) and the buttons. */
  render() {
    const s = this.schedule;
    setText($('schedule-summary'), s ? this.summary() : 'No schedule loaded.');
    const list = $('schedule-list');
    if (list.schedule !== s) {
      list.schedule = s;
      list.replaceChildren(
        ...(s?.conditions ?? []).map((c, i) => {
          const li = document.createElement('li');
          const head = document.createElement('div');
          const b = document.createElement('b');
          b.textContent = c.name || `Condition ${i + 1}`;
          const d = document.createElement('span');
          d.className = 'dur';
          d.textContent = formatClock(c.duration * 1000);
          head.append(b, d);
          const what = document.createElement('div');
          what.className = 'what';
          what.textContent = ['both', 'local', 'remote'].filter((k) => c[k]).map((k) => `${k}: ${describeSide(c[k])}`).join(' · ') || 'the settings before the schedule';
          li.append(head, what);
          return li;
        }),
      );
    }
    const r = this.runner?.schedule === s ? this.runner : null;
    [...list.children].forEach((li, i) => {
      li.classList.toggle('current', Boolean(r) && r.state === 'running' && r.index === i);
      li.classList.toggle('done', Boolean(r) && r.index > i);
    });
    // The current condition in view, scrolling the list only (not the page).
    const li = list.querySelector('.current');
    if (li && li.offsetTop < list.scrollTop) list.scrollTop = li.offsetTop;
    else if (li && li.offsetTop + li.offsetHeight > list.scrollTop + list.clientHeight) list.scrollTop = li.offsetTop + li.offsetHeight - list.clientHeight;
    $('schedule-start').disabled = !s || this.running || this.starting;
    $('schedule-stop').disabled = !this.running;
  }

  /** The running condition, its countdown and progress (4 times a second while running). */
  update() {
    const box = $('schedule-now');
    const r = this.runner;
    box.hidden = !r;
    if (!r) return;
    const s = r.status(performance.now());
    box.dataset.state = s.state;
    const cur = this.current;
    setText($('schedule-cond'), s.state === 'running' ? `Condition ${s.number} of ${s.count}` : s.state === 'ended' ? 'Schedule over' : 'Schedule stopped');
    setText($('schedule-name'), s.state === 'running' ? s.condition.name || '' : `${s.count} condition${s.count === 1 ? '' : 's'} · ${formatClock(s.elapsedMs)} run`);
    setText($('schedule-left'), s.state === 'running' ? formatClock(s.remainingMs) : '–');
    $('schedule-bar').style.width = `${(s.state === 'running' ? s.conditionProgress : 1) * 100}%`;
    $('schedule-total-bar').style.width = `${s.progress * 100}%`;
    setText($('schedule-total'), `${formatClock(s.elapsedMs)} of ${formatClock(s.totalMs)}`);
    const next = s.state === 'running' && s.number < s.count ? r.schedule.conditions[s.number] : null;
    setText($('schedule-next'), s.state !== 'running' ? '' : next ? `Next: ${next.name || `condition ${s.number + 1}`}` : 'Last condition');
    for (const side of ['local', 'remote']) showValues($(`schedule-${side}`), cur?.values[side], cur && { ...cur.set.both, ...cur.set[side] });
    const open = this.call.link?.dc?.readyState === 'open';
    const ok = cur && this.peerCondition === cur.number;
    const state = !cur ? '' : ok ? 'applied' : !open ? 'not connected: sent when it is' : 'not applied yet (does it let the other side set it?)';
    setText($('schedule-remote-state'), state);
    $('schedule-remote-state').dataset.ok = ok ? '1' : '0';
  }
}

// The call page (www/call.html): two people, each seen and heard by the other as the avatar they
// chose. This module wires the page: the models (bundled, and "Your models" from this browser's
// store), the avatar (call-avatar.js: webcam -> tracker -> cloner -> canvas), the signalling
// connection (call-signal.js), the WebRTC link (call-peer.js), the experimenter's controls and
// the status; call-view.js keeps the figures (stats, latency, fps) and the status line;
// call-schedule-ui.js runs the experimenter's condition schedule (both participants blind).
//
// `call.html?room=ID&avatar=NAME&autojoin=1` joins room ID as NAME with no click (no room: a new
// one is made). `window.facemimicCall` is a read-only view of the call (docs/call.md).

import init, * as fm from '../pkg/facemimic.js';
import { notify, message } from './toasts.js';
import { fetchBytes } from './fetch.js';
import { ModelStore } from './store.js';
import { Avatar } from './call-avatar.js';
import { SignalClient, defaultSignalUrl, inviteUrl, randomId } from './call-signal.js';
import { PeerLink, openMicrophone, parseIceServers } from './call-peer.js';
import { parseControl, SETTINGS } from './call-controls.js';
import { CallView, download } from './call-view.js';
import { SchedulePanel } from './call-schedule-ui.js';
import { AvatarSides, defaultAvatars, fillModelMenu } from './call-side.js';

const $ = (id) => document.getElementById(id);
const MODELS = 'models/';
const params = new URLSearchParams(location.search);
const ICE_KEY = 'facemimic-call-ice';

const call = {
  models: new Map(), // key -> { key, name, bytes?, model?, info?, bundled }
  manifest: null,
  avatar: null,
  signal: null,
  link: null,
  room: null,
  joined: false,
  peerPresent: false,
  peerLeft: false,
  manual: false,
  peer: { camera: null, avatar: null, gain: null, head: null, mouth: null, eyes: null, brows: null, style: null, pipelineMs: null, encodeMs: null, at: 0 },
  rejected: 0, // data channel messages refused
  mic: null,
  error: null,
  schedule: null, // the condition schedule (call-schedule-ui.js)
  avatarChosen: false, // this side's avatar was chosen (the address, the menu, the experimenter, a schedule)
  second: null, // this side joined a room the other side was in (or answered by hand); null: not known yet
};

/** A model by key (loaded once). Keys: "b:FILE" bundled, "s:ID" from the store. */
async function modelFor(key) {
  const e = call.models.get(key);
  if (!e) throw new Error(`no model ${key}`);
  if (!e.model) {
    const bytes = e.bytes || (await fetchBytes(MODELS + e.file));
    e.model = fm.Model.fromBytes(bytes);
    e.info = e.model.info();
    e.bytes = null;
  }
  return e;
}

const bundledName = (file) => file.replace(/\.fmm$/i, '');

async function loadModelLists() {
  const r = await fetch(`${MODELS}manifest.json`);
  if (!r.ok) throw new Error(`HTTP ${r.status} for the model list`);
  const m = await r.json();
  call.manifest = m;
  const files = [...new Set([m.source, ...(m.library || []), ...(m.targets || [])])];
  for (const file of files) call.models.set(`b:${file}`, { key: `b:${file}`, file, name: bundledName(file), bundled: true });
  let stored = [];
  try {
    stored = await (await ModelStore.open()).list();
  } catch {
    // no IndexedDB: bundled models only
  }
  for (const rec of stored) {
    if (!(rec.bytes instanceof ArrayBuffer)) continue;
    call.models.set(`s:${rec.id}`, { key: `s:${rec.id}`, name: rec.name || `model ${rec.id}`, bytes: new Uint8Array(rec.bytes), bundled: false });
  }
  const fill = (sel, keys, value) => fillModelMenu(sel, call.models, keys, value);
  const keys = [...call.models.keys()];
  fill($('source-model'), keys, `b:${m.source}`);
  const avatars = keys.filter((k) => k !== `b:${m.source}`);
  const want = params.get('avatar');
  const wantKey = want && `b:${want.replace(/\.fmm$/i, '')}.fmm`;
  if (want && !call.models.has(wantKey)) notify('error', `No bundled avatar named ${want}`, `the avatars are ${bundledAvatarNames().join(', ')}`);
  call.avatarChosen = Boolean(want && call.models.has(wantKey));
  fill($('avatar-model'), avatars, call.avatarChosen ? wantKey : defaultAvatars(call)[0]);
  fill($('peer-avatar'), avatars.filter((k) => k.startsWith('b:')), `b:${(m.targets || [])[0]}`);
}

/** Who takes which default avatar (call-side.js): a default taken is not a choice. */
const sides = new AvatarSides(call, (key) => setAvatarKey(key, { chosen: false }).catch((e) => notify('error', 'Could not use this avatar', message(e))));

/** The bundled avatars' names (what the other side may ask for). */
function bundledAvatarNames() {
  return [...call.models.values()].filter((e) => e.bundled).map((e) => e.name);
}

// ---------------------------------------------------------------------------------------------
// The avatar

async function applyModels() {
  const source = await modelFor($('source-model').value);
  const target = await modelFor($('avatar-model').value);
  call.avatar.setModels(source, target);
  view.selfName(target.name);
}

/** Makes `key` this side's avatar; `chosen`: by someone (the menu, the experimenter, a schedule). */
async function setAvatarKey(key, { chosen = true } = {}) {
  if (chosen) call.avatarChosen = true;
  const target = await modelFor(key);
  $('avatar-model').value = key;
  call.avatar.setTarget(target);
  view.selfName(target.name);
  sendStatus();
}

function setOwnSettings(s) {
  call.avatar.setSettings(s);
  view.ownSettings(call.avatar.settings);
  sendStatus();
}

// ---------------------------------------------------------------------------------------------
// The call

function peerId(room) {
  const k = `facemimic-call-peer:${room}`;
  let id = sessionStorage.getItem(k);
  if (!id) {
    id = randomId(16);
    sessionStorage.setItem(k, id);
  }
  return id;
}

async function getMic() {
  if (call.mic === null) ({ track: call.mic, note: $('mic-note').textContent } = await openMicrophone());
  return call.mic;
}

async function ensureLink() {
  if (call.link) return call.link;
  let iceServers = [];
  try {
    iceServers = parseIceServers(localStorage.getItem(ICE_KEY) || '');
  } catch (e) {
    notify('error', 'The saved ICE servers are not usable', message(e));
  }
  const mic = await getMic();
  const link = new PeerLink({ iceServers, videoTrack: call.videoTrack, audioTrack: mic || null });
  link.addEventListener('signal', (e) => call.signal?.send(e.detail));
  link.addEventListener('state', (e) => onLinkState(e.detail));
  link.addEventListener('remote', () => view.attachRemote(link.remoteStream));
  link.addEventListener('channel', (e) => {
    if (e.detail === 'open') sendStatus();
    view.update();
  });
  link.addEventListener('control', (e) => onControl(e.detail));
  link.addEventListener('error', (e) => view.note(`Connection: ${message(e.detail)}`));
  call.link = link;
  return link;
}

function onLinkState(s) {
  if (s === 'failed' && call.joined && call.peerPresent && call.link?.polite) {
    // The connection broke (a network change): the newcomer offers again.
    setTimeout(() => call.link?.state === 'failed' && call.link.offer(), 1000);
  }
  view.update();
}

async function onSignalMessage(m) {
  const link = await ensureLink();
  switch (m.type) {
    case 'joined':
      call.joined = true;
      call.peerPresent = m.peers === 2;
      sides.take(call.peerPresent);
      link.polite = Boolean(m.polite);
      if (call.peerPresent) {
        call.peerLeft = false;
        // Back after a server restart with the call still up: nothing to negotiate.
        if (link.state !== 'connected') link.offer();
      }
      break;
    case 'peer-joined':
      call.peerPresent = true;
      call.peerLeft = false;
      link.polite = Boolean(m.polite);
      break;
    case 'peer-left':
      call.peerPresent = false;
      call.peerLeft = true;
      link.close();
      Object.assign(call.peer, { camera: null, pipelineMs: null, encodeMs: null, at: 0 });
      view.peerGone();
      break;
    case 'offer':
    case 'answer':
    case 'candidate':
      link.onSignal(m);
      break;
    case 'error':
      if (m.code === 'peer-not-answering') {
        view.note('The other side did not answer; trying again.');
        if (call.peerPresent) setTimeout(() => call.peerPresent && link.state !== 'connected' && link.offer(), 2000);
      }
      break;
    default:
      break;
  }
  view.update();
}

function startSignal() {
  if (call.signal) return call.signal;
  const s = new SignalClient(params.get('signal') || defaultSignalUrl());
  s.addEventListener('message', (e) => onSignalMessage(e.detail));
  s.addEventListener('state', () => view.update());
  s.addEventListener('fail', (e) => {
    call.error = e.detail;
    call.joined = false;
    // Retrying cannot cure this (an unknown or full room): stop, until the user starts again.
    s.stop();
    if (call.signal === s) call.signal = null;
    sessionStorage.removeItem(`facemimic-call-joined:${call.room}`);
    view.update();
    notify('error', 'Could not join the call', message(e.detail));
  });
  s.start();
  call.signal = s;
  return s;
}

async function join(room) {
  if (call.manual) return notify('warning', 'A call without a server is under way', 'reload the page to use a room instead');
  call.error = null;
  const s = startSignal();
  try {
    if (!room) room = await s.create();
    call.room = room;
    view.update();
    await ensureLink();
    await s.join(room, peerId(room));
  } catch (e) {
    call.error = e;
    if (!s.everOpen) {
      // No signalling server where this page comes from (a static host): say what works instead.
      s.stop();
      call.signal = null;
      call.room = null;
      notify('error', 'No signalling server answers here', 'this page may be on a static host: connect with "Without a server" (copy and paste the connection text) instead');
    } else if (!e.code) notify('error', 'Could not join the call', message(e));
    view.update();
    return;
  }
  sessionStorage.setItem(`facemimic-call-joined:${room}`, '1');
  const u = new URL(location.href);
  u.searchParams.set('room', room);
  history.replaceState(null, '', u);
  $('invite').value = inviteUrl(room);
  view.update();
}

function leave() {
  call.link?.sendControl({ t: 'bye' });
  call.signal?.stop();
  call.signal = null;
  call.link?.close();
  if (call.room) sessionStorage.removeItem(`facemimic-call-joined:${call.room}`);
  call.joined = false;
  call.peerPresent = false;
  call.room = null;
  sides.reset();
  const u = new URL(location.href);
  u.searchParams.delete('room');
  u.searchParams.delete('autojoin');
  history.replaceState(null, '', u);
  view.peerGone();
  view.update();
}

// ---------------------------------------------------------------------------------------------
// The data channel: status both ways, and the experimenter's settings

function sendStatus() {
  const a = call.avatar;
  if (!a || !call.link) return;
  call.link.sendControl({
    t: 'status',
    camera: a.camera,
    pipelineMs: a.pipelineMs ?? undefined,
    encodeMs: view.encodeMs ?? undefined,
    avatar: a.target?.name,
    ...a.settings, // gain, head, mouth, eyes, brows, style
    ...call.schedule?.statusFields(), // blind, condition
  });
}

function onControl(data) {
  const { msg, error } = parseControl(data, bundledAvatarNames());
  if (!msg) {
    call.rejected++;
    if (call.rejected === 1 || call.rejected % 100 === 0) view.note(`Ignored ${call.rejected} bad message(s) from the other side (${error}).`);
    return;
  }
  if (msg.t === 'status') {
    Object.assign(call.peer, { camera: msg.camera, avatar: msg.avatar ?? call.peer.avatar, pipelineMs: msg.pipelineMs ?? null, encodeMs: msg.encodeMs ?? null, at: performance.now() });
    for (const k of SETTINGS) call.peer[k] = msg[k] ?? call.peer[k];
    view.peerSettings(call.peer);
    sides.avoid(msg.avatar);
    call.schedule?.onPeerStatus(msg);
  } else if (msg.t === 'set') {
    if (!$('allow-remote').checked) {
      view.note('The other side tried to change your settings (not allowed: see "Let the other side set mine").');
      return;
    }
    call.schedule?.onSet(msg); // a schedule's condition number, for the log
    const s = Object.fromEntries(SETTINGS.filter((k) => msg[k] !== undefined).map((k) => [k, msg[k]]));
    if (Object.keys(s).length) setOwnSettings(s);
    if (msg.avatar !== undefined) setAvatarKey(`b:${msg.avatar}.fmm`).catch((e) => notify('error', 'Could not change the avatar', message(e)));
    if (!call.schedule?.blind) view.note('The other side changed your settings.');
  } else if (msg.t === 'bye') {
    call.peerLeft = true;
  }
  view.update();
}

// ---------------------------------------------------------------------------------------------
// Without a server: copy and paste the connection text

async function manualStep(step) {
  if (call.joined) return notify('warning', 'You are in a room', 'leave it first to connect by hand');
  call.manual = true;
  if (step !== 'accept') sides.take(step === 'answer');
  const link = await ensureLink();
  try {
    if (step === 'offer') $('manual-out').value = await link.offerText();
    else if (step === 'answer') $('manual-out').value = await link.answerText($('manual-in').value);
    else await link.acceptAnswer($('manual-in').value);
    if (step !== 'accept') $('manual-out').select();
  } catch (e) {
    notify('error', 'Connection text', message(e));
  }
  view.update();
}

// ---------------------------------------------------------------------------------------------
// Start-up

let view;

function wire() {
  $('start-call').addEventListener('click', () => join(null));
  $('join-call').addEventListener('click', () => join(params.get('room')));
  $('leave').addEventListener('click', leave);
  $('copy-invite').addEventListener('click', async () => {
    $('invite').select();
    try {
      await navigator.clipboard.writeText($('invite').value);
      notify('info', 'Link copied', 'send it to the other person');
    } catch {
      document.execCommand?.('copy');
    }
  });
  $('source-model').addEventListener('change', () => applyModels().catch((e) => notify('error', 'Could not use this model', message(e))));
  $('avatar-model').addEventListener('change', () => setAvatarKey($('avatar-model').value).catch((e) => notify('error', 'Could not use this avatar', message(e))));
  // Gain, head motion and the region gains: this side's own, and the other side's (the experimenter).
  const setPeer = (patch) => call.link?.sendControl({ t: 'set', ...patch });
  for (const k of SETTINGS) {
    $(k).addEventListener('input', () => setOwnSettings({ [k]: Number($(k).value) }));
    $(`peer-${k}`).addEventListener('input', () => setPeer({ [k]: Number($(`peer-${k}`).value) }));
  }
  $('peer-avatar').addEventListener('change', () => setPeer({ avatar: call.models.get($('peer-avatar').value)?.name }));
  const stamp = () => new Date().toISOString().replace(/[:.]/g, '-');
  $('download-log').addEventListener('click', () => download(`facemimic-call-${stamp()}.csv`, call.avatar.log.toCSV(), 'text/csv'));
  $('make-offer').addEventListener('click', () => manualStep('offer'));
  $('make-answer').addEventListener('click', () => manualStep('answer'));
  $('accept-answer').addEventListener('click', () => manualStep('accept'));
  $('ice').value = localStorage.getItem(ICE_KEY) || '';
  $('save-ice').addEventListener('click', () => {
    try {
      const list = parseIceServers($('ice').value.trim());
      localStorage.setItem(ICE_KEY, list.length ? JSON.stringify(list) : '');
      notify('info', 'Saved', list.length ? `${list.length} ICE server(s), used by the next connection` : 'no ICE server: host candidates only');
    } catch (e) {
      notify('error', 'ICE servers not saved', message(e));
    }
  });
  // Leaving the page: tell the other side at once (the server would notice anyway).
  addEventListener('pagehide', () => {
    call.link?.sendControl({ t: 'bye' });
  });
}

async function main() {
  view = new CallView(call);
  try {
    const out = await init();
    view.memory = out.memory;
  } catch (e) {
    view.fatal('The WebAssembly package could not be loaded.', `Build it with scripts/build-wasm.sh (or run scripts/demo.sh). Details: ${message(e)}`);
    return;
  }
  try {
    await loadModelLists();
  } catch (e) {
    view.fatal('The models could not be loaded.', `Build them with scripts/build-models.sh. Details: ${message(e)}`);
    return;
  }
  const canvas = $('avatar');
  call.avatar = new Avatar({
    fm,
    canvas,
    panelHost: $('tracking-host'),
    bench: params.get('bench') === '1',
    onStatus: () => {
      sendStatus();
      view.update();
    },
  });
  // The only video this page sends: the avatar canvas's.
  const stream = canvas.captureStream();
  call.videoTrack = stream.getVideoTracks()[0];
  call.videoTrack.contentHint = 'motion';
  try {
    await applyModels();
  } catch (e) {
    view.fatal('The models could not be used.', message(e));
    return;
  }
  wire();
  const forceBlind = params.get('blind') === '1';
  call.schedule = new SchedulePanel({ call, view, modelFor, setOwnSettings, setAvatarKey, forceBlind });
  view.start();
  setInterval(sendStatus, 1000);
  const room = params.get('room');
  const rejoin = room && sessionStorage.getItem(`facemimic-call-joined:${room}`) === '1';
  if (params.get('autojoin') === '1' || rejoin) join(room);
  else if (room) $('join-call').hidden = false;
  view.update();
}

main();

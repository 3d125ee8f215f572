// What the call page shows and measures: the status line (honest: connecting, connected, the
// peer's camera lost, the peer left, reconnecting), the remote avatar's video and its figures
// (frames presented per second, capture-to-display latency, the WebRTC statistics), and the
// read-only `window.facemimicCall` (docs/call.md).
//
// Latency of the frames received, by the first of these that is available:
//   "stamp"  bench mode (?bench=1 on the sending page): the sender's camera capture time is
//            drawn into the avatar's bottom-left corner and read back here (one machine: one clock);
//   "rtp"    requestVideoFrameCallback's captureTime of the received frame (the sender's canvas
//            capture, on this clock by RTCP) to its expected display time, plus the sender's own
//            camera-to-canvas time (sent over the data channel);
//   "stats"  the sum of the parts: the sender's camera-to-canvas and encode times, half the
//            round trip, the jitter buffer and the decode time.

import { readStamp, WIDTH, STAMP_BITS, STAMP_BLOCK } from './call-avatar.js';
import { SETTINGS } from './call-controls.js';

const $ = (id) => document.getElementById(id);
const STALE_MS = 2000;

/** Saves `text` as a file named `name` (a download). */
export function download(name, text, type) {
  const url = URL.createObjectURL(new Blob([text], { type }));
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

const median = (a) => {
  if (!a.length) return null;
  const s = [...a].sort((x, y) => x - y);
  return s[s.length >> 1];
};

export class CallView {
  constructor(call) {
    this.call = call;
    this.video = $('remote');
    this.frameTimes = []; // presented remote frames (performance.now), last second
    this.lastFrameAt = 0;
    this.remoteFrames = 0;
    this.latencies = []; // recent per-frame latencies (ms)
    this.latencySource = null;
    this.latencyCount = 0; // frames whose latency was measured, in all
    this.stallMax = 0; // longest gap between two presented frames since connected (ms)
    this.encodeMs = null;
    this.parts = {};
    this.stampCanvas = document.createElement('canvas');
    this.stampCanvas.width = STAMP_BITS * STAMP_BLOCK;
    this.stampCanvas.height = STAMP_BLOCK;
    this.stampCtx = this.stampCanvas.getContext('2d', { willReadFrequently: true });
    this.state = 'loading';
    // While a condition schedule runs (call-schedule-ui.js): `blind` shows no avatar name and no
    // setting's value (a participant's view), `locked` keeps the other side's controls off.
    this.blind = false;
    this.locked = false;
    this.selfNameText = '';
    this.exposeStatus();
  }

  fatal(title, detail) {
    this.state = 'error';
    const s = $('status');
    s.dataset.state = 'error';
    $('status-text').textContent = `${title} ${detail}`;
    document.body.dataset.state = 'error';
  }

  start() {
    this.watchRemote();
    setInterval(() => this.poll(), 1000);
    setInterval(() => this.update(), 500);
  }

  selfName(name) {
    this.selfNameText = name;
    $('self-name').textContent = this.blind ? '' : name;
  }

  note(text) {
    this.lastNote = { text, at: performance.now() };
    this.update();
  }

  attachRemote(stream) {
    if (this.video.srcObject !== stream) this.video.srcObject = stream;
    this.video.muted = false;
    this.video.play().then(
      () => ($('unmute').hidden = true),
      () => {
        // Sound needs a click in this browser: play muted, offer the button.
        this.video.muted = true;
        this.video.play().catch(() => {});
        const b = $('unmute');
        b.hidden = false;
        b.onclick = () => {
          this.video.muted = false;
          this.video.play().catch(() => {});
          b.hidden = true;
        };
      },
    );
    this.watchRemote();
  }

  peerGone() {
    this.frameTimes = [];
    this.latencies = [];
  }

  /** Count presented frames and measure their latency (requestVideoFrameCallback). */
  watchRemote() {
    const v = this.video;
    if (this.watching || typeof v.requestVideoFrameCallback !== 'function') return;
    this.watching = true;
    const cb = (now, meta) => {
      v.requestVideoFrameCallback(cb);
      this.onRemoteFrame(now, meta);
    };
    v.requestVideoFrameCallback(cb);
  }

  onRemoteFrame(now, meta) {
    // A busy main thread may miss callbacks; presentedFrames counts every frame the compositor
    // showed. A gap spanning n frames is counted as n gaps of its mean length.
    const n = meta.presentedFrames;
    const inc = this.lastPresented !== undefined && n > this.lastPresented ? Math.min(n - this.lastPresented, 120) : 1;
    this.lastPresented = n;
    if (this.lastFrameAt && this.call.link?.state === 'connected') this.stallMax = Math.max(this.stallMax, (now - this.lastFrameAt) / inc);
    this.lastFrameAt = now;
    this.remoteFrames += inc;
    for (let i = 0; i < inc; i++) this.frameTimes.push(now);
    while (this.frameTimes.length && now - this.frameTimes[0] > 1000) this.frameTimes.shift();
    const shown = meta.expectedDisplayTime ?? now;
    let lat = null;
    let source = null;
    const stamp = this.readStamp(meta);
    if (stamp !== null) {
      const wall = Math.round(performance.timeOrigin + shown) % 2 ** STAMP_BITS;
      const d = (wall - stamp + 2 ** STAMP_BITS) % 2 ** STAMP_BITS;
      if (d < 5000) {
        lat = d;
        source = 'stamp';
      }
    }
    if (lat === null && typeof meta.captureTime === 'number' && this.call.peer.pipelineMs !== null) {
      const d = shown - meta.captureTime + this.call.peer.pipelineMs;
      if (d > 0 && d < 10000) {
        lat = d;
        source = 'rtp';
        if (typeof meta.receiveTime === 'number') this.parts.receiveToShownMs = shown - meta.receiveTime;
        this.parts.canvasToShownMs = shown - meta.captureTime;
      }
    }
    if (lat !== null) {
      this.latencies.push(lat);
      this.latencyCount++;
      if (this.latencies.length > 60) this.latencies.shift();
      this.latencySource = source;
    }
  }

  /** Bench mode: the stamp in the received frame (null when there is none). */
  readStamp(meta) {
    if (this.stampOff) return null;
    const v = this.video;
    const w = meta.width || v.videoWidth;
    const h = meta.height || v.videoHeight;
    if (!w || !h) return null;
    const k = w / WIDTH;
    const g = this.stampCtx;
    g.drawImage(v, 0, h - STAMP_BLOCK * k, STAMP_BITS * STAMP_BLOCK * k, STAMP_BLOCK * k, 0, 0, this.stampCanvas.width, STAMP_BLOCK);
    const img = g.getImageData(0, 0, this.stampCanvas.width, STAMP_BLOCK);
    // A stamp is pure black / white blocks: a picture without one is not.
    let mid = 0;
    for (let i = 0; i < img.data.length; i += 4) {
      const y = img.data[i];
      if (y > 60 && y < 195) mid++;
    }
    if (mid > img.data.length / 4 / 6) {
      this.noStamp = (this.noStamp || 0) + 1;
      if (this.noStamp > 90 && !this.stampSeen) this.stampOff = true; // not a bench sender: stop looking
      return null;
    }
    this.stampSeen = true;
    return readStamp(img);
  }

  /** WebRTC statistics, once a second. */
  async poll() {
    const link = this.call.link;
    const report = await link?.stats().catch(() => null);
    if (!report) return;
    const p = {};
    report.forEach((s) => {
      if (s.type === 'inbound-rtp' && s.kind === 'video') {
        p.framesReceived = s.framesReceived;
        p.framesDecoded = s.framesDecoded;
        p.framesDropped = s.framesDropped;
        p.receivedFps = s.framesPerSecond;
        p.frameWidth = s.frameWidth;
        p.frameHeight = s.frameHeight;
        if (s.jitterBufferEmittedCount) p.jitterBufferMs = (s.jitterBufferDelay / s.jitterBufferEmittedCount) * 1000;
        if (s.framesDecoded) p.decodeMs = (s.totalDecodeTime / s.framesDecoded) * 1000;
        p.decoder = s.decoderImplementation;
      } else if (s.type === 'inbound-rtp' && s.kind === 'audio') {
        p.audioLevel = s.audioLevel ?? null;
        p.audioEnergy = s.totalAudioEnergy ?? null;
        p.audioSamples = s.totalSamplesReceived ?? null;
      } else if (s.type === 'outbound-rtp' && s.kind === 'video') {
        if (s.framesEncoded) this.encodeMs = (s.totalEncodeTime / s.framesEncoded) * 1000;
        p.framesEncoded = s.framesEncoded;
        p.sentFps = s.framesPerSecond;
        p.encoder = s.encoderImplementation;
        p.qualityLimitation = s.qualityLimitationReason;
      } else if (s.type === 'candidate-pair' && s.nominated && s.state === 'succeeded') {
        if (typeof s.currentRoundTripTime === 'number') p.rttMs = s.currentRoundTripTime * 1000;
      }
    });
    p.encodeMs = this.encodeMs;
    this.parts = { ...this.parts, ...p };
    this.update();
  }

  /** The latency figure (median of the recent frames), or the sum of its parts. */
  get latencyMs() {
    const m = median(this.latencies);
    if (m !== null) return m;
    const q = this.parts;
    const peer = this.call.peer;
    if (this.call.link?.state !== 'connected' || peer.pipelineMs === null || q.decodeMs === undefined) return null;
    this.latencySource = 'stats';
    return peer.pipelineMs + (peer.encodeMs ?? 0) + (q.rttMs ?? 0) / 2 + (q.jitterBufferMs ?? 0) + q.decodeMs;
  }

  get remoteFps() {
    const now = performance.now();
    return now - this.lastFrameAt > 1000 ? 0 : this.frameTimes.length;
  }

  /** The state the status line and `facemimicCall.state` show. */
  computeState() {
    const c = this.call;
    if (this.state === 'error') return 'error';
    const link = c.link?.state ?? 'closed';
    const flowing = link === 'connected' && performance.now() - this.lastFrameAt < STALE_MS;
    const peerCamera = c.peer.camera;
    const fresh = performance.now() - c.peer.at < 5000;
    if (!c.joined && !c.manual) return c.signal?.state === 'reconnecting' ? 'reconnecting' : c.room ? 'connecting' : 'idle';
    if (link === 'connected' && fresh && peerCamera === 'camera-lost') return 'camera-lost';
    if (link === 'connected' && fresh && peerCamera === 'face-lost') return 'face-lost';
    if (flowing) return 'connected';
    if (link === 'connected' && this.remoteFrames > 0) return 'stalled';
    if (link === 'disconnected' || link === 'failed') return 'reconnecting';
    if (c.peerLeft && !c.peerPresent) return 'peer-left';
    if (c.signal && c.signal.state !== 'open' && !c.manual) return 'reconnecting';
    if (c.joined && !c.peerPresent) return 'waiting';
    return 'connecting';
  }

  update() {
    if (this.state === 'error') return;
    const c = this.call;
    const s = this.computeState();
    this.state = s;
    const peerName = c.peer.avatar && !this.blind ? ` (${c.peer.avatar})` : '';
    const signalNote = c.signal && c.signal.state !== 'open' && !c.manual ? ' · the signalling server is away: reconnecting to it' : '';
    const text = {
      idle: 'Not in a call. Start one, or open the link the other side sent you.',
      waiting: 'Waiting for the other side: send them the link.',
      connecting: c.peerPresent || c.manual ? 'Connecting…' : 'Joining the room…',
      connected: `Connected: you see and hear the other side${peerName}.`,
      'camera-lost': `Their camera is lost: their avatar holds its last frame.`,
      'face-lost': `Their face is lost by their tracker: their avatar holds its last frame.`,
      stalled: `Connected, but no picture for ${((performance.now() - this.lastFrameAt) / 1000).toFixed(0)} s: their avatar holds its last frame.`,
      'peer-left': 'The other side left. They can come back with the same link.',
      reconnecting: 'Reconnecting…',
      error: 'Error.',
    }[s];
    const note = this.lastNote && performance.now() - this.lastNote.at < 6000 ? ` ${this.lastNote.text}` : '';
    const full = `${text}${signalNote}${note}`;
    if ($('status-text').textContent !== full) $('status-text').textContent = full;
    $('status').dataset.state = s;
    document.body.dataset.callState = s;
    // The remote view: empty until there is a picture; marked when it holds.
    const holding = ['camera-lost', 'face-lost', 'stalled', 'peer-left'].includes(s) && this.remoteFrames > 0;
    $('remote-empty').hidden = this.remoteFrames > 0 && s !== 'idle' && s !== 'waiting';
    if (!$('remote-empty').hidden) $('remote-empty-text').textContent = s === 'waiting' ? 'Waiting for the other side…' : s === 'idle' ? 'Nobody is here yet.' : text;
    const badge = $('remote-badge');
    badge.hidden = !holding;
    badge.textContent = s === 'peer-left' ? 'left · last frame' : s === 'stalled' ? 'no picture · last frame' : `${s === 'face-lost' ? 'face' : 'camera'} lost · last frame`;
    $('remote-card').classList.toggle('holding', holding);
    $('remote-name').textContent = this.blind ? '' : c.peer.avatar || '–';
    const self = this.blind ? '' : this.selfNameText;
    if ($('self-name').textContent !== self) $('self-name').textContent = self;
    // The room panel.
    $('room-idle').hidden = Boolean(c.room) && c.joined;
    $('room-active').hidden = !(c.room && c.joined);
    for (const id of ['peer-avatar', ...SETTINGS.map((k) => `peer-${k}`)]) $(id).disabled = c.link?.dc?.readyState !== 'open' || this.locked;
    // Figures.
    const fps = this.remoteFps;
    const lat = this.latencyMs;
    $('ro-fps').textContent = c.link?.state === 'connected' ? String(fps) : '–';
    $('ro-latency').textContent = lat === null ? '–' : `${Math.round(lat)} ms`;
    $('ro-latency').parentElement.title = `Capture of their camera frame to its avatar shown here (${this.latencySource || 'not measured yet'})`;
    $('ro-rtt').textContent = this.parts.rttMs === undefined ? '–' : `${this.parts.rttMs.toFixed(0)} ms`;
    $('ro-sent').textContent = String(c.avatar ? c.avatar.fpsNow() : 0);
    $('log-count').textContent = `${c.avatar?.log?.length ?? 0} frames`;
    this.netStats();
  }

  netStats() {
    const q = this.parts;
    const rows = [
      ['received', q.frameWidth ? `${q.frameWidth}×${q.frameHeight}, ${q.receivedFps ?? 0} fps` : '–'],
      ['decode', q.decodeMs === undefined ? '–' : `${q.decodeMs.toFixed(1)} ms (${q.decoder || '?'})`],
      ['jitter buffer', q.jitterBufferMs === undefined ? '–' : `${q.jitterBufferMs.toFixed(0)} ms`],
      ['encode (yours)', this.encodeMs === null ? '–' : `${this.encodeMs.toFixed(1)} ms (${q.encoder || '?'})`],
      ['their pipeline', this.call.peer.pipelineMs === null ? '–' : `${this.call.peer.pipelineMs.toFixed(0)} ms camera to canvas`],
    ];
    const dl = $('net-stats');
    const key = JSON.stringify(rows);
    if (dl.dataset.key === key) return;
    dl.dataset.key = key;
    dl.replaceChildren(
      ...rows.flatMap(([k, v]) => {
        const dt = document.createElement('dt');
        dt.textContent = k;
        const dd = document.createElement('dd');
        dd.textContent = v;
        return [dt, dd];
      }),
    );
  }

  /** This side's settings (gain, head motion, region gains) on its sliders. */
  ownSettings(s) {
    for (const k of SETTINGS) {
      $(k).value = String(s[k]);
      $(`${k}-out`).textContent = this.blind ? '–' : s[k].toFixed(2);
    }
  }

  /** The other side's settings, as their status reports them, on the experimenter's sliders. */
  peerSettings(p) {
    const set = (id, v) => {
      if (v === null || v === undefined) return;
      if (document.activeElement !== $(id)) $(id).value = String(v);
      $(`${id}-out`).textContent = this.blind ? '–' : Number(v).toFixed(2);
    };
    for (const k of SETTINGS) set(`peer-${k}`, p[k]);
    if (p.avatar && document.activeElement !== $('peer-avatar')) {
      const key = `b:${p.avatar}.fmm`;
      if ([...$('peer-avatar').options].some((o) => o.value === key)) $('peer-avatar').value = key;
    }
  }

  /** `window.facemimicCall`: read-only getters (assignments are ignored, or throw in strict code). */
  exposeStatus() {
    const v = this;
    const c = this.call;
    const status = {};
    const getters = {
      state: () => v.state,
      inviteUrl: () => (c.room ? $('invite').value || null : null),
      room: () => c.room,
      remoteFps: () => v.remoteFps,
      sentVideo: () => {
        const tracks = c.link?.sentVideoTracks() ?? [];
        if (!tracks.length) return 'none';
        return tracks.length === 1 && tracks[0] === c.videoTrack && c.videoTrack.canvas === $('avatar') ? 'canvas' : 'other';
      },
      latencyMs: () => v.latencyMs,
      latencySource: () => v.latencySource,
      latencyCount: () => v.latencyCount,
      recentLatencies: () => [...v.latencies],
      breakdown: () => ({ peerPipelineMs: c.peer.pipelineMs, peerEncodeMs: c.peer.encodeMs, ...v.parts }),
      signal: () => c.signal?.state ?? 'closed',
      signalReconnects: () => c.signal?.reconnects ?? 0,
      signalDelays: () => [...(c.signal?.delays ?? [])],
      connection: () => c.link?.state ?? 'closed',
      negotiations: () => c.link?.negotiations ?? 0,
      remoteFrames: () => v.remoteFrames,
      longestStallMs: () => v.stallMax,
      peer: () => ({ ...c.peer }),
      avatar: () => c.avatar?.target?.name ?? null,
      method: () => c.avatar?.method ?? null,
      settings: () => ({ ...(c.avatar?.settings ?? {}) }),
      camera: () => c.avatar?.camera ?? null,
      framesSent: () => c.avatar?.frames ?? 0,
      fits: () => ({ fits: c.avatar?.fits ?? 0, lost: c.avatar?.lost ?? 0 }),
      drawGaps: () => (c.avatar?.drawGaps ?? []).map((g) => ({ ...g })),
      logRows: () => c.avatar?.log?.length ?? 0,
      schedule: () => c.schedule?.status() ?? null,
      switches: () => (c.avatar?.log?.events ?? []).map((e) => ({ ...e, local: e.local && { ...e.local }, remote: e.remote && { ...e.remote } })),
      rejectedMessages: () => c.rejected,
      audio: () => ({ sending: Boolean(c.mic), level: v.parts.audioLevel ?? null, energy: v.parts.audioEnergy ?? null, samples: v.parts.audioSamples ?? null }),
      wasmBytes: () => v.wasmBytes(),
    };
    for (const [k, get] of Object.entries(getters)) Object.defineProperty(status, k, { get, enumerable: true });
    Object.freeze(status);
    Object.defineProperty(window, 'facemimicCall', { value: status, writable: false, configurable: false, enumerable: true });
  }

  wasmBytes() {
    return this.memory ? this.memory.buffer.byteLength : null;
  }
}

// The WebRTC link between the two pages: one RTCPeerConnection sending the avatar canvas's track
// and the microphone, receiving the other side's, and a data channel ("control", negotiated, id
// 0) for the experimenter's settings and each side's status. The connection text (SDP offer,
// answer, ICE candidates) goes through the signalling server, or, without a server, is copied and
// pasted by hand (`offerText` / `answerText` / `acceptAnswer`: the whole description with its
// candidates, gathered first).
//
// No STUN or TURN server is contacted unless configured (`iceServers`): host candidates serve a
// LAN and one machine.
//
// Events: "signal" (detail: a message for the server: offer / answer / candidate), "state"
// (detail: connectionState), "remote" (the remote stream has a new track), "control" (detail: the
// raw data channel text, for the page to check), "channel" (detail: "open" | "closed").

const TEXT_PREFIX = 'facemimic-call-1:';
const GATHER_MS = 5000;

/** Parse an ICE server list (JSON: [{urls, username?, credential?}]); throws with the reason. */
export function parseIceServers(text) {
  if (!text) return [];
  let v;
  try {
    v = JSON.parse(text);
  } catch {
    throw new Error('the ICE servers are not JSON (a list like [{"urls": "stun:host:3478"}])');
  }
  if (!Array.isArray(v)) throw new Error('the ICE servers must be a JSON list');
  return v.map((s, i) => {
    const urls = typeof s?.urls === 'string' ? [s.urls] : s?.urls;
    if (!Array.isArray(urls) || !urls.length || !urls.every((u) => typeof u === 'string' && /^(stuns?|turns?):/.test(u))) {
      throw new Error(`ICE server ${i + 1} needs urls starting with stun:, stuns:, turn: or turns:`);
    }
    const out = { urls };
    if (typeof s.username === 'string') out.username = s.username;
    if (typeof s.credential === 'string') out.credential = s.credential;
    return out;
  });
}

/** The microphone (echo cancellation, noise suppression): `{ track, note }`, the track `false`
 *  when there is none or it is refused; `note` says so for the page. */
export async function openMicrophone() {
  try {
    const s = await navigator.mediaDevices.getUserMedia({ audio: { echoCancellation: true, noiseSuppression: true }, video: false });
    const track = s.getAudioTracks()[0] || false;
    return { track, note: track ? `Microphone: ${track.label || 'on'} (sent to the other side only).` : 'Microphone: none.' };
  } catch (e) {
    const why = e?.name === 'NotAllowedError' ? 'permission refused' : e?.message || String(e);
    return { track: false, note: `Microphone: not available (${why}); they see you but cannot hear you.` };
  }
}

/** A description as connection text to copy. */
export function encodeDescription(desc) {
  return TEXT_PREFIX + btoa(unescape(encodeURIComponent(JSON.stringify({ type: desc.type, sdp: desc.sdp }))));
}

/** Connection text pasted by the user -> { type, sdp }; throws an Error saying what is wrong. */
export function decodeDescription(text, want) {
  const t = String(text || '').replace(/\s+/g, '');
  if (!t) throw new Error('paste the connection text from the other side first');
  if (!t.startsWith(TEXT_PREFIX)) throw new Error('this is not facemimic connection text (it starts with "facemimic-call-1:")');
  let d;
  try {
    d = JSON.parse(decodeURIComponent(escape(atob(t.slice(TEXT_PREFIX.length)))));
  } catch {
    throw new Error('the connection text is damaged (copy all of it)');
  }
  if (!d || (d.type !== 'offer' && d.type !== 'answer') || typeof d.sdp !== 'string' || !d.sdp.startsWith('v=')) {
    throw new Error('the connection text holds no offer or answer');
  }
  if (want && d.type !== want) throw new Error(`this is an ${d.type}; an ${want} is expected here`);
  return d;
}

export class PeerLink extends EventTarget {
  constructor({ iceServers = [], videoTrack, audioTrack = null }) {
    super();
    this.iceServers = iceServers;
    this.videoTrack = videoTrack;
    this.audioTrack = audioTrack;
    this.pc = null;
    this.dc = null;
    this.remoteStream = new MediaStream();
    this.polite = false;
    this.negotiations = 0; // offers and answers made (a switch of avatar makes none)
    this.queue = Promise.resolve();
    this.pendingCandidates = [];
  }

  emit(type, detail) {
    this.dispatchEvent(new CustomEvent(type, { detail }));
  }

  get state() {
    return this.pc ? this.pc.connectionState : 'closed';
  }

  /** A fresh connection (the old one closed). */
  fresh() {
    this.close();
    const pc = new RTCPeerConnection({ iceServers: this.iceServers });
    this.pc = pc;
    const local = new MediaStream([this.videoTrack, ...(this.audioTrack ? [this.audioTrack] : [])]);
    this.videoSender = pc.addTrack(this.videoTrack, local);
    if (this.audioTrack) pc.addTrack(this.audioTrack, local);
    else pc.addTransceiver('audio', { direction: 'recvonly' });
    this.remoteStream = new MediaStream();
    pc.ontrack = (e) => {
      if (pc !== this.pc) return;
      for (const t of this.remoteStream.getTracks()) if (t.kind === e.track.kind) this.remoteStream.removeTrack(t);
      this.remoteStream.addTrack(e.track);
      this.emit('remote', e.track);
    };
    pc.onicecandidate = (e) => {
      if (pc !== this.pc || this.manual) return;
      this.emit('signal', { type: 'candidate', candidate: e.candidate ? e.candidate.toJSON() : null });
    };
    pc.onconnectionstatechange = () => {
      if (pc === this.pc) this.emit('state', pc.connectionState);
    };
    const dc = pc.createDataChannel('control', { negotiated: true, id: 0 });
    this.dc = dc;
    dc.onopen = () => dc === this.dc && this.emit('channel', 'open');
    dc.onclose = () => dc === this.dc && this.emit('channel', 'closed');
    dc.onmessage = (e) => {
      if (dc === this.dc) this.emit('control', e.data);
    };
    this.pendingCandidates = [];
    this.emit('state', pc.connectionState);
    return pc;
  }

  /** Run signalling steps one after another (candidates wait for their description). */
  serial(fn) {
    this.queue = this.queue.then(fn).catch((e) => this.emit('error', e));
    return this.queue;
  }

  /** Make an offer (a new connection) and send it through the server. */
  offer() {
    return this.serial(async () => {
      this.manual = false;
      const pc = this.fresh();
      await pc.setLocalDescription(await pc.createOffer());
      this.negotiations++;
      this.emit('signal', { type: 'offer', sdp: pc.localDescription.sdp });
    });
  }

  /** A message from the other side, through the server: offer, answer or candidate. */
  onSignal(m) {
    return this.serial(async () => {
      this.manual = false;
      if (m.type === 'offer') {
        // Both offered at once: the impolite side keeps its own offer.
        if (this.pc && this.pc.signalingState === 'have-local-offer' && !this.polite) return;
        const pc = this.fresh();
        await pc.setRemoteDescription({ type: 'offer', sdp: m.sdp });
        await this.flushCandidates();
        await pc.setLocalDescription(await pc.createAnswer());
        this.negotiations++;
        this.emit('signal', { type: 'answer', sdp: pc.localDescription.sdp });
      } else if (m.type === 'answer') {
        if (!this.pc || this.pc.signalingState !== 'have-local-offer') return;
        await this.pc.setRemoteDescription({ type: 'answer', sdp: m.sdp });
        await this.flushCandidates();
      } else if (m.type === 'candidate') {
        if (!this.pc) return;
        if (!this.pc.remoteDescription) this.pendingCandidates.push(m.candidate);
        else await this.addCandidate(m.candidate);
      }
    });
  }

  async addCandidate(c) {
    try {
      await this.pc.addIceCandidate(c === null ? null : c);
    } catch (e) {
      this.emit('error', new Error(`a connection candidate from the other side was refused: ${e.message}`));
    }
  }

  async flushCandidates() {
    const list = this.pendingCandidates.splice(0);
    for (const c of list) await this.addCandidate(c);
  }

  async gathered(pc) {
    if (pc.iceGatheringState === 'complete') return;
    await new Promise((resolve) => {
      const timer = setTimeout(resolve, GATHER_MS);
      pc.addEventListener('icegatheringstatechange', () => {
        if (pc.iceGatheringState === 'complete') {
          clearTimeout(timer);
          resolve();
        }
      });
    });
  }

  /** Without a server: the offer, with its candidates, as text to copy. */
  async offerText() {
    return this.manualText(null);
  }

  /** Without a server: the other side's offer text -> our answer text. */
  async answerText(text) {
    return this.manualText(decodeDescription(text, 'offer'));
  }

  /** A fresh connection's offer (or, given the other side's offer `offer`, its answer), with
   *  its candidates, as text. */
  async manualText(offer) {
    this.manual = true;
    const pc = this.fresh();
    if (offer) await pc.setRemoteDescription(offer);
    await pc.setLocalDescription(await (offer ? pc.createAnswer() : pc.createOffer()));
    await this.gathered(pc);
    this.negotiations++;
    return encodeDescription(pc.localDescription);
  }

  /** Without a server: the other side's answer text completes our offer. */
  async acceptAnswer(text) {
    const d = decodeDescription(text, 'answer');
    if (!this.pc || this.pc.signalingState !== 'have-local-offer') throw new Error('make an offer first (the answer belongs to an offer)');
    await this.pc.setRemoteDescription(d);
  }

  sendControl(obj) {
    if (this.dc?.readyState !== 'open') return false;
    this.dc.send(JSON.stringify(obj));
    return true;
  }

  /** The video tracks this page sends (the privacy check: only the avatar canvas's). */
  sentVideoTracks() {
    if (!this.pc) return [];
    return this.pc.getSenders().map((s) => s.track).filter((t) => t && t.kind === 'video');
  }

  async stats() {
    return this.pc ? this.pc.getStats() : null;
  }

  close() {
    const pc = this.pc;
    this.pc = null;
    this.dc = null;
    if (pc) {
      pc.ontrack = pc.onicecandidate = pc.onconnectionstatechange = null;
      pc.close();
      this.emit('state', 'closed');
    }
  }
}

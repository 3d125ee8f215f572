// The call page's link to the signalling server (scripts/signal.mjs): one WebSocket, opened again
// with exponential back-off (0.5 s doubling to 15 s, with jitter) whenever it closes, and the
// room joined again on every reconnection, so a restart of the server costs the call nothing (the
// media flows between the browsers, not through the server). An application ping every 10 s
// finds a half-open connection (a browser sees no WebSocket ping frames).
//
// Events (an EventTarget): "state" (detail: "connecting" | "open" | "reconnecting" | "closed"),
// "message" (detail: a server message object), "fail" (detail: Error) for refusals that retrying
// will not cure (an unknown room, a full room).

const BACKOFF_MIN = 500;
const BACKOFF_MAX = 15000;
const PING_MS = 10000;
const PONG_WAIT = 5000;

/** The signalling endpoint of the server that served this page. */
export function defaultSignalUrl(loc = location) {
  return `${loc.protocol === 'https:' ? 'wss:' : 'ws:'}//${loc.host}/signal`;
}

/** The link for the other side: this page with only `?room=ID`. */
export function inviteUrl(room, loc = location) {
  const u = new URL(loc.href);
  u.search = '';
  u.hash = '';
  u.searchParams.set('room', room);
  return u.href;
}

/** A random id of `bytes` bytes, base64url. */
export function randomId(bytes = 16) {
  const b = crypto.getRandomValues(new Uint8Array(bytes));
  return btoa(String.fromCharCode(...b)).replace(/\+/g, '-').replace(/\//g, '_').replace(/=+$/, '');
}

export class SignalClient extends EventTarget {
  constructor(url) {
    super();
    this.url = url;
    this.ws = null;
    this.state = 'closed';
    this.room = null;
    this.peer = null;
    this.attempt = 0;
    this.reconnects = 0; // connections opened again after a loss
    this.delays = []; // the back-off delays waited (ms), latest last
    this.stopped = true;
    this.waiters = [];
  }

  setState(s) {
    if (this.state === s) return;
    this.state = s;
    this.dispatchEvent(new CustomEvent('state', { detail: s }));
  }

  /** Open (and keep open) the connection. */
  start() {
    if (!this.stopped) return;
    this.stopped = false;
    this.open();
  }

  open() {
    clearTimeout(this.retryTimer);
    this.setState(this.attempt ? 'reconnecting' : 'connecting');
    let ws;
    try {
      ws = new WebSocket(this.url);
    } catch (e) {
      this.dispatchEvent(new CustomEvent('fail', { detail: new Error(`the signalling address is not usable: ${e.message}`) }));
      this.stopped = true;
      this.setState('closed');
      return;
    }
    this.ws = ws;
    ws.onopen = () => {
      this.everOpen = true;
      if (this.attempt) this.reconnects++;
      this.attempt = 0;
      this.setState('open');
      if (this.room) this.send({ type: 'join', room: this.room, peer: this.peer });
      this.ping();
    };
    ws.onmessage = (e) => {
      let m;
      try {
        m = JSON.parse(e.data);
      } catch {
        return; // the server sends JSON; anything else is ignored
      }
      if (!m || typeof m !== 'object' || typeof m.type !== 'string') return;
      if (m.type === 'pong') {
        clearTimeout(this.pongTimer);
        return;
      }
      const i = this.waiters.findIndex((w) => w.type === m.type || (m.type === 'error' && w.errors));
      if (i >= 0) {
        const w = this.waiters.splice(i, 1)[0];
        if (m.type === 'error') w.reject(Object.assign(new Error(m.message || m.code), { code: m.code }));
        else w.resolve(m);
      }
      if (m.type === 'error' && ['unknown-room', 'bad-room', 'room-full', 'replaced'].includes(m.code)) {
        this.room = null;
        this.dispatchEvent(new CustomEvent('fail', { detail: Object.assign(new Error(m.message || m.code), { code: m.code }) }));
      }
      this.dispatchEvent(new CustomEvent('message', { detail: m }));
    };
    ws.onclose = () => {
      if (this.ws !== ws) return;
      this.ws = null;
      clearTimeout(this.pingTimer);
      clearTimeout(this.pongTimer);
      for (const w of this.waiters.splice(0)) w.reject(new Error('the signalling connection closed'));
      if (this.stopped) {
        this.setState('closed');
        return;
      }
      const base = Math.min(BACKOFF_MAX, BACKOFF_MIN * 2 ** this.attempt);
      const delay = Math.round(base * (0.75 + Math.random() * 0.5));
      this.attempt++;
      this.delays.push(delay);
      if (this.delays.length > 20) this.delays.shift();
      this.setState('reconnecting');
      this.retryTimer = setTimeout(() => this.open(), delay);
    };
  }

  ping() {
    clearTimeout(this.pingTimer);
    this.pingTimer = setTimeout(() => {
      if (this.state !== 'open') return;
      this.send({ type: 'ping' });
      this.pongTimer = setTimeout(() => this.ws?.close(), PONG_WAIT);
      this.ping();
    }, PING_MS);
  }

  send(msg) {
    if (this.ws?.readyState !== 1) return false;
    this.ws.send(JSON.stringify(msg));
    return true;
  }

  /** Wait for the connection to open (or time out). */
  async ready(ms = 10000) {
    if (this.state === 'open') return;
    await new Promise((resolve, reject) => {
      const timer = setTimeout(() => {
        this.removeEventListener('state', on);
        reject(new Error('the signalling server does not answer'));
      }, ms);
      const on = (e) => {
        const never = e.detail === 'reconnecting' && !this.everOpen;
        if (e.detail !== 'open' && !never) return;
        clearTimeout(timer);
        this.removeEventListener('state', on);
        if (never) reject(new Error('the signalling server does not answer'));
        else resolve();
      };
      this.addEventListener('state', on);
    });
  }

  request(msg, type) {
    return new Promise((resolve, reject) => {
      this.waiters.push({ type, errors: true, resolve, reject });
      if (!this.send(msg)) {
        this.waiters.pop();
        reject(new Error('the signalling server is not connected'));
      }
    });
  }

  /** A new room (its id issued by the server). */
  async create() {
    await this.ready();
    return (await this.request({ type: 'create' }, 'created')).room;
  }

  /** Join `room` as `peer` (and again after every reconnection). Resolves to the `joined` message. */
  async join(room, peer) {
    await this.ready();
    const joined = await this.request({ type: 'join', room, peer }, 'joined');
    this.room = room;
    this.peer = peer;
    return joined;
  }

  leave() {
    if (this.room) this.send({ type: 'leave' });
    this.room = null;
  }

  stop() {
    this.stopped = true;
    clearTimeout(this.retryTimer);
    this.leave();
    this.ws?.close();
  }
}

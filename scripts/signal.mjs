// The call page's signalling server (www/call.html, docs/call.md): a WebSocket endpoint that
// pairs two browsers in a room and relays their connection text (SDP offer / answer and ICE
// candidates). Media never passes through it: the browsers connect to each other (WebRTC).
//
// Rooms of two. A room id is issued by this server (`create`): 16 random bytes and an 8-byte
// HMAC-SHA256 tag under the server's secret, base64url (32 characters, 128 random bits). A
// `join` with an id this server did not issue (a guess, a typo, another server's) is answered
// with `unknown-room`; an issued id stays valid across restarts of the server, since the secret
// is kept in a file (FACEMIMIC_SIGNAL_SECRET_FILE, by default in the temporary folder, mode
// 0600): so a server restart, like a reload of either page, ends with both sides back in their
// room. A peer names itself with a random id of its own (kept by the page for the tab's life), so
// a reloaded page takes its own place back instead of being a third peer.
//
// Protocol (JSON text messages, at most 64 KB each; docs/call.md lists them):
//   -> {type:"create"}                      <- {type:"created", room}
//   -> {type:"join", room, peer}            <- {type:"joined", room, peers, polite}
//                                              (the other side: {type:"peer-joined", polite})
//   -> {type:"offer"|"answer", sdp}         relayed to the other peer as {type, sdp}
//   -> {type:"candidate", candidate}        relayed as {type, candidate}
//   -> {type:"leave"}                       the other side: {type:"peer-left"}
//   -> {type:"ping"}                        <- {type:"pong"}
//   <- {type:"error", code, message}        for anything refused; the connection stays open
//                                           except after too many errors or messages
// Hostile input: malformed JSON, binary frames, unknown types and bad fields get an error; a
// message over 64 KB closes the connection (1009); a third peer gets `room-full`; too many
// connections (in all, or from one address) are refused at the upgrade with HTTP 503 / 429 and
// a JSON body; a connection that joins no room in time, a socket that answers no ping, and an
// offer the other peer never answers are timed out. Nothing one connection does reaches a room
// it is not in.

import { WebSocketServer } from 'ws';
import { createHmac, randomBytes, timingSafeEqual } from 'node:crypto';
import { existsSync, readFileSync, writeFileSync } from 'node:fs';
import { tmpdir, userInfo } from 'node:os';
import { join } from 'node:path';

export const MAX_MESSAGE = 64 * 1024;
export const ROOM_RE = /^[A-Za-z0-9_-]{32}$/;
export const PEER_RE = /^[A-Za-z0-9_-]{16,64}$/;

export const DEFAULTS = {
  path: '/signal',
  maxConnections: 256,
  maxPerIp: 32,
  heartbeatMs: 15000, // a socket that answers no ping for two intervals is closed
  joinTimeoutMs: 30000, // a connection must join (or create) a room by then
  answerTimeoutMs: 20000, // an offer unanswered by then is reported to its sender
  maxErrors: 20, // errors answered before the connection is closed
  ratePerSec: 100, // messages a second (bucket of twice that)
};

const CLOSE_POLICY = 1008;

function secretFrom(env) {
  if (env.FACEMIMIC_SIGNAL_SECRET) return Buffer.from(env.FACEMIMIC_SIGNAL_SECRET, 'utf8');
  let user = 'user';
  try {
    user = String(userInfo().uid);
  } catch {
    // no user information: one file for all
  }
  const file = env.FACEMIMIC_SIGNAL_SECRET_FILE || join(tmpdir(), `facemimic-signal-secret-${user}`);
  if (existsSync(file)) {
    const s = readFileSync(file);
    if (s.length >= 32) return s;
  }
  const s = randomBytes(32);
  writeFileSync(file, s, { mode: 0o600 });
  return s;
}

/** The room-id scheme: ids issued under `secret`, and the check that one was. */
export function roomIds(secret) {
  const tag = (rand) => createHmac('sha256', secret).update(rand).digest().subarray(0, 8);
  return {
    issue() {
      const rand = randomBytes(16);
      return Buffer.concat([rand, tag(rand)]).toString('base64url');
    },
    valid(id) {
      if (typeof id !== 'string' || !ROOM_RE.test(id)) return false;
      const b = Buffer.from(id, 'base64url');
      if (b.length !== 24) return false;
      return timingSafeEqual(b.subarray(16), tag(b.subarray(0, 16)));
    },
  };
}

/**
 * Attach the signalling endpoint to an `http.Server`. Options: DEFAULTS, plus `env` (for the
 * secret) and `log` (a function, or null). Returns `{ stats(), close() }`.
 */
export function attachSignalling(server, options = {}) {
  const o = { ...DEFAULTS, ...options };
  const log = o.log === undefined ? (m) => console.log(`signal: ${m}`) : o.log || (() => {});
  const ids = roomIds(o.secret || secretFrom(o.env || process.env));
  const wss = new WebSocketServer({ noServer: true, maxPayload: MAX_MESSAGE, clientTracking: false });
  const sockets = new Set();
  const perIp = new Map();
  const rooms = new Map(); // id -> { peers: Map(peerId -> ws), offer: { from, timer } | null }
  let refused = 0;

  const refuse = (socket, status, code, message) => {
    refused++;
    const body = JSON.stringify({ type: 'error', code, message });
    try {
      socket.end(
        `HTTP/1.1 ${status}\r\nContent-Type: application/json\r\nContent-Length: ${Buffer.byteLength(body)}\r\nConnection: close\r\n\r\n${body}`,
      );
    } catch {
      socket.destroy();
    }
  };

  const onUpgrade = (req, socket, head) => {
    let url;
    try {
      url = new URL(req.url, 'http://x');
    } catch {
      return refuse(socket, '400 Bad Request', 'bad-request', 'bad request line');
    }
    if (url.pathname !== o.path) return refuse(socket, '404 Not Found', 'not-found', `no WebSocket endpoint at ${url.pathname}`);
    // A page of another site may not use this server (the browser sends its Origin).
    const origin = req.headers.origin;
    if (origin) {
      let host = '';
      try {
        host = new URL(origin).host;
      } catch {
        // unparseable: refused below
      }
      if (host !== req.headers.host) return refuse(socket, '403 Forbidden', 'bad-origin', 'a page of another origin may not use this signalling server');
    }
    const ip = req.socket.remoteAddress || '?';
    if (sockets.size >= o.maxConnections) return refuse(socket, '503 Service Unavailable', 'too-many-connections', 'the server has too many connections; try again later');
    if ((perIp.get(ip) || 0) >= o.maxPerIp) return refuse(socket, '429 Too Many Requests', 'too-many-connections', 'too many connections from this address');
    socket.on('error', () => socket.destroy());
    wss.handleUpgrade(req, socket, head, (ws) => welcome(ws, ip));
  };
  server.on('upgrade', onUpgrade);

  function send(ws, msg) {
    if (ws.readyState === 1) ws.send(JSON.stringify(msg));
  }

  function error(ws, code, message) {
    send(ws, { type: 'error', code, message });
    ws.errors++;
    if (ws.errors > o.maxErrors) ws.close(CLOSE_POLICY, 'too many errors');
  }

  function welcome(ws, ip) {
    sockets.add(ws);
    perIp.set(ip, (perIp.get(ip) || 0) + 1);
    Object.assign(ws, { ip, alive: true, errors: 0, room: null, peer: null, tokens: o.ratePerSec * 2, refill: Date.now() });
    ws.joinTimer = setTimeout(() => {
      if (ws.room) return;
      error(ws, 'join-timeout', 'no room was joined in time');
      ws.close(CLOSE_POLICY, 'join timeout');
    }, o.joinTimeoutMs);
    ws.on('pong', () => {
      ws.alive = true;
    });
    ws.on('message', (data, isBinary) => {
      try {
        onMessage(ws, data, isBinary);
      } catch (e) {
        // A bug here must cost this message only, never the server.
        log(`error handling a message: ${e && e.stack ? e.stack : e}`);
        error(ws, 'internal', 'the server could not handle this message');
      }
    });
    ws.on('error', () => {}); // e.g. a message over maxPayload: ws closes with 1009
    ws.on('close', () => {
      clearTimeout(ws.joinTimer);
      sockets.delete(ws);
      const n = (perIp.get(ip) || 1) - 1;
      if (n > 0) perIp.set(ip, n);
      else perIp.delete(ip);
      leave(ws);
    });
  }

  function other(room, ws) {
    for (const p of room.peers.values()) if (p !== ws) return p;
    return null;
  }

  function clearOffer(room) {
    if (room.offer) clearTimeout(room.offer.timer);
    room.offer = null;
  }

  function leave(ws) {
    const id = ws.room;
    if (!id) return;
    ws.room = null;
    const room = rooms.get(id);
    if (!room || room.peers.get(ws.peer) !== ws) return;
    room.peers.delete(ws.peer);
    clearOffer(room);
    const p = other(room, ws);
    if (p) send(p, { type: 'peer-left' });
    if (room.peers.size === 0) rooms.delete(id);
  }

  function join(ws, msg) {
    if (!ids.valid(msg.room)) {
      return error(ws, typeof msg.room === 'string' && ROOM_RE.test(msg.room) ? 'unknown-room' : 'bad-room', 'this room does not exist on this server (ask the other side for a new link)');
    }
    if (typeof msg.peer !== 'string' || !PEER_RE.test(msg.peer)) return error(ws, 'bad-field', 'join needs a peer id (16-64 base64url characters)');
    if (ws.room) {
      if (ws.room === msg.room && ws.peer === msg.peer) return error(ws, 'already-joined', 'already in this room');
      leave(ws);
    }
    let room = rooms.get(msg.room);
    if (!room) {
      room = { peers: new Map(), offer: null };
      rooms.set(msg.room, room);
    }
    const stale = room.peers.get(msg.peer);
    if (!stale && room.peers.size >= 2) return error(ws, 'room-full', 'this room already has two people in it');
    if (stale) {
      // The same page again (a reload, or a new socket after a network drop): it takes its place.
      stale.room = null;
      room.peers.delete(msg.peer);
      clearOffer(room);
      send(stale, { type: 'error', code: 'replaced', message: 'this page joined again from another connection' });
      stale.close(1000, 'replaced');
    }
    clearTimeout(ws.joinTimer);
    ws.room = msg.room;
    ws.peer = msg.peer;
    room.peers.set(msg.peer, ws);
    const p = other(room, ws);
    // The newcomer makes the offer; the one already there is the "impolite" side of a glare.
    send(ws, { type: 'joined', room: msg.room, peers: room.peers.size, polite: Boolean(p) });
    if (p) send(p, { type: 'peer-joined', polite: false });
  }

  function relay(ws, msg) {
    const room = ws.room && rooms.get(ws.room);
    if (!room) return error(ws, 'not-in-room', `${msg.type} needs a room: join one first`);
    if (msg.type === 'candidate') {
      const c = msg.candidate;
      const ok =
        c === null ||
        (c && typeof c === 'object' && !Array.isArray(c) && typeof c.candidate === 'string' &&
          (c.sdpMid === undefined || c.sdpMid === null || typeof c.sdpMid === 'string') &&
          (c.sdpMLineIndex === undefined || c.sdpMLineIndex === null || Number.isInteger(c.sdpMLineIndex)));
      if (!ok) return error(ws, 'bad-field', 'candidate must be null or { candidate, sdpMid, sdpMLineIndex }');
    } else if (typeof msg.sdp !== 'string' || msg.sdp.length === 0) {
      return error(ws, 'bad-field', `${msg.type} needs an sdp string`);
    }
    const p = other(room, ws);
    if (!p) return error(ws, 'no-peer', 'nobody else is in the room yet');
    if (msg.type === 'offer') {
      clearOffer(room);
      const from = ws;
      room.offer = {
        from,
        timer: setTimeout(() => {
          room.offer = null;
          send(from, { type: 'error', code: 'peer-not-answering', message: 'the other side did not answer the offer' });
        }, o.answerTimeoutMs),
      };
    } else if (msg.type === 'answer' && room.offer && room.offer.from === p) {
      clearOffer(room);
    }
    const out =
      msg.type === 'candidate'
        ? { type: 'candidate', candidate: msg.candidate && { candidate: msg.candidate.candidate, sdpMid: msg.candidate.sdpMid ?? null, sdpMLineIndex: msg.candidate.sdpMLineIndex ?? null } }
        : { type: msg.type, sdp: msg.sdp };
    send(p, out);
  }

  function onMessage(ws, data, isBinary) {
    const now = Date.now();
    ws.tokens = Math.min(o.ratePerSec * 2, ws.tokens + ((now - ws.refill) / 1000) * o.ratePerSec);
    ws.refill = now;
    if (ws.tokens < 1) {
      send(ws, { type: 'error', code: 'rate-limit', message: 'too many messages' });
      ws.close(CLOSE_POLICY, 'rate limit');
      return;
    }
    ws.tokens--;
    if (isBinary) return error(ws, 'bad-json', 'messages are JSON text');
    let msg;
    try {
      msg = JSON.parse(data.toString('utf8'));
    } catch {
      return error(ws, 'bad-json', 'the message is not JSON');
    }
    if (!msg || typeof msg !== 'object' || Array.isArray(msg)) return error(ws, 'bad-json', 'a message is a JSON object');
    switch (msg.type) {
      case 'create':
        return send(ws, { type: 'created', room: ids.issue() });
      case 'join':
        return join(ws, msg);
      case 'offer':
      case 'answer':
      case 'candidate':
        return relay(ws, msg);
      case 'leave':
        if (!ws.room) return error(ws, 'not-in-room', 'not in a room');
        return leave(ws);
      case 'ping':
        return send(ws, { type: 'pong' });
      default:
        return error(ws, 'unknown-type', `unknown message type ${typeof msg.type === 'string' ? JSON.stringify(msg.type.slice(0, 40)) : `(a ${typeof msg.type})`}`);
    }
  }

  const heartbeat = setInterval(() => {
    for (const ws of sockets) {
      if (!ws.alive) {
        ws.terminate();
        continue;
      }
      ws.alive = false;
      try {
        ws.ping();
      } catch {
        ws.terminate();
      }
    }
  }, o.heartbeatMs);
  heartbeat.unref();
  log(`WebSocket signalling on ${o.path} (rooms of two; at most ${o.maxConnections} connections, ${o.maxPerIp} per address)`);

  return {
    stats: () => ({ connections: sockets.size, rooms: rooms.size, refused }),
    close() {
      clearInterval(heartbeat);
      server.off('upgrade', onUpgrade);
      for (const ws of sockets) ws.terminate();
      for (const room of rooms.values()) clearOffer(room);
      rooms.clear();
    },
  };
}

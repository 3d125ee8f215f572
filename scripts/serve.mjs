// A small static file server for the demo: serves a folder on 127.0.0.1 only, with the right
// MIME types (application/wasm for streaming compilation), no directory listings, no path
// escapes, text and wasm gzip-compressed for clients that accept it (as static hosts do). Prints "facemimic demo: http://127.0.0.1:PORT/" once the page can be loaded.
// It is also the call page's signalling server: a WebSocket endpoint at /signal
// (scripts/signal.mjs, docs/call.md).
// Usage: node scripts/serve.mjs [--lan] [ROOT=www] ; PORT from the environment (default 8080).
//   --lan   listen on every interface (0.0.0.0), so other machines of the LAN can open the page
//           and join a call; without it only this machine can (127.0.0.1).
// FACEMIMIC_SIGNAL_HEARTBEAT_MS, _JOIN_TIMEOUT_MS, _ANSWER_TIMEOUT_MS, _MAX_CONNECTIONS,
// _MAX_PER_IP override the signalling limits (scripts/signal.mjs DEFAULTS).
import { createServer } from 'node:http';
import { networkInterfaces } from 'node:os';
import { attachSignalling } from './signal.mjs';
import { createReadStream, readFileSync, statSync } from 'node:fs';
import { gzipSync } from 'node:zlib';
import { extname, join, normalize, resolve, sep } from 'node:path';

const args = process.argv.slice(2);
const lan = args.includes('--lan');
const unknown = args.filter((a) => a.startsWith('-') && a !== '--lan');
if (unknown.length) {
  console.error(`serve.mjs: unknown option ${unknown[0]} (usage: node scripts/serve.mjs [--lan] [ROOT])`);
  process.exit(2);
}
const root = resolve(args.find((a) => !a.startsWith('-')) || 'www');
const host = lan ? '0.0.0.0' : '127.0.0.1';
const port = Number(process.env.PORT || 8080);
const label = process.env.FACEMIMIC_LABEL || 'facemimic demo';
const types = {
  '.html': 'text/html; charset=utf-8', '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8', '.css': 'text/css; charset=utf-8',
  '.json': 'application/json', '.wasm': 'application/wasm', '.fmm': 'application/octet-stream',
  '.png': 'image/png', '.jpg': 'image/jpeg', '.svg': 'image/svg+xml', '.webm': 'video/webm',
  '.ts': 'text/plain; charset=utf-8', '.md': 'text/plain; charset=utf-8', '.ico': 'image/x-icon',
};

const compressible = new Set(['.html', '.js', '.mjs', '.css', '.json', '.wasm', '.svg', '.ts', '.md']);
const gzipCache = new Map();

const server = createServer((req, res) => {
  let path;
  try {
    path = decodeURIComponent(new URL(req.url, 'http://x').pathname);
  } catch {
    res.writeHead(400).end('bad request');
    return;
  }
  let file = normalize(join(root, path));
  if (file !== root && !file.startsWith(root + sep)) {
    res.writeHead(403).end('forbidden');
    return;
  }
  try {
    if (statSync(file).isDirectory()) file = join(file, 'index.html');
    const st = statSync(file);
    const ext = extname(file).toLowerCase();
    if (compressible.has(ext) && /\bgzip\b/.test(req.headers['accept-encoding'] || '')) {
      const key = `${file}:${st.size}:${st.mtimeMs}`;
      let body = gzipCache.get(key);
      if (!body) {
        body = gzipSync(readFileSync(file), { level: 9 });
        gzipCache.set(key, body);
      }
      res.writeHead(200, {
        'Content-Type': types[ext],
        'Content-Encoding': 'gzip',
        Vary: 'Accept-Encoding',
        'Content-Length': body.length,
        'Cache-Control': 'no-cache',
      });
      return res.end(req.method === 'HEAD' ? undefined : body);
    }
    res.writeHead(200, {
      'Content-Type': types[extname(file).toLowerCase()] || 'application/octet-stream',
      'Content-Length': st.size,
      'Cache-Control': 'no-cache',
    });
    if (req.method === 'HEAD') return res.end();
    createReadStream(file).pipe(res);
  } catch {
    res.writeHead(404, { 'Content-Type': 'text/plain' }).end('not found');
  }
});

const envNum = (name) => {
  const v = process.env[`FACEMIMIC_SIGNAL_${name}`];
  if (v === undefined) return undefined;
  const n = Number(v);
  if (!Number.isFinite(n) || n <= 0) {
    console.error(`serve.mjs: FACEMIMIC_SIGNAL_${name} must be a positive number, not ${JSON.stringify(v)}`);
    process.exit(2);
  }
  return n;
};
const limits = Object.fromEntries(
  Object.entries({
    heartbeatMs: envNum('HEARTBEAT_MS'),
    joinTimeoutMs: envNum('JOIN_TIMEOUT_MS'),
    answerTimeoutMs: envNum('ANSWER_TIMEOUT_MS'),
    maxConnections: envNum('MAX_CONNECTIONS'),
    maxPerIp: envNum('MAX_PER_IP'),
  }).filter(([, v]) => v !== undefined),
);
const signalling = attachSignalling(server, limits);

server.on('error', (e) => {
  console.error(`${label}: cannot listen on ${host}:${port}: ${e.message}`);
  process.exit(1);
});
server.listen(port, host, () => {
  const p = server.address().port;
  console.log(`${label}: http://127.0.0.1:${p}/`);
  if (lan) {
    console.log(`${label}: listening on every interface (${server.address().address}:${p}), so the LAN can reach it`);
    for (const list of Object.values(networkInterfaces())) {
      for (const a of list || []) if (a.family === 'IPv4' && !a.internal) console.log(`${label} on the LAN: http://${a.address}:${p}/`);
    }
  }
});
for (const sig of ['SIGINT', 'SIGTERM']) {
  process.on(sig, () => {
    signalling.close();
    server.closeAllConnections?.();
    server.close(() => process.exit(0));
  });
}

// Helpers for the call page's end-to-end test and its benches (scripts/bench/call*.mjs): the demo
// server with its signalling endpoint as a child process (so it can be stopped and started
// again), a fake camera (a GRID clip of spk07, committed data, 640x480) and a fake microphone (a
// tone, written as a WAV), two pages joined in one room, and readers of the status object and of
// the remote picture.

import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { ROOT, fakeCameraFile, fakeCameraArgs } from './browser.mjs';

/** The clip the fake camera plays (spk07 is the default source model; an unseen clip). */
export const CAMERA_CLIP = path.join(ROOT, 'data', 'grid', 'spk07_id2_vcd_swwp2s');

/** A mono 16-bit WAV of `seconds` of a `hz` tone (quiet: amplitude 0.3). */
export function toneWav(file, { seconds = 4, hz = 440, rate = 48000 } = {}) {
  const n = seconds * rate;
  const b = Buffer.alloc(44 + n * 2);
  b.write('RIFF', 0);
  b.writeUInt32LE(36 + n * 2, 4);
  b.write('WAVEfmt ', 8);
  b.writeUInt32LE(16, 16);
  b.writeUInt16LE(1, 20);
  b.writeUInt16LE(1, 22);
  b.writeUInt32LE(rate, 24);
  b.writeUInt32LE(rate * 2, 28);
  b.writeUInt16LE(2, 32);
  b.writeUInt16LE(16, 34);
  b.write('data', 36);
  b.writeUInt32LE(n * 2, 40);
  for (let i = 0; i < n; i++) b.writeInt16LE(Math.round(Math.sin((2 * Math.PI * hz * i) / rate) * 0.3 * 32767), 44 + i * 2);
  fs.writeFileSync(file, b);
  return file;
}

/**
 * The fake camera and microphone files (in the temporary folder; `cleanup` is called with a
 * remover, e.g. `t.after`). Returns Chromium's switches for them.
 */
export async function fakeMedia(cleanup, name = 'call') {
  const camera = await fakeCameraFile({ after: cleanup }, CAMERA_CLIP, { name });
  const wav = toneWav(path.join(os.tmpdir(), `facemimic-${name}-${process.pid}.wav`));
  cleanup(() => fs.rmSync(wav, { force: true }));
  return [...fakeCameraArgs(camera), `--use-file-for-fake-audio-capture=${wav}`, '--allow-loopback-in-peer-connection'];
}

/**
 * node scripts/serve.mjs www on `port` (0: a free one), with its own signalling secret file.
 * Resolves to { port, url, proc, output(), stop() }.
 */
export async function startDemoServer({ port = 0, env = {}, secretFile } = {}) {
  const proc = spawn(process.execPath, ['scripts/serve.mjs', 'www'], {
    cwd: ROOT,
    env: { ...process.env, PORT: String(port), FACEMIMIC_SIGNAL_SECRET_FILE: secretFile || path.join(os.tmpdir(), `facemimic-call-secret-${process.pid}`), ...env },
    stdio: ['ignore', 'pipe', 'pipe'],
  });
  let out = '';
  proc.stdout.on('data', (d) => (out += d));
  proc.stderr.on('data', (d) => (out += d));
  const p = await new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`the demo server did not start: ${out}`)), 15000);
    const onData = () => {
      const m = /facemimic demo: http:\/\/127\.0\.0\.1:(\d+)\//.exec(out);
      if (m) {
        clearTimeout(timer);
        resolve(Number(m[1]));
      }
    };
    proc.stdout.on('data', onData);
    proc.once('exit', (code) => {
      clearTimeout(timer);
      reject(new Error(`the demo server exited (${code}): ${out}`));
    });
  });
  proc.removeAllListeners('exit');
  return {
    port: p,
    url: `http://127.0.0.1:${p}/`,
    proc,
    output: () => out,
    stop: () =>
      new Promise((resolve) => {
        if (proc.exitCode !== null || proc.signalCode !== null) return resolve();
        proc.once('exit', () => resolve());
        proc.kill('SIGTERM');
      }),
  };
}

/** Every field of window.facemimicCall, as plain data. */
export function status(page) {
  return page.evaluate(() => {
    const o = {};
    for (const k in window.facemimicCall) o[k] = window.facemimicCall[k];
    return o;
  });
}

/** Wait until `facemimicCall[key]` satisfies `pred` (a function source run in the page). */
export function waitCall(page, pred, timeout = 30000) {
  return page.waitForFunction(pred, null, { timeout, polling: 100 });
}

/**
 * The remote video's current picture at 160x120: { mean, variance, pixels } (luma; pixels on a
 * grid, for comparing two pictures).
 */
export function remotePicture(page) {
  return page.evaluate(() => {
    const v = document.getElementById('remote');
    const c = document.createElement('canvas');
    c.width = 160;
    c.height = 120;
    const g = c.getContext('2d');
    g.drawImage(v, 0, 0, 160, 120);
    const d = g.getImageData(0, 0, 160, 120).data;
    let s = 0;
    let s2 = 0;
    const pixels = [];
    for (let i = 0; i < d.length; i += 4) {
      const y = 0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2];
      s += y;
      s2 += y * y;
      pixels.push(Math.round(y));
    }
    const n = d.length / 4;
    return { mean: s / n, variance: s2 / n - (s / n) ** 2, pixels, width: v.videoWidth, height: v.videoHeight };
  });
}

export function meanAbs(a, b) {
  let s = 0;
  for (let i = 0; i < a.length; i++) s += Math.abs(a[i] - b[i]);
  return s / a.length;
}

/**
 * Two pages in one room: A starts the call (`?autojoin=1&avatar=...`), B opens A's invite link.
 * Each in its own browser context (its own session storage, as two people). Returns { a, b, room }.
 */
export async function twoPages(browser, server, { avatarA = 'spk02', avatarB = 'spk03', extra = '', viewport = { width: 1360, height: 900 }, onPage } = {}) {
  const open = async (url, label) => {
    const ctx = await browser.newContext({ viewport });
    const page = await ctx.newPage();
    onPage?.(page, label);
    await page.goto(url);
    return page;
  };
  const a = await open(`${server.url}call.html?autojoin=1&avatar=${avatarA}${extra}`, 'A');
  await waitCall(a, () => window.facemimicCall?.inviteUrl);
  const invite = await a.evaluate(() => window.facemimicCall.inviteUrl);
  const b = await open(`${invite}&autojoin=1&avatar=${avatarB}${extra}`, 'B');
  return { a, b, room: new URL(invite).searchParams.get('room') };
}

// The entry of the npm package `facemimic`: the wasm-bindgen API (`facemimic_wasm.js`) with
// what a JS developer expects around it. Written by hand; the build copies it into pkg/.
//  - init() that works in a page, a worker and Node (which reads the .wasm from disk);
//  - models loaded from a URL, a path (Node), a Response, a Blob, an ArrayBuffer or bytes;
//  - frames from ImageData, ImageBitmap, a video, an image, a canvas, a VideoFrame or raw RGBA;
//  - every error a `FacemimicError` with a stable `code` (also for a call before init() and
//    a use after free()).
import rawInit, * as glue from "./facemimic_wasm.js";

/** The codes a `FacemimicError` carries. The wasm side's come from the core's error kinds. */
export const ERROR_CODES = Object.freeze([
  "not-initialised", "freed", "busy", "internal", "bad-argument", "bad-frame",
  "frame-unavailable", "bad-model", "mismatched-models", "bad-params", "bad-landmarks",
  "training", "cancelled", "fetch-failed", "detached-buffer", "io", "bad-weights",
  "overflow", "too-large",
]);

/** An error of the package: `message` names the problem, `code` is one of `ERROR_CODES`. */
export class FacemimicError extends Error {
  constructor(code, message, options) {
    super(message, options);
    this.name = "FacemimicError";
    this.code = code;
  }
}

let ready = false;
let starting = null;
const isNode = typeof process !== "undefined" && !!process.versions?.node
  && typeof window === "undefined";

/** Turns anything thrown by the glue into a FacemimicError (keeping the wasm side's code). */
function coded(e) {
  if (e instanceof FacemimicError) return e;
  if (e instanceof Error && typeof e.code === "string" && ERROR_CODES.includes(e.code)) {
    Object.setPrototypeOf(e, FacemimicError.prototype);
    e.name = "FacemimicError";
    return e;
  }
  const message = e instanceof Error ? e.message : String(e);
  if (/null pointer passed to rust/.test(message)) {
    return new FacemimicError("freed", "this object was freed (free() was called on it)", { cause: e });
  }
  if (/recursive use of an object/.test(message)) {
    return new FacemimicError("busy", "this object is in use by a call that has not returned (re-entrant call)", { cause: e });
  }
  return new FacemimicError("internal", `internal error: ${message}`, { cause: e });
}

function notReady(what) {
  return new FacemimicError("not-initialised",
    `${what}: the package is not initialised: await init() (or call initSync) first`);
}

function guard(what, fn) {
  return function (...args) {
    if (!ready) throw notReady(what);
    if (this && this.__wbg_ptr === 0) {
      throw new FacemimicError("freed", `${what}: this object was freed (free() was called on it)`);
    }
    try {
      return fn.apply(this, args);
    } catch (e) {
      throw coded(e);
    }
  };
}

const isBytes = (x) => ArrayBuffer.isView(x) && !(x instanceof DataView);

/** Wraps a method whose pixels come first (rgba, width, height, ...rest) to take a frame too. */
function framed(fn, at = 0) {
  return function (...args) {
    if (args.length > at && !isBytes(args[at])) {
      const f = toFrame(args[at]);
      args.splice(at, 1, f.data, f.width, f.height);
    }
    return fn.apply(this, args);
  };
}

/** Guards every method, getter and static of a glue class; returns the class to export. */
function wrapClass(cls, frameMethods = {}, frameStatics = {}) {
  const proto = cls.prototype;
  for (const key of Object.getOwnPropertyNames(proto)) {
    if (key === "constructor" || key === "free" || key.startsWith("__")) continue;
    const d = Object.getOwnPropertyDescriptor(proto, key);
    const what = `${cls.name}.${key}`;
    if (typeof d.value === "function") {
      const inner = key in frameMethods ? framed(d.value, frameMethods[key]) : d.value;
      d.value = guard(what, inner);
    }
    if (d.get) d.get = guard(what, d.get);
    if (d.set) d.set = guard(what, d.set);
    Object.defineProperty(proto, key, d);
  }
  for (const key of Object.getOwnPropertyNames(cls)) {
    const d = Object.getOwnPropertyDescriptor(cls, key);
    if (typeof d.value !== "function" || key.startsWith("__")) continue;
    const inner = key in frameStatics ? framed(d.value, frameStatics[key]) : d.value;
    d.value = guard(`${cls.name}.${key}`, inner);
    Object.defineProperty(cls, key, d);
  }
  return new Proxy(cls, {
    construct(target, args, newTarget) {
      if (!ready) throw notReady(`new ${cls.name}`);
      try {
        return Reflect.construct(target, args, newTarget);
      } catch (e) {
        throw coded(e);
      }
    },
  });
}

// ---- init -------------------------------------------------------------------------------

async function nodeBytes(where) {
  const fsName = "node:fs/promises";
  const fs = await import(/* @vite-ignore */ /* webpackIgnore: true */ fsName);
  return fs.readFile(where instanceof URL || /^file:/.test(where) ? new URL(where) : where);
}

/**
 * Loads and instantiates the wasm once (later calls return the same promise). With no
 * argument it loads `facemimic_bg.wasm` beside this module: by `fetch` in a page or a worker,
 * from disk in Node. Takes what wasm-bindgen's init takes otherwise (a URL, a Response, bytes,
 * a `WebAssembly.Module`, or `{ module_or_path }`).
 */
export default function init(input) {
  if (starting) return starting;
  starting = (async () => {
    let arg = input;
    if (arg && typeof arg === "object" && "module_or_path" in arg) arg = arg.module_or_path;
    arg = await arg;
    if (arg === undefined) arg = new URL("facemimic_bg.wasm", import.meta.url);
    if (isNode && (arg instanceof URL || typeof arg === "string") && !/^https?:/.test(String(arg))) {
      arg = await nodeBytes(arg);
    }
    try {
      const out = await rawInit({ module_or_path: arg });
      ready = true;
      return out;
    } catch (e) {
      throw new FacemimicError("fetch-failed", `init: cannot load the wasm: ${e.message ?? e}`, { cause: e });
    }
  })();
  starting.catch(() => { starting = null; });
  return starting;
}

/** Instantiates the wasm synchronously from its bytes or a compiled `WebAssembly.Module`. */
export function initSync(module) {
  const arg = module && typeof module === "object" && "module" in module ? module : { module };
  const out = glue.initSync(arg);
  ready = true;
  starting = Promise.resolve(out);
  return out;
}

/** Whether `init()` (or `initSync`) has finished. */
export function initialised() {
  return ready;
}

// ---- bytes ------------------------------------------------------------------------------

const isDetached = (buf) => buf.detached === true
  || (buf.byteLength === 0 && (() => { try { new Uint8Array(buf, 0, 0); return false; } catch { return true; } })());

function htmlCheck(bytes, where) {
  // A dev server answering a missing file with its index page is the commonest mistake.
  const head = new TextDecoder().decode(bytes.subarray(0, 64)).trimStart().toLowerCase();
  if (head.startsWith("<")) {
    throw new FacemimicError("bad-model", `${where}: got HTML, not a model file (check the URL and the server's MIME setup)`);
  }
  return bytes;
}

async function fromResponse(res, where) {
  if (!res.ok) {
    throw new FacemimicError("fetch-failed", `${where}: HTTP ${res.status}${res.statusText ? ` ${res.statusText}` : ""}`);
  }
  const type = res.headers?.get?.("content-type") ?? "";
  if (/text\/html/i.test(type)) {
    throw new FacemimicError("bad-model", `${where}: got HTML (${type}), not a model file (check the URL: a server answers a missing file with its page)`);
  }
  return htmlCheck(new Uint8Array(await res.arrayBuffer()), where);
}

/**
 * The bytes of a file given as a URL or path (fetched; read from disk in Node for paths and
 * `file:` URLs), a `Request`, a `Response`, a `Blob`, an `ArrayBuffer` or a typed array.
 */
export async function readBytes(source, what = "readBytes") {
  if (source == null) throw new FacemimicError("bad-argument", `${what}: nothing given (a URL, Response, Blob, ArrayBuffer or Uint8Array)`);
  if (source instanceof ArrayBuffer || (typeof SharedArrayBuffer !== "undefined" && source instanceof SharedArrayBuffer)) {
    if (isDetached(source)) throw new FacemimicError("detached-buffer", `${what}: the ArrayBuffer is detached (it was transferred to a worker or another call)`);
    return new Uint8Array(source);
  }
  if (ArrayBuffer.isView(source)) {
    if (isDetached(source.buffer)) throw new FacemimicError("detached-buffer", `${what}: the typed array's buffer is detached (it was transferred)`);
    return new Uint8Array(source.buffer, source.byteOffset, source.byteLength);
  }
  if (typeof Response !== "undefined" && source instanceof Response) return fromResponse(source, what);
  if (typeof Blob !== "undefined" && source instanceof Blob) return new Uint8Array(await source.arrayBuffer());
  const isRequest = typeof Request !== "undefined" && source instanceof Request;
  if (!(typeof source === "string" || source instanceof URL || isRequest)) {
    throw new FacemimicError("bad-argument", `${what}: cannot read bytes from ${Object.prototype.toString.call(source)}`);
  }
  const where = `${what}: ${isRequest ? source.url : String(source)}`;
  if (isNode && !isRequest && !/^(https?|data|blob):/i.test(String(source))) {
    try {
      return await nodeBytes(source);
    } catch (e) {
      throw new FacemimicError("fetch-failed", `${where}: ${e.message}`, { cause: e });
    }
  }
  let res;
  try {
    res = await fetch(source);
  } catch (e) {
    throw new FacemimicError("fetch-failed", `${where}: ${e.message}`, { cause: e });
  }
  return fromResponse(res, where);
}

/** A model from a URL, a path (Node), a Response, a Blob, an ArrayBuffer or a Uint8Array. */
export async function loadModel(source) {
  const bytes = await readBytes(source, "loadModel");
  if (!ready) throw notReady("loadModel");
  return Model.fromBytes(bytes);
}

// ---- frames -----------------------------------------------------------------------------

let scratch = null;
function scratchContext(w, h) {
  if (!scratch) {
    const canvas = typeof OffscreenCanvas !== "undefined" ? new OffscreenCanvas(w, h)
      : typeof document !== "undefined" ? document.createElement("canvas") : null;
    if (!canvas) {
      throw new FacemimicError("bad-frame",
        "toFrame: no canvas here (Node): pass raw RGBA as { data, width, height }");
    }
    scratch = canvas.getContext("2d", { willReadFrequently: true });
  }
  const c = scratch.canvas;
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  return scratch;
}

const has = (name) => typeof globalThis[name] !== "undefined";

function drawable(source) {
  if (has("HTMLVideoElement") && source instanceof HTMLVideoElement) {
    if (source.readyState < 2 || !source.videoWidth) {
      throw new FacemimicError("frame-unavailable",
        `toFrame: the video has no frame to read yet (readyState ${source.readyState}): wait for its 'loadeddata' event, or play it`);
    }
    return [source.videoWidth, source.videoHeight];
  }
  if (has("HTMLImageElement") && source instanceof HTMLImageElement) {
    if (!source.complete || !source.naturalWidth) {
      throw new FacemimicError("frame-unavailable", "toFrame: the image has not loaded (or failed to): wait for its 'load' event");
    }
    return [source.naturalWidth, source.naturalHeight];
  }
  if (has("VideoFrame") && source instanceof VideoFrame) return [source.displayWidth, source.displayHeight];
  if ((has("ImageBitmap") && source instanceof ImageBitmap)
    || (has("HTMLCanvasElement") && source instanceof HTMLCanvasElement)
    || (has("OffscreenCanvas") && source instanceof OffscreenCanvas)) {
    if (!source.width || !source.height) {
      throw new FacemimicError("frame-unavailable", "toFrame: the bitmap or canvas is empty (0 pixels, or a closed ImageBitmap)");
    }
    return [source.width, source.height];
  }
  return null;
}

/**
 * A frame's straight RGBA pixels `{ data, width, height }` from an `ImageData`, an
 * `ImageBitmap`, a video or image element, a canvas, an `OffscreenCanvas`, a `VideoFrame`, or
 * raw RGBA given as `{ data, width, height }` (or `{ rgba, width, height }`). Elements and
 * bitmaps are drawn into one reused scratch canvas (a page or a worker; Node takes raw RGBA).
 */
export function toFrame(source) {
  if (source == null || typeof source !== "object") {
    throw new FacemimicError("bad-frame", `toFrame: expected a frame (ImageData, ImageBitmap, video, canvas, or { data, width, height }), got ${source}`);
  }
  const size = drawable(source);
  if (size) {
    const [w, h] = size;
    const ctx = scratchContext(w, h);
    ctx.clearRect(0, 0, w, h);
    ctx.drawImage(source, 0, 0, w, h);
    const image = ctx.getImageData(0, 0, w, h);
    return { data: image.data, width: w, height: h };
  }
  const data = source.data ?? source.rgba;
  const { width, height } = source;
  if (!isBytes(data)) {
    throw new FacemimicError("bad-frame", "toFrame: expected a frame (ImageData, ImageBitmap, video, canvas, or { data, width, height } with RGBA bytes)");
  }
  if (isDetached(data.buffer)) throw new FacemimicError("detached-buffer", "toFrame: the frame's buffer is detached (it was transferred)");
  if (!(width > 0 && height > 0 && Number.isInteger(width) && Number.isInteger(height))
    || data.length !== width * height * 4) {
    throw new FacemimicError("bad-frame", `toFrame: ${data.length} bytes for ${width}x${height} RGBA (needs width * height * 4)`);
  }
  return { data, width, height };
}

// ---- the API ----------------------------------------------------------------------------

export const Model = wrapClass(glue.Model, { project: 1 }, { fromPhoto: 1 });
export const Cloner = wrapClass(glue.Cloner);
export const Tracker = wrapClass(glue.Tracker, { track: 0 });
export const FaceFinder = wrapClass(glue.FaceFinder, { find: 0, landmarks: 0, enrol: 0 });
export const PoseDamper = wrapClass(glue.PoseDamper);
glue.Model.load = loadModel;

function framesOf(options) {
  if (!options || typeof options !== "object" || !Array.isArray(options.frames)) return options;
  const frames = options.frames.map((f) => {
    if (f && typeof f === "object" && isBytes(f.rgba)) return f;
    const { data, width, height } = toFrame(f);
    return { rgba: data, width, height, landmarks: f?.landmarks };
  });
  return { ...options, frames };
}

export const buildModel = guard("buildModel", (options, onProgress) => glue.buildModel(framesOf(options), onProgress));
export const enrolFace = guard("enrolFace", framed(glue.enrolFace));
export const expressionCoverage = guard("expressionCoverage", glue.expressionCoverage);
export const landmarkError = guard("landmarkError", glue.landmarkError);
export const lerpPose = guard("lerpPose", glue.lerpPose);
export const meanPose = guard("meanPose", glue.meanPose);
export const methods = guard("methods", glue.methods);
export const modelSummary = guard("modelSummary", glue.modelSummary);
export const mostAtRest = guard("mostAtRest", glue.mostAtRest);
export const parsePts = guard("parsePts", glue.parsePts);
export const policy = guard("policy", glue.policy);
export const recentrePose = guard("recentrePose", glue.recentrePose);
export const renderMode = guard("renderMode", glue.renderMode);
export const samePicture = guard("samePicture", glue.samePicture);
export const selectVaried = guard("selectVaried", glue.selectVaried);
export const shapeCoverage = guard("shapeCoverage", glue.shapeCoverage);
export const version = guard("version", glue.version);

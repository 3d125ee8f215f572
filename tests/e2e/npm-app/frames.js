// The package's frame sources in a browser, from the installed tarball: every drawable kind
// gives the same pixels and the same faces; a video without a frame and bad inputs throw
// coded errors; a module worker initialises and clones. Results go to window.result.
import init, { loadModel, Cloner, FaceFinder, Tracker, toFrame, FacemimicError } from "facemimic";
import { source, targets } from "facemimic-faces";

const codeOf = async (f) => {
  try { await f(); return "none"; } catch (e) { return e instanceof FacemimicError ? e.code : `plain: ${e}`; }
};

async function run() {
  const out = {};
  out.beforeInit = await codeOf(() => new FaceFinder());
  await init();
  const model = await loadModel(source);
  const cloner = new Cloner(model);
  cloner.addTarget(await loadModel(targets[0]));
  cloner.update();
  const canvas = document.getElementById("picture");
  const ctx = canvas.getContext("2d");
  cloner.renderTarget(0, ctx, { composite: true });
  const image = ctx.getImageData(0, 0, canvas.width, canvas.height);
  const bitmap = await createImageBitmap(canvas);
  const offscreen = new OffscreenCanvas(canvas.width, canvas.height);
  offscreen.getContext("2d").drawImage(canvas, 0, 0);
  const raw = { data: new Uint8Array(image.data), width: image.width, height: image.height };
  const same = (f) => f.width === image.width && f.height === image.height
    && f.data.every((v, i) => v === image.data[i]);
  const finder = new FaceFinder();
  const kinds = { imageData: image, bitmap, canvas, offscreen, raw,
                  videoFrame: new VideoFrame(canvas, { timestamp: 0 }) };
  out.same = {};
  out.faces = {};
  for (const [name, src] of Object.entries(kinds)) {
    out.same[name] = same(toFrame(src));
    out.faces[name] = finder.find(src).length;
  }
  out.rawCall = finder.find(image.data, image.width, image.height).length;

  // A playing video (the canvas's stream) is a frame source; tracking reads it directly.
  const live = document.getElementById("live");
  live.srcObject = canvas.captureStream(30);
  await live.play();
  for (let i = 0; i < 60 && live.readyState < 2; i++) await new Promise((r) => setTimeout(r, 50));
  const tracker = Tracker.forModel(model, false);
  tracker.startAuto();
  let fit = null;
  for (let i = 0; i < 5; i++) {
    cloner.renderTarget(0, ctx, { composite: true });
    fit = tracker.track(live);
    await new Promise((r) => requestAnimationFrame(r));
  }
  out.videoFrame = toFrame(live).width;
  out.tracked = fit && !fit.lost && fit.landmarks.length === 136;

  out.idleVideo = await codeOf(() => toFrame(document.getElementById("idle")));
  out.idleTrack = await codeOf(() => tracker.track(document.getElementById("idle")));
  out.notAFrame = await codeOf(() => toFrame({ hello: 1 }));
  out.wrongSize = await codeOf(() => finder.find({ data: new Uint8Array(7), width: 2, height: 2 }));
  out.missing = await codeOf(() => loadModel("./no-such-face.fmm"));
  out.html = await codeOf(() => loadModel("./frames.html"));
  out.otherType = await codeOf(async () => loadModel(await (await fetch("./frames.js")).arrayBuffer()));
  const gone = new ArrayBuffer(16);
  structuredClone(gone, { transfer: [gone] });
  out.detached = await codeOf(() => loadModel(gone));
  const freed = await loadModel(targets[1]);
  freed.free();
  out.freed = await codeOf(() => freed.info());
  out.freedArg = await codeOf(() => cloner.addTarget(freed));
  out.nan = await codeOf(() => cloner.setSourceParams({ ...model.baseParams(), shape: [NaN] }));

  // A module worker: init() and a clone there.
  const worker = new Worker(new URL("./worker.js", import.meta.url), { type: "module" });
  out.worker = await new Promise((resolve) => {
    worker.onmessage = (e) => resolve(e.data);
    worker.onerror = (e) => resolve({ error: e.message });
  });
  return out;
}

run().then((r) => { window.result = r; }, (e) => { window.result = { error: `${e.code ?? ""} ${e.stack ?? e}` }; });

// A module worker using the package: init() fetches the wasm from the worker's module URL.
import init, { loadModel, Cloner } from "facemimic";
import { source, targets } from "facemimic-faces";

try {
  await init();
  const cloner = new Cloner(await loadModel(source));
  cloner.addTarget(await loadModel(targets[2]));
  cloner.update();
  const rgba = cloner.renderTargetRGBA(0, 64, 48);
  let sum = 0;
  for (let i = 0; i < rgba.length; i += 4) sum += rgba[i];
  postMessage({ ok: true, bytes: rgba.length, mean: sum / (64 * 48) });
} catch (e) {
  postMessage({ error: `${e.code ?? ""} ${e.message}` });
}

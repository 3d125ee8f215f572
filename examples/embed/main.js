// A minimal use of the facemimic npm package: one source model drives one target model.
// Models default to models/spk07.fmm (source) and models/spk02.fmm (target); override with
// ?source=URL&target=URL.
import init, { Model, Cloner, version } from "facemimic";

const $ = (id) => document.getElementById(id);
const status = $("status");
const query = new URLSearchParams(location.search);
const sourceUrl = query.get("source") || "models/spk07.fmm";
const targetUrl = query.get("target") || "models/spk02.fmm";

async function loadModel(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  try {
    return Model.fromBytes(new Uint8Array(await response.arrayBuffer()));
  } catch (e) {
    throw new Error(`${url}: ${e.message}`);
  }
}

async function main() {
  await init();
  const [source, target] = await Promise.all([loadModel(sourceUrl), loadModel(targetUrl)]);
  const cloner = new Cloner(source);
  cloner.addTarget(target);
  $("source-name").textContent = `source: ${source.name}`;
  $("target-name").textContent = `target: ${target.name}`;

  // Crisp on high-DPI screens: the backing store at the CSS size times devicePixelRatio.
  for (const canvas of [$("source"), $("target")]) {
    const dpr = window.devicePixelRatio || 1;
    canvas.width = Math.round(canvas.clientWidth * dpr);
    canvas.height = Math.round(canvas.clientHeight * dpr);
  }
  const sourceCtx = $("source").getContext("2d");
  const targetCtx = $("target").getContext("2d");
  const sigma = source.info().shapeSigma;
  const params = source.baseParams();

  // Draws one frame with the first shape mode at `k` standard deviations.
  function draw(k) {
    if (params.shape.length > 0) params.shape[0] = k * sigma[0];
    cloner.setSourceParams(params);
    cloner.update();
    cloner.renderSource(sourceCtx);
    cloner.renderTarget(0, targetCtx);
    $("mode-value").textContent = k.toFixed(1);
  }

  const slider = $("mode");
  slider.addEventListener("input", () => draw(Number(slider.value)));
  let t0 = performance.now();
  function tick(now) {
    if ($("animate").checked) {
      const k = 2.5 * Math.sin((now - t0) / 500);
      slider.value = k.toFixed(1);
      draw(k);
    }
    requestAnimationFrame(tick);
  }
  draw(Number(slider.value));
  requestAnimationFrame(tick);
  status.textContent = `facemimic ${version()}: ${source.name} drives ${target.name}`;
  status.dataset.state = "ready";
}

main().catch((e) => {
  status.textContent = `error: ${e.message}`;
  status.dataset.state = "error";
  console.error(e);
});

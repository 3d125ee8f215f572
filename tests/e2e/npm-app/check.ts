// Type-checked (tsc --noEmit, strict, lib ES2022 + DOM, no skipLibCheck) against the installed
// tarball: the calls users make type as they should, and wrong calls are rejected.
import init, {
  loadModel, Model, Cloner, Tracker, FaceFinder, toFrame, FacemimicError, type ErrorCode,
  type FitResult, type FoundFace, type Method, methods,
} from "facemimic";
import { source, targets, faces, credits } from "facemimic-faces";

export async function usage(video: HTMLVideoElement, image: ImageData, bitmap: ImageBitmap): Promise<string> {
  await init();
  const model: Model = await loadModel(source);
  const again: Model = await Model.load(faces.spk02);
  const cloner = new Cloner(model);
  cloner.addTarget(again);
  cloner.addTarget(await loadModel(targets[1]));
  const finder = new FaceFinder();
  const found: FoundFace[] = finder.find(image.data, image.width, image.height);   // Uint8ClampedArray
  const alsoFound: FoundFace[] = finder.find(bitmap);
  const tracker = Tracker.forModel(model, false);
  tracker.startAuto();
  const fit: FitResult = tracker.track(video);
  const raw: FitResult = tracker.track(image.data, image.width, image.height, 1 / 30);
  const lost: boolean = fit.lost && raw.converged;
  const last: FitResult | null = tracker.last();
  const rgba: Uint8ClampedArray = cloner.renderTargetRGBA(0, 64, 64, { composite: true });
  const frame = toFrame(video);
  const method: Method = methods()[0].name;
  cloner.setMethod(method);
  try {
    Model.fromBytes(new Uint8Array(4));
  } catch (e) {
    if (e instanceof FacemimicError) {
      const code: ErrorCode = e.code;
      return code;
    }
  }
  // @ts-expect-error a frame is not a number
  tracker.track(42);
  // @ts-expect-error not a method
  cloner.setMethod("warp-everything");
  // @ts-expect-error not an error code
  const wrong: ErrorCode = "oops";
  return `${found.length} ${alsoFound.length} ${lost} ${last?.error} ${rgba.length} ${frame.width} ${credits} ${wrong}`;
}

//! The wasm-bindgen glue (wasm32 only): the JavaScript API of the npm package `facemimic`.
//!
//! A thin layer over the core: [`JsModel`] (`Model` in JS) wraps [`facemimic::Model`] and
//! [`facemimic::format`], [`JsCloner`] (`Cloner`) wraps [`facemimic::Stage`] (the cloner, the
//! compositors, the views, the compare view and the timings), whose pictures go into the
//! canvases with `putImageData`. The contract is `npm/README.md`.
//!
//! Every entry point validates its input and returns `Result<_, JsError>`: a bad model file,
//! mismatched models, NaN parameters or a wrong argument throw a JS `Error` whose message
//! names the problem; nothing panics across the boundary (a panic hook logs any bug to the
//! console as a safety net).

#![cfg(target_arch = "wasm32")]

use wasm_bindgen::prelude::*;

pub use error::{JsError, CODES};

use facemimic::Params;

mod build;
mod cloner;
mod error;
mod finder;
mod landmarks;
mod model;
mod policy;
mod pose;
mod surface;
mod tracker;

pub use build::{build_model, enrol_face};
pub use cloner::JsCloner;
pub use finder::JsFaceFinder;
pub use landmarks::{landmark_error, parse_pts};
pub use model::{model_summary, render_mode, JsModel};
pub use policy::policy;
pub use pose::{lerp_pose, mean_pose, recentre_pose, JsPoseDamper};
pub use tracker::WasmTracker;

/// Converts a library error into a JS `Error` (its message names the problem).
pub(crate) fn js_err(e: facemimic::Error) -> JsError {
    e.into()
}

/// Parameters from JS: `{ pose: { scale, rotation, tx, ty }, shape: number[], appearance: number[] }`
/// (arrays may be typed arrays).
pub(crate) fn params_from_js(value: &JsValue) -> Result<Params, JsError> {
    if !value.is_object() {
        return Err(JsError::coded("bad-params", format!(
            "parameters: expected {{ pose: {{ scale, rotation, tx, ty }}, shape: [...], appearance: [...] }}, got {}",
            surface::describe(value)
        )));
    }
    serde_wasm_bindgen::from_value(value.clone())
        .map_err(|e| JsError::coded("bad-params", format!("parameters: {e}")))
}

/// Parameters to JS as a plain object with number arrays.
pub(crate) fn params_to_js(params: &Params) -> Result<JsValue, JsError> {
    serde_wasm_bindgen::to_value(params)
        .map_err(|e| JsError::coded("bad-params", format!("parameters: {e}")))
}

pub use facemimic::canvas_view;

/// The package version (the crate's).
#[wasm_bindgen]
pub fn version() -> String {
    install_panic_hook();
    env!("CARGO_PKG_VERSION").to_string()
}

/// The cloning methods, from the core's one list (`Method::ALL`): `{name, label, description}`
/// each, in the order the page shows them; the first entry with `isDefault` is the default.
#[wasm_bindgen(unchecked_return_type = "MethodInfo[]")]
pub fn methods() -> Result<JsValue, JsError> {
    #[derive(serde::Serialize)]
    #[serde(rename_all = "camelCase")]
    struct Info {
        name: &'static str,
        label: &'static str,
        description: &'static str,
        is_default: bool,
    }
    let list: Vec<Info> = facemimic::clone::Method::ALL
        .iter()
        .map(|m| Info {
            name: m.name(),
            label: m.label(),
            description: m.description(),
            is_default: *m == facemimic::clone::Method::default(),
        })
        .collect();
    serde_wasm_bindgen::to_value(&list).map_err(|e| JsError::new(&e.to_string()))
}

/// Installs (once) `console_error_panic_hook`, which reports any panic (a bug: the API
/// validates its input) with its message and stack on the console before the module traps.
/// Called by the constructors.
pub(crate) fn install_panic_hook() {
    console_error_panic_hook::set_once();
}

#[wasm_bindgen]
extern "C" {
    /// `RenderOptions` in TypeScript (an optional plain object).
    #[wasm_bindgen(typescript_type = "RenderOptions")]
    pub type RenderOptionsArg;

    /// A 2D canvas context, on screen or off (`CanvasRenderingContext2D |
    /// OffscreenCanvasRenderingContext2D` in TypeScript): what the `render*` methods draw into.
    #[wasm_bindgen(
        typescript_type = "CanvasRenderingContext2D | OffscreenCanvasRenderingContext2D"
    )]
    pub type Context2dArg;
}

#[wasm_bindgen(typescript_custom_section)]
const TS_TYPES: &'static str = r##"
/** Pose: similarity from model coordinates to image pixels. */
export interface Pose { scale: number; rotation: number; tx: number; ty: number }
/** One face instance: pose, shape parameters p, appearance parameters lambda. */
export interface Params { pose: Pose; shape: number[]; appearance: number[] }
/** Parameters accepted as input (typed arrays allowed). */
export type ParamsInput = { pose: Pose; shape: ArrayLike<number>; appearance: ArrayLike<number> };
/** What `Model.info()` returns. */
export interface ModelInfo {
  name: string; landmarks: number; triangles: number; frameWidth: number; frameHeight: number;
  pixels: number; channels: 3; shapeModes: number; appearanceModes: number;
  shapeSigma: number[]; appearanceSigma: number[];
  /** Each mode's share of the kept variance. */
  shapeVarianceShare: number[]; appearanceVarianceShare: number[];
  /** The reference frame's fingerprint, hex: models with equal fingerprints can be cloned. */
  fingerprint: string;
  /** "mean" or the name of the training image the bases show. */
  reference: string;
  imageWidth: number; imageHeight: number;
  /** The picture the face is composited into (`render*` with `composite: true`), or null. */
  backdrop: { width: number; height: number; bytes: number } | null;
  /** Set when the file's backdrop was damaged and left out (the face renders alone): why. */
  backdropNotice: string | null;
  /** A target made from one photo: no modes of its own; cloned onto by substitution whatever
   *  the method (Fig. 4 A). */
  isPhoto: boolean;
}
/** The core's front-end policy (`policy()`): what the page, the call page and a package user
 *  take from the core instead of deciding themselves. */
export interface Policy {
  /** Longer side (px) video frames are scaled down to before tracking and finding. */
  workSide: number;
  /** Photo targets: picture kept at `maxSide`, searched at `findSide`; a still source fitted in
   *  `fitPasses` passes. */
  photo: { maxSide: number; findSide: number; fitPasses: number };
  /** Enrolment sampling: frames built from, fewest usable, kept in memory, frame side, ms
   *  between live samples, frames searched in a dropped video. */
  enrol: { want: number; minFrames: number; maxCandidates: number; maxSide: number; sampleMs: number; videoSamples: number };
  /** The cloning defaults a new `Cloner` starts with (`clamp`: k, or null for no clamp). */
  clone: { method: Method; gain: number; clamp: number | null; followPose: boolean; mouth: number; eyes: number; brows: number; style: number };
}
/** What `modelSummary(bytes)` reads of a model file without building the model (its header,
 *  length and checksum): enough to list kept models. */
export interface ModelSummary {
  name: string; version: number; landmarks: number; shapeModes: number; appearanceModes: number;
  framePixels: number;
  /** The reference frame's fingerprint, hex (as `ModelInfo.fingerprint`). */
  fingerprint: string;
  imageWidth: number; imageHeight: number; isPhoto: boolean; fileBytes: number;
}
/** Cloning method: the paper's Fig. 4 A, B, C and the expressive method (`methods()` lists
 *  them with labels and descriptions). */
export type Method = "substitute" | "map" | "map-residual" | "expressive";
/** One entry of `methods()`. */
export interface MethodInfo { name: Method; label: string; description: string; isDefault: boolean }
/** Rendering options. */
export interface RenderOptions {
  /** CSS hex colour (#rgb, #rgba, #rrggbb, #rrggbbaa) or "transparent"; default "#202024". */
  background?: string;
  /** Overlay the triangle mesh (thin, semi-transparent). Default false. */
  mesh?: boolean;
  /** Triangle rasteriser: "tiny-skia" (default; one tiny-skia pattern fill per triangle) or
   *  "scanline" (opt-in fast path: a faster fixed-point rasteriser that writes into the same
   *  tiny-skia pixmap; results agree within ~1.5 levels). */
  raster?: "tiny-skia" | "scanline";
  /** Targets: show the whole picture (the model's backdrop, letterboxed to the canvas) with the
   *  face composited into it, the head moving with the face. Default false (the face alone,
   *  the paper's view). A model without a backdrop is drawn face only. */
  composite?: boolean;
  /** Composited targets: keep the picture whole (default true): with `followPose`, the head's
   *  motion is damped where the picture around it would fold or stretch past 2x. False applies
   *  the head's whole motion (the face lands where the source's head is; the picture around
   *  it may stretch). */
  keepWhole?: boolean;
}
/** Milliseconds spent per stage since the last `update()` or `drawFrame()` (mapping, synthesis,
 *  rasterising, blitting). */
export interface Timings { mapMs: number; synthMs: number; rasterMs: number; blitMs: number }
"##;

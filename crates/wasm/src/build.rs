//! `buildModel`, `selectVaried` and `shapeCoverage` for JavaScript: the core [`facemimic::Builder`]
//! and [`facemimic::select_varied`] over RGBA frames.
//!
//! Every entry point validates its input and returns `Result<_, JsError>`; nothing panics
//! across the boundary. The build runs synchronously: in a page, call it from a Web Worker
//! (`www/js/build-worker.js` does) so the page keeps drawing.

use crate::JsError;
use wasm_bindgen::prelude::*;

use super::install_panic_hook;
use super::model::JsModel;
use super::surface::describe;
use facemimic::{
    enrol, EnrolFinder, EnrolFrame, EnrolOptions, EnrolProgress, EnrolStage, FrameProblem,
    FrameQuality, QualityScope, DEFAULT_MIN_SCORE, ENROL_BOXES, MAX_REFINE_ROUNDS,
};
use facemimic::{BuildOptions, ReferenceChoice};
use facemimic::{Image, ImageRef};

#[wasm_bindgen]
extern "C" {
    /// `BuildModelOptions` in TypeScript.
    #[wasm_bindgen(typescript_type = "BuildModelOptions")]
    pub type BuildModelOptionsArg;
    /// `BuildProgressCallback` in TypeScript.
    #[wasm_bindgen(typescript_type = "BuildProgressCallback")]
    pub type BuildProgressArg;
}

#[wasm_bindgen(typescript_custom_section)]
const TS_BUILD: &'static str = r##"
/** One training frame: straight (not premultiplied) RGBA pixels, row-major. */
export interface BuildFrame {
  rgba: Uint8Array | Uint8ClampedArray; width: number; height: number;
  /** This frame's 68 landmarks (136 numbers, 0-based image pixels, x0, y0, x1, y1, ...).
   *  Without them the face finder places them (the most confident face, if its score reaches
   *  `minScore`, its points averaged with a pass on the mirrored image, as `enrolFace`;
   *  otherwise the frame is skipped and reported in the progress). */
  landmarks?: ArrayLike<number> | null;
}
/** What `buildModel` builds from. */
export interface BuildModelOptions {
  /** Training frames (2 or more; 15-20 varied ones make a good model). */
  frames: BuildFrame[];
  /** Landmarks per frame (same order as `frames`), instead of `frames[i].landmarks`. */
  landmarks?: ArrayLike<number>[];
  /** Keep this many varied frames (farthest-point sampling of the aligned shapes) out of
   *  more; default: use every frame. */
  select?: number;
  /** The model's name. */
  name: string;
  /** The face the bases show: "mean" (default), "rest" (the usable frame most at rest:
   *  mouth closed, no smile, eyes open, facing the camera; the page's enrolment builds so, and
   *  a person tracked with their model has their expressions measured from it) or the index
   *  of a frame in `frames`. */
  reference?: "mean" | "rest" | number;
  /** Rounds of refinement (0 = none, the default; at most 3): fit the model to its own training
   *  frames and rebuild from the fitted landmarks. Measured to halve finder-like landmark noise
   *  but to track unseen frames worse (docs/fitting.md), hence off by default. */
  refine?: number;
  /** Fractions of the variance kept (default 0.99 of the shape, at most 12 modes, and 0.98 of the appearance). */
  shapeVariance?: number; appearanceVariance?: number;
  /** The face finder's score (0..1) a face needs to be used, for frames given without
   *  landmarks (default 0: every face the finder accepts). */
  minScore?: number;
  /** Fewest usable frames to build from (default 2, at least 2); fewer throws, naming the
   *  frames skipped and the frames rejected with their reasons. */
  minFrames?: number;
  /** Which frames the quality checks judge: "found" (default: those whose landmarks the face
   *  finder placed), "all" (also frames given with landmarks, as the page's guide passes them)
   *  or "off". A frame whose face is occluded (a hand, a cup, hair), blurred, dark, turned too
   *  far or partly outside the picture is not built from; it is listed in the progress's
   *  `rejected`. */
  quality?: "found" | "all" | "off";
}
/** Why a frame is not used: its face is covered, blurred, too dark or flat, turned too far, or
 *  partly outside the picture. */
export type FrameReason = "occluded" | "blurred" | "dark" | "turned" | "outside" | "frozen";
/** An expression the enrolment guide asks for. */
export type Expression = "smile" | "mouth-open" | "brows" | "eyes-closed" | "turn-left" | "turn-right";
/** How many of the frames show each expression the guide asks for (`expressionCoverage`):
 *  measured in the face frame against the faces' own median (docs/fitting.md). */
export interface ExpressionCoverage {
  smile: number; mouthOpen: number; brows: number; eyesClosed: number;
  /** The person's own left (a mirrored preview shows it on the left) and right. */
  turnLeft: number; turnRight: number;
  /** Every expression shown. */
  enough: boolean;
  /** The expressions not shown yet, in the order the guide asks for them. */
  missing: Expression[];
}
/** Build progress. `stage` "landmarks": the face finder has searched `done` of the `total`
 *  frames given without landmarks, `skipped` lists the indices (into `frames`) of those where it
 *  found no confident face so far. `stage` "model": `done` of `total` build steps. Return
 *  `false` to cancel (the build then throws an Error whose message is "cancelled" and makes
 *  nothing). */
/** A face found by `enrolFace`. */
export interface EnrolFace {
  /** The 68 landmarks, averaged over the passes (0-based image pixels, x0, y0, x1, y1, ...). */
  landmarks: Float32Array;
  /** The finder's confidence, 0..1. */
  score: number;
  /** How much the passes disagreed (mean point distance to their average / eye distance). */
  spread: number;
  /** The per-frame quality checks' verdict: null for a good frame, else why it should not be
   *  built from (the check of faces against each other is `buildModel`'s). */
  reason: FrameReason | null;
}
export type BuildProgressCallback = (progress: {
  stage: "landmarks" | "model"; done: number; total: number; skipped: number[];
  /** The frames rejected so far by the quality checks (indices into `frames`), with why. */
  rejected: { frame: number; reason: FrameReason }[];
}) => boolean | void;
"##;

fn get(obj: &JsValue, key: &str) -> Result<JsValue, JsError> {
    js_sys::Reflect::get(obj, &JsValue::from_str(key))
        .map_err(|_| JsError::new(&format!("buildModel: cannot read '{key}'")))
}

fn number(obj: &JsValue, key: &str, what: &str) -> Result<Option<f64>, JsError> {
    let v = get(obj, key)?;
    if v.is_undefined() || v.is_null() {
        return Ok(None);
    }
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(Some(x)),
        _ => Err(JsError::new(&format!(
            "buildModel: {what} must be a finite number, got {}",
            describe(&v)
        ))),
    }
}

fn points(v: &JsValue, what: &str) -> Result<Vec<f32>, JsError> {
    if v.is_instance_of::<js_sys::Float32Array>() {
        return Ok(js_sys::Float32Array::from(v.clone()).to_vec());
    }
    if v.is_instance_of::<js_sys::Float64Array>() || js_sys::Array::is_array(v) {
        let a = js_sys::Array::from(v);
        return a
            .iter()
            .map(|x| {
                x.as_f64()
                    .map(|f| f as f32)
                    .ok_or_else(|| JsError::new(&format!("{what}: not a number: {}", describe(&x))))
            })
            .collect();
    }
    Err(JsError::new(&format!(
        "{what}: expected an array of numbers, got {}",
        describe(v)
    )))
}

fn pixels(v: &JsValue, what: &str) -> Result<Vec<u8>, JsError> {
    if v.is_instance_of::<js_sys::Uint8Array>() {
        return Ok(js_sys::Uint8Array::from(v.clone()).to_vec());
    }
    if v.is_instance_of::<js_sys::Uint8ClampedArray>() {
        return Ok(js_sys::Uint8ClampedArray::from(v.clone()).to_vec());
    }
    Err(JsError::new(&format!(
        "{what}.rgba: expected a Uint8Array or Uint8ClampedArray, got {}",
        describe(v)
    )))
}

fn dim(obj: &JsValue, key: &str, what: &str) -> Result<u32, JsError> {
    match number(obj, key, &format!("{what}.{key}"))? {
        Some(x) if x >= 1.0 && x <= facemimic::MAX_IMAGE_SIDE as f64 && x.fract() == 0.0 => {
            Ok(x as u32)
        }
        _ => Err(JsError::new(&format!(
            "buildModel: {what}.{key} must be a whole number in 1..={}",
            facemimic::MAX_IMAGE_SIDE
        ))),
    }
}

/// Builds a person-specific model from RGBA frames, in the canonical reference frame (so it
/// clones with every other model), optionally keeping `select` varied frames. Frames given
/// without landmarks get the face finder's (most confident face, averaged with a pass on the
/// mirrored image, score >= `minScore`); frames
/// where it finds none are skipped and listed in the progress reports. `onProgress` is called
/// after each frame searched and each build step and may return `false` to cancel. Throws an
/// `Error` naming the problem (wrong sizes, too few frames with a face, cancelled).
#[wasm_bindgen(js_name = buildModel)]
pub fn build_model(
    options: BuildModelOptionsArg,
    on_progress: Option<BuildProgressArg>,
) -> Result<JsModel, JsError> {
    install_panic_hook();
    let options: JsValue = options.into();
    if !options.is_object() {
        return Err(JsError::new(&format!(
            "buildModel: expected an options object {{ frames, name, ... }}, got {}",
            describe(&options)
        )));
    }
    let given = read_frames(&options)?;
    let enrol_options = read_options(&options, given.len())?;
    let callback = progress_callback(on_progress)?;
    // Progress goes to the callback; a callback that throws cancels, and its error is thrown.
    let thrown = std::cell::RefCell::new(None::<JsValue>);
    let mut report = |p: EnrolProgress<'_>| -> bool {
        let Some(f) = &callback else { return true };
        if thrown.borrow().is_some() {
            return false;
        }
        let stage = match p.stage {
            EnrolStage::Landmarks => "landmarks",
            EnrolStage::Model => "model",
        };
        let arg = js_sys::Object::new();
        let _ = js_sys::Reflect::set(&arg, &"stage".into(), &stage.into());
        let _ = js_sys::Reflect::set(&arg, &"done".into(), &(p.done as f64).into());
        let _ = js_sys::Reflect::set(&arg, &"total".into(), &(p.total as f64).into());
        let list: js_sys::Array = p.skipped.iter().map(|&i| JsValue::from(i as f64)).collect();
        let _ = js_sys::Reflect::set(&arg, &"skipped".into(), &list);
        let _ = js_sys::Reflect::set(&arg, &"rejected".into(), &rejected_list(p.rejected));
        match f.call1(&JsValue::NULL, &arg) {
            Ok(r) => r.as_bool() != Some(false),
            Err(e) => {
                *thrown.borrow_mut() = Some(e);
                false
            }
        }
    };
    let needs_finder = given.iter().any(|f| f.landmarks.is_none());
    let made = if needs_finder {
        with_finder(|finder| {
            Ok(enrol(
                given,
                &enrol_options,
                None,
                Some(finder),
                &mut report,
            ))
        })?
    } else {
        enrol(given, &enrol_options, None, None, &mut report)
    };
    match made {
        Ok(e) => Ok(JsModel::from(e.model)),
        Err(e) => match thrown.take() {
            Some(t) => Err(JsError::new(&format!(
                "buildModel: onProgress threw: {}",
                describe(&t)
            ))),
            None => Err(build_err(e)),
        },
    }
}

/// `[{ frame, reason }]` of the frames the quality checks rejected.
fn rejected_list(rejected: &[(usize, FrameProblem)]) -> js_sys::Array {
    rejected
        .iter()
        .map(|&(i, why)| {
            let o = js_sys::Object::new();
            let _ = js_sys::Reflect::set(&o, &"frame".into(), &(i as f64).into());
            let _ = js_sys::Reflect::set(&o, &"reason".into(), &why.code().into());
            JsValue::from(o)
        })
        .collect()
}

/// The frames of `buildModel`'s options, each with its landmarks or `None` (the finder's).
fn read_frames(options: &JsValue) -> Result<Vec<EnrolFrame>, JsError> {
    let frames = get(options, "frames")?;
    if !js_sys::Array::is_array(&frames) {
        return Err(JsError::new(&format!(
            "buildModel: 'frames' must be an array of {{ rgba, width, height }}, got {}",
            describe(&frames)
        )));
    }
    let frames = js_sys::Array::from(&frames);
    let landmark_list = get(options, "landmarks")?;
    let landmark_list = if landmark_list.is_undefined() || landmark_list.is_null() {
        None
    } else if js_sys::Array::is_array(&landmark_list) {
        let a = js_sys::Array::from(&landmark_list);
        if a.length() != frames.length() {
            return Err(JsError::new(&format!(
                "buildModel: {} landmark sets for {} frames",
                a.length(),
                frames.length()
            )));
        }
        Some(a)
    } else {
        return Err(JsError::new(&format!(
            "buildModel: 'landmarks' must be an array (one per frame), got {}",
            describe(&landmark_list)
        )));
    };
    // The frames, with the landmarks given (or None: the finder places them).
    let mut given: Vec<EnrolFrame> = Vec::with_capacity(frames.length() as usize);
    for (i, f) in frames.iter().enumerate() {
        let what = format!("frames[{i}]");
        if !f.is_object() {
            return Err(JsError::new(&format!(
                "buildModel: {what} must be {{ rgba, width, height }}, got {}",
                describe(&f)
            )));
        }
        let (width, height) = (dim(&f, "width", &what)?, dim(&f, "height", &what)?);
        let data = pixels(&get(&f, "rgba")?, &what)?;
        if data.len() != width as usize * height as usize * 4 {
            return Err(JsError::coded(
                "bad-frame",
                format!(
                    "buildModel: {what}.rgba has {} bytes, {width}x{height} RGBA needs {}",
                    data.len(),
                    width as usize * height as usize * 4
                ),
            ));
        }
        let lm = match &landmark_list {
            Some(a) => a.get(i as u32),
            None => get(&f, "landmarks")?,
        };
        let landmarks = if lm.is_undefined() || lm.is_null() {
            None
        } else {
            Some(points(&lm, &format!("buildModel: landmarks of {what}"))?)
        };
        given.push(EnrolFrame {
            name: format!("frame{i}"),
            image: Image {
                width,
                height,
                data,
            },
            landmarks,
        });
    }
    if given.len() < 2 {
        return Err(JsError::new(&format!(
            "buildModel: {} frame(s); at least 2 are needed (15-20 varied ones recommended)",
            given.len()
        )));
    }

    Ok(given)
}

/// The enrolment options of `buildModel`'s options, for `frames` frames.
fn read_options(options: &JsValue, frames: usize) -> Result<EnrolOptions, JsError> {
    let name = get(options, "name")?
        .as_string()
        .filter(|s| !s.trim().is_empty())
        .ok_or_else(|| JsError::new("buildModel: 'name' must be a non-empty string"))?;
    if name.len() > 256 {
        return Err(JsError::new("buildModel: 'name' is longer than 256 bytes"));
    }

    let min_score = match number(options, "minScore", "'minScore'")? {
        None => DEFAULT_MIN_SCORE,
        Some(s) if (0.0..=1.0).contains(&s) => s as f32,
        Some(_) => return Err(JsError::new("buildModel: 'minScore' must be in 0..=1")),
    };
    let min_frames = match number(options, "minFrames", "'minFrames'")? {
        None => 2,
        Some(n) if n >= 2.0 && n.fract() == 0.0 && n <= 1e6 => n as usize,
        Some(_) => {
            return Err(JsError::new(
                "buildModel: 'minFrames' must be a whole number of at least 2",
            ))
        }
    };

    // The reference, as an index into the frames given (before skipping and selection).
    let reference = get(options, "reference")?;
    let named = reference.as_string();
    let at_rest = named.as_deref() == Some("rest");
    let reference_index = if reference.is_undefined()
        || reference.is_null()
        || matches!(named.as_deref(), Some("mean" | "rest"))
    {
        None
    } else {
        match reference.as_f64() {
            Some(x) if x >= 0.0 && x.fract() == 0.0 && (x as usize) < frames => Some(x as usize),
            _ => {
                return Err(JsError::new(&format!(
                    "buildModel: 'reference' must be \"mean\", \"rest\" or a frame index below {}, got {}",
                    frames,
                    describe(&reference)
                )))
            }
        }
    };
    let select = match number(options, "select", "'select'")? {
        None => None,
        Some(n) if n >= 2.0 && n.fract() == 0.0 => Some(n as usize),
        Some(_) => {
            return Err(JsError::new(
                "buildModel: 'select' must be a whole number of at least 2",
            ))
        }
    };
    let refine_rounds = match number(options, "refine", "'refine'")? {
        None => 0,
        Some(r) if (0.0..=MAX_REFINE_ROUNDS as f64).contains(&r) && r.fract() == 0.0 => r as usize,
        Some(_) => {
            return Err(JsError::new(
                "buildModel: 'refine' must be a whole number of rounds in 0..=3",
            ))
        }
    };
    let quality = match get(options, "quality")?.as_string().as_deref() {
        None | Some("found") => QualityScope::Found,
        Some("all") => QualityScope::All,
        Some("off") => QualityScope::Off,
        Some(q) => {
            return Err(JsError::new(&format!(
                "buildModel: 'quality' must be \"found\", \"all\" or \"off\", got \"{q}\""
            )))
        }
    };
    let mut build = BuildOptions {
        name,
        reference: match reference_index {
            Some(i) => ReferenceChoice::Named(format!("frame{i}")),
            None if at_rest => ReferenceChoice::Rest,
            None => ReferenceChoice::Mean,
        },
        ..BuildOptions::default()
    };
    if let Some(v) = number(options, "shapeVariance", "'shapeVariance'")? {
        build.shape_variance = v;
    }
    if let Some(v) = number(options, "appearanceVariance", "'appearanceVariance'")? {
        build.appearance_variance = v;
    }
    Ok(EnrolOptions {
        build,
        min_score,
        min_frames,
        select,
        refine_rounds,
        quality,
        ..EnrolOptions::default()
    })
}

/// `buildModel`'s progress callback (`None` when not given).
fn progress_callback(
    on_progress: Option<BuildProgressArg>,
) -> Result<Option<js_sys::Function>, JsError> {
    Ok(match on_progress {
        None => None,
        Some(f) => {
            let v: JsValue = f.into();
            if v.is_undefined() || v.is_null() {
                None
            } else {
                Some(v.dyn_into::<js_sys::Function>().map_err(|v| {
                    JsError::new(&format!(
                        "buildModel: onProgress must be a function, got {}",
                        describe(&v)
                    ))
                })?)
            }
        }
    })
}

thread_local! {
    /// One enrolment finder per thread (worker), made on first use: its nets and buffers are
    /// reused.
    static FINDER: std::cell::RefCell<Option<EnrolFinder>> = const { std::cell::RefCell::new(None) };
}

fn with_finder<T>(f: impl FnOnce(&mut EnrolFinder) -> Result<T, JsError>) -> Result<T, JsError> {
    FINDER.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.is_none() {
            *slot =
                Some(EnrolFinder::new(ENROL_BOXES).map_err(|e| JsError::core("face finder", e))?);
        }
        match slot.as_mut() {
            Some(finder) => f(finder),
            None => Err(JsError::new("buildModel: face finder unavailable")),
        }
    })
}

fn build_err(e: facemimic::Error) -> JsError {
    match e {
        facemimic::Error::Cancelled => JsError::coded("cancelled", "cancelled"),
        // The pipeline's messages name the frames already ("a face in 0 of 3 frames, ...").
        facemimic::Error::Training(msg) => JsError::coded("training", format!("buildModel: {msg}")),
        e => JsError::core("buildModel", e),
    }
}

/// Indices of `n` varied shapes among `shapes` (each 2k numbers, image coordinates), chosen by
/// farthest-point sampling after Procrustes alignment, in the order chosen.
#[wasm_bindgen(js_name = selectVaried)]
pub fn select_varied_js(shapes: Vec<js_sys::Float32Array>, n: usize) -> Result<Vec<u32>, JsError> {
    install_panic_hook();
    let owned: Vec<Vec<f32>> = shapes.iter().map(|s| s.to_vec()).collect();
    let refs: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
    facemimic::select_varied(&refs, n)
        .map(|v| v.into_iter().map(|i| i as u32).collect())
        .map_err(|e| JsError::core("selectVaried", e))
}

/// How much of the variety of `shapes` the `chosen` ones cover, in [0, 1] (see the core's
/// `coverage`): 1 when every shape is among them, 0 when they are no better than the mean face.
#[wasm_bindgen(js_name = shapeCoverage)]
pub fn shape_coverage_js(
    shapes: Vec<js_sys::Float32Array>,
    chosen: Vec<u32>,
) -> Result<f32, JsError> {
    install_panic_hook();
    let owned: Vec<Vec<f32>> = shapes.iter().map(|s| s.to_vec()).collect();
    let refs: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
    let chosen: Vec<usize> = chosen.into_iter().map(|i| i as usize).collect();
    facemimic::coverage(&refs, &chosen).map_err(|e| JsError::core("shapeCoverage", e))
}

/// The index of the face most at rest among `shapes` (each a face's 68 landmarks, image
/// pixels; the core's `most_at_rest`: mouth closed, no smile, brows level, eyes open, facing the
/// camera): the face a person's model is best built about (`buildModel`'s `reference: "rest"`).
#[wasm_bindgen(js_name = mostAtRest)]
pub fn most_at_rest_js(shapes: Vec<js_sys::Float32Array>) -> Result<u32, JsError> {
    install_panic_hook();
    let owned: Vec<Vec<f32>> = shapes.iter().map(|s| s.to_vec()).collect();
    let refs: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
    facemimic::most_at_rest(&refs)
        .map(|i| i as u32)
        .map_err(|e| JsError::core("mostAtRest", e))
}

/// How many of `shapes` (each a face's 68 landmarks, image pixels) show each expression the
/// enrolment guide asks for (the core's `expression_coverage`): `{ smile, mouthOpen, brows,
/// eyesClosed, turnLeft, turnRight, enough, missing }`. Fewer than 5 faces count nothing.
#[wasm_bindgen(js_name = expressionCoverage, unchecked_return_type = "ExpressionCoverage")]
pub fn expression_coverage_js(shapes: Vec<js_sys::Float32Array>) -> Result<JsValue, JsError> {
    install_panic_hook();
    let owned: Vec<Vec<f32>> = shapes.iter().map(|s| s.to_vec()).collect();
    let refs: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
    let c = facemimic::expression_coverage(&refs)
        .map_err(|e| JsError::core("expressionCoverage", e))?;
    let o = js_sys::Object::new();
    let set = |k: &str, v: JsValue| js_sys::Reflect::set(&o, &JsValue::from_str(k), &v);
    let counts = [
        ("smile", c.smile),
        ("mouthOpen", c.mouth_open),
        ("brows", c.brows),
        ("eyesClosed", c.eyes_closed),
        ("turnLeft", c.turn_left),
        ("turnRight", c.turn_right),
    ];
    for (k, n) in counts {
        let _ = set(k, (n as f64).into());
    }
    let _ = set("enough", c.enough.into());
    let missing: js_sys::Array = c.missing().into_iter().map(JsValue::from_str).collect();
    let _ = set("missing", missing.into());
    Ok(o.into())
}

/// Whether two RGBA frames of one size show the same picture (a frozen camera: the core's
/// `same_picture`, the rule `buildModel` rejects repeated frames by as "frozen").
#[wasm_bindgen(js_name = samePicture)]
pub fn same_picture_js(
    #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] a: &[u8],
    #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] b: &[u8],
    width: u32,
    height: u32,
) -> Result<bool, JsError> {
    install_panic_hook();
    let a =
        ImageRef::new(width, height, a).map_err(|e| JsError::new(&format!("samePicture: {e}")))?;
    let b =
        ImageRef::new(width, height, b).map_err(|e| JsError::new(&format!("samePicture: {e}")))?;
    Ok(facemimic::same_picture(&a, &b))
}

/// The face to enrol in one RGBA frame: the finder's most confident face if its score reaches
/// `minScore` (default 0: every face the finder accepts), its landmarks averaged over passes on the image and its mirror
/// (the same landmarks `buildModel` uses for frames given without any); `null` when there is
/// none. Returns `{ landmarks, score, spread, reason }`: `reason` is the per-frame quality
/// checks' verdict ("occluded", "blurred", "dark", "turned", "outside", or null for a good
/// frame).
#[wasm_bindgen(js_name = enrolFace, unchecked_return_type = "EnrolFace | null")]
pub fn enrol_face(
    #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] rgba: &[u8],
    width: u32,
    height: u32,
    min_score: Option<f32>,
) -> Result<JsValue, JsError> {
    install_panic_hook();
    with_finder(|f| enrol_with(f, "enrolFace", rgba, width, height, min_score))
}

/// `enrolFace` with a given finder (`FaceFinder.enrol` passes its own, so one page worker holds
/// one finder for both uses); `what` names the caller in errors.
pub(super) fn enrol_with(
    finder: &mut EnrolFinder,
    what: &str,
    rgba: &[u8],
    width: u32,
    height: u32,
    min_score: Option<f32>,
) -> Result<JsValue, JsError> {
    let min_score = match min_score {
        None => DEFAULT_MIN_SCORE,
        Some(s) if (0.0..=1.0).contains(&s) => s,
        Some(_) => return Err(JsError::new(&format!("{what}: minScore must be in 0..=1"))),
    };
    let img =
        ImageRef::new(width, height, rgba).map_err(|e| JsError::new(&format!("{what}: {e}")))?;
    let face = finder
        .find(&img, min_score)
        .map_err(|e| JsError::new(&format!("{what}: {e}")))?;
    let Some(face) = face else {
        return Ok(JsValue::NULL);
    };
    let o = js_sys::Object::new();
    let set = |k: &str, v: &JsValue| {
        js_sys::Reflect::set(&o, &JsValue::from_str(k), v)
            .map(|_| ())
            .map_err(|_| JsError::new(&format!("{what}: cannot build the result")))
    };
    set(
        "landmarks",
        &js_sys::Float32Array::from(face.landmarks.as_slice()).into(),
    )?;
    set("score", &face.score.into())?;
    set("spread", &face.spread.into())?;
    let reason = FrameQuality::measure(&img, &face.landmarks, Some(face.spread))
        .map_err(|e| JsError::new(&format!("{what}: {e}")))?
        .problem();
    set(
        "reason",
        &reason.map_or(JsValue::NULL, |r| JsValue::from_str(r.code())),
    )?;
    Ok(o.into())
}

//! `buildModel`, `selectVaried` and `shapeCoverage` for JavaScript: the core [`crate::Builder`]
//! and [`crate::select_varied`] over RGBA frames.
//!
//! Every entry point validates its input and returns `Result<_, JsError>`; nothing panics
//! across the boundary. The build runs synchronously: in a page, call it from a Web Worker
//! (`www/js/build-worker.js` does) so the page keeps drawing.

use wasm_bindgen::prelude::*;

use super::install_panic_hook;
use super::model::JsModel;
use super::surface::describe;
use crate::builder::{BuildOptions, Builder, ReferenceChoice, TrainingImage};
use crate::image::Image;

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
  /** This frame's 68 landmarks (136 numbers, 0-based image pixels, x0, y0, x1, y1, ...). */
  landmarks?: ArrayLike<number>;
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
  /** The face the bases show: "mean" (default) or the index of a frame in `frames`. */
  reference?: "mean" | number;
  /** Rounds of refinement (0 = none, the default; at most 3): fit the model to its own training
   *  frames and rebuild from the fitted landmarks. Measured to halve finder-like landmark noise
   *  but to track unseen frames worse (docs/fitting.md), hence off by default. */
  refine?: number;
  /** Fractions of the variance kept (default 0.98 each). */
  shapeVariance?: number; appearanceVariance?: number;
}
/** Build progress: `done` of `total` steps; return `false` to cancel (the build then throws
 *  an Error whose message is "cancelled" and makes nothing). */
export type BuildProgressCallback = (progress: { done: number; total: number }) => boolean | void;
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
        Some(x) if x >= 1.0 && x <= crate::MAX_IMAGE_SIDE as f64 && x.fract() == 0.0 => {
            Ok(x as u32)
        }
        _ => Err(JsError::new(&format!(
            "buildModel: {what}.{key} must be a whole number in 1..={}",
            crate::MAX_IMAGE_SIDE
        ))),
    }
}

/// Builds a person-specific model from RGBA frames with landmarks, in the canonical reference
/// frame (so it clones with every other model), optionally keeping `select` varied frames.
/// `onProgress` is called after each step and may return `false` to cancel. Throws an `Error`
/// naming the problem (missing landmarks, wrong sizes, too few frames, cancelled).
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
    let frames = get(&options, "frames")?;
    if !js_sys::Array::is_array(&frames) {
        return Err(JsError::new(&format!(
            "buildModel: 'frames' must be an array of {{ rgba, width, height }}, got {}",
            describe(&frames)
        )));
    }
    let frames = js_sys::Array::from(&frames);
    let landmark_list = get(&options, "landmarks")?;
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
    let name = get(&options, "name")?
        .as_string()
        .filter(|s| !s.trim().is_empty())
        .ok_or_else(|| JsError::new("buildModel: 'name' must be a non-empty string"))?;
    if name.len() > 256 {
        return Err(JsError::new("buildModel: 'name' is longer than 256 bytes"));
    }

    let mut images = Vec::with_capacity(frames.length() as usize);
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
            return Err(JsError::new(&format!(
                "buildModel: {what}.rgba has {} bytes, {width}x{height} RGBA needs {}",
                data.len(),
                width as usize * height as usize * 4
            )));
        }
        let lm = match &landmark_list {
            Some(a) => a.get(i as u32),
            None => get(&f, "landmarks")?,
        };
        if lm.is_undefined() || lm.is_null() {
            return Err(JsError::new(&format!(
                "buildModel: {what} has no landmarks (give frames[i].landmarks or options.landmarks)"
            )));
        }
        let landmarks = points(&lm, &format!("buildModel: landmarks of {what}"))?;
        images.push(TrainingImage {
            name: format!("frame{i}"),
            image: Image {
                width,
                height,
                data,
            },
            landmarks,
        });
    }
    if images.len() < 2 {
        return Err(JsError::new(&format!(
            "buildModel: {} frame(s); at least 2 are needed (15-20 varied ones recommended)",
            images.len()
        )));
    }

    // The reference, as an index into the frames given (before selection).
    let reference = get(&options, "reference")?;
    let reference_index = if reference.is_undefined()
        || reference.is_null()
        || reference.as_string().as_deref() == Some("mean")
    {
        None
    } else {
        match reference.as_f64() {
            Some(x) if x >= 0.0 && x.fract() == 0.0 && (x as usize) < images.len() => {
                Some(x as usize)
            }
            _ => {
                return Err(JsError::new(&format!(
                    "buildModel: 'reference' must be \"mean\" or a frame index below {}, got {}",
                    images.len(),
                    describe(&reference)
                )))
            }
        }
    };

    if let Some(n) = number(&options, "select", "'select'")? {
        if !(n >= 2.0 && n.fract() == 0.0) {
            return Err(JsError::new(
                "buildModel: 'select' must be a whole number of at least 2",
            ));
        }
        let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
        let mut keep = crate::select_varied(&shapes, n as usize).map_err(build_err)?;
        if let Some(r) = reference_index {
            if !keep.contains(&r) {
                keep.pop();
                keep.push(r);
            }
        }
        keep.sort_unstable();
        let mut all: Vec<Option<TrainingImage>> = images.into_iter().map(Some).collect();
        images = keep.iter().filter_map(|&i| all[i].take()).collect();
    }

    let mut o = BuildOptions {
        name,
        reference: match reference_index {
            Some(i) => ReferenceChoice::Named(format!("frame{i}")),
            None => ReferenceChoice::Mean,
        },
        ..BuildOptions::default()
    };
    if let Some(v) = number(&options, "shapeVariance", "'shapeVariance'")? {
        o.shape_variance = v;
    }
    if let Some(v) = number(&options, "appearanceVariance", "'appearanceVariance'")? {
        o.appearance_variance = v;
    }
    let callback: Option<js_sys::Function> = match on_progress {
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
    };
    let rounds = match number(&options, "refine", "'refine'")? {
        None => 0,
        Some(r) if (0.0..=3.0).contains(&r) && r.fract() == 0.0 => r as usize,
        Some(_) => {
            return Err(JsError::new(
                "buildModel: 'refine' must be a whole number of rounds in 0..=3",
            ))
        }
    };
    let mut thrown: Option<JsValue> = None;
    let model = Builder::new(o).build_refined(&images, None, rounds, &mut |p| {
        let Some(f) = &callback else { return true };
        let arg = js_sys::Object::new();
        let _ = js_sys::Reflect::set(&arg, &"done".into(), &(p.done as f64).into());
        let _ = js_sys::Reflect::set(&arg, &"total".into(), &(p.total as f64).into());
        match f.call1(&JsValue::NULL, &arg) {
            Ok(r) => r.as_bool() != Some(false),
            Err(e) => {
                thrown = Some(e);
                false
            }
        }
    });
    match model {
        Ok(m) => Ok(JsModel::from(m)),
        Err(e) => match thrown {
            Some(t) => Err(JsError::new(&format!(
                "buildModel: onProgress threw: {}",
                describe(&t)
            ))),
            None => Err(build_err(e)),
        },
    }
}

fn build_err(e: crate::Error) -> JsError {
    match e {
        crate::Error::Cancelled => JsError::new("cancelled"),
        e => JsError::new(&format!("buildModel: {e}")),
    }
}

/// Indices of `n` varied shapes among `shapes` (each 2k numbers, image coordinates), chosen by
/// farthest-point sampling after Procrustes alignment, in the order chosen.
#[wasm_bindgen(js_name = selectVaried)]
pub fn select_varied_js(shapes: Vec<js_sys::Float32Array>, n: usize) -> Result<Vec<u32>, JsError> {
    install_panic_hook();
    let owned: Vec<Vec<f32>> = shapes.iter().map(|s| s.to_vec()).collect();
    let refs: Vec<&[f32]> = owned.iter().map(Vec::as_slice).collect();
    crate::select_varied(&refs, n)
        .map(|v| v.into_iter().map(|i| i as u32).collect())
        .map_err(|e| JsError::new(&format!("selectVaried: {e}")))
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
    crate::coverage(&refs, &chosen).map_err(|e| JsError::new(&format!("shapeCoverage: {e}")))
}

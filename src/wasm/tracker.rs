//! `Tracker` in JS: real-time AAM tracking of RGBA frames (wraps [`crate::fit::Tracker`]).
//!
//! Every entry point validates its input and returns `Result<_, JsError>`; nothing panics
//! across the boundary.

use serde::Serialize;
use wasm_bindgen::prelude::*;

use crate::fit::{FitOptions, FitResult, Tracker};
use crate::image::ImageRef;
use crate::similarity::PoseJson;

use super::model::JsModel;

/// What `Tracker.track` returns (a plain JS object).
#[derive(Serialize)]
struct TrackJs<'a> {
    /// Landmarks, image coordinates, `[x0, y0, x1, y1, ...]`.
    landmarks: &'a [f32],
    pose: PoseJson,
    shape: &'a [f32],
    appearance: &'a [f32],
    error: f32,
    iterations: u32,
    converged: bool,
    /// The face is lost on this frame: `landmarks` are the last good fit's, not a face here.
    lost: bool,
    /// The face was (re-)acquired from the face finder on this frame.
    reacquired: bool,
}

fn to_js(r: &FitResult) -> Result<JsValue, JsError> {
    let v = TrackJs {
        landmarks: &r.landmarks,
        pose: r.params.pose.into(),
        shape: &r.params.shape,
        appearance: &r.params.appearance,
        error: r.error,
        iterations: r.iterations,
        converged: r.converged,
        lost: r.lost,
        reacquired: r.reacquired,
    };
    serde_wasm_bindgen::to_value(&v).map_err(|e| JsError::new(&format!("tracker: {e}")))
}

fn err(e: crate::Error) -> JsError {
    JsError::new(&format!("tracker: {e}"))
}

/// Tracks one face through video frames with a model's AAM (inverse compositional fitting,
/// see `docs/fitting.md`). Start a sequence with `startFromLandmarks` or `startFromBox`, then
/// call `track` once per frame.
#[wasm_bindgen(js_name = Tracker)]
pub struct WasmTracker {
    inner: Tracker,
}

#[wasm_bindgen(js_class = Tracker)]
impl WasmTracker {
    /// A tracker for a model given as `.fmm` bytes. Throws if the bytes are not a valid model.
    #[wasm_bindgen(constructor)]
    pub fn new(model_bytes: &[u8]) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        let model = crate::format::read_model(model_bytes).map_err(|e| err(e.into()))?;
        let inner = Tracker::new(&model, FitOptions::default()).map_err(err)?;
        Ok(WasmTracker { inner })
    }

    /// A tracker for a loaded `Model`.
    #[wasm_bindgen(js_name = fromModel)]
    pub fn from_model(model: &JsModel) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        let inner = Tracker::new(model.model(), FitOptions::default()).map_err(err)?;
        Ok(WasmTracker { inner })
    }

    /// Starts a sequence from landmarks on the next frame (`[x0, y0, ...]`, image pixels).
    #[wasm_bindgen(js_name = startFromLandmarks)]
    pub fn start_from_landmarks(&mut self, landmarks: &[f32]) -> Result<(), JsError> {
        self.inner.start_from_landmarks(landmarks).map_err(err)
    }

    /// Starts a sequence from a face box (left, top, width, height in image pixels).
    #[wasm_bindgen(js_name = startFromBox)]
    pub fn start_from_box(&mut self, x: f32, y: f32, w: f32, h: f32) -> Result<(), JsError> {
        self.inner.start_from_box(x, y, w, h).map_err(err)
    }

    /// Starts a sequence with no landmarks: the face finder (built in, loaded on the first
    /// call) finds the face; until it does, frames are reported `lost`. From then on a lost
    /// face is looked for again on every frame, and the frame it is found on reports
    /// `reacquired`. Throws for a model without the finder's 68 landmarks.
    #[wasm_bindgen(js_name = startAuto)]
    pub fn start_auto(&mut self) -> Result<(), JsError> {
        if !self.inner.has_face_source() {
            let n = self.inner.fitter().landmarks();
            if n != 68 {
                return Err(JsError::new(&format!(
                    "tracker: startAuto needs a 68-landmark model (the face finder's layout); this one has {n}"
                )));
            }
            let finder = crate::find::FaceFinder::new().map_err(err)?;
            self.inner.set_face_source(Box::new(finder));
        }
        self.inner.start_auto().map_err(err)
    }

    /// Fits the next frame (RGBA bytes, e.g. `ImageData.data`, `width * height * 4`). Returns
    /// `{ landmarks, pose, shape, appearance, error, iterations, converged, lost, reacquired }`.
    pub fn track(&mut self, data: &[u8], width: u32, height: u32) -> Result<JsValue, JsError> {
        let image = ImageRef::new(width, height, data).map_err(err)?;
        let r = self.inner.track(&image).map_err(err)?;
        to_js(r)
    }

    /// The last frame's result (same shape as `track`'s), or `null` before the first frame.
    pub fn last(&self) -> Result<JsValue, JsError> {
        match self.inner.last() {
            Some(r) => to_js(r),
            None => Ok(JsValue::NULL),
        }
    }

    /// Re-initialisations so far (fits judged implausible, refitted from the last good one).
    #[wasm_bindgen(getter)]
    pub fn resets(&self) -> u32 {
        self.inner.resets()
    }

    /// Frames reported lost so far.
    #[wasm_bindgen(getter, js_name = lostCount)]
    pub fn lost_count(&self) -> u32 {
        self.inner.lost_count()
    }

    /// Faces acquired from the face finder so far (the first of `startAuto`, then each face
    /// found again after lost frames).
    #[wasm_bindgen(getter)]
    pub fn reacquisitions(&self) -> u32 {
        self.inner.reacquisitions()
    }

    /// Frames tracked so far.
    #[wasm_bindgen(getter)]
    pub fn frames(&self) -> u32 {
        self.inner.frames()
    }
}

impl std::fmt::Debug for WasmTracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WasmTracker")
            .field("inner", &self.inner)
            .finish()
    }
}

//! `Tracker` in JS: real-time AAM tracking of RGBA frames (wraps [`facemimic::fit::Tracker`]).
//!
//! Every entry point validates its input and returns `Result<_, JsError>`; nothing panics
//! across the boundary.

use serde::Serialize;
use wasm_bindgen::prelude::*;

use js_sys::{Array, Float32Array, Reflect};
use wasm_bindgen::JsCast;

use facemimic::fit::{
    FitOptions, FitResult, FollowOptions, Follower, Sequence, TrackPolicy, Tracker,
    DEFAULT_TIME_STEP,
};
use facemimic::ImageRef;
use facemimic::PoseJson;

use super::model::JsModel;

/// What `Tracker.track` returns (a plain JS object).
#[derive(Serialize)]
struct TrackJs<'a> {
    /// Landmarks, the frame's pixels, `[x0, y0, x1, y1, ...]`.
    landmarks: &'a [f32],
    /// The fit's pose, the frame's pixels.
    pose: PoseJson,
    /// The last good pose re-centred on the model's mean pose about the sequence's anchor
    /// (`Sequence::placed`): the head placement to drive the source face with.
    placed: PoseJson,
    /// The fit scale in use (fitted pixels per frame pixel; 1 for a follower).
    scale: f32,
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

fn to_js(r: &FitResult, seq: &Sequence, scale: f32) -> Result<JsValue, JsError> {
    let v = TrackJs {
        landmarks: &r.landmarks,
        pose: r.params.pose.into(),
        placed: seq.placed().into(),
        scale,
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

/// `TrackPolicy` in JS (camelCase).
#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
struct PolicyJs {
    appearance_limit: f32,
    max_fit_side: u32,
    min_fit_side: u32,
    max_upscale: f32,
    native_band: f32,
    rescale_change: f32,
    recentre_tau: f32,
    recheck_frames: u32,
}

impl From<&TrackPolicy> for PolicyJs {
    fn from(p: &TrackPolicy) -> Self {
        PolicyJs {
            appearance_limit: p.appearance_limit,
            max_fit_side: p.max_fit_side,
            min_fit_side: p.min_fit_side,
            max_upscale: p.max_upscale,
            native_band: p.native_band,
            rescale_change: p.rescale_change,
            recentre_tau: p.recentre_tau,
            recheck_frames: p.recheck_frames,
        }
    }
}

/// `setPolicy`'s argument: any subset of the policy's values.
#[derive(serde::Deserialize)]
#[serde(rename_all = "camelCase")]
struct PolicyPatch {
    appearance_limit: Option<f32>,
    max_fit_side: Option<u32>,
    min_fit_side: Option<u32>,
    max_upscale: Option<f32>,
    native_band: Option<f32>,
    rescale_change: Option<f32>,
    recentre_tau: Option<f32>,
    recheck_frames: Option<u32>,
}

#[wasm_bindgen(typescript_custom_section)]
const TS_POLICY: &'static str = r##"
/** How a `Tracker` resamples frames and bounds what it reports (`Tracker.policy`). */
export interface TrackPolicy {
  /** Reported appearance parameters are clamped to +- this many standard deviations (0: off). */
  appearanceLimit: number;
  /** `fitScale`: the resampled frame's longer side is at most this, and at least `minFitSide` (px). */
  maxFitSide: number;
  minFitSide: number;
  /** `fitScale`: a frame is enlarged at most this much. */
  maxUpscale: number;
  /** `fitScale`: a face within 1/nativeBand..nativeBand of the model's size is fitted unscaled. */
  nativeBand: number;
  /** `fitScale`: the current scale is kept unless the wanted one differs by more than this fraction. */
  rescaleChange: number;
  /** Seconds in which the pose anchor follows the head (`placed`); 0: it stays at the sequence's first pose. */
  recentreTau: number;
  /** While a face is tracked, every this many frames `wantsFaces` turns true and the faces
   *  offered give a second opinion: a fit from the one nearest the tracked face, kept when it
   *  fits lower (a fit led into a wrong minimum, a hand under the chin read as an open mouth,
   *  comes back). 0: never. */
  recheckFrames: number;
}
"##;

fn err(e: facemimic::Error) -> JsError {
    JsError::new(&format!("tracker: {e}"))
}

/// `offerFaces`' argument: `FaceFinder.find`'s result (objects with `landmarks`) or arrays of
/// `2n` numbers, as vectors (lengths and values are checked by the core).
fn faces_from_js(faces: &JsValue, who: &str) -> Result<Vec<Vec<f32>>, JsError> {
    if !Array::is_array(faces) {
        return Err(JsError::new(&format!(
            "{who}: offerFaces expects an array of faces"
        )));
    }
    let key = JsValue::from_str("landmarks");
    let mut out = Vec::new();
    for (i, f) in Array::from(faces).iter().enumerate() {
        let pts = match Reflect::get(&f, &key) {
            Ok(v) if !v.is_undefined() && !v.is_null() => v,
            _ => f,
        };
        if !(pts.is_object() && Reflect::has(&pts, &JsValue::from_str("length")).unwrap_or(false)) {
            return Err(JsError::new(&format!(
                "{who}: offerFaces: face {i} has no landmarks (an array of 2n numbers expected)"
            )));
        }
        out.push(Float32Array::new(&pts).to_vec());
    }
    Ok(out)
}

/// Tracks one face through video frames with a model's AAM (inverse compositional fitting,
/// see `docs/fitting.md`). Start a sequence with `startFromLandmarks` or `startFromBox`, then
/// call `track` once per frame.
#[wasm_bindgen(js_name = Tracker)]
#[derive(Debug)]
pub struct WasmTracker {
    inner: Tracker,
}

#[wasm_bindgen(js_class = Tracker)]
impl WasmTracker {
    /// A tracker for a model given as `.fmm` bytes. Throws if the bytes are not a valid model.
    #[wasm_bindgen(constructor)]
    pub fn new(model_bytes: &[u8]) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        let model = facemimic::format::read_model(model_bytes).map_err(|e| err(e.into()))?;
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

    /// The scale at which the tracker fits a `width x height` frame with a face `faceHeight`
    /// pixels tall (the policy's rule; `track` applies it itself). `current` (0 for none) is
    /// kept unless the wanted scale differs by more than the policy's `rescaleChange`.
    #[wasm_bindgen(js_name = fitScale)]
    pub fn fit_scale(&self, face_height: f32, width: u32, height: u32, current: f32) -> f32 {
        self.inner.fit_scale(face_height, width, height, current)
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
            let finder = facemimic::find::FaceFinder::new().map_err(err)?;
            self.inner.set_face_source(Box::new(finder));
        }
        self.inner.start_auto().map_err(err)
    }

    /// The last frame's result (same shape as `track`'s), or `null` before the first frame.
    pub fn last(&self) -> Result<JsValue, JsError> {
        match self.inner.last() {
            Some(r) => to_js(r, self.inner.sequence(), self.inner.scale()),
            None => Ok(JsValue::NULL),
        }
    }

    /// The fit scale in use (fitted pixels per frame pixel; 0 before a sequence's first frame).
    #[wasm_bindgen(getter)]
    pub fn scale(&self) -> f32 {
        self.inner.scale()
    }

    /// Starts a sequence with no landmarks, with faces given by `offerFaces` (e.g. from a
    /// `FaceFinder` running in a worker, so finding never stalls the page): frames are reported
    /// `lost` until a face is acquired; from then on a lost face is first refitted from the last
    /// good fit and acquired again from the next faces offered (`wantsFaces` says when).
    #[wasm_bindgen(js_name = startSearching)]
    pub fn start_searching(&mut self) {
        self.inner.start_searching();
    }

    /// Whether faces will be offered (`offerFaces`) in every sequence, however it was started:
    /// then a lost face is searched for (`wantsFaces` turns true), and until faces are offered
    /// each frame gets one ordinary fit from the last good fit (no harder retry).
    /// `startSearching` turns it on.
    #[wasm_bindgen(js_name = expectOffers)]
    pub fn expect_offers(&mut self, yes: bool) {
        self.inner.expect_offers(yes);
    }

    /// The tracking policy (`{ appearanceLimit, maxFitSide, minFitSide, maxUpscale, nativeBand,
    /// rescaleChange }`).
    #[wasm_bindgen(getter, unchecked_return_type = "TrackPolicy")]
    pub fn policy(&self) -> Result<JsValue, JsError> {
        serde_wasm_bindgen::to_value(&PolicyJs::from(self.inner.policy()))
            .map_err(|e| JsError::new(&format!("tracker: {e}")))
    }

    /// Changes some of the tracking policy's values (the others keep theirs). Throws, changing
    /// nothing, for a value out of range.
    #[wasm_bindgen(js_name = setPolicy)]
    pub fn set_policy(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Partial<TrackPolicy>")] policy: JsValue,
    ) -> Result<(), JsError> {
        const KEYS: [&str; 8] = [
            "appearanceLimit",
            "maxFitSide",
            "minFitSide",
            "maxUpscale",
            "nativeBand",
            "rescaleChange",
            "recentreTau",
            "recheckFrames",
        ];
        if !policy.is_object() {
            return Err(JsError::new("tracker: setPolicy expects an object"));
        }
        for k in js_sys::Object::keys(policy.unchecked_ref::<js_sys::Object>()).iter() {
            let k = k.as_string().unwrap_or_default();
            if !KEYS.contains(&k.as_str()) {
                return Err(JsError::new(&format!(
                    "tracker: setPolicy: unknown value \"{k}\" (known: {})",
                    KEYS.join(", ")
                )));
            }
        }
        let base = PolicyJs::from(self.inner.policy());
        let patch: PolicyPatch = serde_wasm_bindgen::from_value(policy)
            .map_err(|e| JsError::new(&format!("tracker: setPolicy: {e}")))?;
        let p = TrackPolicy {
            appearance_limit: patch.appearance_limit.unwrap_or(base.appearance_limit),
            max_fit_side: patch.max_fit_side.unwrap_or(base.max_fit_side),
            min_fit_side: patch.min_fit_side.unwrap_or(base.min_fit_side),
            max_upscale: patch.max_upscale.unwrap_or(base.max_upscale),
            native_band: patch.native_band.unwrap_or(base.native_band),
            rescale_change: patch.rescale_change.unwrap_or(base.rescale_change),
            recentre_tau: patch.recentre_tau.unwrap_or(base.recentre_tau),
            recheck_frames: patch.recheck_frames.unwrap_or(base.recheck_frames),
        };
        self.inner.set_policy(p).map_err(err)
    }

    /// Re-initialisations so far (fits judged implausible, refitted from the last good one).
    #[wasm_bindgen(getter)]
    pub fn resets(&self) -> u32 {
        self.inner.resets()
    }

    /// Second opinions taken while tracking (`policy.recheckFrames`).
    #[wasm_bindgen(getter)]
    pub fn rechecks(&self) -> u32 {
        self.inner.rechecks().0
    }

    /// Second opinions kept (they fitted lower than the tracked fit).
    #[wasm_bindgen(getter, js_name = rechecksKept)]
    pub fn rechecks_kept(&self) -> u32 {
        self.inner.rechecks().1
    }
}

impl WasmTracker {
    /// `track`'s step: the core's, `dt` defaulting to [`DEFAULT_TIME_STEP`].
    fn step(&mut self, image: &ImageRef<'_>, dt: Option<f32>) -> facemimic::Result<()> {
        self.inner
            .track_timed(image, dt.unwrap_or(DEFAULT_TIME_STEP))
            .map(drop)
    }
}

fn follow_err(e: facemimic::Error) -> JsError {
    JsError::new(&format!("follower: {e}"))
}

/// Follows anyone's face with a model that is not theirs (a bundled person's): the
/// person-independent path ([`facemimic::fit::Follower`]; docs/fitting.md, "Following anyone").
/// Each frame, the face finder's landmarks near the last face, smoothed, read as expression
/// relative to the person's own running neutral shape and mapped onto the model's shape modes;
/// the appearance stays at the model's mean. Same calls and results as `Tracker`, so a page
/// drives either: `track` returns `{ landmarks, pose, shape, appearance, error, iterations,
/// converged, lost, reacquired }` (`error`: the disagreement of the frame's two landmark
/// passes, in eye distances; `iterations`: the passes run). Faces to start from come from
/// `offerFaces` (a finder in a worker) unless `expectOffers(false)`, when the follower runs
/// its own finder on the frame.
#[wasm_bindgen(js_name = Follower)]
pub struct WasmFollower {
    inner: Follower,
    /// Seconds between frames when `track` is given none.
    dt: f32,
}

#[wasm_bindgen(js_class = Follower)]
impl WasmFollower {
    /// A follower driving a loaded `Model`'s shape modes. Throws for a model without the
    /// finder's 68 landmarks.
    #[wasm_bindgen(js_name = fromModel)]
    pub fn from_model(model: &JsModel) -> Result<WasmFollower, JsError> {
        super::install_panic_hook();
        let mut inner =
            Follower::new(model.model(), FollowOptions::default()).map_err(follow_err)?;
        inner.set_search(false);
        Ok(WasmFollower {
            inner,
            dt: 1.0 / 30.0,
        })
    }

    /// The last frame's result (same shape as `track`'s).
    pub fn last(&self) -> Result<JsValue, JsError> {
        to_js(self.inner.last(), self.inner.sequence(), 1.0)
    }

    /// Always 1: a follower reads the frame at its own size.
    #[wasm_bindgen(getter)]
    pub fn scale(&self) -> f32 {
        1.0
    }

    /// Starts a new person from their face's 68 landmarks on the next frame.
    #[wasm_bindgen(js_name = startFromLandmarks)]
    pub fn start_from_landmarks(&mut self, landmarks: &[f32]) -> Result<(), JsError> {
        self.inner
            .start_from_landmarks(landmarks)
            .map_err(follow_err)
    }

    /// Starts a new person from a face box (left, top, width, height) on the next frame.
    #[wasm_bindgen(js_name = startFromBox)]
    pub fn start_from_box(&mut self, x: f32, y: f32, w: f32, h: f32) -> Result<(), JsError> {
        self.inner.start_from_box(x, y, w, h).map_err(follow_err)
    }

    /// Starts a new person with no face yet: frames are `lost` until faces are offered.
    #[wasm_bindgen(js_name = startSearching)]
    pub fn start_searching(&mut self) {
        self.inner.restart();
    }

    /// `true` (the default): faces to start from come from `offerFaces`; `false`: the
    /// follower searches the frame itself (a finder on the main thread: tens of ms a search).
    #[wasm_bindgen(js_name = expectOffers)]
    pub fn expect_offers(&mut self, yes: bool) {
        self.inner.set_search(!yes);
    }

    /// Always 0 (a follower does not refit; kept so a page drives it as a `Tracker`).
    #[wasm_bindgen(getter)]
    pub fn resets(&self) -> u32 {
        0
    }

    /// Which path this is: `"landmarks"` (a `Tracker` has none).
    #[wasm_bindgen(getter)]
    pub fn path(&self) -> String {
        "landmarks".into()
    }
}

impl WasmFollower {
    /// `track`'s step: the core's, `dt` defaulting to the follower's.
    fn step(&mut self, image: &ImageRef<'_>, dt: Option<f32>) -> facemimic::Result<()> {
        self.inner.track(image, dt.unwrap_or(self.dt)).map(drop)
    }
}

impl std::fmt::Debug for WasmFollower {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WasmFollower")
            .field("inner", &self.inner)
            .finish()
    }
}

/// The calls a `Tracker` and a `Follower` share, read from their core's `Sequence` and policy
/// (one definition for both classes); `track` runs the class's own `step` and is documented by
/// the doc comment given last.
macro_rules! shared_calls {
    ($class:ident, $js:ident, $err:ident, $who:literal, $(#[$track_doc:meta])*) => {
        #[wasm_bindgen(js_class = $js)]
        impl $class {
            $(#[$track_doc])*
            pub fn track(
                &mut self,
                data: &[u8],
                width: u32,
                height: u32,
                dt: Option<f32>,
            ) -> Result<JsValue, JsError> {
                let image = ImageRef::new(width, height, data).map_err($err)?;
                self.step(&image, dt).map_err($err)?;
                self.last()
            }

            /// Faces found in a recent frame, in the frame's pixels, most confident first:
            /// `FaceFinder.find`'s result (objects with `landmarks`) or arrays of `2n` values.
            /// The next acquisition (or a `Tracker`'s second opinion) takes the one nearest
            /// the last face. Throws for a wrong
            /// number of points or non-finite ones (nothing is kept then).
            #[wasm_bindgen(js_name = offerFaces)]
            pub fn offer_faces(
                &mut self,
                #[wasm_bindgen(
                    unchecked_param_type = "ReadonlyArray<FoundFace | ArrayLike<number>>"
                )]
                faces: JsValue,
            ) -> Result<(), JsError> {
                let out = faces_from_js(&faces, $who)?;
                self.inner.offer_faces(out).map_err($err)
            }

            /// True while a face is looked for (a search, or a lost face with offers
            /// expected), or a `Tracker`'s second opinion on a tracked face is due
            /// (`policy.recheckFrames`), and no offered faces are left to try: the moment to
            /// run a finder and `offerFaces`.
            #[wasm_bindgen(getter, js_name = wantsFaces)]
            pub fn wants_faces(&self) -> bool {
                self.inner.wants_faces()
            }

            /// Frames reported lost so far.
            #[wasm_bindgen(getter, js_name = lostCount)]
            pub fn lost_count(&self) -> u32 {
                self.inner.sequence().lost_count()
            }

            /// Faces acquired so far (the first face of a search, then each face found again).
            #[wasm_bindgen(getter)]
            pub fn reacquisitions(&self) -> u32 {
                self.inner.sequence().reacquisitions()
            }

            /// Frames followed so far.
            #[wasm_bindgen(getter)]
            pub fn frames(&self) -> u32 {
                self.inner.sequence().frames()
            }
        }
    };
}

shared_calls!(
    WasmTracker,
    Tracker,
    err,
    "tracker",
    /// Fits the next frame (RGBA bytes at the frame's own size, e.g. `ImageData.data`,
    /// `width * height * 4`), `dt` seconds after the previous one (default 1/30; the pose
    /// anchor's time step). The tracker chooses the fit scale and resamples the frame itself.
    /// Returns `{ landmarks, pose, placed, scale, shape, appearance, error, iterations,
    /// converged, lost, reacquired }`, landmarks and poses in the frame's pixels; `placed` is
    /// the pose re-centred on the model's mean pose (what to drive the source face with).
    /// Throws for a bad image or a `dt` that is not a finite non-negative number.
);
shared_calls!(
    WasmFollower,
    Follower,
    follow_err,
    "follower",
    /// Follows the face in the next frame (RGBA bytes, `width * height * 4`), `dt` seconds
    /// after the previous one (default 1/30). Throws for a bad image or a `dt` that is not a
    /// positive number.
);

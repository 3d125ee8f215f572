//! `Tracker` in JS: real-time tracking of RGBA frames, one class over the core's one tracking
//! interface ([`facemimic::fit::FaceTracker`]): the AAM [`facemimic::fit::Tracker`] or the
//! landmark [`facemimic::fit::Follower`], chosen by the core's policy
//! ([`facemimic::fit::tracker_for`]).
//!
//! Every entry point validates its input and returns `Result<_, JsError>`; nothing panics
//! across the boundary.

use crate::JsError;
use serde::Serialize;
use wasm_bindgen::prelude::*;

use js_sys::{Array, Float32Array, Reflect};
use wasm_bindgen::JsCast;

use facemimic::fit::{
    tracker_for, tracker_of_kind, FaceTracker, FitResult, Sequence, TrackPolicy, TrackerKind,
    Whose, DEFAULT_TIME_STEP,
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
    /// The fit scale in use (fitted pixels per frame pixel; 1 for the landmark path).
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
    /// "tracking", "unsure" or "lost" (`TrackStatus::name`).
    status: &'static str,
    /// Why the fit is unsure or lost (`Reasons::names`); empty while tracking.
    reasons: Vec<&'static str>,
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
        status: r.status.name(),
        reasons: r.reasons.names().collect(),
    };
    serde_wasm_bindgen::to_value(&v).map_err(|e| JsError::core("tracker", e))
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
/** Which way a `Tracker` follows a face (`Tracker.path`, `Tracker.kindFor`): "aam" fits the
 *  model's active appearance model to every frame (for the person the model was built from);
 *  "landmarks" reads the face finder's landmarks as expression and maps them onto the model's
 *  shape modes (anyone, with a model that is not theirs). */
export type TrackerKind = "aam" | "landmarks";
/** What `Tracker.track` and `Tracker.last` return: one frame's fit (or follow). */
export interface FitResult {
  /** 68 landmarks in the frame's pixels, `[x0, y0, x1, y1, ...]`. */
  landmarks: number[];
  /** The fit's pose, model -> frame pixels. */
  pose: Pose;
  /** The last good pose re-centred on the model's mean pose: the head placement to drive the
   *  source face with (`Cloner.setSourceParams({ ...fit, pose: fit.placed })`). */
  placed: Pose;
  /** The fit scale in use (fitted pixels per frame pixel; 1 for the landmark path). */
  scale: number;
  shape: number[];
  /** Clamped to +- `policy.appearanceLimit` standard deviations. */
  appearance: number[];
  /** The AAM's RMS grey residual, or for the landmark path 1 minus the mesh's face score. */
  error: number;
  iterations: number;
  converged: boolean;
  /** No face on this frame: `landmarks` are the last good fit's, not a face here. */
  lost: boolean;
  /** The face was found (again) by the face finder on this frame. */
  reacquired: boolean;
  /** How far the fit can be trusted: "tracking"; "unsure" (the tracker's checks doubt it:
   *  collapsed, folded, slid off the finder's face, an unlikely shape, a residual or pose jump;
   *  drive nothing with it, hold the last good expression); "lost" (as `lost`). */
  status: "tracking" | "unsure" | "lost";
  /** Why the fit is unsure or lost, by stable name: "collapsed", "folded", "shape",
   *  "residual", "jump", "finder", "contrast", "outside", "no-face", "covered" (the follower:
   *  the lips do not stand out from the skin, something covers the mouth); empty while tracking. */
  reasons: string[];
}
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
    JsError::core("tracker", e)
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

/// Follows one face through video frames, one frame at a time: the package's one tracking
/// class, over the core's one interface (`FaceTracker`). Two kinds (`path`):
///
/// - `"aam"` (`new Tracker(bytes)`, `Tracker.fromModel(model)`): the model's AAM is fitted to
///   every frame (inverse compositional fitting, see `docs/fitting.md`): for the person the
///   model was built from.
/// - `"landmarks"` (`Tracker.follower(model)`): anyone is followed with a model that is not
///   theirs (a bundled person's): the face finder's landmarks near the last face, smoothed, read
///   as expression relative to the person's own running neutral face and mapped onto the
///   model's shape modes; the appearance stays the model's mean (docs/fitting.md, "Following
///   anyone"). Needs a 68-landmark model.
///
/// `Tracker.forModel(model, own)` chooses by the core's policy (`Tracker.kindFor`). Both kinds
/// take the same calls and return the same results: start a sequence (`startFromLandmarks`,
/// `startFromBox`, `startSearching`, `startAuto`), then `track` once per frame; faces found in
/// a worker are given with `offerFaces` when `wantsFaces` (after `expectOffers(true)`).
/// Calls that mean nothing for the landmark path answer neutrally: `resets`, `rechecks` and
/// `rechecksKept` are 0, `scale` and `fitScale` are 1 (it reads frames at their own size), and
/// of `policy` only `recentreTau` is used.
#[wasm_bindgen(js_name = Tracker)]
#[derive(Debug)]
pub struct WasmTracker {
    inner: Box<dyn FaceTracker>,
}

#[wasm_bindgen(js_class = Tracker)]
impl WasmTracker {
    /// An AAM tracker (`path` "aam") for a model given as `.fmm` bytes. Throws if the bytes are
    /// not a valid model.
    #[wasm_bindgen(constructor)]
    pub fn new(
        #[wasm_bindgen(unchecked_param_type = "Uint8Array")] model_bytes: &[u8],
    ) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        let model = facemimic::format::read_model(model_bytes).map_err(|e| err(e.into()))?;
        Self::of_kind(&model, TrackerKind::Aam)
    }

    /// An AAM tracker (`path` "aam") for a loaded `Model`.
    #[wasm_bindgen(js_name = fromModel)]
    pub fn from_model(model: &JsModel) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        Self::of_kind(model.model(), TrackerKind::Aam)
    }

    /// A landmark follower (`path` "landmarks") driving a loaded `Model`'s shape modes: anyone
    /// followed with a model that is not theirs. Throws for a model without the face finder's
    /// 68 landmarks. Like every new tracker it searches with its own finder until
    /// `expectOffers(true)`.
    pub fn follower(model: &JsModel) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        Self::of_kind(model.model(), TrackerKind::Landmarks)
    }

    /// The tracker the core's policy chooses for following a face with `model` (`kindFor`):
    /// `own` true when the model was built from the person followed (their own model, or the
    /// bundled clip of the bundled person).
    #[wasm_bindgen(js_name = forModel)]
    pub fn for_model(model: &JsModel, own: bool) -> Result<WasmTracker, JsError> {
        super::install_panic_hook();
        let inner = tracker_for(model.model(), whose(own)).map_err(err)?;
        Ok(WasmTracker { inner })
    }

    /// The core's tracking policy without building a tracker: `"aam"` for the person's own
    /// model, `"landmarks"` for anyone else's (a model with the finder's 68 landmarks; `"aam"`
    /// otherwise, the only way it can follow a face).
    #[wasm_bindgen(js_name = kindFor, unchecked_return_type = "TrackerKind")]
    pub fn kind_for(model: &JsModel, own: bool) -> String {
        TrackerKind::for_source(whose(own), model.model().landmarks())
            .name()
            .into()
    }

    /// Which way this tracker follows a face: `"aam"` or `"landmarks"`.
    #[wasm_bindgen(getter, unchecked_return_type = "TrackerKind")]
    pub fn path(&self) -> String {
        self.inner.kind().name().into()
    }

    /// Fits or follows the next frame (RGBA bytes at the frame's own size, e.g.
    /// `ImageData.data`, `width * height * 4`), `dt` seconds after the previous one (default
    /// 1/30; the pose anchor's time step, and the landmark smoothing's). Returns `{ landmarks,
    /// pose, placed, scale, shape, appearance, error, iterations, converged, lost, reacquired,
    /// status, reasons }` (`status`: "tracking", "unsure" or "lost"; `reasons`: why not tracking),
    /// landmarks and poses in the frame's pixels; `placed` is the pose re-centred on the
    /// model's mean pose (what to drive the source face with). `error`: the AAM's RMS grey
    /// residual, or for the landmark path 1 minus the mesh's face score; `iterations`: the
    /// fit's iterations, or the mesh passes. Throws for a bad image, a `dt` that is not a
    /// finite non-negative number, or an AAM tracker with no sequence started.
    #[wasm_bindgen(unchecked_return_type = "FitResult")]
    pub fn track(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] data: &[u8],
        width: u32,
        height: u32,
        dt: Option<f32>,
    ) -> Result<JsValue, JsError> {
        let image = ImageRef::new(width, height, data).map_err(err)?;
        self.inner
            .track(&image, dt.unwrap_or(DEFAULT_TIME_STEP))
            .map_err(err)?;
        self.last()
    }

    /// The last frame's result (same shape as `track`'s), or `null` before the first frame
    /// (for an AAM tracker: of the sequence).
    #[wasm_bindgen(unchecked_return_type = "FitResult | null")]
    pub fn last(&self) -> Result<JsValue, JsError> {
        match self.inner.last() {
            Some(r) => to_js(r, self.inner.sequence(), self.inner.scale()),
            None => Ok(JsValue::NULL),
        }
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

    /// Starts a sequence with no landmarks, found by the tracker's own face finder (built in,
    /// loaded on the first call for an AAM tracker); until it is found, frames are reported
    /// `lost`. From then on a lost face is looked for again on every frame, and the frame it is
    /// found on reports `reacquired`. The landmark path stops expecting offers. Throws for an
    /// AAM tracker of a model without the finder's 68 landmarks.
    #[wasm_bindgen(js_name = startAuto)]
    pub fn start_auto(&mut self) -> Result<(), JsError> {
        self.inner.start_auto().map_err(err)
    }

    /// Starts a sequence with no landmarks, with faces given by `offerFaces` (e.g. from a
    /// `FaceFinder` running in a worker, so finding never stalls the page): frames are reported
    /// `lost` until a face is acquired (`wantsFaces` says when to offer). The AAM tracker turns
    /// `expectOffers` on, and from then on refits a lost face from the last good fit until the
    /// next faces offered; the landmark path forgets the person (their neutral face is
    /// estimated again) and searches with its own finder unless `expectOffers(true)`.
    #[wasm_bindgen(js_name = startSearching)]
    pub fn start_searching(&mut self) {
        self.inner.start_searching();
    }

    /// Whether faces will be offered (`offerFaces`) in every sequence, however it was started:
    /// then a lost face is searched for with them (`wantsFaces` turns true); the landmark path
    /// no longer runs its own finder on the whole frame, the AAM tracker's frames get one
    /// ordinary fit from the last good fit until they come. Off for a new tracker.
    #[wasm_bindgen(js_name = expectOffers)]
    pub fn expect_offers(&mut self, yes: bool) {
        self.inner.expect_offers(yes);
    }

    /// Faces found in a recent frame, in the frame's pixels, most confident first:
    /// `FaceFinder.find`'s result (objects with `landmarks`) or arrays of `2n` values. The next
    /// acquisition (or an AAM tracker's second opinion) takes the one nearest the last face.
    /// Throws for a wrong number of points or non-finite ones (nothing is kept then).
    #[wasm_bindgen(js_name = offerFaces)]
    pub fn offer_faces(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "ReadonlyArray<FoundFace | ArrayLike<number>>")]
        faces: JsValue,
    ) -> Result<(), JsError> {
        let out = faces_from_js(&faces, "tracker")?;
        self.inner.offer_faces(out).map_err(err)
    }

    /// True while a face is looked for (a search, or a lost face with offers expected), or an
    /// AAM tracker's second opinion on a tracked face is due (`policy.recheckFrames`), and no
    /// offered faces are left to try: the moment to run a finder and `offerFaces`.
    #[wasm_bindgen(getter, js_name = wantsFaces)]
    pub fn wants_faces(&self) -> bool {
        self.inner.wants_faces()
    }

    /// The fit scale in use (fitted pixels per frame pixel; 0 before an AAM sequence's first
    /// frame; always 1 for the landmark path).
    #[wasm_bindgen(getter)]
    pub fn scale(&self) -> f32 {
        self.inner.scale()
    }

    /// The scale at which the tracker fits a `width x height` frame with a face `faceHeight`
    /// pixels tall (the policy's rule; `track` applies it itself). `current` (0 for none) is
    /// kept unless the wanted scale differs by more than the policy's `rescaleChange`. Always
    /// 1 for the landmark path.
    #[wasm_bindgen(js_name = fitScale)]
    pub fn fit_scale(&self, face_height: f32, width: u32, height: u32, current: f32) -> f32 {
        self.inner.fit_scale(face_height, width, height, current)
    }

    /// The tracking policy (`{ appearanceLimit, maxFitSide, minFitSide, maxUpscale, nativeBand,
    /// rescaleChange, recentreTau, recheckFrames }`).
    #[wasm_bindgen(getter, unchecked_return_type = "TrackPolicy")]
    pub fn policy(&self) -> Result<JsValue, JsError> {
        serde_wasm_bindgen::to_value(&PolicyJs::from(self.inner.policy()))
            .map_err(|e| JsError::core("tracker", e))
    }

    /// Changes some of the tracking policy's values (the others keep theirs). Throws, changing
    /// nothing, for a value out of range or an unknown name.
    #[wasm_bindgen(js_name = setPolicy)]
    pub fn set_policy(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Partial<TrackPolicy>")] policy: JsValue,
    ) -> Result<(), JsError> {
        let p = patched_policy(self.inner.policy(), policy)?;
        self.inner.set_policy(p).map_err(err)
    }

    /// Re-initialisations so far (fits judged implausible, refitted from the last good one);
    /// always 0 for the landmark path (it does not refit).
    #[wasm_bindgen(getter)]
    pub fn resets(&self) -> u32 {
        self.inner.resets()
    }

    /// Second opinions taken while tracking (`policy.recheckFrames`); 0 for the landmark path.
    #[wasm_bindgen(getter)]
    pub fn rechecks(&self) -> u32 {
        self.inner.rechecks().0
    }

    /// Second opinions kept (they fitted lower than the tracked fit); 0 for the landmark path.
    #[wasm_bindgen(getter, js_name = rechecksKept)]
    pub fn rechecks_kept(&self) -> u32 {
        self.inner.rechecks().1
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

    /// Frames tracked so far.
    #[wasm_bindgen(getter)]
    pub fn frames(&self) -> u32 {
        self.inner.sequence().frames()
    }
}

impl WasmTracker {
    fn of_kind(model: &facemimic::Model, kind: TrackerKind) -> Result<WasmTracker, JsError> {
        let inner = tracker_of_kind(model, kind).map_err(err)?;
        Ok(WasmTracker { inner })
    }
}

/// `own` as the core's [`Whose`].
fn whose(own: bool) -> Whose {
    if own {
        Whose::Own
    } else {
        Whose::Other
    }
}

/// `setPolicy`'s argument over `base`: any subset of the policy's values, by their JS names.
fn patched_policy(base: &TrackPolicy, policy: JsValue) -> Result<TrackPolicy, JsError> {
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
    let base = PolicyJs::from(base);
    let patch: PolicyPatch = serde_wasm_bindgen::from_value(policy)
        .map_err(|e| JsError::core("tracker: setPolicy", e))?;
    Ok(TrackPolicy {
        appearance_limit: patch.appearance_limit.unwrap_or(base.appearance_limit),
        max_fit_side: patch.max_fit_side.unwrap_or(base.max_fit_side),
        min_fit_side: patch.min_fit_side.unwrap_or(base.min_fit_side),
        max_upscale: patch.max_upscale.unwrap_or(base.max_upscale),
        native_band: patch.native_band.unwrap_or(base.native_band),
        rescale_change: patch.rescale_change.unwrap_or(base.rescale_change),
        recentre_tau: patch.recentre_tau.unwrap_or(base.recentre_tau),
        recheck_frames: patch.recheck_frames.unwrap_or(base.recheck_frames),
    })
}

impl WasmTracker {
    /// The core tracker, for a `Cloner` that reads its fit inside wasm (`sourceFromTracker`).
    pub(crate) fn face_tracker(&self) -> &dyn FaceTracker {
        &*self.inner
    }
}

//! AAM fitting and tracking: inverse compositional fitting of a [`crate::Model`] with the
//! global similarity composed with the shape (Matthews & Baker, "Active Appearance Models
//! Revisited", IJCV 2004), and a [`Tracker`] that follows a face through video; and a
//! [`Follower`], the person-independent path that follows anyone's face with a model that is not
//! theirs (the face finder's landmarks mapped onto the model's shape modes).
//!
//! Design (see `docs/fitting.md` for the measurements behind it):
//! - The fit runs on a grey-level appearance model derived once per model (luminance of `A0`
//!   and of the RGB modes, plus optional gain and bias images, re-orthonormalised) on a
//!   subsampled set of frame pixels per level (coarse to fine).
//! - Each level first runs project-out inverse compositional iterations (steepest-descent
//!   images and Hessian precomputed; an iteration costs `O(kN)`), then, on the finest level, a
//!   few appearance-aware refinement steps: the appearance `lambda` is estimated by projection,
//!   the template gradient is that of `A0 + A lambda` (not of `A0` alone), and the Hessian is
//!   the Schur complement that eliminates `lambda` (the Wiberg / simultaneous Gauss-Newton
//!   step). This is what keeps a talking face (teeth, tongue, shadows the mean does not have)
//!   from dragging the mesh off.
//! - A Tikhonov prior on `p / sigma` conditions the shape update.

mod algorithm;
mod anchor;
mod confidence;
mod driver;
mod face_tracker;
mod follow;
mod geometry;
mod grey;
mod linalg;
mod observe;
mod options;
mod policy;
mod precompute;
mod resample;
mod tracker;
// Native: they read the committed GRID frames from disk.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod tracking_tests;

use serde::{Deserialize, Serialize};

use crate::model::Params;

pub use anchor::{HeadDamper, PoseAnchor, Sequence};
pub use confidence::{ConfidenceBounds, Reasons, TrackStatus};
pub use driver::Fitter;
pub use face_tracker::{FaceTracker, TrackerKind, Whose, WORK_SIDE};
pub use follow::{
    bound_neutral_mouth, close_first_neutral, close_mouth, expression_params, mouth_opening,
    mouth_shape, neutral_update, rest_boundary, split_head_turn, split_head_yaw, FollowOptions,
    Follower, REST_CORNER_LIFT, REST_MOUTH_WIDTH,
};
pub(crate) use follow::{split_head_turn_keeping_nod, turn_directions};
pub use observe::{
    at_rest, neutral_like, rest_distance, Observed, ObservedAppearance, NEUTRAL_MAX_MOVE,
    NEUTRAL_STEP, NEUTRAL_WARMUP,
};
pub use options::{FitOptions, LevelSpec, TrackPolicy};
pub use policy::{tracker_for, tracker_of_kind};
pub use tracker::{FaceSource, Tracker, DEFAULT_TIME_STEP, MIN_CONTRAST};

/// The result of one fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitResult {
    /// Fitted landmarks, image coordinates, interleaved `(x0, y0, ..., x_{n-1}, y_{n-1})`.
    pub landmarks: Vec<f32>,
    /// Pose, shape parameters `p` and RGB appearance parameters `lambda` (zeros when
    /// [`FitOptions::appearance`] is off).
    pub params: Params,
    /// Final error: RMS of the grey residual `I(W(x)) - A0(x) - sum lambda_i A_i(x)` over the
    /// finest level's pixels (grey levels in `0..=1`).
    pub error: f32,
    /// Iterations run (all levels and both stages).
    pub iterations: u32,
    /// True when the last iteration moved no landmark more than the tolerance.
    pub converged: bool,
    /// Set by the [`Tracker`]: the fit was judged a lost face and the result is the last good
    /// one (the tracker re-initialised from it).
    pub lost: bool,
    /// Set by the [`Tracker`]: this frame's face was (re-)acquired from its [`FaceSource`]
    /// (the first face of [`Tracker::start_auto`](crate::fit::FaceTracker::start_auto), or a face found again after a loss).
    #[serde(default)]
    pub reacquired: bool,
    /// How far the fit can be trusted: "tracking", "unsure" (the [`Tracker`]'s confidence
    /// checks doubt it: the targets hold the last good expression) or "lost" (as `lost`).
    #[serde(default)]
    pub status: TrackStatus,
    /// Why the fit is unsure or lost (empty while tracking).
    #[serde(default)]
    pub reasons: Reasons,
}

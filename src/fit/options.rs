//! Options of the fitter and tracker, with their checks.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Options of the [`super::Fitter`] and [`super::Tracker`]. `Default` is tuned for real-time tracking.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Most project-out iterations per level.
    pub max_iters: u32,
    /// Appearance-aware (simultaneous / Wiberg) refinement iterations on the finest level,
    /// after the project-out iterations (0 = plain project-out).
    pub refine_iters: u32,
    /// The levels, coarse to fine. The finest level also gives the reported error.
    pub levels: Vec<LevelSpec>,
    /// Convergence tolerance: the fit stops when no landmark moves more than this many image
    /// pixels in an iteration.
    pub tolerance: f32,
    /// Weight `rho` of the Tikhonov prior `rho * N * sum (p_i / sigma_i)^2` on the shape
    /// parameters (`N` = level pixels). 0 disables it.
    pub shape_prior: f32,
    /// Add gain and bias images to the grey appearance basis, making the fit invariant to
    /// global brightness and contrast changes.
    pub gain_bias: bool,
    /// Fitting channels: 1 = luminance only, 2 = luminance and red chroma (lips against
    /// skin).
    pub channels: u32,
    /// Compute the RGB appearance parameters `lambda` of the result (projection of the image
    /// sampled at the final landmarks; costs one full-frame sample).
    pub appearance: bool,
    /// Tracker: a fit whose error (RMS grey residual) exceeds this is a lost face.
    pub max_error: f32,
    /// Tracker: a fit whose shape parameters' RMS in standard deviations,
    /// `sqrt(mean_i (p_i / sigma_i)^2)`, exceeds this is a lost face (an implausible shape).
    pub max_sigmas: f32,
    /// Tracker: a fit whose scale changes by more than this fraction from the previous frame
    /// (or whose rotation by more than 0.5 rad) is a lost face.
    pub max_scale_jump: f32,
    /// Starts of the coarsest level in a cold fit ([`super::Fitter::fit`], [`super::Fitter::fit_params`],
    /// the tracker's first frame and re-initialisations), 1 to 7: the given start, then the
    /// start moved by `+-start_offset` of the face width along x, along y, then rotated by
    /// `+-start_offset` radians. The coarse result with the lowest cost (projected-out
    /// residual plus prior) is refined on the finer levels. Widens the convergence basin.
    #[serde(default = "default_coarse_starts")]
    pub coarse_starts: u32,
    /// Starts of the coarsest level for a tracked frame (started from the previous frame's
    /// result), 1 to 7.
    #[serde(default = "default_tracking_starts")]
    pub tracking_starts: u32,
    /// Offset of the extra coarse starts: a fraction of the face width (and radians).
    #[serde(default = "default_start_offset")]
    pub start_offset: f32,
    /// Tracker: a tracked fit whose error exceeds this multiple of the typical error of the
    /// recent good fits (a slow running mean) is a lost face: an occluder or a cut raises the
    /// error suddenly, long before the fit drifts off. 0 disables the check.
    #[serde(default = "default_max_error_ratio")]
    pub max_error_ratio: f32,
    /// Tracker: a fit with fewer than this fraction of its landmarks inside the image is a
    /// lost face (a face leaving the picture cannot be checked against the image).
    #[serde(default = "default_min_inside")]
    pub min_inside: f32,
    /// Before the second level, compare on that level the first level's result with the state
    /// the first level started from, and keep the one of lower cost: the first, most smoothed
    /// level is undone when it made things worse (checking before every later level measured
    /// the same, docs/fitting.md).
    #[serde(default = "default_level_check")]
    pub level_check: bool,
}

fn default_level_check() -> bool {
    true
}

fn default_max_error_ratio() -> f32 {
    3.0
}

fn default_min_inside() -> f32 {
    0.75
}

fn default_coarse_starts() -> u32 {
    3
}

fn default_tracking_starts() -> u32 {
    1
}

fn default_start_offset() -> f32 {
    0.06
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_iters: 10,
            refine_iters: 2,
            levels: vec![
                LevelSpec {
                    step: 4,
                    sigma: 4.0,
                },
                LevelSpec {
                    step: 4,
                    sigma: 2.0,
                },
                LevelSpec {
                    step: 2,
                    sigma: 0.0,
                },
            ],
            tolerance: 0.05,
            shape_prior: 1e-5,
            gain_bias: true,
            channels: 1,
            appearance: true,
            max_error: 0.12,
            max_sigmas: 3.5,
            max_scale_jump: 0.25,
            coarse_starts: 3,
            tracking_starts: 1,
            start_offset: 0.06,
            max_error_ratio: default_max_error_ratio(),
            min_inside: default_min_inside(),
            level_check: default_level_check(),
        }
    }
}

impl FitOptions {
    pub(super) fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Params(format!("fit options: {m}")));
        if self.levels.is_empty() || self.levels.len() > 4 {
            return bad(format!("{} levels (1 to 4 expected)", self.levels.len()));
        }
        for l in &self.levels {
            // `contains` is false for NaN, so a NaN sigma is rejected too.
            if !(1..=8).contains(&l.step) || !(0.0..=8.0).contains(&l.sigma) {
                return bad(format!(
                    "level {l:?}: step must be in 1..=8, sigma in 0..=8"
                ));
            }
        }
        if !(1..=2).contains(&self.channels) {
            return bad(format!("channels = {} must be 1 or 2", self.channels));
        }
        for (what, v) in [
            ("coarse_starts", self.coarse_starts),
            ("tracking_starts", self.tracking_starts),
        ] {
            if !(1..=7).contains(&v) {
                return bad(format!("{what} = {v} must be in 1..=7"));
            }
        }
        if !(self.start_offset.is_finite() && (0.0..=0.5).contains(&self.start_offset)) {
            return bad(format!(
                "start_offset = {} must be in 0..=0.5",
                self.start_offset
            ));
        }
        if !(0.0..=1.0).contains(&self.min_inside) {
            return bad(format!("min_inside = {} must be in 0..=1", self.min_inside));
        }
        if self.max_iters > 1000 || self.refine_iters > 1000 {
            return bad("more than 1000 iterations".into());
        }
        for (what, v) in [
            ("tolerance", self.tolerance),
            ("shape_prior", self.shape_prior),
            ("max_error", self.max_error),
            ("max_sigmas", self.max_sigmas),
            ("max_scale_jump", self.max_scale_jump),
            ("max_error_ratio", self.max_error_ratio),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{what} = {v} must be finite and non-negative"));
            }
        }
        Ok(())
    }
}

/// One level of the coarse-to-fine schedule.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LevelSpec {
    /// Use every `step`-th frame pixel along x and y.
    pub step: u32,
    /// Gaussian smoothing (standard deviation, frame pixels) of the template; the image is
    /// smoothed by the same amount in its own pixels (times the pose's scale). 0 = none.
    pub sigma: f32,
}

/// Tracking policy shared by every front end (the CLI, the npm package, the page): how a frame
/// is resampled before fitting, and how the tracked parameters are bounded. `Default` is what
/// the page and the package use.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TrackPolicy {
    /// Tracked appearance parameters are clamped to `+-appearance_limit` standard deviations
    /// of the model ([`crate::clone::constrain`]): another person's face (a webcam, a dropped
    /// video) projects far outside a person-specific appearance space, and an unclamped
    /// projection paints noise on the face it drives; the faces a model was built for stay well
    /// inside. 0 disables the clamp.
    pub appearance_limit: f32,
    /// [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale): the resampled frame's longer side is at most this (pixels).
    pub max_fit_side: u32,
    /// [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale): ...and at least this (pixels).
    pub min_fit_side: u32,
    /// [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale): a frame is enlarged at most this much.
    pub max_upscale: f32,
    /// [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale): a face whose size is within `1/native_band..native_band` of the
    /// model's is fitted at the frame's own resolution (no resampling).
    pub native_band: f32,
    /// [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale): while tracking, the scale changes only when the wanted one
    /// differs from the current one by more than this fraction (a face moving to or from the
    /// camera), so the resampling does not flicker between nearby scales.
    pub rescale_change: f32,
    /// The time constant (seconds) with which the pose anchor follows the head
    /// ([`crate::fit::Sequence`]): the placement a tracked face drives is its pose re-centred
    /// on the model's mean pose about the anchor, so a face anywhere in the picture ends up
    /// centred. 0: the anchor stays at the sequence's first pose (a clip's motion reproduced
    /// exactly).
    pub recentre_tau: f32,
    /// While a face is tracked, every this many frames the tracker takes a second opinion:
    /// the faces found in the frame (its [`FaceSource`](crate::fit::FaceSource), or faces
    /// offered: [`Tracker::wants_faces`](crate::fit::FaceTracker::wants_faces) turns true), a cold
    /// fit from the one nearest the tracked face, kept when its residual is lower. A tracked
    /// fit can be led into a wrong minimum by frames before it (a hand under the chin read as
    /// an open mouth) and stay there with a plausible shape and residual; a fit from the
    /// finder's points lands in the right one. 0: never.
    pub recheck_frames: u32,
}

impl Default for TrackPolicy {
    fn default() -> Self {
        TrackPolicy {
            appearance_limit: 3.0,
            max_fit_side: 1280,
            min_fit_side: 160,
            max_upscale: 2.0,
            native_band: 1.33,
            rescale_change: 0.3,
            recentre_tau: 4.0,
            recheck_frames: 15,
        }
    }
}

impl TrackPolicy {
    /// Replaces `self` with `policy` after [`TrackPolicy::check`]; fails with
    /// [`crate::Error::Params`] (keeping `self`) when a value is out of range. What
    /// `Tracker::set_policy` and `Follower::set_policy` do.
    pub(crate) fn replace(&mut self, policy: TrackPolicy) -> Result<()> {
        policy.check()?;
        *self = policy;
        Ok(())
    }

    /// The scale by which to resample a `width x height` frame before following a face
    /// `face_height` pixels tall in it, for a model whose mean face is `model_face_height`
    /// pixels tall: [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale) (which gives the rule).
    pub fn fit_scale(
        &self,
        model_face_height: f32,
        face_height: f32,
        width: u32,
        height: u32,
        current: f32,
    ) -> f32 {
        let keep = if current.is_finite() && current > 0.0 {
            current
        } else {
            1.0
        };
        let side = width.max(height) as f32;
        if !(face_height.is_finite() && face_height > 0.0 && side >= 1.0) {
            return keep;
        }
        let p = self;
        let want = model_face_height.max(1.0) / face_height.max(1.0);
        let want = if want > 1.0 / p.native_band
            && want < p.native_band
            && side <= p.max_fit_side as f32
        {
            1.0
        } else {
            p.max_upscale
                .min(p.max_fit_side as f32 / side)
                .min((p.min_fit_side as f32 / side).max(want))
        };
        if current.is_finite() && current > 0.0 && (want / current - 1.0).abs() <= p.rescale_change
        {
            current
        } else {
            want
        }
    }

    /// Fails with [`Error::Params`] naming the first value out of range.
    pub fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Params(format!("tracking policy: {m}")));
        if !(self.appearance_limit.is_finite() && self.appearance_limit >= 0.0) {
            return bad(format!(
                "appearance_limit = {} must be finite and non-negative",
                self.appearance_limit
            ));
        }
        if !(16..=16384).contains(&self.min_fit_side)
            || !(self.min_fit_side..=16384).contains(&self.max_fit_side)
        {
            return bad(format!(
                "min_fit_side = {}, max_fit_side = {}: 16 <= min <= max <= 16384 expected",
                self.min_fit_side, self.max_fit_side
            ));
        }
        for (what, v, lo, hi, unit) in [
            ("max_upscale", self.max_upscale, 1.0, 8.0, ""),
            ("native_band", self.native_band, 1.0, 4.0, ""),
            ("rescale_change", self.rescale_change, 0.0, 4.0, ""),
            ("recentre_tau", self.recentre_tau, 0.0, 3600.0, " (seconds)"),
        ] {
            // `contains` is false for NaN, so a NaN is rejected too.
            if !(lo..=hi).contains(&v) {
                return bad(format!("{what} = {v} must be in {lo}..={hi}{unit}"));
            }
        }
        if self.recheck_frames > 100_000 {
            return bad(format!(
                "recheck_frames = {} must be at most 100000 (0: never)",
                self.recheck_frames
            ));
        }
        Ok(())
    }
}

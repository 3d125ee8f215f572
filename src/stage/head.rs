//! Head-motion damping of the source pose taken from fits: the core's one pose anchor
//! ([`PoseAnchor`]), so a call attenuates or exaggerates the head's motion without the pose
//! leaving the stage.

use crate::error::{Error, Result};
use crate::fit::PoseAnchor;
use crate::similarity::Similarity;

/// The damping a stage applies to the pose of every fit it takes.
///
/// Represents: a running anchor of the fitted poses (time constant `tau` seconds, 0: the first
/// pose stays the anchor) and a `factor` on the deviation from it (0 holds the head at the
/// anchor, 1 passes the pose unchanged, over 1 exaggerates).
#[derive(Debug)]
pub(super) struct HeadDamping {
    anchor: PoseAnchor,
    tau: f32,
    factor: f32,
    /// The clock (ms) of the last pose taken.
    at: Option<f64>,
}

impl HeadDamping {
    /// Requires `tau` finite and non-negative, `factor` finite (else [`Error::Params`]).
    pub fn new(tau: f32, factor: f32) -> Result<HeadDamping> {
        check(tau, factor)?;
        Ok(HeadDamping {
            anchor: PoseAnchor::new(),
            tau,
            factor,
            at: None,
        })
    }

    /// New settings, keeping the anchor (a slider moved mid-call does not restart it).
    pub fn set(&mut self, tau: f32, factor: f32) -> Result<()> {
        check(tau, factor)?;
        self.tau = tau;
        self.factor = factor;
        Ok(())
    }

    /// Forgets the anchor (a new source: the next pose becomes it).
    pub fn restart(&mut self) {
        self.anchor.reset();
        self.at = None;
    }

    /// Moves the anchor towards `pose` for the time since the last pose (`now`, ms; a clock
    /// going back counts as no time) and returns the damped pose. An invalid pose passes
    /// unchanged (the model's checks refuse it).
    pub fn apply(&mut self, pose: Similarity, now: f64) -> Similarity {
        let dt = self
            .at
            .map_or(0.0, |at| ((now - at) / 1000.0).max(0.0) as f32);
        self.at = Some(now);
        self.anchor.wait(dt);
        if self.anchor.follow(&pose, self.tau).is_none() {
            return pose;
        }
        self.anchor.damped(&pose, self.factor)
    }
}

fn check(tau: f32, factor: f32) -> Result<()> {
    if tau.is_finite() && tau >= 0.0 && factor.is_finite() {
        Ok(())
    } else {
        Err(Error::Params(format!(
            "head damping: tau {tau} must be finite and non-negative, factor {factor} finite"
        )))
    }
}

//! The source's parameters: given, read from a fit, or tracked from pixels by the stage's own
//! [`FaceTracker`].

use crate::error::{check_len, Error, Result};
use crate::fit::{FaceTracker, FitResult};
use crate::image::ImageRef;
use crate::model::{Model, Params};
use crate::similarity::Similarity;

impl super::Stage {
    /// The current source parameters.
    pub fn source_params(&self) -> &Params {
        &self.params
    }

    /// Sets the source parameters for the next [`super::Stage::update`]. Requires lengths that
    /// match the source model and finite values within its bounds
    /// ([`Model::check_params`]); on error the old ones stay. The parameters are the model's:
    /// an observed face ([`crate::clone::Cloner::set_observed`]) is dropped. Allocates nothing.
    pub fn set_source_params(&mut self, params: &Params) -> Result<()> {
        take_params(
            self.cloner.source(),
            (params.pose, &params.shape, &params.appearance),
            &mut self.pending,
            &mut self.params,
        )?;
        self.cloner.set_observed(None)
    }

    /// Takes the source parameters from a tracker's fit: its shape and appearance parameters
    /// and `placed`, the head placement to draw the source with
    /// ([`crate::fit::Sequence::placed`]). A fit that is not "tracking" (lost, or unsure:
    /// [`crate::fit::TrackStatus`]) is not taken: the parameters stay the last good ones, so
    /// the targets hold the last good expression instead of copying a broken shape. Returns
    /// whether the fit was taken; fails (changing nothing) when the fit does not fit the
    /// source model. A fit taken drops a face observed earlier
    /// ([`crate::clone::Cloner::set_observed`]): its parameters are the model's.
    pub fn source_from_fit(&mut self, fit: &FitResult, placed: Similarity) -> Result<bool> {
        let taken = self.take_from_fit(fit, placed)?;
        if taken {
            // The fit's parameters alone: a face observed with an earlier fit is dropped.
            self.cloner.set_observed(None)?;
        }
        Ok(taken)
    }

    /// [`super::Stage::source_from_fit`] keeping the observed face the cloner holds.
    fn take_from_fit(&mut self, fit: &FitResult, placed: Similarity) -> Result<bool> {
        let placed = damped(&mut self.head, self.painter.clock, placed, !trusted(fit));
        take_fit(
            self.cloner.source(),
            (Some(fit), placed),
            &mut self.pending,
            &mut self.params,
        )
    }

    /// Takes the source parameters from `tracker`'s last frame ([`super::Stage::source_from_fit`]
    /// with its [`crate::fit::Sequence::placed`] pose), and, when taken, the appearance the
    /// tracker observed ([`crate::fit::FaceTracker::observed`], a follower's: the expressive
    /// method's ratio image and inner mouth come from it, [`crate::clone::Cloner::set_observed`]);
    /// `false` before its first frame. A fit not taken keeps the last good parameters and
    /// observed face (the targets hold the whole expression).
    pub fn source_from_tracker(&mut self, tracker: &dyn FaceTracker) -> Result<bool> {
        let taken = match tracker.last() {
            Some(fit) => self.take_from_fit(fit, tracker.sequence().placed())?,
            None => return Ok(false),
        };
        if taken {
            self.cloner.set_observed(tracker.observed())?;
        }
        Ok(taken)
    }

    /// Damps the head's motion in the poses taken from fits from now on
    /// ([`super::Stage::source_from_fit`], [`super::Stage::source_from_tracker`],
    /// [`super::Stage::track`]): each pose's deviation from a running anchor of the poses (time
    /// constant `tau` seconds; 0 keeps the first pose as the anchor) scaled by `factor` (0 holds
    /// the head still, 1 passes it unchanged, over 1 exaggerates), the core's one pose anchor
    /// ([`crate::fit::PoseAnchor`]). Changing the settings keeps the anchor. Fails with
    /// [`Error::Params`] (changing nothing) for a non-finite or negative `tau` or a non-finite
    /// `factor`.
    pub fn set_head_damping(&mut self, tau: f32, factor: f32) -> Result<()> {
        match &mut self.head {
            Some(h) => h.set(tau, factor),
            None => {
                self.head = Some(crate::fit::HeadDamper::new(tau, factor)?);
                Ok(())
            }
        }
    }

    /// Stops damping the head (poses are taken as fitted) and forgets the anchor.
    pub fn clear_head_damping(&mut self) {
        self.head = None;
    }

    /// The tracker that reads the source from video, if any.
    pub fn tracker(&self) -> Option<&dyn FaceTracker> {
        self.tracker.as_deref()
    }

    /// The tracker, to start a sequence or offer faces.
    pub fn tracker_mut(&mut self) -> Option<&mut (dyn FaceTracker + 'static)> {
        self.tracker.as_deref_mut()
    }

    /// Gives the stage a tracker of the source model (e.g. [`crate::fit::tracker_for`]), or
    /// none; returns the previous one. [`super::Stage::set_source`] drops it.
    pub fn set_tracker(
        &mut self,
        tracker: Option<Box<dyn FaceTracker>>,
    ) -> Option<Box<dyn FaceTracker>> {
        std::mem::replace(&mut self.tracker, tracker)
    }

    /// Tracks the source in the next video frame, `dt` seconds after the previous one, and
    /// takes the fit as the source parameters unless the face is lost or the fit unsure
    /// ([`super::Stage::source_from_fit`]). Returns whether it was taken. Fails with
    /// [`Error::Params`] when the stage has no tracker, or as the tracker does.
    pub fn track(&mut self, frame: &ImageRef<'_>, dt: f32) -> Result<bool> {
        let Some(tracker) = self.tracker.as_mut() else {
            return Err(Error::Params(
                "the stage has no tracker: give one with set_tracker".into(),
            ));
        };
        tracker.track(frame, dt)?;
        let tracker: &dyn FaceTracker = &**tracker;
        let (fit, placed) = (tracker.last(), tracker.sequence().placed());
        let lost = !fit.is_some_and(trusted);
        let placed = damped(&mut self.head, self.painter.clock, placed, lost);
        let taken = take_fit(
            self.cloner.source(),
            (fit, placed),
            &mut self.pending,
            &mut self.params,
        )?;
        if taken {
            // A followed face's appearance drives the expressive method (the fit has no
            // appearance parameters of its own): held, like the parameters, while unsure.
            self.cloner.set_observed(tracker.observed())?;
        }
        Ok(taken)
    }

    /// One frame from pixels: [`super::Stage::track`], [`super::Stage::update`],
    /// [`super::Stage::draw`]. Returns whether the frame's fit was taken (a lost face keeps the
    /// last good parameters, and the frame is drawn with them).
    pub fn frame_from_pixels(&mut self, frame: &ImageRef<'_>, dt: f32) -> Result<bool> {
        let taken = self.track(frame, dt)?;
        self.update()?;
        self.draw()?;
        Ok(taken)
    }
}

/// `placed` damped by `head` (at the time `clock` reads), when there is head damping and the
/// fit is taken (not `lost`).
fn damped(
    head: &mut Option<crate::fit::HeadDamper>,
    clock: super::Clock,
    placed: Similarity,
    lost: bool,
) -> Similarity {
    match head {
        Some(h) if !lost => h.apply(placed, clock()),
        _ => placed,
    }
}

/// Whether a fit drives the source: its status is "tracking" (not lost, not unsure).
fn trusted(fit: &FitResult) -> bool {
    !fit.lost && fit.status == crate::fit::TrackStatus::Tracking
}

/// Takes a fit and its placed pose as the source parameters ([`take_params`]) unless there is
/// none or it is not trusted (lost or unsure); returns whether it was taken.
fn take_fit(
    model: &Model,
    (fit, placed): (Option<&FitResult>, Similarity),
    pending: &mut Params,
    current: &mut Params,
) -> Result<bool> {
    let Some(fit) = fit.filter(|f| trusted(f)) else {
        return Ok(false);
    };
    take_params(
        model,
        (placed, &fit.params.shape, &fit.params.appearance),
        pending,
        current,
    )?;
    Ok(true)
}

/// Copies `(pose, shape, appearance)` into `pending` (sized like the model's parameters),
/// checks it against `model` and swaps it into `current`: no allocation, and `current` is
/// unchanged on error.
fn take_params(
    model: &Model,
    (pose, shape, appearance): (Similarity, &[f32], &[f32]),
    pending: &mut Params,
    current: &mut Params,
) -> Result<()> {
    check_len("shape parameters", shape, pending.shape.len())?;
    check_len(
        "appearance parameters",
        appearance,
        pending.appearance.len(),
    )?;
    pending.pose = pose;
    pending.shape.copy_from_slice(shape);
    pending.appearance.copy_from_slice(appearance);
    model.check_params(pending)?;
    std::mem::swap(pending, current);
    Ok(())
}

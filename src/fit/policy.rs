//! The one policy that chooses how a face is followed: the person's own model gets the AAM
//! [`Tracker`], anyone else (a bundled or another person's model) the landmark [`Follower`].

use crate::error::Result;
use crate::model::Model;

use super::face_tracker::{FaceTracker, TrackerKind, Whose};
use super::{FitOptions, FollowOptions, Follower, Tracker};

/// The tracker the policy chooses ([`TrackerKind::for_source`]) for following a face with
/// `model`, the model being `whose` face: an AAM [`Tracker`] with the default [`FitOptions`],
/// or a landmark [`Follower`] with the default [`FollowOptions`] (and its finder's searches
/// on: [`FaceTracker::expect_offers`] turns them off).
///
/// Fails as [`Tracker::new`] or [`Follower::new`] do (an invalid model; the shipped finder
/// not loading).
pub fn tracker_for(model: &Model, whose: Whose) -> Result<Box<dyn FaceTracker>> {
    tracker_of_kind(model, TrackerKind::for_source(whose, model.landmarks()))
}

/// A tracker of `kind` for `model`, with the default options (see [`tracker_for`]). Fails with
/// [`Error::Params`](crate::Error::Params) for a landmark follower of a model without the finder's 68 landmarks.
pub fn tracker_of_kind(model: &Model, kind: TrackerKind) -> Result<Box<dyn FaceTracker>> {
    Ok(match kind {
        TrackerKind::Aam => Box::new(Tracker::new(model, FitOptions::default())?),
        TrackerKind::Landmarks => Box::new(Follower::new(model, FollowOptions::default())?),
    })
}

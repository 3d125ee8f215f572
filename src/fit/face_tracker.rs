//! One interface for following a face through video: [`FaceTracker`], implemented by the AAM
//! [`Tracker`](super::Tracker) (a person's own model fitted to every frame) and the landmark [`Follower`](super::Follower)
//! (anyone followed with a model that is not theirs), and the policy choosing between them
//! ([`tracker_for`](super::tracker_for), [`TrackerKind::for_source`]).

use crate::error::Result;
use crate::image::ImageRef;

use super::anchor::Sequence;
use super::{FitResult, TrackPolicy};

/// The longer side (pixels) of the work frame a page tracks and finds faces on: a camera or
/// video frame larger than this is scaled down to it first (the trackers then choose their own
/// fit scale within it, [`FaceTracker::fit_scale`]). 640 keeps a webcam's VGA frame as it
/// comes, and the face finder's and the tracker's costs bounded on HD sources.
pub const WORK_SIDE: u32 = 640;

/// Which way a [`FaceTracker`] follows a face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TrackerKind {
    /// The model's active appearance model is fitted to every frame ([`Tracker`](super::Tracker)): for the
    /// person the model was built from.
    Aam,
    /// The face finder's landmarks are read as expression and mapped onto the model's shape
    /// modes ([`Follower`](super::Follower)): for anyone, with a model that is not theirs.
    Landmarks,
}

impl TrackerKind {
    /// The kind's stable name: `"aam"` or `"landmarks"` (what the page and its tests read).
    pub fn name(self) -> &'static str {
        match self {
            TrackerKind::Aam => "aam",
            TrackerKind::Landmarks => "landmarks",
        }
    }

    /// The kind named `name` ([`TrackerKind::name`]), if any.
    pub fn from_name(name: &str) -> Option<TrackerKind> {
        match name {
            "aam" => Some(TrackerKind::Aam),
            "landmarks" => Some(TrackerKind::Landmarks),
            _ => None,
        }
    }

    /// The tracking policy: the kind that follows a face with a model of `whose` face, with
    /// `landmarks` points.
    ///
    /// Ensures: [`Whose::Own`] gives [`TrackerKind::Aam`] (the model was built from this
    /// person, so its appearance model fits their face: the closest match); [`Whose::Other`]
    /// gives [`TrackerKind::Landmarks`] (an AAM fitted to someone it was not built from drifts
    /// and mistakes identity for expression) when the model has the face finder's 68
    /// landmarks, else [`TrackerKind::Aam`] (the only way such a model can follow a face).
    pub fn for_source(whose: Whose, landmarks: usize) -> TrackerKind {
        match whose {
            Whose::Own => TrackerKind::Aam,
            Whose::Other if landmarks == 68 => TrackerKind::Landmarks,
            Whose::Other => TrackerKind::Aam,
        }
    }
}

impl std::fmt::Display for TrackerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Whose face a source model is, relative to the person followed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Whose {
    /// The model was built from the person in front of the camera (their own enrolment, or
    /// the bundled clip that shows the bundled person).
    Own,
    /// The model is someone else's (a bundled model driven by anyone's webcam).
    Other,
}

/// A tracker following one face through video frames: the one interface of the AAM
/// [`Tracker`](super::Tracker) and the landmark [`Follower`](super::Follower), so a front end drives either the same way.
/// Object-safe: `Box<dyn FaceTracker>` is what [`tracker_for`](super::tracker_for) returns.
///
/// **Represents** one followed face: where a sequence starts (landmarks, a box, or a search
/// for a face), the last frame's [`FitResult`], the [`Sequence`] (frame counters and the pose
/// anchor the driven face is placed about), the faces offered from elsewhere and the
/// [`TrackPolicy`].
///
/// **One pixel convention.** Frames come in at their own size; everything going in and out
/// (start landmarks and boxes, offered faces, the results' landmarks and poses) is in that
/// frame's pixels, `2n` interleaved values for `n` landmarks in the model's layout.
///
/// **Lifecycle.** Start a sequence ([`FaceTracker::start_from_landmarks`],
/// [`FaceTracker::start_from_box`], [`FaceTracker::start_searching`],
/// [`FaceTracker::start_auto`]), then call [`FaceTracker::track`] once per frame. A frame whose
/// face is lost reports `lost = true` with the last good result; the face found again reports
/// `reacquired = true`. Faces found elsewhere (a finder on another thread) are given with
/// [`FaceTracker::offer_faces`] when [`FaceTracker::wants_faces`] says so.
pub trait FaceTracker: std::fmt::Debug {
    /// Which way this tracker follows a face.
    fn kind(&self) -> TrackerKind;

    /// Follows the face in the next frame, `dt` seconds after the previous one (the pose
    /// anchor's time step, and the landmark smoothing's).
    ///
    /// Requires: a started sequence (else the [`Tracker`](super::Tracker) fails with [`Error::Params`](crate::Error::Params); a
    /// [`Follower`](super::Follower) searches the frame), `dt` finite and non-negative (else [`Error::Params`](crate::Error::Params);
    /// the follower needs it positive to smooth, a `dt` of 0 restarts its smoothing).
    ///
    /// Ensures: the result is the frame's face, or `lost = true` and the last good result;
    /// its `status` says how far to trust it ("tracking", "unsure" with its `reasons`: drive
    /// nothing with it, or "lost");
    /// [`FaceTracker::sequence`] counted the frame. Allocates nothing per frame while a face
    /// is followed.
    fn track(&mut self, frame: &ImageRef<'_>, dt: f32) -> Result<&FitResult>;

    /// The last frame's result, `None` before the first frame of the tracker (the [`Tracker`](super::Tracker):
    /// of the sequence).
    fn last(&self) -> Option<&FitResult>;

    /// The frame counters (frames, lost, reacquisitions) and the pose anchor:
    /// [`Sequence::placed`] is the head placement to draw the driven face with.
    fn sequence(&self) -> &Sequence;

    /// Re-initialisations: frames whose fit was judged implausible and refitted from the last
    /// good one (the [`Tracker`](super::Tracker)); always 0 for the [`Follower`](super::Follower), which does not refit.
    fn resets(&self) -> u32;

    /// Second opinions taken while tracking ([`TrackPolicy::recheck_frames`]) and those kept;
    /// `(0, 0)` for the [`Follower`](super::Follower) (its landmarks come from the finder every frame).
    fn rechecks(&self) -> (u32, u32);

    /// Faces found elsewhere, in the frame's pixels, `2n` values each, most confident first:
    /// the next acquisition takes the one nearest the last face (the [`Tracker`](super::Tracker) also uses
    /// them for a second opinion). They are used once.
    ///
    /// Fails with [`Error::Params`](crate::Error::Params), keeping none, when a face has the wrong length or a
    /// non-finite point.
    fn offer_faces(&mut self, faces: Vec<Vec<f32>>) -> Result<()>;

    /// Whether the tracker is looking for a face (or a second opinion is due) and has no
    /// offered faces left to try: the moment to run a finder on a frame and
    /// [`FaceTracker::offer_faces`].
    fn wants_faces(&self) -> bool;

    /// Whether faces will be offered from elsewhere ([`FaceTracker::offer_faces`]).
    ///
    /// Ensures, `yes`: a lost face is searched for with the faces offered
    /// ([`FaceTracker::wants_faces`] turns true when they are needed); the [`Follower`](super::Follower) no
    /// longer runs its own finder on the whole frame (the finder elsewhere does that), the
    /// [`Tracker`](super::Tracker) still asks its face source if it was given one. `no`: offered faces are
    /// dropped; the [`Follower`](super::Follower) searches the frame with its own finder, the [`Tracker`](super::Tracker) only
    /// with its face source.
    fn expect_offers(&mut self, yes: bool);

    /// Starts a new sequence with no face: frames are lost until one is acquired (from the
    /// faces offered, or the tracker's own finder when it uses one), and the face is then
    /// followed. The [`Tracker`](super::Tracker) also expects offers from then on
    /// ([`FaceTracker::expect_offers`]); the [`Follower`](super::Follower) forgets the person (their neutral
    /// face is estimated again).
    fn start_searching(&mut self);

    /// Starts a new sequence with no face, found by the tracker's own finder on each frame
    /// until one is acquired: the [`Tracker`](super::Tracker)'s face source (the shipped face finder when it
    /// has none and the model has its 68 landmarks), the [`Follower`](super::Follower)'s finder (faces are no
    /// longer expected from elsewhere).
    ///
    /// Fails with [`Error::Params`](crate::Error::Params) for a [`Tracker`](super::Tracker) with no face source and a model without
    /// the finder's 68 landmarks.
    fn start_auto(&mut self) -> Result<()>;

    /// Starts a new sequence from the face's landmarks on the next frame (frame pixels, `2n`).
    /// Fails with [`Error::Params`](crate::Error::Params), changing nothing, for the wrong length, non-finite or
    /// degenerate points.
    fn start_from_landmarks(&mut self, landmarks: &[f32]) -> Result<()>;

    /// Starts a new sequence from a face box on the next frame (frame pixels: left, top,
    /// width, height). Fails with [`Error::Params`](crate::Error::Params), changing nothing, for a non-finite box or
    /// one under 4x4.
    fn start_from_box(&mut self, x: f32, y: f32, w: f32, h: f32) -> Result<()>;

    /// The tracking policy (resampling scale, appearance bounds, the anchor's time constant,
    /// second opinions); the [`Follower`](super::Follower) uses its `recentre_tau` only.
    fn policy(&self) -> &TrackPolicy;

    /// Replaces the tracking policy; fails with [`Error::Params`](crate::Error::Params), keeping the old one, when a
    /// value is out of range.
    fn set_policy(&mut self, policy: TrackPolicy) -> Result<()>;

    /// The fit scale in use (fitted pixels per frame pixel): the [`Tracker`](super::Tracker)'s (0 before a
    /// sequence's first frame decides it), always 1 for the [`Follower`](super::Follower) (it reads the frame
    /// at its own size).
    fn scale(&self) -> f32;

    /// The fit scale the tracker would choose for a `width x height` frame with a face
    /// `face_height` pixels tall, `current` the scale in use (0: none): the [`Tracker`](super::Tracker)'s rule
    /// ([`TrackPolicy::fit_scale`]); always 1 for the [`Follower`](super::Follower).
    fn fit_scale(&self, face_height: f32, width: u32, height: u32, current: f32) -> f32;

    /// The last frame's appearance as observed in the frame's pixels, with the person's own
    /// neutral one ([`super::ObservedAppearance`]), when the tracker keeps them: the
    /// [`Follower`](super::Follower) does (its fits carry no appearance parameters); the [`Tracker`](super::Tracker) does
    /// not (its fitted appearance parameters say it). `None` by default and before a face.
    fn observed(&self) -> Option<super::Observed<'_>> {
        None
    }
}

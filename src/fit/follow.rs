//! The person-independent path (issue 20, item 6): anyone is followed at once, before they
//! have a model of their own, by reading the face finder's landmarks as expression and mapping
//! it onto a source model's shape modes. See [`Follower`] and docs/fitting.md, "Following
//! anyone".

use crate::error::{Error, Result};
use crate::filter::OneEuro;
use crate::find::{BBox, FaceFinder};
use crate::image::ImageRef;
use crate::landmarks::STABLE_POINTS;
use crate::model::limits::{check_face_box, check_landmarks_len};
use crate::model::Model;
use crate::similarity::Similarity;
use crate::summary::summary;

use super::anchor::Sequence;
use super::face_tracker::{FaceTracker, TrackerKind};
use super::{FitResult, TrackPolicy};

/// Tuning of a [`Follower`]. The defaults were chosen on webcam-dev frames 0-599 and measured
/// on its unseen frames 600-1336 (docs/fitting.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FollowOptions {
    /// One-Euro filter (Casiez et al. 2012): the cutoff (Hz) of a still landmark. Lower is
    /// steadier and lags more.
    pub min_cutoff: f32,
    /// One-Euro filter: how fast the cutoff rises with a landmark's speed, per eye distance per
    /// second (so near and far faces are smoothed alike).
    pub beta: f32,
    /// One-Euro filter: the cutoff (Hz) of the speed estimate.
    pub d_cutoff: f32,
    /// Frames averaged for the first estimate of the person's neutral shape.
    pub warmup: u32,
    /// After the warm-up, each frame moves every coordinate of the neutral shape by at most
    /// this (model units; the canonical base face is about 150 wide) towards the frame's shape:
    /// a running per-coordinate median, so brief expressions (an open mouth, a smile) do not
    /// pull it and a lasting change does.
    pub neutral_step: f32,
    /// Only frames whose mouth is no more open than the neutral's, plus this (a fraction of
    /// the eye distance; the opening is the inner lips' mean distance, [`mouth_opening`]),
    /// enter the neutral shape; a frame more closed than the neutral by more than this pulls
    /// it a fifth of the way at once. A talking person's mouth is open half the time: a
    /// neutral with a half-open mouth would read closing it as an expression the source model
    /// draws as lips crossing. So the neutral settles on the person's closed mouth, in
    /// whatever convention the finder places closed lips. A first face with its mouth open
    /// starts the neutral closed to this opening (or the model's base face's, if smaller).
    pub mouth_margin: f32,
    /// Mapped shape parameters are clamped to `+-max_sigmas` standard deviations of the
    /// source model's modes.
    pub max_sigmas: f32,
    /// While following, the finder's mesh runs near the last face; when its face-presence
    /// score is below this (0..1), the face is searched for again. The finder's own threshold
    /// ([`FindOptions::min_face_score`](crate::FindOptions)) by default.
    pub min_face_score: f32,
    /// At least this fraction of the landmarks must lie inside the frame, else the face is
    /// lost (it left the picture).
    pub min_inside: f32,
    /// `true` (default): the part of a frame's shape that turning or nodding the head out of
    /// the image plane explains ([`split_head_turn`]) is not read as expression: a person who
    /// turns their head does not make the clone open or twist its mouth. The followed
    /// landmarks keep the turn.
    pub split_head_turns: bool,
}

impl Default for FollowOptions {
    fn default() -> Self {
        FollowOptions {
            min_cutoff: 1.5,
            beta: 1.0,
            d_cutoff: 1.0,
            warmup: 10,
            neutral_step: 0.05,
            mouth_margin: 0.02,
            max_sigmas: 3.0,
            min_face_score: crate::find::FindOptions::default().min_face_score,
            min_inside: 0.5,
            split_head_turns: true,
        }
    }
}

impl FollowOptions {
    /// Fails with [`Error::Params`] naming the first value that is not finite or out of range.
    pub fn check(&self) -> Result<()> {
        let positive = [
            ("min_cutoff", self.min_cutoff),
            ("d_cutoff", self.d_cutoff),
            ("max_sigmas", self.max_sigmas),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Params(format!(
                    "follow option {name} is {v}: a positive number is needed"
                )));
            }
        }
        for (name, v) in [
            ("beta", self.beta),
            ("neutral_step", self.neutral_step),
            ("mouth_margin", self.mouth_margin),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Params(format!(
                    "follow option {name} is {v}: a non-negative number is needed"
                )));
            }
        }
        for (name, v) in [
            ("min_inside", self.min_inside),
            ("min_face_score", self.min_face_score),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::Params(format!(
                    "follow option {name} is {v}: a fraction in 0..=1 is needed"
                )));
            }
        }
        Ok(())
    }
}

/// Follows anyone's face with a source model that is not theirs: the person-independent path.
///
/// Represents: a face finder, the state of one followed face (the finder's last points, a
/// One-Euro filter over them, the person's running neutral shape in the source model's
/// coordinates) and the source model's shape basis (`s0`, its orthonormal modes and their
/// standard deviations).
///
/// Each frame ([`Follower::track`](crate::fit::FaceTracker::track)):
/// 1. **Landmarks.** While a face is followed, the finder's mesh runs near it: one pass on the
///    region of the last frame's mesh ([`FaceFinder::follow_into`]), or two from the box of
///    its last points after a search ([`FaceFinder::scored_landmarks_into`]). If the mesh
///    says the region holds no face ([`FollowOptions::min_face_score`]), or no face is
///    followed yet, the finder searches the whole frame (or the faces offered by
///    [`Follower::offer_faces`](crate::fit::FaceTracker::offer_faces) are used) and the face nearest the last one is taken. No face:
///    the frame is lost.
/// 2. **Expression.** The pose `P` is the least-squares similarity from the neutral shape `n`
///    onto the points, fitted on the nose and the eye corners ([`STABLE_POINTS`], which an
///    expression hardly moves; over all 68 a laugh's jaw and mouth pulled it, and the laugh
///    arrived weaker), and the frame's shape in model coordinates is
///    `x = P^-1(points)`, smoothed by a One-Euro filter (in model coordinates, so a moving
///    head is not lagged; speeds in eye distances per second, [`FollowOptions::min_cutoff`],
///    [`FollowOptions::beta`]; restarted when the face is acquired again); the expression is
///    the deviation `x - n`. The neutral is the first face's shape (its mouth closed), then
///    the mean of the first [`FollowOptions::warmup`] frames' shapes, then a running
///    per-coordinate median ([`FollowOptions::neutral_step`]), of the frames whose mouth is
///    not more open than the neutral's ([`FollowOptions::mouth_margin`], [`mouth_opening`])
///    and, after the warm-up, whose expression is at rest ([`super::neutral_like`]: a held
///    smile does not become the neutral), kept aligned to the model's `s0`
///    ([`neutral_update`]).
///    **Appearance.** The frame is sampled into the model's reference frame at the smoothed
///    points, and the person's neutral appearance kept from the frames at rest
///    ([`super::ObservedAppearance`]); with the whole deviation `x - n`, less the part a
///    turn of the head to the side explains ([`split_head_yaw`]; a nod is left in, as the
///    expressive method leaves it in its own model's displacement: it moves the lip corners
///    as a smile lifts them), they are the [`FaceTracker::observed`] face the expressive
///    method clones. A frame whose mouth is
///    covered (then "unsure", reason "covered") or whose face is partly outside the picture
///    keeps the last look.
/// 3. **Head turns.** The part of `x - n` that turning or nodding the head out of the image
///    plane explains, to first order, is split off as `t` ([`split_head_turn`],
///    [`FollowOptions::split_head_turns`]): a turn is pose, not expression.
/// 4. **Mapping.** `p = S^T (x - t - n)`, the deviation projected onto the source model's
///    orthonormal modes, clamped to `+-max_sigmas` ([`expression_params`]).
///
/// Ensures: the result has the [`FitResult`] layout of the AAM tracker, so cloning and
/// drawing take it unchanged: `params.shape = p`; `params.pose = P ∘ align(s0 -> n)` (where the
/// model's base face sits on the person's neutral); `params.appearance` all zeros, the model's
/// mean appearance (the colours of the person in front of the camera say nothing about the
/// source model's appearance modes, which describe another person's face; projecting them
/// would drive the targets' appearance with lighting and identity, not expression);
/// `landmarks = P(n + S p + t)`, the person's neutral plus the mapped deviation and the
/// head's turn, posed (the face as the source model can express it, turned as the person's);
/// `error` = 1 minus the mesh's face-presence score near the last face (0 for a face taken
/// from a search or an offer); `iterations` = the mesh passes run near the last face this
/// frame (0 when a search alone gave the face; the finder's own passes are not counted). A
/// frame with no face has `lost = true` and carries the last good result; the next frames
/// search until a face is found (`reacquired = true` on that frame).
///
/// After the first search, a frame followed near the last face allocates nothing; a search
/// allocates the finder's list of faces.
pub struct Follower {
    finder: FaceFinder,
    options: FollowOptions,
    /// The source model's base shape `s0` (model coordinates).
    base: Vec<f32>,
    /// The source model's modes, row-major `m x 2n` (orthonormal).
    modes: Vec<f32>,
    /// `sigma_i` of each mode.
    sigmas: Vec<f32>,
    /// Appearance parameters reported (zeros).
    appearance_modes: usize,
    filter: OneEuro,
    /// The finder's points of the last face (not smoothed): where the next passes look.
    last_raw: [f32; 136],
    /// True while a face is followed (the next frame looks near `last_raw`).
    following: bool,
    /// True once a face was seen, so `neutral` and `result` hold one.
    seen: bool,
    /// Frames whose shape entered the neutral.
    neutral_frames: u32,
    /// The person's neutral shape (model coordinates, aligned to `s0`).
    neutral: [f32; 136],
    /// Scratch: the frame's points, the shape in model coordinates, the followed shape.
    points: [f32; 136],
    shape: [f32; 136],
    followed: [f32; 136],
    /// Scratch: the displacement a head turn explains ([`split_head_turn`]).
    turn: [f32; 136],
    /// The face's smoothed points in the frame (the head's turn kept, no mode projection):
    /// where its appearance is observed.
    seen_at: [f32; 136],
    /// How far the last frame was from rest ([`super::rest_distance`]; at rest up to 1).
    rest: f32,
    /// The last frame's whole expression: its smoothed shape less the neutral, model
    /// coordinates ([`super::Observed::displacement`]); the head's turn to the side left out
    /// ([`split_head_yaw`]), its nod left in (a nod moves the lip corners against the lips'
    /// middle much as a smile lifts them, and the expressive method keeps a smile's lift).
    deviation: [f32; 136],
    /// The frame's appearance at the followed face and the person's neutral one.
    observed: super::ObservedAppearance,
    /// Faces offered from elsewhere, used by the next search.
    offered: Option<Vec<Vec<f32>>>,
    /// Whether a search runs the finder on the frame (else it waits for offered faces).
    search: bool,
    /// A box to look in on the next frame ([`Follower::start_from_box`](crate::fit::FaceTracker::start_from_box)).
    start_box: Option<BBox>,
    /// The last frame's points came from the finder's mesh near the last face (not from a
    /// search), so the next frame can follow that mesh (`FaceFinder::follow_into`).
    meshed: bool,
    /// The policy: its pose anchor's time constant (the follower reads frames at their own
    /// size, so its resampling rule is not used).
    policy: TrackPolicy,
    result: FitResult,
    /// The counters and the pose anchor.
    seq: Sequence,
}

impl FaceTracker for Follower {
    fn kind(&self) -> TrackerKind {
        TrackerKind::Landmarks
    }

    /// Always 0: the follower does not refit.
    fn resets(&self) -> u32 {
        0
    }

    /// Always `(0, 0)`: its landmarks come from the finder every frame.
    fn rechecks(&self) -> (u32, u32) {
        (0, 0)
    }

    /// Always 1: it reads the frame at its own size.
    fn scale(&self) -> f32 {
        1.0
    }

    /// Always 1 (see [`FaceTracker::scale`]).
    fn fit_scale(&self, _face_height: f32, _width: u32, _height: u32, _current: f32) -> f32 {
        1.0
    }

    /// Follows the face in the next frame, `dt` seconds after the previous one (the One-Euro
    /// filter's step; `1/25` for a 25 fps clip).
    ///
    /// Fails with [`Error::Params`] when `dt` is not a finite non-negative number (0 restarts
    /// the smoothing: a frame at the same instant); otherwise the result (see the type's
    /// documentation) has `lost = true` when no face was found.
    /// [`super::FaceTracker::track`].
    fn track(&mut self, frame: &ImageRef<'_>, dt: f32) -> Result<&FitResult> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(Error::Params(format!(
                "the time step is {dt} s: a finite non-negative number is needed"
            )));
        }
        self.step(frame, dt)?;
        // Something over the mouth (its lips do not stand out from the skin around them):
        // the finder's mouth there is a guess and the frame's look the cover's.
        let covered = !self.result.lost
            && crate::train::quality::lip_contrast(frame, &self.seen_at)
                < crate::train::quality::MIN_LIP_CONTRAST;
        if !self.result.lost {
            if self.result.reacquired {
                // Found again after a loss: it may be someone else.
                self.observed.reset();
            }
            // A face partly outside the picture has no look there (the samples would repeat
            // the picture's edge): the last whole one is kept.
            let (w, h) = (frame.width() as f32 - 1.0, frame.height() as f32 - 1.0);
            let whole = self
                .seen_at
                .chunks_exact(2)
                .all(|p| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w && p[1] <= h);
            if !covered && whole {
                self.observed.observe(frame, &self.seen_at, self.rest)?;
            }
        }
        // The follower reads the finder's face on every frame: it is tracking a face, unsure
        // of it (the mouth covered: the targets hold the last good expression), or has none
        // (a mesh score under the bound is a search, then no face).
        let r = &mut self.result;
        (r.status, r.reasons) = if r.lost {
            (super::TrackStatus::Lost, super::Reasons::NO_FACE)
        } else if covered {
            (super::TrackStatus::Unsure, super::Reasons::COVERED)
        } else {
            (super::TrackStatus::Tracking, super::Reasons::NONE)
        };
        let r = &self.result;
        let pose = (!r.lost).then_some(r.params.pose);
        let reacquired = !r.lost && r.reacquired;
        self.seq
            .frame(pose.as_ref(), dt, self.policy.recentre_tau, reacquired);
        Ok(&self.result)
    }

    /// The frame's appearance at the followed face, and the person's neutral one
    /// ([`super::ObservedAppearance`]); `None` before the first face of the sequence.
    fn observed(&self) -> Option<super::Observed<'_>> {
        self.observed.get().map(|o| super::Observed {
            displacement: Some(&self.deviation[..]),
            ..o
        })
    }

    /// The last frame's result, `None` before the follower's first frame.
    fn last(&self) -> Option<&FitResult> {
        (self.seq.frames() > 0).then_some(&self.result)
    }

    /// The sequence's counters and pose anchor, as [`Tracker::sequence`](crate::fit::FaceTracker::sequence):
    /// [`Sequence::placed`] is the last face's pose re-centred on the model's mean pose.
    fn sequence(&self) -> &Sequence {
        &self.seq
    }

    /// Faces found elsewhere (68 landmarks each, image coordinates, most confident first):
    /// the next search takes the one nearest the last face instead of running the finder.
    /// Fails with [`Error::Params`] (keeping none) when a face has another length or a
    /// non-finite point.
    fn offer_faces(&mut self, faces: Vec<Vec<f32>>) -> Result<()> {
        for f in &faces {
            check_landmarks_len("offered face landmarks", f, 136)?;
        }
        self.offered = Some(faces);
        Ok(())
    }

    /// Whether the follower is searching for a face and has none offered: the moment to run a
    /// finder on a frame and [`Follower::offer_faces`](crate::fit::FaceTracker::offer_faces).
    fn wants_faces(&self) -> bool {
        !self.following && self.offered.is_none() && self.start_box.is_none()
    }

    /// Whether faces will be offered from elsewhere ([`Follower::offer_faces`](crate::fit::FaceTracker::offer_faces): a finder on
    /// another thread): then a search only uses them (until they come, frames are lost);
    /// else (the default) a search runs the follower's own finder on the whole frame and the
    /// faces offered are dropped. [`super::FaceTracker::expect_offers`].
    fn expect_offers(&mut self, yes: bool) {
        self.search = !yes;
        if !yes {
            self.offered = None;
        }
    }

    /// Starts a new sequence with no face: forgets the person; the next frame searches for a
    /// face (the faces offered, or its finder: [`Follower::expect_offers`](crate::fit::FaceTracker::expect_offers)), and the neutral
    /// shape is estimated again from the first frames.
    fn start_searching(&mut self) {
        self.following = false;
        self.meshed = false;
        self.seen = false;
        self.neutral_frames = 0;
        self.observed.reset();
        self.offered = None;
        self.start_box = None;
        self.result.lost = true;
        self.seq.restart();
    }

    /// Starts a new sequence with no face, found by the follower's own finder on the whole
    /// frame: [`Follower::start_searching`](crate::fit::FaceTracker::start_searching) with offers no longer expected
    /// ([`Follower::expect_offers`](crate::fit::FaceTracker::expect_offers)). Never fails (the trait's signature).
    fn start_auto(&mut self) -> Result<()> {
        self.expect_offers(false);
        self.start_searching();
        Ok(())
    }

    /// Starts a new person from their face's 68 landmarks on the next frame (image
    /// coordinates): [`Follower::start_searching`](crate::fit::FaceTracker::start_searching), then the landmarks offered as the face. Fails with
    /// [`Error::Params`] (changing nothing) for another length or non-finite values.
    fn start_from_landmarks(&mut self, landmarks: &[f32]) -> Result<()> {
        check_landmarks_len("landmarks", landmarks, 136)?;
        self.start_searching();
        self.offered = Some(vec![landmarks.to_vec()]);
        Ok(())
    }

    /// Starts a new person from a face box on the next frame (image coordinates: left, top,
    /// width, height): [`Follower::start_searching`](crate::fit::FaceTracker::start_searching), then the mesh in the box; if it holds no face,
    /// the frame is searched as usual. Fails with [`Error::Params`] for a
    /// non-finite box or one under 4x4.
    fn start_from_box(&mut self, x: f32, y: f32, w: f32, h: f32) -> Result<()> {
        check_face_box(x, y, w, h)?;
        self.start_searching();
        self.start_box = Some(BBox {
            x,
            y,
            width: w,
            height: h,
        });
        Ok(())
    }

    /// The policy (the pose anchor's `recentre_tau`).
    fn policy(&self) -> &TrackPolicy {
        &self.policy
    }

    /// Replaces the resampling policy; fails with [`Error::Params`] (keeping the old one) when
    /// a value is out of range.
    fn set_policy(&mut self, policy: TrackPolicy) -> Result<()> {
        self.policy.replace(policy)
    }
}

impl std::fmt::Debug for Follower {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (o, following, frames) = (&self.options, self.following, self.seq.frames());
        summary(
            f,
            "Follower",
            &[
                ("options", o),
                ("following", &following),
                ("frames", &frames),
            ],
        )
    }
}

impl Follower {
    /// A follower driving `model`'s shape modes, with the shipped finder.
    ///
    /// Requires a 68-landmark model (the finder's layout); fails with [`Error::Params`]
    /// otherwise or when `options` are out of range ([`FollowOptions::check`]).
    pub fn new(model: &Model, options: FollowOptions) -> Result<Follower> {
        Self::with_finder(model, options, FaceFinder::new()?)
    }

    /// [`Follower::new`] with a finder of the caller's (its options are kept).
    pub fn with_finder(
        model: &Model,
        options: FollowOptions,
        finder: FaceFinder,
    ) -> Result<Follower> {
        options.check()?;
        if model.landmarks() != 68 {
            return Err(Error::Params(format!(
                "following landmarks needs a 68-landmark model (the face finder's layout); \
                 '{}' has {}",
                model.name(),
                model.landmarks()
            )));
        }
        let shape = model.shape();
        let base = model.base_params();
        let mut landmarks = vec![0.0; 136];
        model.image_shape(&base, &mut landmarks)?;
        Ok(Follower {
            finder,
            options,
            base: shape.base.clone(),
            modes: shape.modes.clone(),
            sigmas: shape.sigmas(),
            appearance_modes: model.appearance().n_modes(),
            filter: OneEuro::default(),
            last_raw: [0.0; 136],
            following: false,
            seen: false,
            neutral_frames: 0,
            neutral: [0.0; 136],
            points: [0.0; 136],
            shape: [0.0; 136],
            followed: [0.0; 136],
            turn: [0.0; 136],
            seen_at: [0.0; 136],
            rest: f32::INFINITY,
            deviation: [0.0; 136],
            observed: super::ObservedAppearance::new(model.frame()),
            offered: None,
            search: true,
            start_box: None,
            meshed: false,
            policy: TrackPolicy::default(),
            seq: Sequence::new(base.pose),
            result: FitResult {
                landmarks,
                params: base,
                error: 0.0,
                iterations: 0,
                converged: false,
                lost: true,
                reacquired: false,
                status: crate::fit::TrackStatus::Tracking,
                reasons: crate::fit::Reasons::NONE,
            },
        })
    }

    /// The options in use.
    pub fn options(&self) -> &FollowOptions {
        &self.options
    }

    /// Replaces the options; fails with [`Error::Params`] (keeping the old ones) when a value
    /// is out of range.
    pub fn set_options(&mut self, options: FollowOptions) -> Result<()> {
        options.check()?;
        self.options = options;
        Ok(())
    }

    /// One frame of [`Follower::track`](crate::fit::FaceTracker::track) into `self.result` (the counters left to it).
    fn step(&mut self, frame: &ImageRef<'_>, dt: f32) -> Result<()> {
        let mut passes = 0u32;
        // The frame's `FitResult::error`: the mesh's doubt that the region holds a face.
        let mut doubt = 0.0f32;
        let mut found = false;
        let reacquired;
        let start_box = self.start_box.take();
        if self.following || start_box.is_some() {
            // Near the last face: one mesh pass on the region of its last mesh when this
            // finder made it (MediaPipe's tracking), else two from its box (or the box given).
            let r = if self.meshed && start_box.is_none() {
                passes = 1;
                self.finder.follow_into(frame, &mut self.points)
            } else {
                passes = 2;
                let near = start_box.unwrap_or_else(|| BBox::around_landmarks(&self.last_raw));
                self.finder
                    .scored_landmarks_into(frame, near, &mut self.points)
            };
            if let Ok(score) = r {
                doubt = 1.0 - score;
                found = score >= self.options.min_face_score && self.inside(frame, &self.points);
            }
        }
        self.meshed = found;
        if found {
            reacquired = start_box.is_some();
        } else {
            found = self.search_face(frame);
            doubt = 0.0;
            reacquired = found;
        }
        if !found {
            self.following = false;
            self.result.lost = true;
            self.result.converged = false;
            self.result.reacquired = false;
            self.result.iterations = passes;
            return Ok(());
        }
        self.last_raw.copy_from_slice(&self.points);
        if reacquired {
            self.filter.reset(136);
        }
        self.following = true;
        self.follow_points(reacquired, doubt, passes, dt)
    }

    /// Searches a lost or new face (the faces offered, else the finder on the whole frame when
    /// [`Follower::expect_offers`](crate::fit::FaceTracker::expect_offers) allows): the one nearest the last face, inside the frame, into
    /// `self.points`. Returns whether there was one.
    fn search_face(&mut self, frame: &ImageRef<'_>) -> bool {
        let faces = match self.offered.take() {
            Some(f) => f,
            None if self.search => self
                .finder
                .find(frame)
                .into_iter()
                .map(|f| f.landmarks)
                .collect(),
            None => Vec::new(),
        };
        let centre = |s: &[f32]| {
            let b = BBox::of_points(s);
            (b.x + 0.5 * b.width, b.y + 0.5 * b.height)
        };
        let near = self.seen.then(|| centre(&self.last_raw));
        let best = super::tracker::nearest_face(&faces, near, centre, |f| {
            f.len() == 136 && self.inside(frame, f)
        });
        match best {
            Some(f) => {
                self.points.copy_from_slice(f);
                true
            }
            None => false,
        }
    }

    /// Whether at least [`FollowOptions::min_inside`] of `points` lie inside `frame`.
    fn inside(&self, frame: &ImageRef<'_>, points: &[f32]) -> bool {
        let (w, h) = (frame.width() as f32, frame.height() as f32);
        let n = points
            .chunks_exact(2)
            .filter(|p| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w - 1.0 && p[1] <= h - 1.0)
            .count();
        n as f32 >= self.options.min_inside * (points.len() / 2) as f32
    }

    /// Steps 2 and 3 on the frame's points in `self.points`, into `self.result`.
    fn follow_points(&mut self, reacquired: bool, doubt: f32, passes: u32, dt: f32) -> Result<()> {
        if !self.seen {
            // The first face: its shape, aligned to s0, is the first neutral (replaced by the
            // closed-mouth frames' mean as they come).
            let to_base = Similarity::align(&self.points, &self.base);
            to_base.apply(&self.points, &mut self.neutral);
            close_first_neutral(
                &mut self.neutral,
                &self.base,
                &self.modes,
                self.options.mouth_margin,
            );
            self.neutral_frames = 0;
            self.seen = true;
        }
        // The pose of the neutral onto the points, and the points in model coordinates.
        // Fitted on the points an expression hardly moves (the nose and the eye corners): over
        // all 68, a laugh's dropped jaw and widened mouth pulled the pose, and part of the laugh
        // was taken for the head growing and moving.
        let pose = Similarity::align_points(&self.neutral, &self.points, &STABLE_POINTS);
        let Some(inv) = pose.inverse() else {
            // Degenerate points (all in one place): no face.
            self.following = false;
            self.result.lost = true;
            self.result.reacquired = false;
            return Ok(());
        };
        inv.apply(&self.points, &mut self.shape);
        // Smoothing in model coordinates: the shape alone, so a moving head is not lagged
        // (the pose, a least-squares fit over 68 points, is steady without it).
        let iod = crate::landmarks::eye_line(&self.neutral)
            .map(|[x, y]| (x * x + y * y).sqrt())
            .unwrap_or(1.0);
        let o = self.options;
        self.filter
            .filter(&mut self.shape, dt, o.min_cutoff, o.beta, o.d_cutoff, iod);
        let moved = neutral_update(
            &mut self.neutral,
            &self.shape,
            &self.base,
            &mut self.neutral_frames,
            o.warmup,
            o.neutral_step,
            o.mouth_margin,
        );
        // The neutral was re-aligned to s0 by `moved`: the frame's shape and pose follow it.
        moved.apply_in_place(&mut self.shape);
        let pose = match moved.inverse() {
            Some(back) => pose.compose(&back),
            None => pose,
        };
        if o.split_head_turns {
            split_head_turn_keeping_nod(
                &mut self.shape,
                &self.neutral,
                crate::find::IBUG_DEPTH,
                &mut self.turn,
                &mut self.deviation,
            );
        } else {
            self.turn = [0.0; 136];
            for ((d, s), n) in self
                .deviation
                .iter_mut()
                .zip(&self.shape)
                .zip(&self.neutral)
            {
                *d = s - n;
            }
        }
        // Where the face is in the frame (smoothed, turned as it is), and whether it rests.
        for ((o, s), t) in self.seen_at.iter_mut().zip(&self.shape).zip(&self.turn) {
            *o = s + t;
        }
        pose.apply_in_place(&mut self.seen_at);
        self.rest = super::rest_distance(&self.shape, &self.neutral, o.mouth_margin);
        let r = &mut self.result;
        expression_params(
            &self.shape,
            &self.neutral,
            &self.modes,
            &self.sigmas,
            self.options.max_sigmas,
            &mut r.params.shape,
        );
        // The followed shape: the neutral plus the mapped deviation and the head's turn, posed.
        for ((f, n), t) in self.followed.iter_mut().zip(&self.neutral).zip(&self.turn) {
            *f = n + t;
        }
        let d = self.base.len();
        for (pi, mode) in r.params.shape.iter().zip(self.modes.chunks_exact(d)) {
            self.followed
                .iter_mut()
                .zip(mode)
                .for_each(|(o, s)| *o += pi * s);
        }
        // Placed on the points by all 68 of them, as the face the source model can express
        // fits them best (the pose above is the head's alone: the part of a laugh the model
        // cannot express would be left as an offset of the jaw).
        let place = Similarity::align(&self.followed, &self.points);
        let place = if place.is_valid() { place } else { pose };
        place.apply(&self.followed, &mut r.landmarks);
        r.params.pose = pose.compose(&Similarity::align(&self.base, &self.neutral));
        r.params.appearance.clear();
        r.params.appearance.resize(self.appearance_modes, 0.0);
        r.error = doubt;
        r.iterations = passes;
        r.converged = true;
        r.lost = false;
        r.reacquired = reacquired;
        crate::model::limits::check_output("followed landmarks", &r.landmarks)?;
        crate::model::limits::check_output("followed shape parameters", &r.params.shape)?;
        Ok(())
    }

    /// The person's neutral shape as estimated so far (model coordinates, aligned to the
    /// model's `s0`); `None` before the first face.
    pub fn neutral(&self) -> Option<&[f32]> {
        self.seen.then_some(&self.neutral[..])
    }
}

/// The inner lips' opening of 68 points: the mean distance of the upper inner lip's points
/// 61, 62, 63 to the lower's 67, 66, 65, over the outer-eye-corner distance (0 for another
/// length or coinciding eye corners).
pub fn mouth_opening(points: &[f32]) -> f32 {
    let Some([ex, ey]) = crate::landmarks::eye_line(points) else {
        return 0.0;
    };
    let iod = (ex * ex + ey * ey).sqrt();
    if !(iod > 0.0) {
        return 0.0;
    }
    let d = |i: usize, j: usize| {
        (points[2 * i] - points[2 * j]).hypot(points[2 * i + 1] - points[2 * j + 1])
    };
    (d(61, 67) + d(62, 66) + d(63, 65)) / 3.0 / iod
}

/// Closes the mouth of a person's first neutral shape (68 points, model coordinates): to
/// `mouth_margin`, or to the model's base face's opening `base` if that is smaller, along
/// `modes` ([`close_mouth`]), when it is more open than that by more than `mouth_margin`.
/// Both trackers start their neutral with it: the [`Follower`] from the first face it sees, the
/// AAM tracker's observer from the person's model's mean shape.
///
/// Else a person first seen talking or laughing would read their opening as no expression
/// until they closed their mouth; and closed only as far as the base face, which for a speech
/// model is its frames' mean, half open (spk07's inner lips 0.084 of the eye corners' distance
/// apart), a session that opened laughing let the laugh's parted tail into the neutral, whose
/// wide, lifted, half-open mouth then hid the smiles that followed (franck-dev2's laughs on the
/// targets through the follower: 0.19 of the source's "happy", 0.28 closed; through his own
/// model 0.62, 0.68 closed; docs/cloning.md).
pub fn close_first_neutral(neutral: &mut [f32], base: &[f32], modes: &[f32], mouth_margin: f32) {
    let rest = mouth_opening(base).min(mouth_margin);
    if mouth_opening(neutral) > rest + mouth_margin {
        close_mouth(neutral, modes, rest);
    }
    bound_neutral_mouth(neutral);
}

/// The widest mouth of a face at rest, in outer eye corners' distances ([`mouth_shape`]'s
/// width): where a face becomes likelier smiling than at rest, the two equally likely, with
/// the London set's 60 people's neutral photos (0.578 +- 0.035) and smiling ones (0.674 +-
/// 0.058) as normal distributions (dlib's points, `data/london`; [`rest_boundary`] finds it,
/// and `tests/integration/follow.rs` learns it again from them). About one face at rest in
/// ten is wider (6 of the 60 by dlib's points, 2 by the face finder's), three smiles in four
/// (45).
pub const REST_MOUTH_WIDTH: f32 = 0.6246;

/// The highest lip corners of a face at rest ([`mouth_shape`]'s lift), found as
/// [`REST_MOUTH_WIDTH`]: between the London set's neutral photos (0.001 +- 0.023) and its
/// smiles (0.056 +- 0.034). [`bound_neutral_mouth`] holds the lift only of a mouth wider than
/// [`REST_MOUTH_WIDTH`]: a head bowed to the camera lifts the corners alone.
pub const REST_CORNER_LIFT: f32 = 0.0285;

/// Where two normal distributions `(mean, sd)` are equally likely, between their means: the
/// bound between a measure's values at rest (`rest`) and in an expression (`expressed`), as
/// [`REST_MOUTH_WIDTH`] and [`REST_CORNER_LIFT`] are found. `None` when the means coincide or
/// a deviation is not positive.
pub fn rest_boundary(rest: (f32, f32), expressed: (f32, f32)) -> Option<f32> {
    let ((m1, s1), (m2, s2)) = (
        (f64::from(rest.0), f64::from(rest.1)),
        (f64::from(expressed.0), f64::from(expressed.1)),
    );
    if !(s1 > 0.0 && s2 > 0.0 && m1 != m2) {
        return None;
    }
    // log N(x; m1, s1) = log N(x; m2, s2): a x^2 + b x + c = 0.
    let a = 0.5 / (s2 * s2) - 0.5 / (s1 * s1);
    let b = m1 / (s1 * s1) - m2 / (s2 * s2);
    let c = 0.5 * m2 * m2 / (s2 * s2) - 0.5 * m1 * m1 / (s1 * s1) + (s2 / s1).ln();
    let (lo, hi) = (m1.min(m2), m1.max(m2));
    // Equal deviations: one root (the other slot is not a number, inside no range).
    let roots = if a.abs() < 1e-12 {
        [-c / b, f64::NAN]
    } else {
        let d = (b * b - 4.0 * a * c).sqrt();
        [(-b + d) / (2.0 * a), (-b - d) / (2.0 * a)]
    };
    roots
        .into_iter()
        .find(|x| (lo..=hi).contains(x))
        .map(|x| x as f32)
}

/// Mouth width and lip-corner lift of 68 points, in outer eye corners' (36, 45) distances:
/// `|p48 - p54|`, and how far the corners' midpoint lies above the midpoint of the lips' centre
/// points 51 and 57 along the face's up direction (perpendicular to the eye line). `None` for
/// another length or coinciding eye corners.
pub fn mouth_shape(p: &[f32]) -> Option<[f32; 2]> {
    let [ex, ey] = crate::landmarks::eye_line(p)?;
    let iod = ex.hypot(ey);
    if !(iod > 0.0) {
        return None;
    }
    let (ux, uy) = (ey / iod, -ex / iod);
    let width = (p[108] - p[96]).hypot(p[109] - p[97]) / iod;
    let corners = [(p[96] + p[108]) / 2.0, (p[97] + p[109]) / 2.0];
    let centre = [(p[102] + p[114]) / 2.0, (p[103] + p[115]) / 2.0];
    let lift = ((corners[0] - centre[0]) * ux + (corners[1] - centre[1]) * uy) / iod;
    Some([width, lift])
}

/// Brings a person's neutral shape (68 points) within the mouths of faces at rest: a mouth
/// wider than [`REST_MOUTH_WIDTH`] is narrowed to it, the lips (points 48-67) drawn towards
/// their centre along the eye line, and if it was wider, lip corners higher than
/// [`REST_CORNER_LIFT`] are lowered to it (a smile widens the mouth and lifts its corners; a
/// head bowed to the camera lifts them alone: followed through GRID's eleven committed clips,
/// six neutrals end with corners 0.029-0.058 high, and one mouth is wide enough to be held),
/// each lip point along the face's down direction by the excess times the
/// square of its distance from the corners' midpoint along the eye line over half theirs (the
/// corners by all of it, the middle of the lips hardly at all). Returns whether it moved anything;
/// a shape with a point that is not finite, or not of 68 points, is left as it is.
///
/// Else a session that opens smiling, or a person who smiles as they talk, keeps a smile as
/// their neutral, and every smile after it reads as no expression: franck-dev2's neutral
/// through the follower was 0.70 wide with its corners 0.05 up through his first 600 frames,
/// a smile (docs/cloning.md).
pub fn bound_neutral_mouth(neutral: &mut [f32]) -> bool {
    // A point that is not a number would spread to every lip through their centre.
    if !neutral.iter().all(|v| v.is_finite()) {
        return false;
    }
    let Some([width, lift]) = mouth_shape(neutral) else {
        return false;
    };
    // A ten-thousandth of the eye distance over a bound is within it (rounding). The lift is
    // held only with the width: a head bowed to the camera lifts the corners of a mouth at
    // rest in the picture (they lie deeper than the lips' middle), but does not widen it.
    if !(width > REST_MOUTH_WIDTH + 1e-4) {
        return false;
    }
    let Some([ex, ey]) = crate::landmarks::eye_line(neutral) else {
        return false;
    };
    let iod = ex.hypot(ey);
    let (ax, ay) = (ex / iod, ey / iod);
    // Down the face: the eye line turned a quarter clockwise (y grows downwards).
    let (dx, dy) = (-ay, ax);
    let lips = 48..68;
    let n = lips.len() as f32;
    let (cx, cy) = lips.clone().fold((0.0, 0.0), |(x, y), i| {
        (x + neutral[2 * i] / n, y + neutral[2 * i + 1] / n)
    });
    // The corners' distance along the eye line scaled so that, with the part across it kept,
    // they lie the bound apart.
    let (wx, wy) = (neutral[108] - neutral[96], neutral[109] - neutral[97]);
    let (along, across) = (wx * ax + wy * ay, wx * dx + wy * dy);
    let target = (REST_MOUTH_WIDTH * iod).powi(2) - across * across;
    let k = if target > 0.0 && along.abs() > 0.0 {
        target.sqrt() / along.abs() - 1.0
    } else {
        REST_MOUTH_WIDTH / width - 1.0
    };
    for i in lips.clone() {
        let a = (neutral[2 * i] - cx) * ax + (neutral[2 * i + 1] - cy) * ay;
        neutral[2 * i] += k * a * ax;
        neutral[2 * i + 1] += k * a * ay;
    }
    if lift > REST_CORNER_LIFT + 1e-4 {
        let drop = (lift - REST_CORNER_LIFT) * iod;
        // Along the eye line from the corners' midpoint, in half the corners' distance.
        let (mx, my) = (
            0.5 * (neutral[96] + neutral[108]),
            0.5 * (neutral[97] + neutral[109]),
        );
        let along = |p: &[f32], i: usize| (p[2 * i] - mx) * ax + (p[2 * i + 1] - my) * ay;
        let half = 0.5 * (along(neutral, 54) - along(neutral, 48)).abs();
        if half > 0.0 {
            for i in lips {
                let w = (along(neutral, i).abs() / half).min(1.0).powi(2);
                neutral[2 * i] += drop * w * dx;
                neutral[2 * i + 1] += drop * w * dy;
            }
        }
    }
    true
}

/// The person's running neutral shape, updated with one frame's `shape` (model coordinates):
/// - a frame whose mouth ([`mouth_opening`]) is more open than the neutral's by more than
///   `mouth_margin` leaves it as it is (speech and smiles do not open the neutral's mouth);
/// - during the first `warmup` frames that enter, the neutral is their mean;
/// - then it moves a fifth of the way at once when the frame's mouth is more closed than the
///   neutral's by more than `mouth_margin` (a neutral that started with an open mouth closes
///   within a few frames); else only a frame whose expression is at rest
///   ([`super::neutral_like`]) moves it, each coordinate at most `step` towards the frame's
///   (a running median: `n += clamp(x - n, -step, step)`, which settles where half the frames
///   lie on either side): a smile with closed lips, held, does not become the neutral and
///   fade from the clone;
/// - finally the neutral is re-aligned to `base` by a similarity so it cannot drift in pose.
///
/// `count` counts the frames that entered the mean. Returns the re-aligning similarity (the
/// identity when nothing moved), so the caller can move shapes in the old neutral's
/// coordinates with it. Requires `neutral`, `shape` and `base` of one length.
pub fn neutral_update(
    neutral: &mut [f32],
    shape: &[f32],
    base: &[f32],
    count: &mut u32,
    warmup: u32,
    step: f32,
    mouth_margin: f32,
) -> Similarity {
    let (open, rest) = (mouth_opening(shape), mouth_opening(neutral));
    if open > rest + mouth_margin {
        return Similarity::IDENTITY;
    }
    if *count < warmup {
        *count += 1;
        let w = 1.0 / *count as f32;
        neutral
            .iter_mut()
            .zip(shape)
            .for_each(|(n, x)| *n += w * (x - *n));
    } else if open < rest - mouth_margin {
        neutral
            .iter_mut()
            .zip(shape)
            .for_each(|(n, x)| *n += 0.2 * (x - *n));
    } else if !super::neutral_like(shape, neutral) {
        return Similarity::IDENTITY;
    } else {
        neutral
            .iter_mut()
            .zip(shape)
            .for_each(|(n, x)| *n += (x - *n).clamp(-step, step));
    }
    bound_neutral_mouth(neutral);
    let to_base = Similarity::align(neutral, base);
    if to_base.is_valid() {
        to_base.apply_in_place(neutral);
        to_base
    } else {
        Similarity::IDENTITY
    }
}

/// Splits off the part of a 68-point `shape`'s deviation from `neutral` that a small turn or
/// nod of the head out of the image plane explains, to first order, and writes it to `turn`
/// (`shape` keeps the rest).
///
/// Turning a face by a small angle `a` about its vertical axis moves each point sideways by
/// `a` times its depth (`x' = x cos a + z sin a`), and nodding moves it along the face's
/// vertical axis the same way: two directions in shape space, `z_i u` and `z_i v`, with `u`
/// the neutral's eye line (point 36 to 45) and `v` its perpendicular. Whatever of them a
/// similarity explains (the pose is fitted before) is taken out of them; the deviation's
/// component along what remains is the turn. `depth` is each point's depth in any unit (only
/// its profile matters; the finder's is [`IBUG_DEPTH`](crate::find::IBUG_DEPTH)). The lips,
/// brows and jaw move with expression along other directions, which a turn's leaves to the
/// modes; an expression that moves every point by its depth would be read as a turn.
///
/// Requires 136 values in `shape`, `neutral` and `turn` and 68 in `depth`; leaves `shape`
/// unchanged and `turn` zero otherwise, or when the neutral is degenerate. Allocates nothing.
pub fn split_head_turn(shape: &mut [f32], neutral: &[f32], depth: &[f32], turn: &mut [f32]) {
    split_turn(shape, neutral, depth, turn, true, None);
}

/// [`split_head_turn`], and beside it, from the same directions, the whole expression the
/// expressive method clones from a followed face: `shape` less `neutral` with only the turn to
/// the side left out, the nod left in (a nod moves the lip corners against the lips' middle
/// much as a smile lifts them, and the expressive method keeps a smile's lift: it splits its
/// own model's displacement the same way, [`split_head_yaw`]). Through the follower on
/// franck-dev the clones' lift spread rose from 0.74 to 0.86-0.97 of the real one with its
/// correlation unchanged (0.93). `expression` is left as it is where `shape` is (wrong
/// lengths). Allocates nothing.
pub(crate) fn split_head_turn_keeping_nod(
    shape: &mut [f32],
    neutral: &[f32],
    depth: &[f32],
    turn: &mut [f32],
    expression: &mut [f32],
) {
    split_turn(shape, neutral, depth, turn, true, Some(expression));
}

/// [`split_head_turn`] about the vertical axis only: the head's turn to the side is split off,
/// its nod is left in `shape`. A nod moves the mouth's corners against its middle much as a
/// smile lifts them (the corners lie deeper), so where the expression must keep its whole lift
/// (the expressive method holding a target's own pose) only the turn is taken out.
pub fn split_head_yaw(shape: &mut [f32], neutral: &[f32], depth: &[f32], turn: &mut [f32]) {
    split_turn(shape, neutral, depth, turn, false, None);
}

/// [`split_head_turn`] (`nod`: both directions) or [`split_head_yaw`]; with `expression`, the
/// deviation `shape - neutral` once the turn to the side is out and before the nod is
/// ([`split_head_turn_keeping_nod`]). The directions are found once.
fn split_turn(
    shape: &mut [f32],
    neutral: &[f32],
    depth: &[f32],
    turn: &mut [f32],
    nod: bool,
    expression: Option<&mut [f32]>,
) {
    turn.iter_mut().for_each(|t| *t = 0.0);
    if shape.len() != 136 || turn.len() != 136 {
        return;
    }
    let [yaw, pitch] = turn_directions(neutral, depth);
    // The component of the deviation along `b`, moved from `shape` to `turn`.
    let mut take = |shape: &mut [f32], b: &[f32; 136]| {
        let c: f32 = shape
            .iter()
            .zip(neutral)
            .zip(b)
            .map(|((x, n), q)| (x - n) * q)
            .sum();
        if c.is_finite() {
            for ((s, t), q) in shape.iter_mut().zip(turn.iter_mut()).zip(b) {
                *s -= c * q;
                *t += c * q;
            }
        }
    };
    if let Some(b) = &yaw {
        take(shape, b);
    }
    if let Some(e) = expression {
        for ((d, s), n) in e.iter_mut().zip(shape.iter()).zip(neutral) {
            *d = s - n;
        }
    }
    if let (true, Some(b)) = (nod, &pitch) {
        take(shape, b);
    }
}

/// The unit directions in shape space (136 values) along which a small turn and a small nod
/// of the head move a 68-point `neutral`, made orthogonal to the similarities at it and the nod
/// to the turn ([`split_head_turn`]'s); `None` for one a similarity (or the turn) nearly
/// explains, both `None` for another length or a degenerate neutral. They depend on the
/// neutral alone: a caller whose neutral is fixed computes them once.
pub(crate) fn turn_directions(neutral: &[f32], depth: &[f32]) -> [Option<[f32; 136]>; 2] {
    if neutral.len() != 136 || depth.len() != 68 {
        return [None, None];
    }
    // The neutral's centroid and eye-line direction `u`.
    let Some(([cx, cy], _, ux, uy)) = crate::find::face_frame(neutral) else {
        return [None, None];
    };
    // An orthonormal basis of the similarities at the neutral (two translations, scale,
    // rotation), then the two turn directions made orthogonal to it and to each other.
    let mut basis = [[0.0f32; 136]; 6];
    for i in 0..68 {
        let (dx, dy) = (neutral[2 * i] - cx, neutral[2 * i + 1] - cy);
        basis[0][2 * i] = 1.0;
        basis[1][2 * i + 1] = 1.0;
        basis[2][2 * i] = dx;
        basis[2][2 * i + 1] = dy;
        basis[3][2 * i] = -dy;
        basis[3][2 * i + 1] = dx;
        basis[4][2 * i] = depth[i] * ux;
        basis[4][2 * i + 1] = depth[i] * uy;
        basis[5][2 * i] = -depth[i] * uy;
        basis[5][2 * i + 1] = depth[i] * ux;
    }
    let dot = |a: &[f32; 136], b: &[f32; 136]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f32>();
    let mut usable = [false; 6];
    for k in 0..6 {
        let (done, rest) = basis.split_at_mut(k);
        let b = &mut rest[0];
        let before = dot(b, b).sqrt();
        for (q, _) in done.iter().zip(&usable).filter(|(_, &u)| u) {
            let c = dot(b, q);
            b.iter_mut().zip(q).for_each(|(x, y)| *x -= c * y);
        }
        let norm = dot(b, b).sqrt();
        // A direction a similarity (or the other turn) nearly explains is left alone.
        if norm.is_finite() && norm > 1e-3 * before {
            b.iter_mut().for_each(|x| *x /= norm);
            usable[k] = true;
        }
    }
    [4, 5].map(|k| usable[k].then_some(basis[k]))
}

/// Closes the mouth of a 68-point `shape` (model coordinates) the way the model opens one:
/// moves it along the direction in the span of the model's orthonormal `modes` (row-major `m x
/// 136`) that changes [`mouth_opening`] fastest, until its opening is `opening` (within 1% of
/// the eye distance), so the jaw, chin and outer lips follow the inner lips as they do in the
/// model's faces. Leaves `shape` unchanged when another length is given, or when the modes
/// cannot move the inner lips apart. Allocates nothing.
pub fn close_mouth(shape: &mut [f32], modes: &[f32], opening: f32) {
    if shape.len() != 136 || modes.is_empty() || modes.len() % 136 != 0 || !opening.is_finite() {
        return;
    }
    let pairs = [(61, 67), (62, 66), (63, 65)];
    for _ in 0..4 {
        let now = mouth_opening(shape);
        let Some([ex, ey]) = crate::landmarks::eye_line(shape) else {
            return;
        };
        let iod = ex.hypot(ey);
        if !(iod > 0.0) || (now - opening).abs() < 0.01 {
            return;
        }
        // The gradient of the opening (the inner lips' three distances over 3 eye distances).
        let mut g = [0.0f32; 136];
        for (u, l) in pairs {
            let (dx, dy) = (
                shape[2 * u] - shape[2 * l],
                shape[2 * u + 1] - shape[2 * l + 1],
            );
            let d = dx.hypot(dy).max(1e-6) * 3.0 * iod;
            g[2 * u] += dx / d;
            g[2 * u + 1] += dy / d;
            g[2 * l] -= dx / d;
            g[2 * l + 1] -= dy / d;
        }
        // Its part in the modes' span, m = S S^T g (S's columns the modes): the opening
        // changes by g . m per unit along m.
        let mut m = [0.0f32; 136];
        for mode in modes.chunks_exact(136) {
            let c: f32 = mode.iter().zip(&g).map(|(a, b)| a * b).sum();
            m.iter_mut().zip(mode).for_each(|(o, v)| *o += c * v);
        }
        let rate: f32 = m.iter().zip(&g).map(|(a, b)| a * b).sum();
        if !(rate.is_finite() && rate > 1e-9) {
            return;
        }
        let step = (now - opening) / rate;
        shape.iter_mut().zip(&m).for_each(|(x, v)| *x -= step * v);
    }
}

/// The expression of a shape read on a model's modes: `p = S^T (shape - neutral)`, each
/// `p_i` clamped to `+-max_sigmas * sigma_i`, into `out` (resized to the number of modes).
///
/// Requires `modes` row-major `m x 2n` and orthonormal (a [`crate::ShapeModel`]'s), `shape`
/// and `neutral` in the model's coordinates (`2n` values each).
pub fn expression_params(
    shape: &[f32],
    neutral: &[f32],
    modes: &[f32],
    sigmas: &[f32],
    max_sigmas: f32,
    out: &mut Vec<f32>,
) {
    let d = neutral.len().max(1);
    out.resize(sigmas.len(), 0.0);
    for ((o, mode), s) in out.iter_mut().zip(modes.chunks_exact(d)).zip(sigmas) {
        let p: f32 = mode
            .iter()
            .zip(shape.iter().zip(neutral))
            .map(|(m, (x, n))| m * (x - n))
            .sum();
        let lim = max_sigmas * s;
        *o = p.clamp(-lim, lim);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expression_is_the_clamped_projection_of_the_deviation() {
        // Two orthonormal modes on 2 points (4 values).
        let modes = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 0.8];
        let neutral = [0.0, 0.0, 10.0, 0.0];
        let shape = [2.0, 5.0, 10.6, 0.8];
        let mut p = Vec::new();
        expression_params(&shape, &neutral, &modes, &[10.0, 10.0], 3.0, &mut p);
        assert!(
            (p[0] - 2.0).abs() < 1e-6 && (p[1] - 1.0).abs() < 1e-6,
            "{p:?}"
        );
        expression_params(&shape, &neutral, &modes, &[0.5, 10.0], 3.0, &mut p);
        assert!((p[0] - 1.5).abs() < 1e-6, "{p:?}");
    }

    /// A face-like ring of 68 points with its mouth closed (inner lips together).
    fn ring() -> Vec<f32> {
        let mut base: Vec<f32> = (0..68)
            .flat_map(|i| {
                let a = i as f32 * 0.37;
                [40.0 * a.cos() + 0.3 * i as f32, 50.0 * a.sin()]
            })
            .collect();
        for (u, l) in [(61, 67), (62, 66), (63, 65)] {
            base[2 * l] = base[2 * u];
            base[2 * l + 1] = base[2 * u + 1];
        }
        base
    }

    /// The canonical frame's face (a mean face at rest), its inner lips closed.
    fn face() -> Vec<f32> {
        let mut f = crate::canonical_frame().vertices().to_vec();
        for (u, l) in [(61, 67), (62, 66), (63, 65)] {
            f[2 * l] = f[2 * u];
            f[2 * l + 1] = f[2 * u + 1];
        }
        f
    }

    #[test]
    fn a_smiling_neutral_is_brought_within_a_mouth_at_rest() {
        let rest = face();
        let [w0, l0] = mouth_shape(&rest).unwrap();
        assert!(w0 < REST_MOUTH_WIDTH && l0 < REST_CORNER_LIFT, "{w0} {l0}");
        // A face at rest is left as it is.
        let mut n = rest.clone();
        assert!(!bound_neutral_mouth(&mut n));
        assert_eq!(n, rest);
        // A smile: the lips 25% wider and their corners up by a tenth of the eye distance.
        let [ex, ey] = crate::landmarks::eye_line(&rest).unwrap();
        let iod = ex.hypot(ey);
        let cx = (48..68).map(|i| rest[2 * i]).sum::<f32>() / 20.0;
        let mut smile = rest.clone();
        for i in 48..68 {
            smile[2 * i] = cx + 1.25 * (rest[2 * i] - cx);
        }
        for i in [48, 54, 60, 64] {
            smile[2 * i + 1] -= 0.1 * iod;
        }
        let [w1, l1] = mouth_shape(&smile).unwrap();
        assert!(
            w1 > REST_MOUTH_WIDTH + 0.05 && l1 > REST_CORNER_LIFT + 0.05,
            "{w1} {l1}"
        );
        let mut n = smile.clone();
        assert!(bound_neutral_mouth(&mut n));
        let [w, l] = mouth_shape(&n).unwrap();
        assert!((w - REST_MOUTH_WIDTH).abs() < 1e-3, "{w}");
        assert!((l - REST_CORNER_LIFT).abs() < 1e-3, "{l}");
        // Only the lips move, and the upper lip stays above the lower one.
        assert_eq!(n[..96], smile[..96]);
        for (u, lo) in [(50, 58), (51, 57), (52, 56), (61, 67), (63, 65)] {
            assert!(n[2 * u + 1] <= n[2 * lo + 1], "{u} over {lo}");
        }
        // Lifted corners alone (a bowed head) are left as they are.
        let mut bowed = rest.clone();
        for i in [48, 54, 60, 64] {
            bowed[2 * i + 1] -= 0.1 * iod;
        }
        assert!(mouth_shape(&bowed).unwrap()[1] > REST_CORNER_LIFT + 0.05);
        let before = bowed.clone();
        assert!(!bound_neutral_mouth(&mut bowed));
        assert_eq!(bowed, before);
        // Bounded again, nothing moves.
        let once = n.clone();
        assert!(!bound_neutral_mouth(&mut n));
        assert_eq!(n, once);
        // Bad shapes are left as they are: not a number, coinciding eye corners, a short one.
        let mut bad = smile.clone();
        bad[100] = f32::NAN;
        assert!(!bound_neutral_mouth(&mut bad));
        let mut flat = vec![1.0f32; 136];
        assert!(!bound_neutral_mouth(&mut flat));
        assert!(flat.iter().all(|&v| v == 1.0));
        let mut short = vec![0.0f32; 40];
        assert!(!bound_neutral_mouth(&mut short));
        assert_eq!(mouth_shape(&short), None);
    }

    #[test]
    fn the_rest_boundary_lies_where_both_are_equally_likely() {
        // Equal deviations: halfway.
        let x = rest_boundary((0.0, 1.0), (2.0, 1.0)).unwrap();
        assert!((x - 1.0).abs() < 1e-6, "{x}");
        let pdf = |x: f32, m: f32, s: f32| (-0.5 * ((x - m) / s).powi(2)).exp() / s;
        let x = rest_boundary((0.578, 0.035), (0.674, 0.058)).unwrap();
        assert!((pdf(x, 0.578, 0.035) - pdf(x, 0.674, 0.058)).abs() < 1e-3 * pdf(x, 0.578, 0.035));
        assert!(x > 0.578 && x < 0.674);
        assert_eq!(rest_boundary((0.5, 0.0), (0.6, 0.1)), None);
        assert_eq!(rest_boundary((0.5, 0.1), (0.5, 0.1)), None);
    }

    #[test]
    fn a_head_turn_is_split_off_and_the_rest_kept() {
        let n = ring();
        let depth: Vec<f32> = (0..68).map(|i| 20.0 * (i as f32 * 0.7).sin()).collect();
        let [ex, ey] = crate::landmarks::eye_line(&n).unwrap();
        let (ux, uy) = (ex / ex.hypot(ey), ey / ex.hypot(ey));
        // The head turned (0.1 rad) and nodded (0.05 rad), to first order, then posed onto
        // the neutral as the follower does: the split gives the neutral back.
        let turned: Vec<f32> = (0..68)
            .flat_map(|i| {
                let (a, b) = (0.1 * depth[i], 0.05 * depth[i]);
                [n[2 * i] + a * ux - b * uy, n[2 * i + 1] + a * uy + b * ux]
            })
            .collect();
        let mut shape = vec![0.0; 136];
        Similarity::align(&turned, &n).apply(&turned, &mut shape);
        let before = shape.clone();
        let mut turn = vec![1.0; 136];
        split_head_turn(&mut shape, &n, &depth, &mut turn);
        for i in 0..136 {
            // To first order: the pose fit leaves a second-order remainder.
            assert!(
                (shape[i] - n[i]).abs() < 0.1,
                "value {i}: {} {}",
                shape[i],
                n[i]
            );
            assert!((shape[i] + turn[i] - before[i]).abs() < 1e-4, "value {i}");
        }
        assert!(turn.iter().any(|t| t.abs() > 0.5));
        // No turn: nothing split off.
        let mut same = n.clone();
        split_head_turn(&mut same, &n, &depth, &mut turn);
        assert!(turn.iter().all(|t| t.abs() < 1e-4) && same == n);
        // Wrong lengths or a degenerate neutral: unchanged, no turn.
        let mut s = before.clone();
        split_head_turn(&mut s, &n, &depth[..60], &mut turn);
        assert!(s == before && turn.iter().all(|&t| t == 0.0));
        split_head_turn(&mut s, &[0.0; 136], &depth, &mut turn);
        assert!(s == before && turn.iter().all(|&t| t == 0.0));
    }

    #[test]
    fn the_whole_expression_keeps_a_nod_and_leaves_out_a_turn() {
        let n = ring();
        let [Some(yaw), Some(nod)] = turn_directions(&n, crate::find::IBUG_DEPTH) else {
            panic!("the ring's turn directions");
        };
        let mut shape = n.clone();
        for i in 0..136 {
            shape[i] += 3.0 * yaw[i] + 2.0 * nod[i];
        }
        let (mut plain, mut plain_turn) = (shape.clone(), vec![0.0; 136]);
        split_head_turn(&mut plain, &n, crate::find::IBUG_DEPTH, &mut plain_turn);
        let (mut turn, mut expression) = (vec![0.0; 136], vec![0.0; 136]);
        split_head_turn_keeping_nod(
            &mut shape,
            &n,
            crate::find::IBUG_DEPTH,
            &mut turn,
            &mut expression,
        );
        for i in 0..136 {
            // The expression keeps the nod, not the turn; the shape and the turn are
            // split_head_turn's.
            assert!(
                (expression[i] - 2.0 * nod[i]).abs() < 1e-4,
                "value {i}: {}",
                expression[i]
            );
            assert!((shape[i] - n[i]).abs() < 1e-4, "value {i}");
            assert!(
                (turn[i] - (3.0 * yaw[i] + 2.0 * nod[i])).abs() < 1e-4,
                "value {i}"
            );
            assert_eq!((shape[i], turn[i]), (plain[i], plain_turn[i]), "value {i}");
        }
    }

    #[test]
    fn close_mouth_closes_along_the_modes() {
        let base = ring();
        // Mode 0 opens the mouth (lower lips and chin down), mode 1 raises the brows.
        let mut open = [0.0f32; 136];
        for i in [7, 8, 9, 55, 56, 57, 58, 59, 65, 66, 67] {
            open[2 * i + 1] = 1.0;
        }
        let mut brows = [0.0f32; 136];
        for i in 17..27 {
            brows[2 * i + 1] = -1.0;
        }
        let unit = |v: [f32; 136]| {
            let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
            v.map(|x| x / n)
        };
        let modes: Vec<f32> = unit(open)
            .iter()
            .chain(unit(brows).iter())
            .copied()
            .collect();
        let mut shape: Vec<f32> = base
            .iter()
            .zip(unit(open).iter().zip(unit(brows).iter()))
            .map(|(b, (o, r))| b + 60.0 * o + 5.0 * r)
            .collect();
        assert!(mouth_opening(&shape) > 0.1);
        close_mouth(&mut shape, &modes, 0.02);
        assert!(
            (mouth_opening(&shape) - 0.02).abs() < 0.01,
            "{}",
            mouth_opening(&shape)
        );
        // The brows stay raised; the chin came up with the lips.
        assert!(
            (shape[2 * 20 + 1] - (base[2 * 20 + 1] + 5.0 * unit(brows)[2 * 20 + 1])).abs() < 1e-3
        );
        assert!(shape[2 * 8 + 1] < base[2 * 8 + 1] + 60.0 * unit(open)[2 * 8 + 1] - 1.0);
        // Modes that cannot move the lips: unchanged.
        let before = shape.clone();
        let mut wide = shape.clone();
        for l in [65, 66, 67] {
            wide[2 * l + 1] += 10.0;
        }
        let w0 = wide.clone();
        close_mouth(&mut wide, &unit(brows), 0.0);
        assert_eq!(wide, w0);
        // Other lengths: unchanged.
        let mut short = before[..100].to_vec();
        close_mouth(&mut short, &modes, 0.0);
        assert_eq!(short, before[..100].to_vec());
    }

    #[test]
    fn a_first_neutral_closes_its_mouth_below_a_half_open_base() {
        // A unit mode that opens the inner lips (the lower inner lip and chin down).
        let mut open = [0.0f32; 136];
        for i in [7, 8, 9, 55, 56, 57, 58, 59, 65, 66, 67] {
            open[2 * i + 1] = 1.0;
        }
        let n = open.iter().map(|x| x * x).sum::<f32>().sqrt();
        let mode: Vec<f32> = open.iter().map(|x| x / n).collect();
        let opened =
            |by: f32| -> Vec<f32> { face().iter().zip(&mode).map(|(b, m)| b + by * m).collect() };
        let margin = FollowOptions::default().mouth_margin;
        // A speech model's base, half open: the neutral it starts from is closed to the margin,
        // not to the base's opening.
        let base = opened(25.0);
        assert!(
            mouth_opening(&base) > 3.0 * margin,
            "{}",
            mouth_opening(&base)
        );
        let mut neutral = base.clone();
        close_first_neutral(&mut neutral, &base, &mode, margin);
        assert!(
            mouth_opening(&neutral) <= margin + 0.01,
            "{}",
            mouth_opening(&neutral)
        );
        // A base more closed than the margin: a laughing first face closes to the base's.
        let closed = face();
        let mut laugh = opened(60.0);
        close_first_neutral(&mut laugh, &closed, &mode, margin);
        assert!(mouth_opening(&laugh) <= mouth_opening(&closed) + 0.01);
        // A neutral no more open than the margin above that is left as it is.
        let mut rest = opened(2.0);
        let before = rest.clone();
        assert!(mouth_opening(&rest) <= margin);
        close_first_neutral(&mut rest, &base, &mode, margin);
        assert_eq!(rest, before);
    }

    #[test]
    fn neutral_is_a_mean_then_a_running_median() {
        let base = face();
        let mut n = base.clone();
        let mut count = 0;
        // Warm-up: the mean of two shapes.
        neutral_update(&mut n, &base, &base, &mut count, 2, 0.01, 0.02);
        neutral_update(&mut n, &base, &base, &mut count, 2, 0.01, 0.02);
        assert_eq!(count, 2);
        assert!(n.iter().zip(&base).all(|(a, b)| (a - b).abs() < 1e-3));
        // A shape at rest moves each coordinate by at most the step (before re-alignment).
        let mut near = base.clone();
        near[5] += 1.0;
        assert!(crate::fit::neutral_like(&near, &n));
        let before = n.clone();
        neutral_update(&mut n, &near, &base, &mut count, 2, 0.01, 0.02);
        let moved = n
            .iter()
            .zip(&before)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(moved > 0.0 && moved < 0.05, "{moved}");
        // An expression (a point far off) does not enter once warmed up.
        let mut far = base.clone();
        far[5] += 10.0;
        assert!(!crate::fit::neutral_like(&far, &n));
        let before = n.clone();
        neutral_update(&mut n, &far, &base, &mut count, 2, 0.01, 0.02);
        assert_eq!(n, before);
        // An open mouth does not enter.
        let mut open = base.clone();
        for l in [67, 66, 65] {
            open[2 * l + 1] += 20.0;
        }
        let before = n.clone();
        neutral_update(&mut n, &open, &base, &mut count, 2, 0.01, 0.02);
        assert_eq!(n, before);
        // A neutral with an open mouth closes fast on a closed one.
        let mut m = open.clone();
        let mut c = 5;
        for _ in 0..10 {
            neutral_update(&mut m, &base, &base, &mut c, 2, 0.01, 0.02);
        }
        assert!(mouth_opening(&m) < 0.5 * mouth_opening(&open));
    }
}

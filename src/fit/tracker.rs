//! Tracking a face through a sequence: each frame starts from the previous result; a lost
//! face is detected, and the tracker re-initialises from the last good result or, when it has
//! a [`FaceSource`] (a face finder), from the face found nearest the last position.

use crate::error::{check_len, Error, Result};
use crate::image::ImageRef;
use crate::model::limits::{check_face_box, check_landmarks_len};
use crate::model::Model;
use crate::similarity::Similarity;
use crate::summary::summary;

use super::anchor::Sequence;
use super::confidence::{sigma_rms, Confidence, ConfidenceBounds, Reasons, TrackStatus};
use super::face_tracker::{FaceTracker, TrackerKind};
use super::resample::{from_scaled, pose_from_scaled, to_scaled, Resampler};
use super::{FitOptions, FitResult, Fitter, TrackPolicy};

/// The time step of 30 frames a second (seconds): what a front end gives [`Tracker::track`](crate::fit::FaceTracker::track)
/// when it knows no better.
pub const DEFAULT_TIME_STEP: f32 = 1.0 / 30.0;

/// A fit whose image contrast under the mesh is below this fraction of the template's (or
/// above its inverse) is a lost face: see [`Fitter::contrast`].
pub const MIN_CONTRAST: f32 = 0.2;

/// Where the tracker finds a face to start from or to come back to: the landmarks of the faces
/// visible in an image (image coordinates, `2n` values each, in the model's landmark layout),
/// most confident first; none when no face is visible. A closure
/// `FnMut(&ImageRef) -> Result<Vec<Vec<f32>>>` is one.
pub trait FaceSource {
    /// The faces visible in `image`.
    fn faces(&mut self, image: &ImageRef<'_>) -> Result<Vec<Vec<f32>>>;
}

impl<F> FaceSource for F
where
    F: FnMut(&ImageRef<'_>) -> Result<Vec<Vec<f32>>>,
{
    fn faces(&mut self, image: &ImageRef<'_>) -> Result<Vec<Vec<f32>>> {
        self(image)
    }
}

/// The face finder is the face source of a 68-landmark model: its faces' landmarks, most
/// confident first.
impl FaceSource for crate::find::FaceFinder {
    fn faces(&mut self, image: &ImageRef<'_>) -> Result<Vec<Vec<f32>>> {
        Ok(self.find(image).into_iter().map(|f| f.landmarks).collect())
    }
}

/// Follows one face through video frames with a [`Fitter`].
///
/// Start a sequence with [`Tracker::start_from_landmarks`](crate::fit::FaceTracker::start_from_landmarks) or [`Tracker::start_from_box`](crate::fit::FaceTracker::start_from_box), then
/// call [`Tracker::track`](crate::fit::FaceTracker::track) once per frame. A fit is judged lost when its error exceeds
/// [`FitOptions::max_error`], the shape parameters' RMS in standard deviations
/// (`sqrt(mean (p_i / sigma_i)^2)`) exceeds [`FitOptions::max_sigmas`], the scale jumps by more than [`FitOptions::max_scale_jump`] or the rotation by
/// more than 0.5 rad from the last good fit, the image contrast under the mesh is implausible
/// ([`MIN_CONTRAST`]), or the fit failed numerically. The tracker then
/// retries once from the last good result with more appearance-aware iterations; if that
/// fails too and the tracker has a [`FaceSource`] ([`Tracker::set_face_source`]), it asks the
/// source for the faces in the frame and fits from the one nearest the last good position
/// (a cold fit, judged by the same checks except the jump from the last fit). If that fails
/// too, the frame is lost: its result has `lost = true` and carries the last good fit (not a
/// face on this frame); without a source the next frame starts from the last good fit again,
/// with one it asks the source again on every frame until a face is found and fits
/// (`reacquired = true` on that frame). [`Tracker::start_auto`](crate::fit::FaceTracker::start_auto) starts a sequence that way,
/// from no landmarks at all. With faces offered from elsewhere instead
/// ([`Tracker::expect_offers`](crate::fit::FaceTracker::expect_offers)), a lost face is searched for with the faces offered; until
/// they come, each frame gets only the ordinary fit from the last good fit (no retry).
///
/// **Second opinions.** A fit judged good can still be in a wrong minimum the frames before led
/// it into (a hand under the chin read as an open mouth: a plausible shape, a residual under
/// the checks) and stay there. With a source or faces offered, every
/// [`TrackPolicy::recheck_frames`] good frames the tracker fits the frame again from the face
/// found nearest the tracked one (a cold fit) and keeps whichever fits lower
/// ([`Tracker::rechecks`](crate::fit::FaceTracker::rechecks) counts them).
///
/// **Confidence** (issue 33). A plausible fit is also checked for what the loss checks miss
/// (it collapsed, folded, slid off the finder's face, took an unlikely shape, its residual or
/// pose jumped: [`ConfidenceBounds`]); a doubted fit is reported with
/// [`TrackStatus::Unsure`] and its [`Reasons`], is not the last good fit, is fitted again from
/// the last good fit when its mesh is broken, and asks for a second opinion. The result's
/// `status` is "tracking", "unsure" or "lost".
///
/// **One pixel convention.** Frames come in at their own size, and everything going in and
/// out (start landmarks and boxes, offered faces, what a [`FaceSource`] finds, the results'
/// landmarks and poses) is in that frame's pixels. The tracker decides at what scale it fits
/// ([`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale), under the [`TrackPolicy`]: a large face is fitted in a smaller copy
/// of the frame, at about the size the model was built at): the scale is chosen on the first
/// frame of a sequence from the start landmarks, on an acquisition from the face acquired, and
/// after every good fit from the face's size (a face moving to or from the camera), and the
/// tracker resamples the frame itself (a triangle filter, [`Tracker::scale`](crate::fit::FaceTracker::scale)) with pixel
/// centres on integers, so a frame point `v` is `(v + 0.5) k - 0.5` in the fitted copy.
///
/// **The placement.** Each good fit's pose also moves the sequence's pose anchor
/// ([`Sequence`], [`Tracker::sequence`](crate::fit::FaceTracker::sequence)), and [`Sequence::placed`] is the pose re-centred on
/// the model's mean pose: what the page draws the driven face with.
pub struct Tracker {
    fitter: Fitter,
    /// Where the next fit starts (landmarks, frame pixels).
    start: Vec<f32>,
    /// Scratch: a fit's start in the fitted copy's pixels.
    fit_start: Vec<f32>,
    /// The fit scale in use (fitted pixels per frame pixel); 0 until the sequence's first
    /// frame decides it.
    k: f32,
    resampler: Resampler,
    /// The fitter's last result in frame pixels.
    fitted: FitResult,
    /// True once a sequence has been started.
    started: bool,
    /// True when the next fit starts from a rough guess (a box) and should work harder.
    cold: bool,
    last_good: Option<FitResult>,
    last: Option<FitResult>,
    resets: u32,
    /// The counters and the pose anchor.
    seq: Sequence,
    /// Where faces are found to start from or to come back to.
    source: Option<Box<dyn FaceSource>>,
    /// True while the next frame must be acquired from the source (auto start, or lost).
    searching: bool,
    /// Whether the previous frame was lost.
    was_lost: bool,
    /// Running mean of the good fits' errors (0 before the first).
    typical_error: f32,
    /// Size of the frame being tracked.
    frame_size: (f32, f32),
    /// Policy shared by the front ends (resampling scale, appearance bounds).
    policy: TrackPolicy,
    /// The model's appearance standard deviations (for [`TrackPolicy::appearance_limit`]).
    appearance_sigmas: Vec<f32>,
    /// Height (pixels) of the model's mean face at its mean pose: the face size the model was
    /// built at (for [`Tracker::fit_scale`](crate::fit::FaceTracker::fit_scale)).
    model_face_height: f32,
    /// Faces offered by [`Tracker::offer_faces`](crate::fit::FaceTracker::offer_faces), used by the next acquisition.
    offered: Option<Vec<Vec<f32>>>,
    /// True when faces are offered from elsewhere ([`Tracker::expect_offers`](crate::fit::FaceTracker::expect_offers)): a lost face
    /// is searched for (offered faces are used) even without a source.
    offers: bool,
    /// Good frames tracked since the last second opinion ([`TrackPolicy::recheck_frames`]).
    since_check: u32,
    /// Second opinions taken, and those kept.
    rechecks: (u32, u32),
    /// The tracked fit, kept while a second opinion is fitted.
    tracked: FitResult,
    /// The confidence checks ("unsure" fits).
    confidence: Confidence,
    /// The face finder's face nearest the fit on this frame (a second opinion's), when
    /// `has_finder_face`.
    finder_face: Vec<f32>,
    has_finder_face: bool,
    /// The last frame's fit was unsure: a second opinion is due on the next.
    doubtful: bool,
    /// Why the last fit judged was implausible (a lost frame's reasons).
    why: Reasons,
    /// The person's look on their trusted frames, against their own neutral look kept from
    /// frames at rest ([`FaceTracker::observed`]); 68-landmark models only.
    observed: Option<Observer>,
}

/// What the AAM tracker observes of a 68-landmark face: the frame's pixels at the fit against a
/// neutral look kept from the frames at rest, as the [`super::Follower`] keeps one; the
/// neutral shape is the fitted points' (model coordinates, each frame posed onto the neutral by
/// the points an expression hardly moves, as the follower poses one), moved as the follower's.
#[derive(Clone, Debug)]
struct Observer {
    look: super::ObservedAppearance,
    shape_model: crate::model::shape::ShapeModel,
    /// Scratch: the fit's shape in model coordinates.
    shape: Vec<f32>,
    /// The person's neutral shape, and the frames that entered it.
    neutral: Vec<f32>,
    count: u32,
    /// The follower's neutral rules (warm-up, step, mouth margin).
    rules: super::FollowOptions,
    /// The frame's whole expression (its shape less the neutral, the head's turn to the side
    /// left out, its nod left in) and that turn, model coordinates
    /// ([`super::split_head_turn_keeping_nod`], as the follower splits its own).
    deviation: Vec<f32>,
    turn: Vec<f32>,
}

impl Observer {
    /// The person's own model: its mean shape is their neutral shape to start from and its
    /// mean appearance their neutral look until they rest (a session that starts in a laugh
    /// took the laugh for the neutral: on franck-dev2, which opens laughing, the targets'
    /// FER "happy" fell to 0.29 of the source's, against 0.56 for the model's synthesis).
    fn new(model: &Model) -> Option<Observer> {
        if model.landmarks() != 68 {
            return None;
        }
        let look =
            super::ObservedAppearance::with_prior(model.frame(), model.appearance().base()).ok()?;
        let mut o = Observer {
            look,
            shape_model: model.shape().clone(),
            shape: vec![0.0; 136],
            neutral: vec![0.0; 136],
            count: 0,
            rules: super::FollowOptions::default(),
            deviation: vec![0.0; 136],
            turn: vec![0.0; 136],
        };
        o.reset();
        Some(o)
    }

    /// A new sequence: the neutral shape back to the model's mean, its mouth closed
    /// ([`super::close_first_neutral`]; past the warm-up, so only frames like it move it), and
    /// the look to the model's mean appearance.
    fn reset(&mut self) {
        self.look.reset();
        self.neutral.copy_from_slice(&self.shape_model.base);
        super::close_first_neutral(
            &mut self.neutral,
            &self.shape_model.base,
            &self.shape_model.modes,
            self.rules.mouth_margin,
        );
        self.count = self.rules.warmup;
    }

    /// A trusted frame: its look, and its shape's part in the neutral (the follower's rules,
    /// [`super::neutral_update`] and [`super::rest_distance`]).
    fn observe(&mut self, frame: &ImageRef<'_>, fit: &FitResult) {
        // The fitted points posed onto the neutral by the points an expression hardly moves
        // (the nose and the eye corners), as the follower poses a frame, not by the fit's own
        // similarity: that one is fitted over all 68 points with the modes, and takes part of a
        // laugh (the dropped jaw, the widened mouth) for the head moving and growing. On
        // franck-dev's laughs the clones' lift followed the real one at r 0.80 with a spread of
        // 0.59 of it; posed so, at r 0.98 with 0.84 (docs/cloning.md, "The own model's
        // expression against the person's neutral").
        if fit.landmarks.len() != self.shape.len() {
            return;
        }
        crate::Similarity::align_points(
            &fit.landmarks,
            &self.neutral,
            &crate::landmarks::STABLE_POINTS,
        )
        .apply(&fit.landmarks, &mut self.shape);
        if !self.shape.iter().all(|v| v.is_finite()) {
            return;
        }
        let o = &self.rules;
        let rest = super::rest_distance(&self.shape, &self.neutral, o.mouth_margin);
        let moved = super::neutral_update(
            &mut self.neutral,
            &self.shape,
            &self.shape_model.base,
            &mut self.count,
            o.warmup,
            o.neutral_step,
            o.mouth_margin,
        );
        if self.look.observe(frame, &fit.landmarks, rest).is_err() {
            self.look.reset();
        }
        // The expression against the person's neutral shape, not against the model's mean:
        // the mean of a person's enrolment frames is part speech and part smile, and a laugh
        // measured from it arrived weaker (docs/cloning.md, "The own model's expression
        // against the person's neutral").
        moved.apply_in_place(&mut self.shape);
        super::split_head_turn_keeping_nod(
            &mut self.shape,
            &self.neutral,
            crate::find::IBUG_DEPTH,
            &mut self.turn,
            &mut self.deviation,
        );
    }
}

impl Tracker {
    /// A tracker for `model` (does the fitter's precomputation).
    pub fn new(model: &Model, options: FitOptions) -> Result<Tracker> {
        let fitter = Fitter::new(model, options)?;
        let n2 = fitter.landmarks() * 2;
        let mut mean = vec![0.0; n2];
        model.image_shape(&model.base_params(), &mut mean)?;
        let model_face_height = extent(&mean).1.max(1.0);
        let base = model.base_params();
        Ok(Tracker {
            start: vec![0.0; n2],
            fit_start: vec![0.0; n2],
            k: 0.0,
            resampler: Resampler::default(),
            fitted: FitResult {
                landmarks: mean,
                params: base.clone(),
                error: 0.0,
                iterations: 0,
                converged: false,
                lost: true,
                reacquired: false,
                status: crate::fit::TrackStatus::Tracking,
                reasons: crate::fit::Reasons::NONE,
            },
            seq: Sequence::new(base.pose),
            fitter,
            started: false,
            cold: false,
            last_good: None,
            last: None,
            resets: 0,
            source: None,
            searching: false,
            was_lost: false,
            typical_error: 0.0,
            frame_size: (0.0, 0.0),
            policy: TrackPolicy::default(),
            appearance_sigmas: model.appearance().sigmas(),
            model_face_height,
            offered: None,
            offers: false,
            since_check: 0,
            rechecks: (0, 0),
            tracked: empty_result(),
            confidence: Confidence::new(model),
            observed: Observer::new(model),
            finder_face: vec![0.0; n2],
            has_finder_face: false,
            doubtful: false,
            why: Reasons::NONE,
        })
    }

    /// Whether the next tracked frame takes a second opinion ([`TrackPolicy::recheck_frames`]).
    fn recheck_due(&self) -> bool {
        let every = self.policy.recheck_frames;
        self.last_good.is_some()
            && !self.was_lost
            && (self.doubtful || (every > 0 && self.since_check >= every))
    }

    /// The fitter (for its sizes and options).
    pub fn fitter(&self) -> &Fitter {
        &self.fitter
    }

    fn begin(&mut self, cold: bool) {
        self.started = true;
        self.k = 0.0;
        self.seq.restart();
        self.offered = None;
        self.cold = cold;
        self.searching = false;
        self.was_lost = false;
        self.typical_error = 0.0;
        self.last_good = None;
        self.last = None;
        self.since_check = 0;
        self.confidence.restart();
        self.doubtful = false;
        self.has_finder_face = false;
        self.why = Reasons::NONE;
        if let Some(o) = &mut self.observed {
            o.reset();
        }
    }

    /// Gives the tracker a source of faces (a face finder): it is asked when a face is lost
    /// and by [`Tracker::start_auto`](crate::fit::FaceTracker::start_auto). Replaces any previous source.
    pub fn set_face_source(&mut self, source: Box<dyn FaceSource>) {
        self.source = Some(source);
    }

    /// The bounds of the confidence checks that call a plausible fit "unsure"
    /// ([`ConfidenceBounds::off`]: none, the tracker as it was before them).
    pub fn confidence_bounds(&self) -> &ConfidenceBounds {
        &self.confidence.bounds
    }

    /// Replaces the bounds of the confidence checks; fails with [`Error::Params`] (keeping
    /// the old ones) for a NaN or negative bound.
    pub fn set_confidence_bounds(&mut self, bounds: ConfidenceBounds) -> Result<()> {
        bounds.check()?;
        self.confidence.bounds = bounds;
        Ok(())
    }

    /// Whether the tracker has a face source.
    pub fn has_face_source(&self) -> bool {
        self.source.is_some()
    }

    /// Asks the source for the faces in `frame` (or takes the faces offered) and fits from the
    /// one nearest the last good position (or the most confident one), at the fit scale for
    /// its size. Returns whether the fit is plausible (then it is in `fitted`).
    fn acquire(&mut self, frame: &ImageRef<'_>) -> Result<bool> {
        let faces = match (self.offered.take(), self.source.as_mut()) {
            (Some(faces), _) => faces,
            (None, Some(source)) => source.faces(frame)?,
            (None, None) => return Ok(false),
        };
        for f in &faces {
            check_len("found face landmarks", f, self.start.len())?;
        }
        let near = self.last_good.as_ref().map(|g| centroid(&g.landmarks));
        let Some(face) = nearest_face(&faces, near, centroid, |_| true) else {
            self.why = Reasons::NO_FACE;
            return Ok(false);
        };
        // The scale for the face acquired (kept when near the one in use).
        self.k = self.fit_scale(extent(face).1, frame.width(), frame.height(), self.k);
        let (cold_iters, starts) = (self.cold_iters(), self.fitter.options().coarse_starts);
        match self.fit(frame, From::Face(face), Some(cold_iters), starts) {
            Ok(()) => Ok(self.check(false)),
            // A degenerate found face is no face.
            Err(Error::Params(_)) => {
                self.why = Reasons::NO_FACE;
                Ok(false)
            }
            Err(e) => Err(e),
        }
    }

    /// When one is due ([`TrackPolicy::recheck_frames`], or `doubts` about the tracked fit) or
    /// faces were offered, fits `frame` again from the found face nearest the tracked one (a
    /// cold fit, as an acquisition) and keeps whichever of the two fits has the lower residual
    /// (the second one only when plausible; while the tracked fit is doubted, the second one
    /// also when it raises no doubt); `fitted` holds the tracked fit on entry and the one kept
    /// on return, `finder_face` the found face used.
    fn second_opinion(&mut self, frame: &ImageRef<'_>, doubts: Reasons) -> Result<()> {
        let due = self.recheck_due() || !doubts.is_empty();
        let faces = match (self.offered.take(), self.source.as_mut()) {
            (Some(faces), _) => faces,
            (None, Some(source)) if due => source.faces(frame)?,
            _ => return Ok(()),
        };
        self.since_check = 0;
        for f in &faces {
            check_len("found face landmarks", f, self.start.len())?;
        }
        // The tracked face's centre and size: a found face elsewhere is another face.
        let (cx, cy) = centroid(&self.fitted.landmarks);
        let (w, h) = extent(&self.fitted.landmarks);
        let reach = 0.5 * w.max(h);
        let near = |f: &[f32]| {
            let (x, y) = centroid(f);
            (x - cx).hypot(y - cy) <= reach
        };
        let Some(face) = nearest_face(&faces, Some((cx, cy)), centroid, near) else {
            return Ok(());
        };
        self.finder_face.copy_from_slice(face);
        self.has_finder_face = true;
        self.rechecks.0 = self.rechecks.0.saturating_add(1);
        std::mem::swap(&mut self.tracked, &mut self.fitted);
        let (cold_iters, starts) = (self.cold_iters(), self.fitter.options().coarse_starts);
        let better = match self.fit(frame, From::Face(face), Some(cold_iters), starts) {
            Ok(()) => {
                self.plausible(&self.fitted, true)
                    && (self.fitted.error < self.tracked.error
                        || (!doubts.is_empty() && self.doubts(&self.fitted).is_empty()))
            }
            Err(Error::Params(_)) => false,
            Err(e) => {
                std::mem::swap(&mut self.tracked, &mut self.fitted);
                return Err(e);
            }
        };
        if better {
            self.rechecks.1 = self.rechecks.1.saturating_add(1);
        } else {
            std::mem::swap(&mut self.tracked, &mut self.fitted);
        }
        Ok(())
    }

    /// Iterations (project-out, appearance-aware) of a cold fit: a start from a box or a found
    /// face, or a retry; 3x the options' (at least 10 and 3).
    fn cold_iters(&self) -> (u32, u32) {
        let opts = self.fitter.options();
        (opts.max_iters.max(10) * 3, opts.refine_iters.max(3) * 3)
    }

    /// Fits `frame` at the fit scale (deciding it from the start when there is none yet) from
    /// `from` (frame pixels); the result, in frame pixels, goes to `fitted`.
    fn fit(
        &mut self,
        frame: &ImageRef<'_>,
        from: From<'_>,
        iters: Option<(u32, u32)>,
        starts: u32,
    ) -> Result<()> {
        let src: &[f32] = match from {
            From::Start => &self.start,
            From::LastGood => self
                .last_good
                .as_ref()
                .map_or(&self.start[..], |g| &g.landmarks[..]),
            From::Face(f) => f,
        };
        if !(self.k > 0.0) {
            let h = extent(src).1;
            self.k = self.policy.fit_scale(
                self.model_face_height,
                h,
                frame.width(),
                frame.height(),
                0.0,
            );
        }
        let k = self.k;
        to_scaled(src, k, &mut self.fit_start);
        if k == 1.0 {
            self.fitter
                .fit_with(frame, &self.fit_start, iters, starts)?;
        } else {
            let view = self.resampler.resample(frame, k, self.seq.frames())?;
            self.fitter
                .fit_with(&view, &self.fit_start, iters, starts)?;
        }
        let r = self.fitter.result();
        copy_result(&mut self.fitted, r);
        if k != 1.0 {
            from_scaled(&mut self.fitted.landmarks, k);
            self.fitted.params.pose = pose_from_scaled(&r.params.pose, k);
        }
        Ok(())
    }

    /// The confidence checks on the plausible tracked fit in `fitted`, and the recovery of a
    /// doubted one: a fit that collapsed, folded or took an unlikely shape is fitted again from
    /// the last good fit (kept when that raises no doubt); a doubted fit takes a second opinion
    /// from the faces found or offered (kept when it raises no doubt, or fits lower). Returns
    /// the doubts left about the fit kept (the finder's face included when one was found).
    fn settle(&mut self, frame: &ImageRef<'_>) -> Result<Reasons> {
        let doubts = self.doubts(&self.fitted);
        if doubts.intersects(Reasons::STRUCTURAL) && self.last_good.is_some() {
            std::mem::swap(&mut self.tracked, &mut self.fitted);
            let (cold_iters, coarse) = (self.cold_iters(), self.fitter.options().coarse_starts);
            self.fit(frame, From::LastGood, Some(cold_iters), coarse)?;
            let clear = self.plausible(&self.fitted, true) && self.doubts(&self.fitted).is_empty();
            if !clear {
                std::mem::swap(&mut self.tracked, &mut self.fitted);
            }
        }
        let doubts = self.doubts(&self.fitted);
        self.second_opinion(frame, doubts)?;
        Ok(self.doubts(&self.fitted))
    }

    /// A plausible frame, `dt` seconds after the previous one, with the confidence checks'
    /// `doubts` about it: "tracking" without doubts (the fit becomes the last good one and
    /// moves the pose anchor and the fit scale), "unsure" with them (reported, but the last
    /// good fit stays, the anchor holds, a second opinion is due on the next frame, and a fit
    /// that collapsed or folded is not started from).
    fn good_frame(&mut self, frame: &ImageRef<'_>, dt: f32, reacquired: bool, doubts: Reasons) {
        let sure = doubts.is_empty();
        self.since_check = self.since_check.saturating_add(1);
        self.cold = false;
        self.searching = false;
        self.doubtful = !sure;
        let mut r = std::mem::replace(&mut self.fitted, empty_result());
        self.bound_appearance(&mut r);
        // A face found again after lost frames (or the first face of an auto start).
        r.reacquired = reacquired && (self.was_lost || self.last_good.is_none());
        r.lost = false;
        r.status = if sure {
            TrackStatus::Tracking
        } else {
            TrackStatus::Unsure
        };
        r.reasons = doubts;
        self.confidence.note(&r.landmarks, &r.params.pose, sure);
        let tau = self.policy.recentre_tau;
        if sure {
            // A slow running mean, restarted by a (re-)acquisition.
            self.typical_error = if self.typical_error > 0.0 && !r.reacquired {
                0.95 * self.typical_error + 0.05 * r.error
            } else {
                r.error
            };
            self.seq.frame(Some(&r.params.pose), dt, tau, r.reacquired);
            if let Some(o) = &mut self.observed {
                o.observe(frame, &r);
            }
            store(&mut self.last_good, &r);
            // The face grew or shrank a lot (moving to or from the camera): the next frame is
            // fitted at a new scale.
            self.k = self.fit_scale(
                extent(&r.landmarks).1,
                frame.width(),
                frame.height(),
                self.k,
            );
        } else {
            // The placement holds at the last good pose.
            let held = self
                .last_good
                .as_ref()
                .map_or(r.params.pose, |g| g.params.pose);
            self.seq.frame(Some(&held), dt, tau, r.reacquired);
        }
        match self.last_good.as_ref() {
            Some(g) if doubts.intersects(Reasons::STRUCTURAL) => {
                self.start.copy_from_slice(&g.landmarks)
            }
            _ => self.start.copy_from_slice(&r.landmarks),
        }
        store(&mut self.last, &r);
        self.fitted = r;
    }

    /// A lost frame, `dt` seconds after the previous one: counted, searched for from the next
    /// frame when faces can come, and reported as the last good fit (or the failed attempt).
    fn lost_frame(&mut self, dt: f32, tau: f32) {
        self.seq.frame(None, dt, tau, false);
        self.searching = self.source.is_some() || self.offers;
        self.doubtful = false;
        let why = if self.why.is_empty() {
            Reasons::NO_FACE
        } else {
            self.why
        };
        match &self.last_good {
            Some(g) => {
                self.start.copy_from_slice(&g.landmarks);
                store(&mut self.last, g);
                let last = self.last.as_mut().expect("just stored");
                last.lost = true;
                last.converged = false;
                last.reacquired = false;
                last.status = TrackStatus::Lost;
                last.reasons = why;
            }
            None => {
                // Nothing good yet (a bad box, or no face found): report the attempt.
                let mut r = std::mem::replace(&mut self.fitted, empty_result());
                r.lost = true;
                r.reacquired = false;
                r.status = TrackStatus::Lost;
                r.reasons = why;
                self.bound_appearance(&mut r);
                store(&mut self.last, &r);
                self.fitted = r;
            }
        }
    }

    /// Clamps a result's appearance parameters to the policy's `+-appearance_limit` sigmas.
    fn bound_appearance(&self, r: &mut FitResult) {
        if self.policy.appearance_limit > 0.0 {
            crate::clone::constrain(
                &mut r.params.appearance,
                &self.appearance_sigmas,
                self.policy.appearance_limit,
            );
        }
    }

    /// Whether a fit is plausible (see the type's documentation); `jump` also checks the
    /// change of scale and rotation from the last good fit.
    fn plausible(&self, r: &FitResult, jump: bool) -> bool {
        self.implausible(r, jump).is_empty()
    }

    /// Whether `fitted` is plausible ([`Tracker::plausible`]); if not, `why` says why.
    fn check(&mut self, jump: bool) -> bool {
        self.why = self.implausible(&self.fitted, jump);
        self.why.is_empty()
    }

    /// Why a fit is implausible: a lost face (none: plausible).
    fn implausible(&self, r: &FitResult, jump: bool) -> Reasons {
        let o = self.fitter.options();
        if !r.error.is_finite() || r.error > o.max_error {
            return Reasons::RESIDUAL;
        }
        if !r.landmarks.iter().all(|v| v.is_finite()) || !r.params.pose.is_valid() {
            return Reasons::RESIDUAL;
        }
        let (w, h) = self.frame_size;
        let n = (r.landmarks.len() / 2).max(1) as f32;
        let inside = r
            .landmarks
            .chunks_exact(2)
            .filter(|p| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w - 1.0 && p[1] <= h - 1.0)
            .count() as f32;
        if inside < o.min_inside * n {
            return Reasons::OUTSIDE;
        }
        if jump
            && o.max_error_ratio > 0.0
            && self.typical_error > 0.0
            && r.error > o.max_error_ratio * self.typical_error
        {
            return Reasons::RESIDUAL;
        }
        let c = self.fitter.contrast();
        if !(MIN_CONTRAST..=1.0 / MIN_CONTRAST).contains(&c) {
            return Reasons::CONTRAST;
        }
        if !(sigma_rms(&r.params.shape, self.fitter.shape_sigmas()) <= o.max_sigmas) {
            return Reasons::SHAPE;
        }
        if let Some(g) = self.last_good.as_ref().filter(|_| jump) {
            let (s0, s1) = (g.params.pose.scale(), r.params.pose.scale());
            if !((s1 - s0).abs() <= o.max_scale_jump * s0) {
                return Reasons::JUMP;
            }
            let dr = (r.params.pose.rotation() - g.params.pose.rotation()).abs();
            let dr = dr.min(2.0 * std::f32::consts::PI - dr);
            if dr > 0.5 {
                return Reasons::JUMP;
            }
        }
        Reasons::NONE
    }

    /// The confidence checks' doubts about a plausible fit `r` (none: tracking), with this
    /// frame's finder face when one was found.
    fn doubts(&self, r: &FitResult) -> Reasons {
        let ratio = if self.typical_error > 0.0 {
            r.error / self.typical_error
        } else {
            0.0
        };
        let finder = self.has_finder_face.then_some(&self.finder_face[..]);
        self.confidence
            .doubts(&r.landmarks, &r.params.pose, &r.params.shape, ratio, finder)
    }

    /// The last fit judged good.
    pub fn last_good(&self) -> Option<&FitResult> {
        self.last_good.as_ref()
    }
}

impl FaceTracker for Tracker {
    fn kind(&self) -> TrackerKind {
        TrackerKind::Aam
    }

    /// Fits the next frame, `dt` seconds after the previous one (the pose anchor's time step;
    /// [`DEFAULT_TIME_STEP`] for 30 frames a second), starting from the previous result (or
    /// the sequence's start): [`super::FaceTracker::track`]. The frame comes at its own size:
    /// the tracker fits a resampled copy when the face is far from the model's size, and the
    /// result's landmarks and pose are in the frame's pixels (see the type's documentation).
    ///
    /// Fails with [`Error::Params`] if no sequence was started or `dt` is not a finite
    /// non-negative number. The result's `lost` flag says whether the face was lost on this
    /// frame (then the result is the last good fit).
    fn track(&mut self, frame: &ImageRef<'_>, dt: f32) -> Result<&FitResult> {
        if !self.started {
            return Err(Error::Params(
                "the tracker has no start: call start_from_landmarks or start_from_box".into(),
            ));
        }
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(Error::Params(format!(
                "the time step is {dt} s: a finite non-negative number is needed"
            )));
        }
        self.frame_size = (frame.width() as f32, frame.height() as f32);
        self.has_finder_face = false;
        self.why = Reasons::NONE;
        let mut reacquired = false;
        let mut doubts = Reasons::NONE;
        // Without a source, a search with nothing offered yet refits from the last good fit
        // (when there is one), as a tracker without a source does.
        let can_acquire = self.source.is_some() || self.offered.is_some();
        let ok = if self.searching && (can_acquire || self.last_good.is_none()) {
            reacquired = self.acquire(frame)?;
            reacquired
        } else {
            let cold_iters = self.cold_iters();
            let opts = self.fitter.options();
            let (coarse, tracking) = (opts.coarse_starts, opts.tracking_starts);
            let first = if self.cold { Some(cold_iters) } else { None };
            let starts = if first.is_some() { coarse } else { tracking };
            self.fit(frame, From::Start, first, starts)?;
            let mut ok = self.check(true);
            // Searching here means the face was lost on an earlier frame and the faces to
            // acquire it from are awaited from elsewhere (`offer_faces`: a finder on another
            // thread; no source, nothing offered yet). Then the ordinary fit from the last good
            // fit above is all a frame costs: it catches the face coming back where it was, and
            // the harder retry is left to the offered faces (else every lost frame of the
            // search would cost a few tracked ones).
            let awaiting_offers = self.searching;
            if !ok && self.last_good.is_some() && !awaiting_offers {
                self.resets += 1;
                // Retry from the last good fit, working harder (more appearance-aware steps).
                self.fit(frame, From::LastGood, Some(cold_iters), coarse)?;
                ok = self.check(true);
            }
            if !ok && (self.source.is_some() || self.offered.is_some()) {
                reacquired = self.acquire(frame)?;
                ok = reacquired;
            } else if ok && !awaiting_offers {
                doubts = self.settle(frame)?;
            } else if ok {
                doubts = self.doubts(&self.fitted);
            }
            ok
        };
        if ok && reacquired {
            // A face (found again): judged afresh, not against the fits before.
            self.confidence.restart();
            doubts = self.doubts(&self.fitted);
        }
        let tau = self.policy.recentre_tau;
        if ok {
            self.good_frame(frame, dt, reacquired, doubts);
        } else {
            self.lost_frame(dt, tau);
        }
        self.was_lost = !ok;
        Ok(self.last.as_ref().expect("just set"))
    }

    /// The last trusted frame's pixels sampled at its fit, against the person's neutral look
    /// kept from their frames at rest (a 68-landmark model; as the follower's, so a change of
    /// light since the enrolment does not read as expression), and the fitted shape less the
    /// person's neutral shape as the whole displacement (the head's turn to the side left
    /// out and given beside it; the fit's `S p` is measured from the model's mean, which is
    /// not the person at rest). `None` before the sequence's first trusted frame.
    fn observed(&self) -> Option<super::Observed<'_>> {
        self.observed.as_ref().and_then(|o| {
            o.look.get().map(|look| super::Observed {
                displacement: Some(&o.deviation[..]),
                turn: Some(&o.turn[..]),
                ..look
            })
        })
    }

    /// The last frame's result.
    fn last(&self) -> Option<&FitResult> {
        self.last.as_ref()
    }

    /// The sequence's counters and pose anchor: [`Sequence::placed`] is the last good pose
    /// re-centred on the model's mean pose (what the driven face is drawn with).
    fn sequence(&self) -> &Sequence {
        &self.seq
    }

    /// Re-initialisations: frames whose fit was judged implausible, so that the tracker
    /// re-initialised from the last good result and fitted again.
    fn resets(&self) -> u32 {
        self.resets
    }

    /// Second opinions taken while tracking ([`TrackPolicy::recheck_frames`]), and how many
    /// of them were kept (fitted lower than the tracked fit).
    fn rechecks(&self) -> (u32, u32) {
        self.rechecks
    }

    /// Faces found elsewhere (a face finder on another thread, on a recent frame): landmarks in
    /// frame pixels, `2n` values each, most confident first. The next acquisition (the
    /// start of [`Tracker::start_searching`](crate::fit::FaceTracker::start_searching), or a lost face) fits from the one nearest the
    /// last good position instead of asking the source; offered while a face is tracked, they
    /// give the next frame's second opinion ([`TrackPolicy::recheck_frames`]). They are used
    /// once. Fails with
    /// [`Error::Params`] (keeping none) when a face has the wrong length or non-finite points.
    fn offer_faces(&mut self, faces: Vec<Vec<f32>>) -> Result<()> {
        for f in &faces {
            check_landmarks_len("offered face landmarks", f, self.start.len())?;
        }
        self.offered = Some(faces);
        Ok(())
    }

    /// Whether the tracker is looking for a face (a sequence started with no landmarks, or a
    /// lost face) or a second opinion on the tracked face is due
    /// ([`TrackPolicy::recheck_frames`]), faces are expected from elsewhere
    /// ([`Tracker::expect_offers`](crate::fit::FaceTracker::expect_offers)) and none are left to try: the moment to run a finder on a
    /// frame and [`Tracker::offer_faces`](crate::fit::FaceTracker::offer_faces).
    fn wants_faces(&self) -> bool {
        self.started
            && self.offers
            && self.offered.is_none()
            && (self.searching || self.recheck_due())
    }

    /// Whether faces will be offered from elsewhere ([`Tracker::offer_faces`](crate::fit::FaceTracker::offer_faces)): then a lost
    /// face is searched for ([`Tracker::wants_faces`](crate::fit::FaceTracker::wants_faces) turns true) even without a source, in
    /// every sequence however it was started. Off by default; [`Tracker::start_searching`](crate::fit::FaceTracker::start_searching)
    /// turns it on.
    fn expect_offers(&mut self, yes: bool) {
        self.offers = yes;
        if !yes {
            self.offered = None;
        }
    }

    /// Starts a new sequence with no landmarks, with faces offered from elsewhere
    /// ([`Tracker::offer_faces`](crate::fit::FaceTracker::offer_faces), e.g. a finder running on another thread) and, if the tracker
    /// has one, from its source. Frames are reported lost until a face is acquired; from then
    /// on a lost face is first refitted from the last good fit, and acquired again from the
    /// next faces offered.
    fn start_searching(&mut self) {
        self.begin(false);
        self.offers = true;
        self.searching = true;
    }

    /// Starts a new sequence with no landmarks: each frame asks the face source until a face
    /// is found and fits; until then frames are reported lost. Without a source
    /// ([`Tracker::set_face_source`]) the shipped face finder becomes it for a 68-landmark
    /// model; fails with [`Error::Params`] for another model without one.
    fn start_auto(&mut self) -> Result<()> {
        if self.source.is_none() {
            let finder = shipped_finder(self.fitter.landmarks())?;
            self.source = Some(Box::new(finder));
        }
        self.begin(false);
        self.searching = true;
        Ok(())
    }

    /// Starts a new sequence from landmarks on the next frame (frame pixels, `2n`); the fit
    /// scale is chosen on that frame for their size.
    fn start_from_landmarks(&mut self, landmarks: &[f32]) -> Result<()> {
        check_landmarks_len("landmarks", landmarks, self.start.len())?;
        let pose = Similarity::align(&self.fitter.geom.s0, landmarks);
        if !(pose.is_valid() && pose.scale() > 1e-4) {
            return Err(Error::Params(
                "landmarks are degenerate (all points coincide)".into(),
            ));
        }
        self.start.copy_from_slice(landmarks);
        self.begin(false);
        Ok(())
    }

    /// Starts a new sequence from a face box (frame pixels: left, top, width, height):
    /// the base shape is scaled to the box's width and centred in it.
    fn start_from_box(&mut self, x: f32, y: f32, w: f32, h: f32) -> Result<()> {
        check_face_box(x, y, w, h)?;
        let s0 = &self.fitter.geom.s0;
        let b = crate::geometry::BBox::of_points(s0);
        let (minx, miny, maxx, maxy) = (b.x, b.y, b.right(), b.bottom());
        let scale = (w / (maxx - minx).max(1e-6)).min(h / (maxy - miny).max(1e-6));
        let (cx, cy) = (0.5 * (minx + maxx), 0.5 * (miny + maxy));
        let pose = Similarity {
            a: scale,
            b: 0.0,
            tx: x + 0.5 * w - scale * cx,
            ty: y + 0.5 * h - scale * cy,
        };
        pose.apply(s0, &mut self.start);
        self.begin(true);
        Ok(())
    }

    /// The tracking policy (resampling scale, appearance bounds).
    fn policy(&self) -> &TrackPolicy {
        &self.policy
    }

    /// Replaces the tracking policy; fails with [`Error::Params`] (and keeps the old one) when
    /// a value is out of range.
    fn set_policy(&mut self, policy: TrackPolicy) -> Result<()> {
        self.policy.replace(policy)
    }

    /// The fit scale in use (fitted pixels per frame pixel; 1: the frame is fitted as it
    /// comes), or 0 before a sequence's first frame decides it.
    fn scale(&self) -> f32 {
        self.k
    }

    /// The scale at which the tracker fits a `width x height` frame with a face
    /// `face_height` pixels tall in it (resampled pixels per frame pixel; the tracker asks it
    /// itself, [`Tracker::scale`](crate::fit::FaceTracker::scale) is the one in use), under the
    /// [`TrackPolicy`]: the fit's cost grows with the face's size in pixels (a face twice the
    /// model's size costs about 3 times more), so the face is brought to about the size the
    /// model was built at; a face within [`TrackPolicy::native_band`] of it is fitted at the
    /// frame's own resolution, the resampled frame's longer side stays within
    /// `min_fit_side..=max_fit_side`, and it is enlarged at most [`TrackPolicy::max_upscale`]
    /// times. `current` is the scale in use (0 when there is none): it is kept unless the
    /// wanted scale differs from it by more than [`TrackPolicy::rescale_change`]. A
    /// non-finite or non-positive size gives `current` (or 1).
    fn fit_scale(&self, face_height: f32, width: u32, height: u32, current: f32) -> f32 {
        self.policy
            .fit_scale(self.model_face_height, face_height, width, height, current)
    }
}

impl std::fmt::Debug for Tracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        summary(f, "Tracker", &[("fitter", &self.fitter)])
    }
}

/// Of the `faces` with finite points that pass `ok`, the one whose `centre` is nearest `near`
/// (the first such one when `near` is `None`; the first of equally near ones): how a tracker
/// and a follower pick the face to acquire.
pub(super) fn nearest_face(
    faces: &[Vec<f32>],
    near: Option<(f32, f32)>,
    centre: impl Fn(&[f32]) -> (f32, f32),
    ok: impl Fn(&[f32]) -> bool,
) -> Option<&[f32]> {
    let d = |s: &[f32]| match near {
        Some((x, y)) => {
            let (cx, cy) = centre(s);
            (cx - x).powi(2) + (cy - y).powi(2)
        }
        None => 0.0,
    };
    faces
        .iter()
        .map(Vec::as_slice)
        .filter(|f| f.iter().all(|v| v.is_finite()) && ok(f))
        .min_by(|a, b| d(a).total_cmp(&d(b)))
}

/// The mean of interleaved points: where a face is, to pick the found face nearest it.
fn centroid(s: &[f32]) -> (f32, f32) {
    let n = (s.len() / 2).max(1) as f32;
    (
        s.iter().step_by(2).sum::<f32>() / n,
        s.iter().skip(1).step_by(2).sum::<f32>() / n,
    )
}

/// Width and height of the bounding box of interleaved points.
fn extent(points: &[f32]) -> (f32, f32) {
    let b = crate::geometry::BBox::of_points(points);
    (b.width.max(0.0), b.height.max(0.0))
}

/// Where a fit starts.
enum From<'a> {
    /// The sequence's start (the last good fit while tracking).
    Start,
    /// The last good fit (the sequence's start before one).
    LastGood,
    /// A face found or offered.
    Face(&'a [f32]),
}

/// A result with nothing in it (no allocation): a placeholder while one is moved out.
fn empty_result() -> FitResult {
    FitResult {
        landmarks: Vec::new(),
        params: crate::model::Params {
            pose: Similarity::IDENTITY,
            shape: Vec::new(),
            appearance: Vec::new(),
        },
        error: 0.0,
        iterations: 0,
        converged: false,
        lost: false,
        reacquired: false,
        status: crate::fit::TrackStatus::Tracking,
        reasons: crate::fit::Reasons::NONE,
    }
}

/// Copies `src` into `dst`, reusing its buffers.
fn copy_result(dst: &mut FitResult, src: &FitResult) {
    dst.landmarks.clone_from(&src.landmarks);
    dst.params.pose = src.params.pose;
    dst.params.shape.clone_from(&src.params.shape);
    dst.params.appearance.clone_from(&src.params.appearance);
    dst.error = src.error;
    dst.iterations = src.iterations;
    dst.converged = src.converged;
    dst.lost = src.lost;
    dst.reacquired = src.reacquired;
    dst.status = src.status;
    dst.reasons = src.reasons;
}

/// Stores `src` in `slot`, reusing the buffers of what it held.
fn store(slot: &mut Option<FitResult>, src: &FitResult) {
    match slot {
        Some(d) => copy_result(d, src),
        None => *slot = Some(src.clone()),
    }
}

/// The face finder as a [`Tracker`]'s face source, when the model has its 68 landmarks.
fn shipped_finder(landmarks: usize) -> Result<crate::find::FaceFinder> {
    if landmarks != 68 {
        return Err(Error::Params(format!(
            "the tracker has no face source to start from and its model has {landmarks} \
             landmarks, not the face finder's 68: set one first"
        )));
    }
    crate::find::FaceFinder::new()
}

//! What a landmark follower sees of a face's appearance (issue 30, item 2): the frame sampled
//! into the source model's reference frame at the followed points, and the person's own
//! running neutral appearance. A [`super::Follower`] reads no appearance parameters (the
//! source model's appearance modes describe another person), so without this the expressive
//! method had nothing to take a laugh's teeth, creases or closing lids from: the targets of
//! anyone without a model of their own smiled with closed, unshaded lips. The expressive
//! method takes its ratio image, inner mouth and gaze from the pair (the frame against the
//! person's own neutral: identity-free, as the issue asks, "the source's neutral is ... the
//! running neutral the follower already keeps").

use crate::error::Result;
use crate::image::ImageRef;
use crate::model::frame::ReferenceFrame;
use crate::model::warp::sample_rgb;

/// Frames whose appearance is averaged for the first neutral.
pub const NEUTRAL_WARMUP: u32 = 10;
/// After the warm-up, each neutral-like frame moves every value of the neutral appearance
/// by at most this (RGB in `0..=1`): a running median that a lasting change of light follows
/// in a second or two and a brief expression does not pull.
pub const NEUTRAL_STEP: f32 = 0.01;
/// A frame is neutral-like when no landmark of its expression (its shape in model
/// coordinates, the head's turn left out, against the person's neutral shape) lies further
/// from the neutral than this fraction of the outer eye corners' distance, and its mouth is no more open
/// than the neutral's (the follower's own neutral rule). Chosen on franck-dev's frames
/// 0-999 (docs/cloning.md, "Anyone, without a model").
pub const NEUTRAL_MAX_MOVE: f32 = 0.05;

/// The observed appearance of a followed face and its running neutral.
///
/// Represents: the source model's reference frame, the last frame's appearance sampled there
/// (`3N` RGB in `0..=1`, the frame's pixel order) and the person's neutral appearance (until a
/// neutral-like frame comes, the prior look given to [`ObservedAppearance::with_prior`] (a
/// person's own model's mean appearance) or else the look of the frame nearest rest so far
/// ([`rest_distance`]); then the mean of the first [`NEUTRAL_WARMUP`] neutral-like frames;
/// then a running median, [`NEUTRAL_STEP`]).
///
/// Ensures: [`ObservedAppearance::get`] gives both once a frame was observed; each
/// observation allocates nothing.
#[derive(Clone, Debug)]
pub struct ObservedAppearance {
    frame: ReferenceFrame,
    app: Vec<f32>,
    neutral: Vec<f32>,
    neutral_frames: u32,
    seen: bool,
    /// The [`rest_distance`] of the frame whose look is the neutral before the first
    /// neutral-like frame (without a prior).
    nearest: f32,
    /// The neutral until a neutral-like frame comes (empty: the frame's own).
    prior: Vec<f32>,
}

/// One frame's face as observed: its appearance and the person's neutral one, on the source
/// model's frame pixels (`3N` RGB each), and, when the tracker has it, the expression's whole
/// shape displacement.
#[derive(Clone, Copy, Debug)]
pub struct Observed<'a> {
    /// The frame's appearance.
    pub appearance: &'a [f32],
    /// The person's neutral appearance.
    pub neutral: &'a [f32],
    /// The frame's shape less the person's neutral shape, in the source model's coordinates
    /// (aligned to its `s0`, the head's turn to the side left out, its nod left in; `2n`): the
    /// whole expression, where the fit's `S p` is its projection onto the source model's modes
    /// (a speech model's modes hold no smile). `None` when the tracker has only the projection.
    pub displacement: Option<&'a [f32]>,
    /// The head's turn to the side that `displacement` leaves out (`2n`, the same
    /// coordinates), when the tracker keeps it: the expressive method adds it back when the
    /// target follows the source's pose ([`crate::clone::CloneOptions::follow_pose`]), so the avatar
    /// turns its head with the person's. `None`: the target keeps its view either way (the
    /// [`super::Follower`]'s).
    pub turn: Option<&'a [f32]>,
}

impl ObservedAppearance {
    /// Observes faces into `frame` (the source model's reference frame).
    pub fn new(frame: &ReferenceFrame) -> ObservedAppearance {
        let n = 3 * frame.n_pixels();
        ObservedAppearance {
            frame: frame.clone(),
            app: vec![0.0; n],
            neutral: vec![0.0; n],
            neutral_frames: 0,
            seen: false,
            nearest: f32::INFINITY,
            prior: Vec::new(),
        }
    }

    /// Observes faces into `frame` with `prior` (`3N` RGB) as the neutral until the first
    /// neutral-like frame comes, and again after each [`reset`](Self::reset): the mean look
    /// of a person's own model, so a session that starts in a laugh shows the laugh (with the
    /// frame as its own neutral, it showed nothing until the person rested). Fails with
    /// [`crate::Error::Params`] when `prior` is not `3N` values.
    pub fn with_prior(frame: &ReferenceFrame, prior: &[f32]) -> Result<ObservedAppearance> {
        let mut o = ObservedAppearance::new(frame);
        if prior.len() != o.neutral.len() {
            return Err(crate::Error::Params(format!(
                "the prior neutral appearance has {} values, the frame needs {}",
                prior.len(),
                o.neutral.len()
            )));
        }
        o.prior = prior.to_vec();
        Ok(o)
    }

    /// Forgets the person (a new sequence, or a face found again after a loss, which may be
    /// someone else): the next frame starts a new neutral.
    pub fn reset(&mut self) {
        self.seen = false;
        self.neutral_frames = 0;
        self.nearest = f32::INFINITY;
    }

    /// Samples `image` at `points` (the frame's landmarks in image coordinates, `2n`) and,
    /// when the frame is neutral-like (`rest`, its [`rest_distance`], at most 1), moves the
    /// neutral towards it. Before the first neutral-like frame, without a prior, the neutral
    /// is the look of the frame nearest rest so far (the first frame's, then any nearer
    /// one's): a session that opens laughing shows its laugh against its least laughing
    /// moment instead of nothing. Fails with [`crate::Error::Params`] (changing nothing) when
    /// `points` has another length. Allocates nothing.
    pub fn observe(&mut self, image: &ImageRef<'_>, points: &[f32], rest: f32) -> Result<()> {
        sample_rgb(&self.frame, image, points, &mut self.app)?;
        let neutral_like = rest <= 1.0;
        if !self.seen || self.neutral_frames == 0 {
            // Until a neutral-like frame comes, the prior is the neutral, or else the frame
            // nearest rest so far.
            let first = !self.seen;
            self.seen = true;
            if neutral_like {
                self.neutral.copy_from_slice(&self.app);
                self.neutral_frames = 1;
            } else if !self.prior.is_empty() {
                self.neutral.copy_from_slice(&self.prior);
            } else if first || rest < self.nearest {
                self.neutral.copy_from_slice(&self.app);
                self.nearest = if rest.is_nan() { f32::INFINITY } else { rest };
            }
            return Ok(());
        }
        if !neutral_like {
            return Ok(());
        }
        if self.neutral_frames < NEUTRAL_WARMUP {
            self.neutral_frames += 1;
            let w = 1.0 / self.neutral_frames as f32;
            for (n, a) in self.neutral.iter_mut().zip(&self.app) {
                *n += w * (a - *n);
            }
        } else {
            for (n, a) in self.neutral.iter_mut().zip(&self.app) {
                *n += (a - *n).clamp(-NEUTRAL_STEP, NEUTRAL_STEP);
            }
        }
        Ok(())
    }

    /// The last frame's appearance and the neutral, `None` before the first observation.
    pub fn get(&self) -> Option<Observed<'_>> {
        self.seen.then_some(Observed {
            appearance: &self.app,
            neutral: &self.neutral,
            displacement: None,
            turn: None,
        })
    }

    /// Neutral-like frames taken into the neutral so far.
    pub fn neutral_frames(&self) -> u32 {
        self.neutral_frames
    }
}

/// The farthest landmark's distance from the neutral and the neutral-like limit
/// ([`NEUTRAL_MAX_MOVE`] of the neutral's outer eye corners' distance); the distance is NaN
/// when a value is not a number, and `None` when the neutral has no eye line.
fn farthest_move(shape: &[f32], neutral: &[f32]) -> Option<(f32, f32)> {
    let [ex, ey] = crate::landmarks::eye_line(neutral)?;
    let iod = (ex * ex + ey * ey).sqrt();
    if !(iod > 0.0) {
        return None;
    }
    let far = shape
        .chunks_exact(2)
        .zip(neutral.chunks_exact(2))
        .map(|(s, n)| (s[0] - n[0]).hypot(s[1] - n[1]))
        // A point that is not a number is never near rest (`f32::max` would skip it).
        .fold(0.0f32, |a, d| {
            if a.is_nan() || d.is_nan() {
                f32::NAN
            } else {
                a.max(d)
            }
        });
    Some((far, NEUTRAL_MAX_MOVE * iod))
}

/// Whether a frame's expression is neutral-like ([`NEUTRAL_MAX_MOVE`]): `shape` and `neutral`
/// are 68-point shapes in one coordinate frame (the follower's model coordinates). Its
/// mouth opening is not checked here ([`at_rest`] does both).
pub fn neutral_like(shape: &[f32], neutral: &[f32]) -> bool {
    farthest_move(shape, neutral).is_some_and(|(far, lim)| far <= lim)
}

/// Whether a frame is at rest: its expression neutral-like ([`neutral_like`]) and its mouth no
/// more open than the neutral's plus `mouth_margin` ([`super::mouth_opening`]): the frames
/// whose look enters the person's neutral look. Its [`rest_distance`] is at most 1.
pub fn at_rest(shape: &[f32], neutral: &[f32], mouth_margin: f32) -> bool {
    rest_distance(shape, neutral, mouth_margin) <= 1.0
}

/// How far a frame is from rest, in units of [`at_rest`]'s limits: the larger of its farthest
/// landmark's distance from the neutral over [`NEUTRAL_MAX_MOVE`] eye distances and its mouth's
/// opening beyond the neutral's over `mouth_margin`: at most 1 when the frame is at rest
/// ([`at_rest`]); infinite when the neutral has no eye line, a value is not a number, or the
/// mouth is open beyond a zero margin. `shape` and `neutral` as for [`neutral_like`].
pub fn rest_distance(shape: &[f32], neutral: &[f32], mouth_margin: f32) -> f32 {
    let Some((far, lim)) = farthest_move(shape, neutral) else {
        return f32::INFINITY;
    };
    let open = super::mouth_opening(shape) - super::mouth_opening(neutral);
    let open = if mouth_margin > 0.0 {
        open / mouth_margin
    } else if open > 0.0 {
        f32::INFINITY
    } else {
        0.0
    };
    let far = far / lim;
    if far.is_nan() || open.is_nan() {
        f32::INFINITY
    } else {
        far.max(open)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat grey 400 x 400 picture of `level`, and the canonical frame's vertices moved into
    /// it (the face's points).
    fn picture(level: u8) -> (Vec<u8>, Vec<f32>) {
        let v = crate::canonical_frame().vertices();
        (
            vec![level; 400 * 400 * 4],
            v.iter().map(|c| c + 100.0).collect(),
        )
    }

    #[test]
    fn the_rest_distance_is_at_most_one_exactly_at_rest() {
        let neutral: Vec<f32> = crate::canonical_frame().vertices().to_vec();
        let [ex, ey] = crate::landmarks::eye_line(&neutral).unwrap();
        let iod = ex.hypot(ey);
        let margin = 0.02;
        assert_eq!(rest_distance(&neutral, &neutral, margin), 0.0);
        let mut rng = 0x5eed_u32;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 17;
            rng ^= rng << 5;
            rng as f32 / u32::MAX as f32 - 0.5
        };
        let (mut inside, mut outside) = (0, 0);
        for k in 0..400 {
            // Each point moved by up to 0.03-0.09 of the eye distance, sometimes the mouth
            // opened (the lower inner lip down).
            let reach = 0.06 + 0.12 * next().abs() + 0.06 * (k % 2) as f32;
            let mut shape: Vec<f32> = neutral.iter().map(|&v| v + reach * iod * next()).collect();
            if k % 3 == 0 {
                for p in 65..=67 {
                    shape[2 * p + 1] += 0.04 * iod * (next() + 0.5);
                }
            }
            let d = rest_distance(&shape, &neutral, margin);
            // The two rules at rest: neutral-like, the mouth no more open than a margin.
            let rules = neutral_like(&shape, &neutral)
                && super::super::mouth_opening(&shape)
                    <= super::super::mouth_opening(&neutral) + margin;
            assert_eq!(d <= 1.0, rules, "shape {k}: {d}");
            assert_eq!(at_rest(&shape, &neutral, margin), rules);
            if d <= 1.0 {
                inside += 1;
            } else {
                outside += 1;
            }
        }
        assert!(
            inside > 20 && outside > 20,
            "{inside} at rest, {outside} not"
        );
        // One point 1.5 limits away, or the mouth 2 margins more open: 1.5 and 2.
        let mut far = neutral.clone();
        far[2 * 30] += 1.5 * NEUTRAL_MAX_MOVE * iod;
        assert!((rest_distance(&far, &neutral, margin) - 1.5).abs() < 1e-3);
        let mut open = neutral.clone();
        for p in 65..=67 {
            open[2 * p + 1] += 2.0 * margin * iod;
        }
        let d = rest_distance(&open, &neutral, margin);
        assert!(d > 1.9 && d < 2.1, "{d}");
        assert!(!at_rest(&open, &neutral, margin));
        // Nothing to measure against, or a value that is not a number: infinitely far.
        let mut nan = neutral.clone();
        nan[0] = f32::NAN;
        assert_eq!(rest_distance(&nan, &neutral, margin), f32::INFINITY);
        assert_eq!(
            rest_distance(&neutral, &vec![0.0; 136], margin),
            f32::INFINITY
        );
    }

    #[test]
    fn before_the_first_rest_the_nearest_frame_is_the_neutral() {
        let frame = crate::canonical_frame();
        let (laugh, points) = picture(200);
        let (smile, _) = picture(150);
        let (rest, _) = picture(100);
        let laugh = ImageRef::new(400, 400, &laugh).unwrap();
        let smile = ImageRef::new(400, 400, &smile).unwrap();
        let rest = ImageRef::new(400, 400, &rest).unwrap();
        let mut o = ObservedAppearance::new(frame);
        let level = |o: &ObservedAppearance| (o.get().unwrap().neutral[0] * 255.0).round();
        o.observe(&smile, &points, 2.0).unwrap();
        assert_eq!(level(&o), 150.0);
        // A farther frame (a broader laugh) does not replace it; a nearer one does.
        o.observe(&laugh, &points, 4.0).unwrap();
        assert_eq!(level(&o), 150.0);
        o.observe(&laugh, &points, 1.5).unwrap();
        assert_eq!(level(&o), 200.0);
        assert_eq!(o.neutral_frames(), 0);
        // The first frame at rest ends it.
        o.observe(&rest, &points, 0.9).unwrap();
        assert_eq!(level(&o), 100.0);
        assert_eq!(o.neutral_frames(), 1);
        o.observe(&smile, &points, 1.2).unwrap();
        assert_eq!(level(&o), 100.0);
        // A new person starts again from their first frame.
        o.reset();
        o.observe(&laugh, &points, 5.0).unwrap();
        assert_eq!(level(&o), 200.0);
    }

    #[test]
    fn the_prior_is_the_neutral_until_the_person_rests() {
        let frame = crate::canonical_frame();
        let n = 3 * frame.n_pixels();
        let prior = vec![0.25f32; n];
        let (laugh, points) = picture(200);
        let (rest, _) = picture(100);
        let laugh = ImageRef::new(400, 400, &laugh).unwrap();
        let rest = ImageRef::new(400, 400, &rest).unwrap();
        let mut with = ObservedAppearance::with_prior(frame, &prior).unwrap();
        let mut without = ObservedAppearance::new(frame);
        for o in [&mut with, &mut without] {
            o.observe(&laugh, &points, f32::INFINITY).unwrap();
        }
        // A session that starts in a laugh: against the prior, the laugh shows...
        assert_eq!(with.get().unwrap().neutral, &prior[..]);
        // ...where the frame as its own neutral showed nothing.
        let o = without.get().unwrap();
        assert_eq!(o.neutral, o.appearance);
        // A frame at rest takes over from the prior.
        with.observe(&rest, &points, 0.0).unwrap();
        let o = with.get().unwrap();
        assert_eq!(o.neutral, o.appearance);
        assert!(
            (o.neutral[0] - 100.0 / 255.0).abs() < 0.01,
            "{}",
            o.neutral[0]
        );
        // A new person: the prior again.
        with.reset();
        with.observe(&laugh, &points, f32::INFINITY).unwrap();
        assert_eq!(with.get().unwrap().neutral, &prior[..]);
        // A prior of the wrong size is refused.
        assert!(ObservedAppearance::with_prior(frame, &prior[1..]).is_err());
    }
}

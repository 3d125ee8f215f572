//! The head placement a followed face drives: its pose re-centred on the model's mean pose
//! about an anchor that follows the head slowly, and what the [`crate::fit::Tracker`] and the
//! [`crate::fit::Follower`] share (counters, the anchor), the running [`PoseAnchor`] itself, and
//! [`HeadDamper`], head-motion damping over time.

use crate::error::{Error, Result};
use crate::similarity::Similarity;

/// What a tracker and a follower keep of a sequence beside the fit: the frame counters and the
/// pose anchor. Both expose it as `sequence()`, so their counters and placement are read
/// the same way.
///
/// The placement ([`Sequence::placed`]) is `mean ∘ anchor⁻¹ ∘ pose` ([`Similarity::recentred`]):
/// the tracked pose moved so that where the anchor puts the face, the model's mean pose does.
/// The anchor is the sequence's first good pose; with a time constant `tau > 0`
/// ([`crate::fit::TrackPolicy::recentre_tau`]) it then follows the head with
/// [`Similarity::lerp`] by `1 - exp(-dt / tau)` a good frame (`dt`: the seconds since the
/// last good frame), so a face anywhere in the picture ends up centred while its motion shows;
/// with `tau = 0` it stays (a clip's motion reproduced exactly). All poses are in the frame's
/// pixels.
#[derive(Clone, Debug)]
pub struct Sequence {
    /// The model's mean pose (where the anchor's face is placed).
    target: Similarity,
    anchor: PoseAnchor,
    placed: Similarity,
    lost_count: u32,
    reacquisitions: u32,
    frames: u32,
}

impl Sequence {
    /// A sequence placing faces about `target` (the model's mean pose).
    pub fn new(target: Similarity) -> Sequence {
        Sequence {
            target,
            anchor: PoseAnchor::new(),
            placed: target,
            lost_count: 0,
            reacquisitions: 0,
            frames: 0,
        }
    }

    /// Forgets the anchor (a new sequence: the next good pose becomes it). The counters and
    /// the last placement stay.
    pub fn restart(&mut self) {
        self.anchor.reset();
    }

    /// Counts a frame `dt` seconds after the previous one: `pose` is its good fit's pose, or
    /// `None` for a lost frame (the placement stays); `reacquired` counts an acquisition.
    /// `tau`: the anchor's time constant (seconds, 0: fixed).
    pub fn frame(&mut self, pose: Option<&Similarity>, dt: f32, tau: f32, reacquired: bool) {
        self.frames += 1;
        if reacquired {
            self.reacquisitions += 1;
        }
        self.anchor.wait(dt);
        let Some((pose, anchor)) = pose.and_then(|p| Some((p, self.anchor.follow(p, tau)?))) else {
            self.lost_count += 1;
            return;
        };
        if let Some(p) = pose.recentred(&anchor, &self.target) {
            self.placed = p;
        }
    }

    /// The last good pose re-centred on the model's mean pose about the anchor: the head
    /// placement to draw the driven face with (the model's mean pose before any good frame).
    pub fn placed(&self) -> Similarity {
        self.placed
    }

    /// The anchor (frame pixels), `None` before the sequence's first good frame.
    pub fn anchor(&self) -> Option<Similarity> {
        self.anchor.get()
    }

    /// The model's mean pose, where the anchor's face is placed.
    pub fn target(&self) -> Similarity {
        self.target
    }

    /// Frames reported lost.
    pub fn lost_count(&self) -> u32 {
        self.lost_count
    }

    /// Faces acquired by a search (the first face of a search and every face found again).
    pub fn reacquisitions(&self) -> u32 {
        self.reacquisitions
    }

    /// Frames followed since the tracker or follower was made.
    pub fn frames(&self) -> u32 {
        self.frames
    }
}

/// A pose that follows a head slowly: the core's one running pose anchor, used by the
/// [`Sequence`] (the placement about it) and, through the package's `PoseDamper`, by the call
/// page's head-motion damping ([`PoseAnchor::damped`]).
///
/// Represents the anchor (none before the first pose) and the seconds since it last moved.
/// Ensures: the first pose given is the anchor; each later pose moves it by
/// [`Similarity::lerp`] `1 - exp(-since / tau)` of the way (`since`: the seconds since the
/// anchor last moved, time with no pose included), so with a time constant `tau > 0` it is an
/// exponential running mean of the poses (geometric in scale, the short way round in angle,
/// arithmetic in translation) and with `tau = 0` it stays at the first pose. Allocates nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseAnchor {
    anchor: Option<Similarity>,
    /// Seconds since the anchor last moved.
    since: f32,
}

impl PoseAnchor {
    /// No anchor yet: the next pose becomes it.
    pub fn new() -> PoseAnchor {
        PoseAnchor::default()
    }

    /// Forgets the anchor (the next pose becomes it).
    pub fn reset(&mut self) {
        *self = PoseAnchor::default();
    }

    /// The anchor, `None` before the first pose.
    pub fn get(&self) -> Option<Similarity> {
        self.anchor
    }

    /// Counts `dt` seconds (a non-finite or negative `dt` counts as 0).
    pub fn wait(&mut self, dt: f32) {
        self.since += if dt.is_finite() { dt.max(0.0) } else { 0.0 };
    }

    /// Moves the anchor towards `pose` for the time counted since it last moved
    /// ([`PoseAnchor::wait`]; time constant `tau` seconds, 0: fixed) and returns it; an
    /// invalid pose ([`Similarity::is_valid`]) changes nothing and gives `None`.
    pub fn follow(&mut self, pose: &Similarity, tau: f32) -> Option<Similarity> {
        if !pose.is_valid() {
            return None;
        }
        let anchor = match self.anchor {
            None => *pose,
            Some(a) if tau > 0.0 => a.lerp(pose, 1.0 - (-self.since / tau).exp()),
            Some(a) => a,
        };
        self.anchor = Some(anchor);
        self.since = 0.0;
        Some(anchor)
    }

    /// Head-motion damping: `pose`'s deviation from the anchor scaled by `factor`, i.e.
    /// `anchor.lerp(pose, factor)` (0: the anchor, 1: `pose` itself, over 1: the motion
    /// exaggerated); `pose` itself without an anchor, for a `factor` of 1, or a non-finite one.
    pub fn damped(&self, pose: &Similarity, factor: f32) -> Similarity {
        match self.anchor {
            Some(a) if factor != 1.0 && factor.is_finite() => a.lerp(pose, factor),
            _ => *pose,
        }
    }
}

/// Head-motion damping over time: what the Stage applies to the pose of every fit it takes
/// (the call page's head motion) and the package's `PoseDamper` is.
///
/// Represents: a running anchor of the fitted poses (time constant `tau` seconds, 0: the first
/// pose stays the anchor) and a `factor` on the deviation from it (0 holds the head at the
/// anchor, 1 passes the pose unchanged, over 1 exaggerates).
#[derive(Debug)]
pub struct HeadDamper {
    anchor: PoseAnchor,
    tau: f32,
    factor: f32,
    /// The clock (ms) of the last pose taken.
    at: Option<f64>,
}

impl HeadDamper {
    /// Requires `tau` finite and non-negative, `factor` finite (else [`Error::Params`]).
    pub fn new(tau: f32, factor: f32) -> Result<HeadDamper> {
        check(tau, factor)?;
        Ok(HeadDamper {
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

    /// The anchor's time constant, seconds.
    pub fn tau(&self) -> f32 {
        self.tau
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_anchor_starts_at_the_first_pose_and_follows_slowly() {
        let target = Similarity::from_parts(1.0, 0.0, 100.0, 100.0);
        let mut s = Sequence::new(target);
        assert_eq!(s.placed(), target);
        let p0 = Similarity::from_parts(2.0, 0.1, 300.0, 200.0);
        s.frame(Some(&p0), 0.04, 4.0, true);
        // The first pose is the anchor: it is placed on the target.
        let d = s.placed();
        assert!((d.a - target.a).abs() < 1e-5 && (d.tx - target.tx).abs() < 1e-3);
        // A moved head: the anchor moves a little towards it (1 - exp(-dt / tau)).
        let p1 = Similarity::from_parts(2.0, 0.1, 340.0, 200.0);
        s.frame(None, 1.0, 4.0, false);
        s.frame(Some(&p1), 1.0, 4.0, false);
        let a = s.anchor().unwrap();
        let u = 1.0 - (-2.0f32 / 4.0).exp();
        assert!((a.tx - (300.0 + 40.0 * u)).abs() < 1e-3, "{a:?}");
        assert_eq!((s.frames(), s.lost_count(), s.reacquisitions()), (3, 1, 1));
        // A fixed anchor (tau 0) stays at the first pose.
        let mut f = Sequence::new(target);
        f.frame(Some(&p0), 0.04, 0.0, false);
        f.frame(Some(&p1), 10.0, 0.0, false);
        assert_eq!(f.anchor(), Some(p0));
        let want = p1.recentred(&p0, &target).unwrap();
        assert!((f.placed().tx - want.tx).abs() < 1e-3);
        // A restart forgets the anchor.
        f.restart();
        f.frame(Some(&p1), 0.04, 0.0, false);
        assert_eq!(f.anchor(), Some(p1));
    }

    #[test]
    fn damping_scales_the_deviation_from_the_running_anchor() {
        let still = Similarity::from_parts(2.0, 0.1, 100.0, 50.0);
        let mut a = PoseAnchor::new();
        assert_eq!(a.damped(&still, 0.3), still, "no anchor yet: the pose");
        for _ in 0..300 {
            a.wait(0.033);
            a.follow(&still, 2.0);
        }
        let moved = Similarity::from_parts(2.0, 0.1, 120.0, 50.0);
        a.wait(0.033);
        a.follow(&moved, 2.0);
        // Factor 0 keeps the head near the anchor, 0.5 goes half way, 1 is the pose.
        assert!((a.damped(&moved, 0.0).tx - 100.0).abs() < 0.5);
        assert!((a.damped(&moved, 0.5).tx - 110.0).abs() < 0.5);
        assert_eq!(a.damped(&moved, 1.0), moved);
        // Scale is damped in log space: positive at any factor.
        assert!(
            a.damped(&Similarity::from_parts(0.1, 0.1, 0.0, 0.0), 1.5)
                .scale()
                > 0.0
        );
        // An invalid pose moves nothing.
        let before = a;
        let bad = Similarity {
            a: f32::NAN,
            ..still
        };
        assert_eq!(a.follow(&bad, 2.0), None);
        assert_eq!(a, before);
        a.reset();
        assert_eq!(a.get(), None);
    }
}

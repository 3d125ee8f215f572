//! Silent failures (issue 33): frames where the own-model AAM fit is off but the tracker says
//! it is tracking, on two clips of research data read from ../shared (never committed).
//!
//! **Split** (the convention of `enrol_webcam.rs`): a model is enrolled from each clip's build
//! part only and measured on its unseen part:
//! - webcam-dev: built from frames 0-599 (every 5th frame searched), measured on 600-1336;
//! - franck-dev2: built from frames 3800-4299 (every 5th frame searched), measured on
//!   4300-4799.
//!
//! The model is *enrolled* as the page enrols one: the enrolment finder's landmarks
//! ([`EnrolFinder`]) on the searched frames, 20 of them chosen by farthest-point sampling. It
//! is tracked as the page tracks: [`FaceTracker::start_searching`], a [`FaceFinder`] offering
//! the frame's faces whenever the tracker wants them (its finder worker), default options and
//! policy.
//!
//! **Off**: a frame's mean landmark error against dlib's points is over 0.1 of the eye
//! distance, judged **convention-free** ([`convention_free_errors`]: each point's mean offset
//! from dlib's over the measured frames, in the face frame, removed first, so the enrolment
//! finder's convention is not counted as error). **Flagged**: the frame's status is not
//! "tracking" (unsure or lost). Counted: off and not flagged (aim: at most 0.5% of the measured
//! frames), and flagged but not off (false alarms, kept low). Skips with a message when
//! ../shared is absent; fails then if the CI variable is set. `cargo test --release --test
//! integration confidence:: -- --nocapture` prints the figures.

use facemimic::fit::FaceTracker;
use facemimic_testkit as common;

use std::ops::Range;

use common::{frame, shared_data, varied};
use facemimic::find::{convention_free_errors, landmark_error};
use facemimic::fit::{ConfidenceBounds, FitOptions, TrackPolicy, TrackStatus, Tracker};
use facemimic::{BuildOptions, Builder, EnrolFinder, FaceFinder, Model, TrainingImage};

/// A model enrolled from every 5th frame of `build_from`, as the page enrols one.
fn enrol(dir: &std::path::Path, build_from: Range<usize>) -> Model {
    let mut finder = EnrolFinder::new(1).unwrap();
    let mut found = Vec::new();
    for i in build_from.step_by(5) {
        let mut f = frame(dir, i);
        if let Some(face) = finder.find(&f.image.view().unwrap(), 0.0).unwrap() {
            f.landmarks = face.landmarks;
            found.push(f);
        }
    }
    Builder::new(BuildOptions {
        name: "enrolled".into(),
        ..BuildOptions::default()
    })
    .build(&varied(&found, 20), None)
    .unwrap()
}

/// One measured frame: what the tracker reported and how far it was from dlib.
struct Frame {
    /// Convention-free error of the reported landmarks.
    free: f32,
    /// Raw error.
    raw: f32,
    /// The status was not "tracking".
    flagged: bool,
    /// The frame was reported lost.
    lost: bool,
    /// The status's reasons, for the printout.
    reasons: String,
}

/// Tracks `test` as the page does and scores every frame; `bounds` are the confidence
/// checks' ([`ConfidenceBounds::off`]: today's tracker before them, every frame not lost
/// "tracking").
fn track(
    model: &Model,
    test: &[TrainingImage],
    policy: &TrackPolicy,
    bounds: ConfidenceBounds,
) -> Vec<Frame> {
    let mut finder = FaceFinder::new().unwrap();
    let mut t = Tracker::new(model, FitOptions::default()).unwrap();
    t.set_policy(policy.clone()).unwrap();
    t.set_confidence_bounds(bounds).unwrap();
    t.expect_offers(true);
    t.start_searching();
    let mut reported = Vec::new();
    let mut flags = Vec::new();
    for f in test {
        let view = f.image.view().unwrap();
        common::offer_when_wanted(&mut t, &mut finder, &view);
        let r = t.track(&view, facemimic::fit::DEFAULT_TIME_STEP).unwrap();
        reported.push(r.landmarks.clone());
        flags.push((
            r.status != TrackStatus::Tracking,
            r.lost,
            r.reasons.to_string(),
        ));
    }
    let pairs: Vec<(&[f32], &[f32])> = reported
        .iter()
        .zip(test)
        .map(|(l, f)| (l.as_slice(), f.landmarks.as_slice()))
        .collect();
    let free = convention_free_errors(&pairs);
    free.iter()
        .zip(&pairs)
        .zip(flags)
        .map(|((&free, (l, d)), (flagged, lost, reasons))| Frame {
            free,
            raw: landmark_error(l, d),
            flagged,
            lost,
            reasons,
        })
        .collect()
}

/// Whether an error is over 0.1 of the eye distance (or not a number): the fit is off.
fn over(error: f32) -> bool {
    error.is_nan() || error > 0.1
}

/// An event done to the measured frames: its name, and what it does to the frame at an index
/// among them (whether it changed it).
type Event<'a> = (&'a str, &'a dyn Fn(usize, &mut TrainingImage) -> bool);

/// The counts of one run.
struct Counts {
    measured: usize,
    off: usize,
    silent: usize,
    false_alarms: usize,
    flagged: usize,
    lost: usize,
    mean: f32,
    /// Frames over 0.1 raw, and those not flagged.
    raw_off: (usize, usize),
}

impl std::fmt::Display for Counts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "convention-free mean {:.4}; {} off (> 0.1), {} of them not flagged ({:.2}%); {} \
             flagged ({} lost), {} false alarms ({:.2}%); raw: {} over 0.1, {} not flagged",
            self.mean,
            self.off,
            self.silent,
            100.0 * self.silent as f32 / self.measured as f32,
            self.flagged,
            self.lost,
            self.false_alarms,
            100.0 * self.false_alarms as f32 / self.measured as f32,
            self.raw_off.0,
            self.raw_off.1,
        )
    }
}

/// The counts of a run; `event[i]`: frame `i` was changed by an event (a false alarm is a
/// good frame flagged with no event on it: flagging a half-covered face is no false alarm).
fn counts(frames: &[Frame], event: &[bool]) -> Counts {
    let off = |f: &Frame| over(f.free);
    Counts {
        measured: frames.len(),
        off: frames.iter().filter(|f| off(f)).count(),
        silent: frames.iter().filter(|f| off(f) && !f.flagged).count(),
        false_alarms: frames
            .iter()
            .zip(event)
            .filter(|(f, &e)| !off(f) && f.flagged && !e)
            .count(),
        flagged: frames.iter().filter(|f| f.flagged).count(),
        lost: frames.iter().filter(|f| f.lost).count(),
        mean: frames.iter().map(|f| f.free).sum::<f32>() / frames.len().max(1) as f32,
        raw_off: (
            frames.iter().filter(|f| over(f.raw)).count(),
            frames.iter().filter(|f| over(f.raw) && !f.flagged).count(),
        ),
    }
}

/// Enrols from every 5th frame of `build_from` and measures `measure_on`, with `event` done
/// to the measured frames (their index among them, the frame).
fn measure(
    clip: &str,
    build_from: Range<usize>,
    measure_on: Range<usize>,
    event: Option<Event<'_>>,
) -> Option<Counts> {
    let dir = shared_data(clip)?;
    let model = enrol(&dir, build_from.clone());
    let mut test: Vec<TrainingImage> = measure_on.clone().map(|i| frame(&dir, i)).collect();
    let mut what = format!(
        "{clip}: enrolled from {build_from:?} (every 5th frame), measured on the unseen \
         {measure_on:?} ({} frames)",
        test.len()
    );
    let mut changed = vec![false; test.len()];
    if let Some((name, f)) = event {
        for (i, t) in test.iter_mut().enumerate() {
            changed[i] = f(i, t);
        }
        what = format!("{what}, {name}");
    }
    let first = measure_on.start;
    Some(report(
        &what,
        &model,
        (&test, &changed),
        first,
        &TrackPolicy::default(),
    ))
}

/// Tracks `test` (frame numbers from `first`) before the confidence checks and with them;
/// prints both and, with them, every frame off or flagged; returns the counts with them.
fn report(
    what: &str,
    model: &Model,
    (test, event): (&[TrainingImage], &[bool]),
    first: usize,
    policy: &TrackPolicy,
) -> Counts {
    let before = counts(&track(model, test, policy, ConfidenceBounds::off()), event);
    let frames = track(model, test, policy, ConfidenceBounds::default());
    for (i, f) in frames.iter().enumerate() {
        if over(f.free) || over(f.raw) || f.flagged {
            println!(
                "  frame {}: convention-free {:.3}, raw {:.3}, {}{}",
                first + i,
                f.free,
                f.raw,
                if f.flagged { "flagged " } else { "TRACKING " },
                f.reasons
            );
        }
    }
    let after = counts(&frames, event);
    println!("{what}:\n  before the checks: {before}\n  with them:         {after}");
    after
}

/// The aim: at most 0.5% of the measured frames off and not flagged; false alarms at most 2%.
fn check(clip: &str, c: &Counts) {
    assert!(
        c.silent as f32 <= 0.005 * c.measured as f32,
        "{clip}: {} of {} frames off and reported tracking",
        c.silent,
        c.measured
    );
    assert!(
        c.false_alarms as f32 <= 0.02 * c.measured as f32,
        "{clip}: {} of {} good frames flagged",
        c.false_alarms,
        c.measured
    );
}

/// webcam-dev: enrolled from frames 0-599, measured on the unseen 600-1336.
#[test]
fn webcam_dev_off_frames_are_flagged() {
    let Some(c) = measure("webcam-dev", 0..600, 600..1337, None) else {
        return;
    };
    check("webcam-dev", &c);
}

/// franck-dev2: enrolled from its first half (3800-4299), measured on the unseen second half
/// (4300-4799).
#[test]
fn franck_dev2_off_frames_are_flagged() {
    let Some(c) = measure("franck-dev2", 3800..4300, 4300..4800, None) else {
        return;
    };
    check("franck-dev2", &c);
}

/// A hand over half the face (a skin-coloured box from the jaw's left end to the nose's
/// bridge, brows to chin) on frames 4350-4379, 4500-4529 and 4650-4679 of franck-dev2's
/// measured half, the same split: the fit must not slide onto the visible half unflagged.
#[test]
fn franck_dev2_half_face_covered_is_flagged() {
    let cover = |i: usize, f: &mut TrainingImage| {
        let on = [50..80, 200..230, 350..380].iter().any(|r| r.contains(&i));
        if on {
            half_cover(f)
        }
        on
    };
    let event: Event<'_> = ("half the face covered", &cover);
    let Some(c) = measure("franck-dev2", 3800..4300, 4300..4800, Some(event)) else {
        return;
    };
    check("franck-dev2, half covered", &c);
}

/// Covers the face's left half in `f` (image left: from the jaw's point 0 to the nose's
/// bridge, point 27; from the brows' top to the chin, point 8).
fn half_cover(f: &mut TrainingImage) {
    let lm = &f.landmarks;
    let (x0, x1) = (lm[0] - 5.0, lm[2 * 27]);
    let top = (17..27).map(|i| lm[2 * i + 1]).fold(f32::MAX, f32::min) - 10.0;
    let (y0, y1) = (top, lm[2 * 8 + 1] + 10.0);
    let (w, h) = (f.image.width as usize, f.image.height as usize);
    for y in (y0.max(0.0) as usize)..(y1.min(h as f32 - 1.0) as usize) {
        for x in (x0.max(0.0) as usize)..(x1.min(w as f32 - 1.0) as usize) {
            let o = 4 * (y * w + x);
            f.image.data[o..o + 3].copy_from_slice(&[205, 160, 135]);
        }
    }
}

/// A silent failure of today's tracker: the webcam-dev model of
/// `enrol_webcam::a_second_opinion_brings_the_fit_back_from_the_hand_under_the_chin` (20
/// frames of 0-599, the enrolment finder's points before its local correction) reads the
/// fingers under the lip (1190-1336) as an open mouth, with a plausible shape and residual,
/// when no second opinion is taken. **Split:** built from frames of 0-599, measured on the
/// unseen 1100-1336, second opinions off (`recheck_frames` 0).
#[test]
fn hand_under_the_chin_is_flagged_without_second_opinions() {
    let Some(dir) = shared_data("webcam-dev") else {
        return;
    };
    let model = crate::enrol_webcam::hand_under_the_chin_model(&dir);
    let test: Vec<TrainingImage> = (1100..1337).map(|i| frame(&dir, i)).collect();
    let policy = TrackPolicy {
        recheck_frames: 0,
        ..TrackPolicy::default()
    };
    let what = "webcam-dev, hand under the chin, no second opinions: built from 20 frames of \
                0-599, measured on the unseen 1100-1336";
    let c = report(
        what,
        &model,
        (&test, &vec![false; test.len()]),
        1100,
        &policy,
    );
    check("webcam-dev hand", &c);
}

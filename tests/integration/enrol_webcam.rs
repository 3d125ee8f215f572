//! Enrolment without landmark files, judged **convention-free** (issue 20, item 4), on two
//! clips of research data read from ../shared (never committed):
//!
//! - **webcam-dev. Split:** models are built from frames 0-599 only (every 5th frame searched:
//!   120); tracking is measured on the unseen frames 600-1336.
//! - **franck-dev2** (never in any training list). **Split:** models are built from its first
//!   half, frames 3800-4299 only (every 5th frame searched: 100; the first head turn, about
//!   3800-3900, is in it); tracking is measured on the unseen second half, frames 4300-4799
//!   (the end of the second head turn, 4200-4350, is in it).
//!
//! Every tracker starts from the face finder's landmarks on the first measured frame (no
//! landmark file used to start). Two models per clip, each of 20 frames chosen by
//! farthest-point sampling of the aligned shapes:
//! - *enrolled*: the enrolment finder's landmarks ([`EnrolFinder`]: the finder's points
//!   averaged with a pass on the mirrored image), what the page, `buildModel` without
//!   landmarks and `facemimic build --find-faces` do;
//! - *dlib*: the same searched frames with their dlib landmarks (the reference).
//!
//! **Convention-free error** ([`convention_free_errors`]): for each model, each point's mean
//! offset from dlib's point over the measured frames, in the face frame (eye line horizontal,
//! unit eye distance), is removed before scoring. A landmarker's own convention moves each
//! point by a constant that cloning never sees (it uses deviations from the model's own mean);
//! what is left is how the model follows the face. The raw error (mean landmark distance /
//! outer-eye-corner distance against dlib) is printed beside it.
//!
//! Five enrolments per clip (the searched frames starting one frame later each time; with no
//! second opinions a tracker drifts onto webcam-dev's hand under the chin or not by chance,
//! `ENROLMENTS`). Asserted on each clip, on the medians over the enrolments: the enrolled
//! models' convention-free mean error is at most 1.3x the dlib models', and their frames over
//! 0.1 (convention-free) are at most the dlib models' plus 1% of the measured frames. Skips with a message when ../shared is absent; fails then if the CI
//! variable is set. `cargo test --release --test integration enrol_webcam:: -- --nocapture` prints the
//! figures (a few minutes in release).

use facemimic::fit::FaceTracker;
use facemimic_testkit as common;

use std::ops::Range;

use common::{frame, shared_data, varied};
use facemimic::find::{convention_free_errors, landmark_error};
use facemimic::fit::{FitOptions, Tracker};
use facemimic::{BuildOptions, Builder, EnrolFinder, Model, TrainingImage};

fn build(name: &str, images: &[TrainingImage]) -> Model {
    let chosen = varied(images, 20);
    Builder::new(BuildOptions {
        name: name.into(),
        ..BuildOptions::default()
    })
    .build(&chosen, None)
    .unwrap()
}

/// The webcam-dev model that reads a hand under the chin as an open mouth without second
/// opinions (`a_second_opinion_brings_the_fit_back_from_the_hand_under_the_chin`, and the
/// tracker's confidence checks in `confidence`): 20 frames of 0-599 with the enrolment
/// finder's points, placed as when CI enrolled it, before the finder's local correction.
pub(crate) fn hand_under_the_chin_model(dir: &std::path::Path) -> Model {
    const PICKED: [usize; 20] = [
        4, 78, 111, 167, 172, 183, 230, 304, 346, 479, 490, 501, 514, 519, 529, 540, 557, 562, 573,
        592,
    ];
    let mut enrol = EnrolFinder::new(1).unwrap();
    // With the corrected points these frames give a model that does not drift (0.0230
    // without second opinions), and the tests are about catching the drift.
    enrol.finder().set_local_correction(false);
    let images: Vec<TrainingImage> = PICKED
        .iter()
        .map(|&i| {
            let mut f = frame(dir, i);
            let face = enrol.find(&f.image.view().unwrap(), 0.0).unwrap();
            f.landmarks = face.expect("a face on an enrolled frame").landmarks;
            f
        })
        .collect();
    build("webcam man", &images)
}

/// How one model tracked the measured frames.
#[derive(Debug)]
pub(crate) struct Track {
    /// Mean raw error against dlib.
    raw: f32,
    /// Frames over 0.1, raw.
    raw_over: usize,
    /// Mean convention-free error.
    pub(crate) free: f32,
    /// Frames over 0.1, convention-free.
    free_over: usize,
    /// Frames reported lost.
    lost: u32,
    /// Re-initialisations.
    resets: u32,
}

impl std::fmt::Display for Track {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "convention-free {:.4} ({} frames over 0.1), raw {:.4} ({} over 0.1), {} lost, \
             {} resets",
            self.free, self.free_over, self.raw, self.raw_over, self.lost, self.resets
        )
    }
}

pub(crate) fn track(model: &Model, test: &[TrainingImage], init: &[f32]) -> Track {
    let mut t = Tracker::new(model, FitOptions::default()).unwrap();
    t.start_from_landmarks(init).unwrap();
    let tracked: Vec<Vec<f32>> = test
        .iter()
        .map(|f| {
            t.track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                .unwrap()
                .landmarks
                .clone()
        })
        .collect();
    let raw: Vec<f32> = tracked
        .iter()
        .zip(test)
        .map(|(l, f)| landmark_error(l, &f.landmarks))
        .collect();
    let pairs: Vec<(&[f32], &[f32])> = tracked
        .iter()
        .zip(test)
        .map(|(l, f)| (l.as_slice(), f.landmarks.as_slice()))
        .collect();
    let free = convention_free_errors(&pairs);
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let over = |v: &[f32]| v.iter().filter(|e| e.is_nan() || **e > 0.1).count();
    Track {
        raw: mean(&raw),
        raw_over: over(&raw),
        free: mean(&free),
        free_over: over(&free),
        lost: t.sequence().lost_count(),
        resets: t.resets(),
    }
}

struct Figures {
    measured: usize,
    enrolled: Track,
    dlib: Track,
}

/// Enrolments per clip: the searched frames start at each of the first `ENROLMENTS` frames
/// of the building range (every 5th frame from there), so each enrolment sees other frames.
const ENROLMENTS: usize = 5;

/// Builds both models of `clip` from every 5th frame of `build_from` (starting `ENROLMENTS`
/// times, one frame later each time) and tracks `measure_on` with each; the figures of every
/// enrolment, in order.
///
/// Why several: a tracker with no second opinions drifts onto webcam-dev's hand under the
/// chin (frames 1213-1291) or not by chance. Over offsets 0-11 (29 Nov), 2 of 12 enrolled
/// models and 2 of 12 dlib-built ones drifted with the finder's two-stage correction, 4 and 4
/// with its coarse mouth stage, where the dlib-built models see the finder only in the start
/// on the first measured frame. One enrolment's figure was a coin flip; the median of five is
/// the enrolment's quality.
fn measure(clip: &str, build_from: Range<usize>, measure_on: Range<usize>) -> Option<Vec<Figures>> {
    let dir = shared_data(clip)?;
    let mut finder = EnrolFinder::new(1).unwrap();
    let test: Vec<TrainingImage> = measure_on.clone().map(|i| frame(&dir, i)).collect();
    let init = common::first_face(finder.finder(), &test[0].image)
        .expect("a face on the first measured frame");
    let mut all = Vec::new();
    for offset in 0..ENROLMENTS {
        let frames = build_from.start + offset..build_from.end;
        let mut dlib = Vec::new();
        let mut found = Vec::new();
        let searched = frames.clone().step_by(5).count();
        for i in frames.clone().step_by(5) {
            let f = frame(&dir, i);
            if let Some(face) = finder.find(&f.image.view().unwrap(), 0.0).unwrap() {
                let mut g = f.clone();
                g.landmarks = face.landmarks;
                found.push((f.landmarks.clone(), g));
            }
            dlib.push(f);
        }
        assert!(
            found.len() * 100 >= searched * 95,
            "{clip}: a face in only {} of {searched} frames",
            found.len()
        );
        let finder_error = found
            .iter()
            .map(|(d, g)| landmark_error(&g.landmarks, d))
            .sum::<f32>()
            / found.len() as f32;
        let enrolled_frames: Vec<TrainingImage> = found.iter().map(|(_, g)| g.clone()).collect();
        let figures = Figures {
            measured: test.len(),
            enrolled: track(&build("enrolled", &enrolled_frames), &test, &init),
            dlib: track(&build("dlib20", &dlib), &test, &init),
        };
        println!(
            "{clip}, built from every 5th frame of {frames:?} (finder found {}/{searched} faces, \
             error against dlib {finder_error:.4}), tracked over the unseen {measure_on:?} ({} \
             frames):\n  enrolled model: {}\n  dlib model:     {}\n  enrolled / dlib: \
             convention-free {:.2}x, raw {:.2}x",
            found.len(),
            figures.measured,
            figures.enrolled,
            figures.dlib,
            figures.enrolled.free / figures.dlib.free,
            figures.enrolled.raw / figures.dlib.raw,
        );
        all.push(figures);
    }
    Some(all)
}

/// The median of `v`.
fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// The two conditions on one clip, on the median over its enrolments.
fn check(clip: &str, all: &[Figures]) {
    let med = |f: &dyn Fn(&Figures) -> f32| median(all.iter().map(f).collect());
    let (enrolled, dlib) = (med(&|f| f.enrolled.free), med(&|f| f.dlib.free));
    let (enrolled_raw, dlib_raw) = (med(&|f| f.enrolled.raw), med(&|f| f.dlib.raw));
    let enrolled_over = med(&|f| f.enrolled.free_over as f32);
    let dlib_over = med(&|f| f.dlib.free_over as f32);
    let drifted = |f: &dyn Fn(&Figures) -> usize| all.iter().filter(|x| f(x) > 0).count();
    println!(
        "{clip}, median of {} enrolments: enrolled convention-free {enrolled:.4} ({enrolled_over} \
         frames over 0.1), dlib {dlib:.4} ({dlib_over}); {:.2}x; raw {enrolled_raw:.4} against \
         {dlib_raw:.4}; enrolments with a frame over 0.1: enrolled {}, dlib {}",
        all.len(),
        enrolled / dlib,
        drifted(&|f| f.enrolled.free_over),
        drifted(&|f| f.dlib.free_over),
    );
    assert!(
        enrolled <= 1.3 * dlib,
        "{clip}: the enrolled models track at {enrolled:.4} convention-free (median), more than \
         1.3x the dlib models' {dlib:.4} (raw {enrolled_raw:.4} against {dlib_raw:.4})"
    );
    let allowed = dlib_over + 0.01 * all[0].measured as f32;
    assert!(
        enrolled_over <= allowed,
        "{clip}: the enrolled models have {enrolled_over} frames over 0.1 convention-free \
         (median), more than the dlib models' {dlib_over} plus 1% of {} frames",
        all[0].measured
    );
}

/// webcam-dev: built from frames 0-599, measured on the unseen frames 600-1336.
#[test]
fn enrolled_model_follows_webcam_dev_like_a_dlib_model() {
    let Some(all) = measure("webcam-dev", 0..600, 600..1337) else {
        return;
    };
    check("webcam-dev", &all);
}

/// franck-dev2: built from its first half (3800-4299), measured on the unseen second half
/// (4300-4799).
#[test]
fn enrolled_model_follows_franck_dev2_like_a_dlib_model() {
    let Some(all) = measure("franck-dev2", 3800..4300, 4300..4800) else {
        return;
    };
    check("franck-dev2", &all);
}

/// The tracker's second opinion ([`TrackPolicy::recheck_frames`]) on webcam-dev's hand under
/// the chin (frames 1190-1336). **Split:** the model is built from 20 frames of 0-599 (the
/// enrolment finder's landmarks as they were before its local correction; the frames one of
/// the page's live samplings chose, the one the e2e enrolment test once failed on); it is tracked over the unseen frames 1100-1336,
/// started from the finder's face on frame 1100, with a [`FaceFinder`](facemimic::FaceFinder)
/// offering faces whenever the tracker wants them (as the page's finder worker does). Without
/// second opinions this model reads the fingers under the lip as an open mouth and stays
/// there (a plausible shape, a residual under the lost-face checks); with them a cold fit from
/// the finder's points is kept when it fits lower. Error against dlib (raw, mean over the
/// eye-corner distance), over 1190-1336.
#[test]
fn a_second_opinion_brings_the_fit_back_from_the_hand_under_the_chin() {
    use facemimic::fit::{ConfidenceBounds, TrackPolicy};
    let Some(dir) = shared_data("webcam-dev") else {
        return;
    };
    let model = hand_under_the_chin_model(&dir);
    let test: Vec<TrainingImage> = (1100..1337).map(|i| frame(&dir, i)).collect();
    let run = |recheck_frames: u32, bounds: ConfidenceBounds| {
        let mut finder = facemimic::FaceFinder::new().unwrap();
        let mut t = Tracker::new(&model, FitOptions::default()).unwrap();
        t.set_confidence_bounds(bounds).unwrap();
        t.set_policy(TrackPolicy {
            recheck_frames,
            ..TrackPolicy::default()
        })
        .unwrap();
        t.expect_offers(true);
        t.start_searching();
        let mut errors = Vec::new();
        for f in &test {
            let view = f.image.view().unwrap();
            common::offer_when_wanted(&mut t, &mut finder, &view);
            let r = t.track(&view, facemimic::fit::DEFAULT_TIME_STEP).unwrap();
            errors.push(landmark_error(&r.landmarks, &f.landmarks));
        }
        let hand = &errors[90..];
        let mean = hand.iter().sum::<f32>() / hand.len() as f32;
        (mean, hand.iter().copied().fold(0.0, f32::max), t.rechecks())
    };
    // Without second opinions and without the confidence checks (which would doubt the drifting
    // fit and ask for one: `confidence::hand_under_the_chin_is_flagged_without_second_opinions`).
    let (without, without_max, _) = run(0, ConfidenceBounds::off());
    let (with, with_max, (taken, kept)) = run(
        TrackPolicy::default().recheck_frames,
        ConfidenceBounds::default(),
    );
    println!(
        "webcam-dev 1190-1336, hand under the chin: without second opinions {without:.4} (max \
         {without_max:.3}); with them {with:.4} (max {with_max:.3}; {taken} taken over \
         1100-1336, {kept} kept)"
    );
    assert!(
        without > 0.06,
        "the model no longer drifts onto the hand without second opinions ({without:.4}): \
         the test shows nothing"
    );
    assert!(
        with <= 0.035 && with_max <= 0.1,
        "with second opinions the fit stays at {with:.4} (max {with_max:.3}) under the hand"
    );
}

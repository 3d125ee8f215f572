#![cfg(not(target_arch = "wasm32"))]
//! Enrolment without landmark files on webcam-dev (research data, read from ../shared, never
//! committed).
//!
//! **Split:** models are built from frames 0-599 only (every 5th frame searched: 120); tracking
//! is measured on the unseen frames 600-1336, every tracker started from the face finder's
//! landmarks on frame 600 (no landmark file used to start). Error = mean landmark distance /
//! outer-eye-corner distance against the dlib landmarks.
//!
//! Three models, each of 20 frames chosen by farthest-point sampling of the aligned shapes:
//! - *enrolled*: the enrolment finder's landmarks ([`EnrolFinder`]: the finder's points
//!   averaged with a pass on the mirrored image), what the page, `buildModel` without
//!   landmarks and `facemimic build --find-faces` do;
//! - *dlib*: the same searched frames with their dlib landmarks (the reference);
//! - *own convention* (an oracle): the enrolled landmarks with this person's own mean offset
//!   from dlib's points (over the 120 enrolment frames, in each face's frame) removed — what
//!   enrolment would give if the finder placed its points by dlib's convention on this face.
//!
//! Skips with a message when ../shared is absent; fails then if the CI variable is set.
//! `cargo test --release --test enrol_webcam -- --nocapture` prints the figures.

mod common;

use common::{frame, shared_data, varied};
use facemimic::find::{add_face_offsets, landmark_error, mean_face_offsets};
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

/// Mean error over `test`, resets, and the mean over frames 1200-1299 (the hand on the chin).
fn track(model: &Model, test: &[TrainingImage], init: &[f32]) -> (f32, u32, f32) {
    let mut t = Tracker::new(model, FitOptions::default()).unwrap();
    t.start_from_landmarks(init).unwrap();
    let errs: Vec<f32> = test
        .iter()
        .map(|f| {
            landmark_error(
                &t.track(&f.image.view().unwrap()).unwrap().landmarks,
                &f.landmarks,
            )
        })
        .collect();
    let hand = &errs[600..700];
    (
        errs.iter().sum::<f32>() / errs.len() as f32,
        t.resets(),
        hand.iter().sum::<f32>() / hand.len() as f32,
    )
}

struct Figures {
    found: usize,
    finder_error: f32,
    enrolled: (f32, u32, f32),
    dlib: (f32, u32, f32),
    own_convention: (f32, u32, f32),
}

fn measure() -> Option<Figures> {
    let dir = shared_data("webcam-dev")?;
    let mut finder = EnrolFinder::new(1).unwrap();
    let mut dlib = Vec::new();
    let mut found = Vec::new();
    for i in (0..600).step_by(5) {
        let f = frame(&dir, i);
        if let Some(face) = finder.find(&f.image.view().unwrap(), 0.0).unwrap() {
            let mut g = f.clone();
            g.landmarks = face.landmarks;
            found.push((f.landmarks.clone(), g));
        }
        dlib.push(f);
    }
    assert!(
        found.len() >= 100,
        "a face in only {} of 120 frames",
        found.len()
    );
    let finder_error = found
        .iter()
        .map(|(d, g)| landmark_error(&g.landmarks, d))
        .sum::<f32>()
        / found.len() as f32;
    let own = mean_face_offsets(
        found
            .iter()
            .map(|(d, g)| (g.landmarks.as_slice(), d.as_slice())),
    );
    let enrolled_frames: Vec<TrainingImage> = found.iter().map(|(_, g)| g.clone()).collect();
    let oracle_frames: Vec<TrainingImage> = enrolled_frames
        .iter()
        .map(|g| {
            let mut o = g.clone();
            assert!(add_face_offsets(&mut o.landmarks, &own));
            o
        })
        .collect();

    let test: Vec<TrainingImage> = (600..=1336).map(|i| frame(&dir, i)).collect();
    let init = finder
        .finder()
        .find(&test[0].image.view().unwrap())
        .first()
        .map(|f| f.landmarks.clone())
        .expect("a face in frame 600");
    let figures = Figures {
        found: found.len(),
        finder_error,
        enrolled: track(&build("enrolled", &enrolled_frames), &test, &init),
        dlib: track(&build("dlib20", &dlib), &test, &init),
        own_convention: track(&build("oracle", &oracle_frames), &test, &init),
    };
    let line = |(e, r, h): (f32, u32, f32)| format!("{e:.4} ({r} resets; 1200-1299: {h:.4})");
    println!(
        "webcam-dev, built from 0-599, tracked over 600-1336: finder found {}/120 faces \
         (error against dlib {:.4}); enrolled model {}; dlib model {}; own-convention oracle {}; \
         enrolled / dlib {:.2}, oracle / dlib {:.2}",
        figures.found,
        figures.finder_error,
        line(figures.enrolled),
        line(figures.dlib),
        line(figures.own_convention),
        figures.enrolled.0 / figures.dlib.0,
        figures.own_convention.0 / figures.dlib.0,
    );
    Some(figures)
}

/// What enrolment reaches today (about 15 s in release, a minute in the test profile):
/// - the absolute target: the enrolled model tracks the unseen frames at 0.03 or less;
/// - the enrolment itself (frame choice, building, tracking) loses little: with the finder's
///   landmarks on this person's own convention (the oracle) the model is within 1.3x of the
///   dlib model;
/// - a guard on the finder's calibration: the enrolled model within 2x of the dlib model (1.9x
///   today; 2.5x without the calibration).
///
/// The relative target (the enrolled model itself within 1.3x) is not met; see
/// [`enrolled_model_within_1_3x_of_dlib`].
#[test]
fn enrolled_model_tracks_unseen_frames() {
    let Some(f) = measure() else {
        return;
    };
    assert!(
        f.enrolled.0 <= 0.03,
        "the enrolled model tracks at {}, above 0.03",
        f.enrolled.0
    );
    assert!(
        f.own_convention.0 <= 1.3 * f.dlib.0,
        "with the finder on this person's own convention the model tracks at {}, more than \
         1.3x the dlib model's {}",
        f.own_convention.0,
        f.dlib.0
    );
    assert!(
        f.enrolled.0 <= 2.0 * f.dlib.0,
        "the enrolled model tracks at {}, more than 2x the dlib model's {}",
        f.enrolled.0,
        f.dlib.0
    );
}

/// The relative target: the enrolled model within 1.3x of the dlib model. It FAILS
/// (1.9x): the finder's points differ from dlib's by an offset of this person's own that no
/// calibration learned from other faces removes (docs/fitting.md, "Enrolment with the face
/// finder's landmarks"; docs/finding.md, "A learned correction does not transfer"). Kept,
/// opt-in, so the gap stays measured: `cargo test --release --test enrol_webcam -- --ignored
/// --nocapture`.
#[test]
#[ignore = "fails: the finder's per-person offset from dlib's convention (docs/fitting.md)"]
fn enrolled_model_within_1_3x_of_dlib() {
    let Some(f) = measure() else {
        return;
    };
    assert!(
        f.enrolled.0 <= 1.3 * f.dlib.0,
        "the enrolled model tracks at {}, more than 1.3x the dlib model's {}",
        f.enrolled.0,
        f.dlib.0
    );
}

#![cfg(not(target_arch = "wasm32"))]
//! Enrolment without landmark files on webcam-dev (research data, read from ../shared, never
//! committed): a model built from frames 0-599 with the enrolment finder's landmarks
//! ([`EnrolFinder`]: every 5th frame searched, the finder's points averaged with a pass on the
//! mirrored image, faces of any score kept, 20 varied ones chosen by farthest-point sampling of
//! the aligned shapes) against a model built from 20 frames of the same part chosen the same way
//! with the dlib landmarks; both tracked over the unseen frames 600-1336, started from the
//! finder's landmarks on frame 600 (no landmark file used to start). Error = mean landmark distance /
//! outer-eye-corner distance against the dlib landmarks.
//! Skips with a message when ../shared is absent; fails then if the CI variable is set.
//! `cargo test --release --test enrol_webcam -- --nocapture` prints the figures.

mod common;

use common::{frame, shared_data};
use facemimic::find::landmark_error;
use facemimic::fit::{FitOptions, Tracker};
use facemimic::{select_varied, BuildOptions, Builder, EnrolFinder, Model, TrainingImage};

fn build(name: &str, mut images: Vec<TrainingImage>) -> Model {
    let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
    let mut keep = select_varied(&shapes, 20).unwrap();
    keep.sort_unstable();
    let chosen: Vec<TrainingImage> = keep.iter().rev().map(|&i| images.swap_remove(i)).collect();
    Builder::new(BuildOptions {
        name: name.into(),
        ..BuildOptions::default()
    })
    .build(&chosen, None)
    .unwrap()
}

fn track(model: &Model, test: &[TrainingImage], init: &[f32]) -> (f32, u32) {
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
    (errs.iter().sum::<f32>() / errs.len() as f32, t.resets())
}

/// Long (about 30 s in release: 120 finder searches, two models tracked over 737 frames), so
/// opt-in: `cargo test --release --test enrol_webcam -- --ignored --nocapture`. It FAILS today:
/// its assertions pass (0.0238 against the dlib model's 0.0260), but only because the dlib
/// model of the farthest-point frames, at the builder's default 99% of the shape variance,
/// loses the chin under the hand; built at 98% it tracks at 0.0126 (1.89x). The finder's
/// points differ from dlib's by a per-person offset that the error against dlib counts
/// (docs/fitting.md, "Enrolment with the face finder's landmarks"). Kept so the gap is measured.
#[test]
#[ignore = "opt-in; the 1.3x target is met only against a weakened reference (docs/fitting.md)"]
fn finder_enrolled_model_tracks_unseen_frames() {
    let Some(dir) = shared_data("webcam-dev") else {
        return;
    };
    let mut finder = EnrolFinder::new(1).unwrap();
    let mut found = Vec::new();
    let mut dlib = Vec::new();
    let mut finder_err = Vec::new();
    let mut searched = 0;
    for i in (0..600).step_by(5) {
        let f = frame(&dir, i);
        searched += 1;
        if let Some(face) = finder.find(&f.image.view().unwrap(), 0.0).unwrap() {
            finder_err.push(landmark_error(&face.landmarks, &f.landmarks));
            let mut g = f.clone();
            g.landmarks = face.landmarks;
            found.push(g);
        }
        dlib.push(f);
    }
    let enrolled = build("enrolled", found.clone());
    let reference = build("dlib20", dlib);
    let test: Vec<TrainingImage> = (600..=1336).map(|i| frame(&dir, i)).collect();
    let init = finder
        .finder()
        .find(&test[0].image.view().unwrap())
        .first()
        .map(|f| f.landmarks.clone())
        .expect("a face in frame 600");
    let (e_enrolled, r1) = track(&enrolled, &test, &init);
    let (e_dlib, r2) = track(&reference, &test, &init);
    println!(
        "webcam-dev: faces found in {}/{searched} searched frames of 0-599 (finder error {:.4}); \
         tracking 600-1336 from the finder's frame-600 landmarks: finder-enrolled model {e_enrolled:.4} \
         ({r1} resets), dlib-20 model {e_dlib:.4} ({r2} resets), ratio {:.2}",
        found.len(),
        finder_err.iter().sum::<f32>() / finder_err.len().max(1) as f32,
        e_enrolled / e_dlib
    );
    assert!(found.len() >= 20, "only {} faces found", found.len());
    assert!(
        e_enrolled <= 1.3 * e_dlib,
        "the finder-enrolled model tracks at {e_enrolled}, more than 1.3x the dlib model's {e_dlib}"
    );
    assert!(
        e_enrolled <= 0.03,
        "the finder-enrolled model tracks at {e_enrolled}, above 0.03"
    );
}

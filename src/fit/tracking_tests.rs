//! The one tracking interface ([`FaceTracker`]) and its policy ([`tracker_for`]): both kinds
//! driven through `dyn FaceTracker` on the same GRID frames (spk07's unseen clip, which
//! `tests/data/tiny-v1.fmm` was built from), the calls that mean nothing for one kind answering
//! neutrally, bad input refused the same way, and the policy's choice.

use std::path::{Path, PathBuf};

use super::*;
use crate::io::read_training_image;
use crate::model::Model;
use crate::train::TrainingImage;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The tiny model: 6 frames of spk07's unseen clip, 68 landmarks.
fn tiny() -> Model {
    let bytes = std::fs::read(root().join("tests/data/tiny-v1.fmm")).unwrap();
    crate::format::read_model(&bytes).unwrap()
}

fn frame(i: usize) -> TrainingImage {
    let p: PathBuf = root().join(format!("data/grid/spk07_id2_vcd_swwp2s/{i:06}.jpg"));
    read_training_image(&p).unwrap()
}

/// Mean point distance over the outer-eye-corner distance.
fn error(a: &[f32], truth: &[f32]) -> f32 {
    let [ex, ey] = crate::landmarks::eye_line(truth).unwrap();
    let d: f32 = a
        .chunks_exact(2)
        .zip(truth.chunks_exact(2))
        .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
        .sum();
    d / (a.len() / 2) as f32 / ex.hypot(ey)
}

/// Both kinds, through `dyn FaceTracker`.
fn both(model: &Model) -> [Box<dyn FaceTracker>; 2] {
    [
        tracker_of_kind(model, TrackerKind::Aam).unwrap(),
        tracker_of_kind(model, TrackerKind::Landmarks).unwrap(),
    ]
}

#[test]
fn both_kinds_follow_the_same_frames_through_the_one_interface() {
    let model = tiny();
    let frames: Vec<TrainingImage> = (0..6).map(frame).collect();
    for mut t in both(&model) {
        let kind = t.kind();
        assert!(t.last().is_none(), "{kind}: a result before any frame");
        t.start_from_landmarks(&frames[0].landmarks).unwrap();
        for (i, f) in frames.iter().enumerate() {
            let view = f.image.view().unwrap();
            let r = t.track(&view, 1.0 / 25.0).unwrap();
            assert!(!r.lost, "{kind}: frame {i} lost");
            // One result layout, whatever the kind.
            assert_eq!(r.landmarks.len(), 136);
            assert_eq!(r.params.shape.len(), model.shape().n_modes());
            assert_eq!(r.params.appearance.len(), model.appearance().n_modes());
            let e = error(&r.landmarks, &f.landmarks);
            assert!(e < 0.1, "{kind}: frame {i} is {e} eye distances off");
        }
        let seq = t.sequence();
        assert_eq!((seq.frames(), seq.lost_count()), (6, 0), "{kind}");
        assert!(seq.anchor().is_some(), "{kind}: no anchor");
        assert!(t.last().is_some_and(|r| !r.lost));
        assert!(t.scale() > 0.0, "{kind}");
    }
}

#[test]
fn calls_that_mean_nothing_for_the_landmark_path_answer_neutrally() {
    let model = tiny();
    let [aam, mut lm] = both(&model);
    assert_eq!(
        (aam.kind(), lm.kind()),
        (TrackerKind::Aam, TrackerKind::Landmarks)
    );
    assert_eq!((lm.resets(), lm.rechecks()), (0, (0, 0)));
    assert_eq!(lm.scale(), 1.0);
    assert_eq!(lm.fit_scale(500.0, 640, 480, 0.0), 1.0);
    assert_eq!(
        aam.scale(),
        0.0,
        "the AAM's scale is decided on the first frame"
    );
    assert!(aam.fit_scale(500.0, 640, 480, 0.0) < 1.0);
    // Both take and keep the same policy.
    let p = TrackPolicy {
        recentre_tau: 0.5,
        ..TrackPolicy::default()
    };
    lm.set_policy(p.clone()).unwrap();
    assert_eq!(lm.policy().recentre_tau, 0.5);
    let bad = TrackPolicy {
        recentre_tau: f32::NAN,
        ..TrackPolicy::default()
    };
    assert!(lm.set_policy(bad).is_err());
    assert_eq!(lm.policy(), &p);
}

#[test]
fn bad_input_is_refused_alike_and_searches_want_faces() {
    let model = tiny();
    let f = frame(0);
    let view = f.image.view().unwrap();
    for mut t in both(&model) {
        let kind = t.kind();
        assert!(t.offer_faces(vec![vec![1.0; 10]]).is_err(), "{kind}");
        assert!(t.offer_faces(vec![vec![f32::NAN; 136]]).is_err(), "{kind}");
        assert!(
            t.start_from_landmarks(&f.landmarks[..10]).is_err(),
            "{kind}"
        );
        assert!(
            t.start_from_box(f32::NAN, 0.0, 50.0, 50.0).is_err(),
            "{kind}"
        );
        assert!(t.start_from_box(0.0, 0.0, 1.0, 1.0).is_err(), "{kind}");
        t.start_from_landmarks(&f.landmarks).unwrap();
        for dt in [f32::NAN, -1.0, f32::INFINITY] {
            assert!(t.track(&view, dt).is_err(), "{kind}: dt {dt}");
        }
        // A search with faces offered from elsewhere: wanted, then taken.
        t.expect_offers(true);
        t.start_searching();
        assert!(t.wants_faces(), "{kind}");
        t.offer_faces(vec![f.landmarks.clone()]).unwrap();
        assert!(!t.wants_faces(), "{kind}");
        let r = t.track(&view, 0.04).unwrap();
        assert!(!r.lost && r.reacquired, "{kind}");
        assert!(t.sequence().reacquisitions() >= 1, "{kind}");
        // A box start.
        t.start_from_box(110.0, 90.0, 140.0, 160.0).unwrap();
        assert!(!t.wants_faces(), "{kind}: a box to start from");
    }
}

#[test]
fn an_aam_tracker_needs_a_start_and_starts_auto_with_the_shipped_finder() {
    let model = tiny();
    let f = frame(2);
    let view = f.image.view().unwrap();
    let mut t = tracker_of_kind(&model, TrackerKind::Aam).unwrap();
    assert!(t.track(&view, 0.04).is_err(), "no start");
    t.start_auto().unwrap();
    let r = t.track(&view, 0.04).unwrap();
    assert!(!r.lost && r.reacquired);
    // The follower needs no start: it searches with its own finder.
    let mut l = tracker_of_kind(&model, TrackerKind::Landmarks).unwrap();
    let r = l.track(&view, 0.04).unwrap();
    assert!(!r.lost && r.reacquired);
    l.start_auto().unwrap();
    assert!(l.wants_faces());
}

#[test]
fn the_policy_fits_ones_own_model_and_follows_landmarks_for_anyone() {
    assert_eq!(TrackerKind::for_source(Whose::Own, 68), TrackerKind::Aam);
    assert_eq!(
        TrackerKind::for_source(Whose::Other, 68),
        TrackerKind::Landmarks
    );
    // A model the face finder's landmarks cannot drive: its AAM is the only way.
    assert_eq!(TrackerKind::for_source(Whose::Other, 5), TrackerKind::Aam);
    assert_eq!(TrackerKind::for_source(Whose::Own, 5), TrackerKind::Aam);
    for k in [TrackerKind::Aam, TrackerKind::Landmarks] {
        assert_eq!(TrackerKind::from_name(k.name()), Some(k));
        assert_eq!(k.to_string(), k.name());
    }
    assert_eq!(
        (TrackerKind::Aam.name(), TrackerKind::Landmarks.name()),
        ("aam", "landmarks")
    );
    assert_eq!(TrackerKind::from_name("AAM"), None);
    let model = tiny();
    assert_eq!(
        tracker_for(&model, Whose::Own).unwrap().kind(),
        TrackerKind::Aam
    );
    assert_eq!(
        tracker_for(&model, Whose::Other).unwrap().kind(),
        TrackerKind::Landmarks
    );
    assert_eq!(WORK_SIDE, 640);
}

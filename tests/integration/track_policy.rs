//! The tracking policy that every front end shares (`fit::Tracker`, `TrackPolicy`): the
//! resampling scale for a face of a given size, the appearance bounds of what the tracker
//! reports, and faces offered from elsewhere (a finder running on another thread).
//!
//! Model: spk07 built from its 20 training frames (`data/grid/spk07_pwij3p/train20.txt`);
//! tracked frames: spk07's unseen clip (`data/grid/spk07_id2_vcd_swwp2s`, no frame of it is in
//! the model) and another speaker (spk02) for the appearance bounds.

use facemimic::fit::FaceTracker;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use facemimic::find::landmark_error;
use facemimic::fit::{FitOptions, TrackPolicy, Tracker};
use facemimic::{io, Builder, Image, Model, TrainingImage};

fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn model() -> &'static Model {
    static M: OnceLock<Model> = OnceLock::new();
    M.get_or_init(|| {
        let paths = io::read_list(&repo("data/grid/spk07_pwij3p/train20.txt")).unwrap();
        let images: Vec<TrainingImage> = paths
            .iter()
            .map(|p| io::read_training_image(p).unwrap())
            .collect();
        Builder::default().build(&images, None).unwrap()
    })
}

fn frame(clip: &str, i: usize) -> TrainingImage {
    io::read_training_image(&repo(&format!("data/grid/{clip}/{i:06}.jpg"))).unwrap()
}

/// A black frame of an image's size.
fn black_like(img: &Image) -> Image {
    Image {
        width: img.width,
        height: img.height,
        data: vec![0; img.data.len()],
    }
}

const UNSEEN: &str = "spk07_id2_vcd_swwp2s";

/// Height of the model's mean face at its mean pose (pixels).
fn model_face_height(m: &Model) -> f32 {
    let mut s = vec![0.0; m.landmarks() * 2];
    m.image_shape(&m.base_params(), &mut s).unwrap();
    let ys: Vec<f32> = s.iter().skip(1).step_by(2).copied().collect();
    ys.iter().copied().fold(f32::MIN, f32::max) - ys.iter().copied().fold(f32::MAX, f32::min)
}

#[test]
fn fit_scale_brings_the_face_to_the_model_size_within_the_limits() {
    let t = Tracker::new(model(), FitOptions::default()).unwrap();
    let h = model_face_height(model());
    let p = TrackPolicy::default();
    // A face of about the model's size is fitted at the frame's own resolution.
    for f in [0.8, 1.0, 1.3] {
        assert_eq!(
            t.fit_scale(h * f, 640, 480, 0.0),
            1.0,
            "face {f} x the model's"
        );
    }
    // A face twice the model's size: the frame is halved; half its size: doubled (the most).
    assert!((t.fit_scale(2.0 * h, 640, 480, 0.0) - 0.5).abs() < 1e-5);
    assert!((t.fit_scale(0.5 * h, 640, 480, 0.0) - 2.0).abs() < 1e-5);
    assert_eq!(t.fit_scale(0.1 * h, 640, 480, 0.0), p.max_upscale);
    // The resampled frame stays within min_fit_side..=max_fit_side.
    let k = t.fit_scale(0.5 * h, 1000, 800, 0.0);
    assert!((k * 1000.0 - p.max_fit_side as f32).abs() < 1e-2, "{k}");
    let k = t.fit_scale(20.0 * h, 640, 480, 0.0);
    assert!((k * 640.0 - p.min_fit_side as f32).abs() < 1e-2, "{k}");
    // A frame larger than max_fit_side is resampled even for a face of the model's size.
    let k = t.fit_scale(h, 2560, 1440, 0.0);
    assert!((k - 0.5).abs() < 1e-5, "{k}");
    // Hysteresis: the scale in use is kept unless the wanted one differs by more than 30%.
    assert_eq!(t.fit_scale(2.2 * h, 640, 480, 0.5), 0.5);
    assert!((t.fit_scale(3.0 * h, 640, 480, 0.5) - 1.0 / 3.0).abs() < 1e-5);
    // Nonsense sizes keep the current scale (or 1).
    assert_eq!(t.fit_scale(f32::NAN, 640, 480, 0.7), 0.7);
    assert_eq!(t.fit_scale(-3.0, 640, 480, 0.0), 1.0);
    assert_eq!(t.fit_scale(h, 0, 0, 0.0), 1.0);
}

#[test]
fn the_policy_is_checked() {
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    // Each a field out of its range.
    let bad_fields: [fn(&mut TrackPolicy); 9] = [
        |p| p.appearance_limit = f32::NAN,
        |p| p.appearance_limit = -1.0,
        |p| p.min_fit_side = 2000,
        |p| p.max_upscale = 0.5,
        |p| p.native_band = 0.9,
        |p| p.rescale_change = f32::INFINITY,
        |p| p.recentre_tau = f32::NAN,
        |p| p.recentre_tau = -1.0,
        |p| p.recheck_frames = 100_001,
    ];
    for set in bad_fields {
        let mut bad = TrackPolicy::default();
        set(&mut bad);
        let e = t.set_policy(bad.clone()).unwrap_err().to_string();
        assert!(e.contains("tracking policy"), "{bad:?}: {e}");
    }
    assert_eq!(
        t.policy(),
        &TrackPolicy::default(),
        "a refused policy changed the tracker"
    );
    let p = TrackPolicy {
        appearance_limit: 0.0,
        ..TrackPolicy::default()
    };
    t.set_policy(p.clone()).unwrap();
    assert_eq!(t.policy(), &p);
}

#[test]
fn tracked_appearance_stays_within_the_limit_for_another_face() {
    // spk02 tracked with spk07's model: its appearance projects far outside spk07's space.
    let other = frame("spk02_brbk7n", 2);
    let sig = model().appearance().sigmas();
    let run = |limit: f32| {
        let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
        t.set_policy(TrackPolicy {
            appearance_limit: limit,
            ..TrackPolicy::default()
        })
        .unwrap();
        t.start_from_landmarks(&other.landmarks).unwrap();
        let r = t
            .track(
                &other.image.view().unwrap(),
                facemimic::fit::DEFAULT_TIME_STEP,
            )
            .unwrap()
            .clone();
        r.params
            .appearance
            .iter()
            .zip(&sig)
            .map(|(l, s)| (l / s).abs())
            .fold(0.0f32, f32::max)
    };
    // A limit the unclamped fit exceeds (2.6 sigma with the default fitter; 3 sigma is the
    // policy's default limit).
    const LIMIT: f32 = 2.0;
    let unclamped = run(0.0);
    let clamped = run(LIMIT);
    assert!(
        unclamped > LIMIT,
        "spk02 projects within {LIMIT} sigma of spk07 ({unclamped}): no test"
    );
    assert!(
        clamped <= LIMIT + 1e-4,
        "largest |lambda / sigma| {clamped} > {LIMIT}"
    );
}

#[test]
fn offered_faces_start_and_recover_a_sequence() {
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    let f0 = frame(UNSEEN, 0);
    // Nothing started: no faces wanted.
    assert!(!t.wants_faces());
    t.start_searching();
    assert!(t.wants_faces());
    // No face offered yet: the frame is lost (and no face is claimed).
    let r = t
        .track(&f0.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
        .unwrap();
    assert!(r.lost && !r.reacquired);
    assert!(t.wants_faces());
    // Bad offers are refused and keep nothing.
    assert!(t.offer_faces(vec![vec![1.0; 10]]).is_err());
    let mut nan = f0.landmarks.clone();
    nan[3] = f32::NAN;
    assert!(t.offer_faces(vec![nan]).is_err());
    assert!(t.wants_faces());
    // A face offered from a recent frame (frame 0's landmarks, shifted a little as a face
    // found a few frames earlier would be) starts the sequence on frame 2.
    let offered: Vec<f32> = f0
        .landmarks
        .chunks_exact(2)
        .flat_map(|p| [p[0] + 3.0, p[1] - 2.0])
        .collect();
    // A second face elsewhere in the picture: the most confident (first) is taken when there
    // is no last position.
    let elsewhere: Vec<f32> = f0.landmarks.iter().map(|v| v * 0.4).collect();
    t.offer_faces(vec![offered, elsewhere]).unwrap();
    assert!(!t.wants_faces());
    let f2 = frame(UNSEEN, 2);
    let r = t
        .track(&f2.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
        .unwrap()
        .clone();
    assert!(
        !r.lost && r.reacquired,
        "not acquired from the offered face"
    );
    let e = landmark_error(&r.landmarks, &f2.landmarks);
    assert!(e < 0.06, "acquired fit error {e}");
    assert!(!t.wants_faces());
    // A black frame: the face is lost, and faces are wanted again.
    let black = black_like(&f2.image);
    let r = t
        .track(&black.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
        .unwrap();
    assert!(r.lost, "a black frame was not lost");
    assert!(t.wants_faces());
    // The face is back and offered again: re-acquired at once, the one nearest the last good
    // position chosen among two.
    let f5 = frame(UNSEEN, 5);
    let far: Vec<f32> = f5
        .landmarks
        .iter()
        .enumerate()
        .map(|(i, v)| if i % 2 == 0 { v + 120.0 } else { *v })
        .collect();
    t.offer_faces(vec![far, f5.landmarks.clone()]).unwrap();
    let r = t
        .track(&f5.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
        .unwrap()
        .clone();
    assert!(
        !r.lost && r.reacquired,
        "not re-acquired from the offered faces"
    );
    assert!(landmark_error(&r.landmarks, &f5.landmarks) < 0.06);
    assert_eq!(t.sequence().reacquisitions(), 2);
    // Tracking then goes on from the fit, with no faces wanted.
    let f6 = frame(UNSEEN, 6);
    let r = t
        .track(&f6.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
        .unwrap();
    assert!(!r.lost && !r.reacquired);
    assert!(!t.wants_faces());
}

#[test]
fn a_tracked_face_asks_for_a_second_opinion_every_recheck_frames() {
    // Tracked from frame 0's landmarks with offers expected: no faces are wanted until
    // `recheck_frames` good frames have passed; then the faces offered give a second opinion
    // (a cold fit from the one nearest the tracked face, kept when it fits lower), and the
    // count starts again. A face offered elsewhere in the picture is not used; with
    // `recheck_frames` 0 no faces are ever wanted while the face is tracked.
    let every = TrackPolicy::default().recheck_frames as usize;
    assert!(every > 1);
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    let f0 = frame(UNSEEN, 0);
    t.start_from_landmarks(&f0.landmarks).unwrap();
    t.expect_offers(true);
    let mut wanted_at = Vec::new();
    for i in 0..=2 * every {
        let f = frame(UNSEEN, i);
        if t.wants_faces() {
            wanted_at.push(i);
            // The face as a finder would give it: this frame's landmarks, a little off.
            let found: Vec<f32> = f.landmarks.iter().map(|v| v + 1.5).collect();
            let elsewhere: Vec<f32> = f.landmarks.iter().map(|v| v * 0.3).collect();
            t.offer_faces(vec![elsewhere, found]).unwrap();
            assert!(!t.wants_faces());
        }
        let r = t
            .track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap();
        assert!(!r.lost, "frame {i} lost");
        let e = landmark_error(&r.landmarks, &f.landmarks);
        assert!(e < 0.06, "frame {i}: error {e}");
    }
    assert_eq!(wanted_at, vec![every, 2 * every], "when faces were wanted");
    let (taken, kept) = t.rechecks();
    assert_eq!(taken, 2, "second opinions taken");
    assert!(kept <= taken);
    // Only a face elsewhere: no second opinion (the count starts again all the same).
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    t.start_from_landmarks(&f0.landmarks).unwrap();
    t.expect_offers(true);
    for i in 0..=every {
        let f = frame(UNSEEN, i);
        if t.wants_faces() {
            let elsewhere: Vec<f32> = f.landmarks.iter().map(|v| v * 0.3).collect();
            t.offer_faces(vec![elsewhere]).unwrap();
        }
        t.track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap();
    }
    assert_eq!(
        t.rechecks(),
        (0, 0),
        "a face elsewhere gave a second opinion"
    );
    assert!(!t.wants_faces());
    // Off.
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    t.set_policy(TrackPolicy {
        recheck_frames: 0,
        ..TrackPolicy::default()
    })
    .unwrap();
    t.start_from_landmarks(&f0.landmarks).unwrap();
    t.expect_offers(true);
    for i in 0..=every {
        t.track(
            &frame(UNSEEN, i).image.view().unwrap(),
            facemimic::fit::DEFAULT_TIME_STEP,
        )
        .unwrap();
        assert!(!t.wants_faces(), "faces wanted with second opinions off");
    }
}

#[test]
fn offers_can_be_expected_in_a_sequence_started_from_landmarks() {
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    let f0 = frame(UNSEEN, 0);
    t.start_from_landmarks(&f0.landmarks).unwrap();
    t.expect_offers(true);
    assert!(
        !t.track(&f0.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap()
            .lost
    );
    assert!(!t.wants_faces());
    let black = black_like(&f0.image);
    assert!(
        t.track(&black.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap()
            .lost
    );
    assert!(
        t.wants_faces(),
        "a lost face with offers expected wants faces"
    );
    // Without offers expected a lost face wants none (nobody would offer them).
    t.expect_offers(false);
    assert!(!t.wants_faces());
}

#[test]
fn an_offered_face_on_a_frame_without_one_is_not_acquired() {
    // The page's auto-start: faces found by a finder are only a start; the tracker's own checks
    // (fit error, image contrast under the mesh, shape plausibility) decide. A face offered on
    // a black frame or on a flat grey one (a finder's false face) is not acquired.
    let f0 = frame(UNSEEN, 0);
    let grey = Image {
        width: f0.image.width,
        height: f0.image.height,
        data: vec![128; f0.image.data.len()],
    };
    for (what, img) in [("black", black_like(&f0.image)), ("grey", grey)] {
        let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
        t.start_searching();
        t.offer_faces(vec![f0.landmarks.clone()]).unwrap();
        let r = t
            .track(&img.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap();
        assert!(
            r.lost && !r.reacquired,
            "a face was acquired on a {what} frame"
        );
        assert!(t.wants_faces(), "no more faces wanted after a {what} frame");
        assert_eq!(t.sequence().reacquisitions(), 0);
    }
}

/// While a lost face waits for offered faces (the page's finder worker searching), a frame costs
/// one ordinary fit from the last good fit, not the harder retry: no re-initialisation is
/// counted on those frames; the first lost frame still retries; the face coming back where it
/// was is tracked again without any offer.
#[test]
fn a_lost_face_awaiting_offers_is_refitted_without_retries() {
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    let f0 = frame(UNSEEN, 0);
    t.start_from_landmarks(&f0.landmarks).unwrap();
    t.expect_offers(true);
    assert!(
        !t.track(&f0.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap()
            .lost
    );
    let black = black_like(&f0.image);
    let resets = t.resets();
    assert!(
        t.track(&black.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap()
            .lost
    );
    assert_eq!(t.resets(), resets + 1, "the first lost frame retries");
    for _ in 0..5 {
        assert!(
            t.track(&black.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                .unwrap()
                .lost
        );
        assert!(t.wants_faces());
    }
    assert_eq!(
        t.resets(),
        resets + 1,
        "frames lost while offers are awaited were retried"
    );
    // The face is back where it was, nothing offered: tracked again at once.
    let f1 = frame(UNSEEN, 1);
    let r = t
        .track(&f1.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
        .unwrap()
        .clone();
    assert!(!r.lost, "the face back in place was not tracked again");
    assert!(landmark_error(&r.landmarks, &f1.landmarks) < 0.06);
    assert!(!t.wants_faces());
    // Without offers expected, a lost face is retried on every frame (as before).
    let mut t = Tracker::new(model(), FitOptions::default()).unwrap();
    t.start_from_landmarks(&f0.landmarks).unwrap();
    assert!(
        !t.track(&f0.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap()
            .lost
    );
    for _ in 0..3 {
        assert!(
            t.track(&black.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                .unwrap()
                .lost
        );
    }
    assert_eq!(t.resets(), 3);
}

/// `img` enlarged `n` times (nearest: each pixel an `n x n` block), its landmarks mapped in
/// the crate's convention (`(v + 0.5) n - 0.5`).
fn enlarged(img: &Image, landmarks: &[f32], n: u32) -> (Image, Vec<f32>) {
    let (w, h) = (img.width * n, img.height * n);
    let mut data = vec![0u8; (w * h * 4) as usize];
    for y in 0..h {
        for x in 0..w {
            let s = (((y / n) * img.width + x / n) * 4) as usize;
            let d = ((y * w + x) * 4) as usize;
            data[d..d + 4].copy_from_slice(&img.data[s..s + 4]);
        }
    }
    let lm = landmarks
        .iter()
        .map(|v| (v + 0.5) * n as f32 - 0.5)
        .collect();
    (
        Image {
            width: w,
            height: h,
            data,
        },
        lm,
    )
}

#[test]
fn frames_go_in_at_their_size_and_the_track_comes_back_in_their_pixels() {
    // spk07's unseen clip enlarged 3x: the tracker chooses to fit a copy resampled to about
    // the model's size, and reports in the large frames' pixels; the track matches the track of
    // the original frames mapped to the large ones, and the placement (the pose re-centred on
    // the model's mean pose about a fixed anchor) is the same for both.
    let fixed = TrackPolicy {
        recentre_tau: 0.0,
        ..TrackPolicy::default()
    };
    let mut small = Tracker::new(model(), FitOptions::default()).unwrap();
    let mut large = Tracker::new(model(), FitOptions::default()).unwrap();
    small.set_policy(fixed.clone()).unwrap();
    large.set_policy(fixed).unwrap();
    let f0 = frame(UNSEEN, 0);
    small.start_from_landmarks(&f0.landmarks).unwrap();
    let (_, lm3) = enlarged(&f0.image, &f0.landmarks, 3);
    large.start_from_landmarks(&lm3).unwrap();
    assert_eq!(large.scale(), 0.0, "the scale is chosen on the first frame");
    for i in 0..8 {
        let f = frame(UNSEEN, i);
        let (big, truth3) = enlarged(&f.image, &f.landmarks, 3);
        let s = small.track(&f.image.view().unwrap(), 0.04).unwrap().clone();
        let b = large.track(&big.view().unwrap(), 0.04).unwrap().clone();
        assert!(!s.lost && !b.lost, "frame {i} lost");
        let e = landmark_error(&b.landmarks, &truth3);
        assert!(e < 0.06, "frame {i}: large-frame error {e}");
        let (sp, bp) = (small.sequence().placed(), large.sequence().placed());
        // The placement is about the anchor, so the frame's size does not show in it.
        assert!(
            (sp.scale() / bp.scale() - 1.0).abs() < 0.03
                && (sp.rotation() - bp.rotation()).abs() < 0.03,
            "frame {i}: placed {sp:?} vs {bp:?}"
        );
        // The pose maps shapes into the large frame: its landmarks follow from it.
        let pose = b.params.pose;
        assert!(
            (pose.scale() / s.params.pose.scale() - 3.0).abs() < 0.2,
            "frame {i}: {pose:?}"
        );
    }
    assert!(
        (0.25..0.45).contains(&large.scale()),
        "fit scale {} (about a third expected)",
        large.scale()
    );
    assert_eq!(small.scale(), 1.0);
    assert_eq!(
        (large.sequence().frames(), large.sequence().lost_count()),
        (8, 0)
    );
    // The fixed anchor is the first pose: a bad time step is refused.
    assert!(large.sequence().anchor().is_some());
    assert!(large
        .track(&frame(UNSEEN, 8).image.view().unwrap(), f32::NAN)
        .is_err());
}

//! The person-independent path (issue 20, item 6): [`Follower`] follows anyone with a bundled
//! person's model, before they have one of their own.
//!
//! On the committed GRID frames (always run): a clip followed with another speaker's model,
//! a blank frame lost and the face recovered, bad input refused.
//!
//! On webcam-dev (research data read from ../shared, never committed). **Split:** the source
//! model is spk07's, built from GRID (`data/grid/spk07_pwij3p/train20.txt`, as
//! `scripts/build-models.sh` builds `www/models/spk07.fmm`), so no webcam-dev frame is in it;
//! the follower's options were chosen on webcam-dev frames 0-599 only
//! (`cargo run --release --example follow_tune`); the figures are measured on the unseen frames
//! 600-1336 (737 frames), the follower started with no landmarks on frame 600. The follower's
//! closed-mouth start and head-turn split (`close_mouth`, `split_head_turn`) were added after
//! franck-dev2's first seconds showed the cloned mouth shut while the person laughed with the
//! head turned; they have no tuned constant, and on the frames not measured (franck-dev 0-999,
//! webcam-dev 0-599) they move the cloned mouth's correlation by -0.006 and +0.008
//! (`examples/mouth_probe.rs`). Measured:
//! 1. the followed landmarks against dlib's: mean error (mean landmark distance / outer eye
//!    corner distance) judged **convention-free** (each point's mean offset from dlib's point
//!    over the 737 frames, in the face frame with the eye line horizontal and unit eye
//!    distance, removed before scoring: [`convention_free_errors`]), raw printed beside it;
//!    aim 0.04 or less;
//! 2. frames over 0.1 (convention-free): no more than the face finder's own (`find` on each
//!    frame alone, scored the same way);
//! 3. the cloned target's mouth opening (spk02 by the `map` method: the mean distance of the
//!    inner lips' three upper and three lower points, over its outer-eye-corner distance)
//!    against the person's (dlib's points, the same measure): Pearson correlation, aim 0.8 or
//!    more; measured on franck-dev2 (frames 3800-4799, none in any training list), whose
//!    mouth moves; webcam-dev 600-1336 has almost no mouth movement to correlate with.
//!
//! Skips with a message when ../shared is absent; fails then if the CI variable is set.
//! `cargo test --release --test integration follow:: -- --nocapture` prints the figures.

use facemimic::fit::FaceTracker;
use facemimic_testkit as common;

use common::following::{errors, follow, mean, over, pearson, spk07};
use common::{frame, repo, shared_data};
use facemimic::find::landmark_error;
use facemimic::fit::{mouth_opening, FollowOptions, Follower};
use facemimic::{io, FaceFinder, TrainingImage};

/// The figures of one clip followed with spk07's model.
struct Figures {
    frames: usize,
    /// Followed landmarks: convention-free and raw errors per frame.
    free: Vec<f32>,
    raw: Vec<f32>,
    /// The finder's own (`find` on each frame alone).
    finder_free: Vec<f32>,
    /// Pearson correlation of spk02's cloned mouth opening with the person's (dlib's).
    r_mouth: f32,
    /// The follower's observed displacement (on spk07's base shape): its mouth width's and
    /// lip-corner lift's correlation with the person's (dlib's points; Pearson).
    displaced_r: [f32; 2],
    /// The same displacement's mouth width's and lift's spread (p95 - p5) over the person's.
    displaced_spread: [f32; 2],
    lost: u32,
}

/// Follows frames `range` of `clip` with spk07's model (the follower started with no
/// landmarks on the first), and measures the finder's own points on the same frames.
fn measure(clip: &str, range: std::ops::RangeInclusive<usize>) -> Option<Figures> {
    let dir = shared_data(clip)?;
    let source = spk07();
    let frames: Vec<TrainingImage> = range.clone().map(|i| frame(&dir, i)).collect();
    let n = frames.len();
    let followed = follow(&source, &frames, FollowOptions::default());
    let (free, raw) = errors(&followed.landmarks, &frames);

    // The finder's own points, each frame on its own (a frame with no face keeps the last).
    let mut finder = FaceFinder::new().unwrap();
    let mut last = frames[0].landmarks.clone();
    let mut missed = 0;
    let found: Vec<Vec<f32>> = frames
        .iter()
        .map(|t| {
            match finder.find(&t.image.view().unwrap()).into_iter().next() {
                Some(face) => last = face.landmarks,
                None => missed += 1,
            }
            last.clone()
        })
        .collect();
    let (finder_free, finder_raw) = errors(&found, &frames);

    let person_mouth: Vec<f32> = frames.iter().map(|t| mouth_opening(&t.landmarks)).collect();
    let r_mouth = pearson(&followed.target_mouth, &person_mouth);
    // The same through the finder's own points, unsmoothed (the person's mouth as the finder
    // sees it): what the mapping could reach at best.
    let finder_mouth: Vec<f32> = found.iter().map(|p| mouth_opening(p)).collect();
    let r_finder_mouth = pearson(&finder_mouth, &person_mouth);
    let spread = {
        let m = mean(&person_mouth);
        (person_mouth.iter().map(|v| (v - m).powi(2)).sum::<f32>() / n as f32).sqrt()
    };
    let real_mouth: Vec<[f32; 2]> = frames
        .iter()
        .map(|t| common::following::mouth_features(&t.landmarks))
        .collect();
    let displaced_spread = [0, 1].map(|k| {
        let of = |v: &[[f32; 2]]| common::following::spread(v.iter().map(|m| m[k]).collect());
        of(&followed.displaced_mouth) / of(&real_mouth)
    });
    let displaced_r = [0, 1].map(|k| {
        let of = |v: &[[f32; 2]]| v.iter().map(|m| m[k]).collect::<Vec<f32>>();
        pearson(&of(&followed.displaced_mouth), &of(&real_mouth))
    });
    let worst = (0..n).max_by(|&a, &b| free[a].total_cmp(&free[b])).unwrap();
    println!(
        "{clip} {range:?} ({n} frames), source spk07 (GRID), target spk02 (map):\n  \
         followed landmarks: convention-free {:.4} ({} frames over 0.1, worst {:.4} on frame \
         {}), raw {:.4} ({} over 0.1); {} lost, {} acquisitions; {:.2} ms a frame (release, \
         this machine)\n  \
         the finder's own (find on each frame): convention-free {:.4} ({} over 0.1), raw {:.4} \
         ({} over 0.1), {missed} frames without a face\n  \
         mouth opening, spk02 cloned against the person's (dlib): Pearson {r_mouth:.3} (the \
         finder's own points against dlib's: {r_finder_mouth:.3}; the person's opening: mean \
         {:.4}, sd {spread:.4} of the eye distance)\n  \
         the observed displacement's mouth against the person's (spread, p95 - p5; Pearson): \
         width {:.2}, {:.3}; lip-corner lift {:.2}, {:.3}",
        mean(&free),
        over(&free),
        free[worst],
        range.start() + worst,
        mean(&raw),
        over(&raw),
        followed.lost,
        followed.reacquisitions,
        followed.ms_per_frame,
        mean(&finder_free),
        over(&finder_free),
        mean(&finder_raw),
        over(&finder_raw),
        mean(&person_mouth),
        displaced_spread[0],
        displaced_r[0],
        displaced_spread[1],
        displaced_r[1],
    );
    Some(Figures {
        frames: n,
        free,
        raw,
        finder_free,
        r_mouth,
        displaced_r,
        displaced_spread,
        lost: followed.lost,
    })
}

/// Measures `range` of the shared `clip` (skipped when absent): the landmark aims
/// (`check_landmarks`), and, given `mouth = Some((min, measured))`, the cloned mouth opening
/// correlating with the person's at `min` or more (`measured`: what was measured, for the
/// message). The figures, or `None` when the clip is absent.
fn check_clip(
    clip: &str,
    range: std::ops::RangeInclusive<usize>,
    mouth: Option<(f32, &str)>,
) -> Option<Figures> {
    let f = measure(clip, range)?;
    check_landmarks(clip, &f);
    if let Some((min_mouth, measured)) = mouth {
        assert!(
            f.r_mouth >= min_mouth,
            "{clip}: the cloned mouth opening correlates with the person's at {:.3}, below \
             {min_mouth} ({measured})",
            f.r_mouth
        );
    }
    Some(f)
}

/// The landmark aims: followed landmarks within 0.04 of dlib's (convention-free), no more
/// frames over 0.1 than the finder's own, the face never lost.
fn check_landmarks(clip: &str, f: &Figures) {
    assert!(
        mean(&f.free) <= 0.04,
        "{clip}: followed landmarks at {:.4} of the eye distance (convention-free; raw {:.4}), \
         above 0.04",
        mean(&f.free),
        mean(&f.raw)
    );
    assert!(
        over(&f.free) <= over(&f.finder_free),
        "{clip}: {} followed frames over 0.1, more than the finder's own {} (of {})",
        over(&f.free),
        over(&f.finder_free),
        f.frames
    );
    assert_eq!(f.lost, 0, "{clip}: the face was lost");
}

/// webcam-dev frames 600-1336 followed with spk07's model: the landmark aims (met:
/// 0.0150 convention-free, raw 0.0280; 0 frames over 0.1, as the finder). The mouth aim is
/// not measurable on these frames, and not asserted: the man hardly opens his mouth after
/// frame 600 (dlib's inner-lip opening has a standard deviation of 0.006 of the eye distance,
/// half a pixel, and the finder's own points correlate with dlib's at 0.26 on it); the cloned
/// mouth's correlation is printed (-0.19 measured, 0.14 without the head-turn split: noise
/// either way). The mouth is measured on franck-dev2.
#[test]
fn follows_webcam_dev_with_spk07_as_the_source() {
    let _ = check_clip("webcam-dev", 600..=1336, None);
}

/// franck-dev2 (frames 3800-4799, never in any training list; spk07's model is GRID's): the
/// same landmark aims (met: 0.0216 convention-free, raw 0.0329; 0 frames over 0.1), and the
/// mouth, which moves here (speech, smiles, laughs, head turns): the cloned opening
/// correlates with dlib's at 0.95 (29 Nov, the neutral held within a mouth at rest; 0.92
/// before; 0.86 earlier; the aim is 0.8; 0.79 before the follower started the
/// person's neutral with a closed mouth and split head turns off the expression; the clip
/// starts on a laugh). Asserted at 0.8. And the lip corners' lift in what the expressive
/// method clones, the observed displacement: it correlates with the person's at 0.954 (0.935
/// while the frame's pose was fitted on all 68 points, which a laugh's jaw and mouth pull),
/// asserted at 0.945; and its spread (p95 - p5) over the person's, 0.67 since the finder's
/// local correction has a coarse first stage for the mouth (0.57 with its two finer stages
/// alone), asserted at 0.63.
#[test]
fn follows_franck_dev2_with_spk07_as_the_source() {
    let Some(f) = check_clip(
        "franck-dev2",
        3800..=4799,
        Some((0.8, "0.954 measured; the issue's aim is 0.8")),
    ) else {
        return;
    };
    assert!(
        f.displaced_r[1] >= 0.945,
        "the observed displacement's lift correlates with the person's at {:.3}, under 0.945",
        f.displaced_r[1]
    );
    assert!(
        f.displaced_spread[1] >= 0.63,
        "the observed displacement's lift spreads {:.2} of the person's, under 0.63",
        f.displaced_spread[1]
    );
}

/// On the committed GRID frames: spk03's clip followed with spk07's model (another person's),
/// every frame a face, close to dlib's points; a blank frame is lost and the face recovered;
/// bad input refused.
#[test]
fn follows_another_speaker_and_recovers_after_a_blank_frame() {
    let source = spk07();
    let dir = repo("data/grid/spk03_lbax4n");
    let frames: Vec<TrainingImage> = io::annotated_images(&dir)
        .unwrap()
        .iter()
        .take(30)
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let mut f = Follower::new(&source, FollowOptions::default()).unwrap();
    let blank = vec![128u8; 360 * 288 * 4];
    let blank = facemimic::ImageRef::new(360, 288, &blank).unwrap();
    for (i, t) in frames.iter().enumerate() {
        let view = t.image.view().unwrap();
        if i == 15 {
            let r = f.track(&blank, 0.04).unwrap();
            assert!(r.lost, "a blank frame is no face");
            assert!(f.wants_faces());
        }
        let r = f.track(&view, 0.04).unwrap();
        assert!(!r.lost, "frame {i} lost");
        assert_eq!(r.reacquired, i == 0 || i == 15, "frame {i}");
        assert_eq!(r.params.shape.len(), source.shape().n_modes());
        assert!(r.params.appearance.iter().all(|&v| v == 0.0));
        let e = landmark_error(&r.landmarks, &t.landmarks);
        assert!(e < 0.08, "frame {i}: {e} from dlib's points");
        // The pose places the model's face on the person's.
        let mut posed = vec![0.0; 136];
        source.image_shape(&r.params, &mut posed).unwrap();
        assert!(landmark_error(&posed, &t.landmarks) < 0.25);
    }
    assert_eq!(f.sequence().lost_count(), 1);
    assert_eq!(f.sequence().reacquisitions(), 2);
    assert!(f.neutral().is_some());
    // Bad input: a clear error, no result changed.
    for dt in [f32::NAN, -1.0, f32::INFINITY] {
        assert!(f.track(&frames[0].image.view().unwrap(), dt).is_err());
    }
    let bad = FollowOptions {
        beta: f32::NAN,
        ..FollowOptions::default()
    };
    assert!(Follower::new(&source, bad).is_err());
    assert!(f.set_options(bad).is_err());
    assert!(f.offer_faces(vec![vec![f32::NAN; 136]]).is_err());
    assert!(f.offer_faces(vec![vec![1.0; 10]]).is_err());
    // Faces offered instead of a search.
    f.start_searching();
    f.expect_offers(true);
    let view = frames[3].image.view().unwrap();
    assert!(
        f.track(&view, 0.04).unwrap().lost,
        "no search, nothing offered"
    );
    f.offer_faces(vec![frames[3].landmarks.clone()]).unwrap();
    let r = f.track(&view, 0.04).unwrap();
    assert!(!r.lost && r.reacquired);
}

/// The bounds of a mouth at rest that a tracked person's neutral is held within
/// ([`REST_MOUTH_WIDTH`], [`REST_CORNER_LIFT`], `fit::bound_neutral_mouth`) are learned again
/// from the committed London landmarks (`data/london`, CC BY 4.0, 60 people's neutral and
/// smiling photos, dlib's points): for the mouth's width and its corners' lift, where a face is
/// as likely smiling as at rest, the two as normal distributions. Most smiles are wider than
/// the bound (a neutral that wide is held, its lift too), and few faces at rest.
#[test]
fn the_bounds_of_a_mouth_at_rest_are_learned_from_the_london_set() {
    use facemimic::fit::{mouth_shape, rest_boundary, REST_CORNER_LIFT, REST_MOUTH_WIDTH};
    // The London pairs as the expression prior reads them (`io::expression_sets`).
    let (pairs, _) = facemimic::io::expression_sets(&repo("data"), &[]).unwrap();
    let shapes = |k: usize| -> Vec<[f32; 2]> {
        pairs
            .iter()
            .map(|p| mouth_shape(if k == 0 { &p.0 } else { &p.1 }).unwrap())
            .collect()
    };
    let (rest, smiles) = (shapes(0), shapes(1));
    assert_eq!((rest.len(), smiles.len()), (60, 60));
    let normal = |v: &[[f32; 2]], k: usize| {
        let n = v.len() as f32;
        let m = v.iter().map(|x| x[k]).sum::<f32>() / n;
        let s = (v.iter().map(|x| (x[k] - m).powi(2)).sum::<f32>() / n).sqrt();
        (m, s)
    };
    for (k, name, bound) in [
        (0, "width", REST_MOUTH_WIDTH),
        (1, "lift", REST_CORNER_LIFT),
    ] {
        let learned = rest_boundary(normal(&rest, k), normal(&smiles, k)).unwrap();
        eprintln!(
            "  mouth {name}: at rest {:?}, smiling {:?}, boundary {learned:.4} (the constant {bound})",
            normal(&rest, k),
            normal(&smiles, k)
        );
        assert!(
            (learned - bound).abs() <= 1e-4,
            "mouth {name}: the London set gives {learned}, the constant is {bound}"
        );
    }
    // A neutral is held only when its mouth is wider than at rest (its lift then too).
    let held = |v: &[[f32; 2]]| v.iter().filter(|x| x[0] > REST_MOUTH_WIDTH).count();
    let (r, s) = (held(&rest), held(&smiles));
    eprintln!("  wider than at rest: {r} of 60 faces at rest, {s} of 60 smiles");
    assert!(r <= 8 && s >= 40, "{r} faces at rest, {s} smiles held");
}

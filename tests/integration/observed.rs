//! Anyone without a model: the face a landmark follower observes (`fit::ObservedAppearance`,
//! `FaceTracker::observed`) drives the expressive method (`Cloner::set_observed`): the parts'
//! contracts, bad input, the Stage's path, and the measure of docs/cloning.md ("Anyone,
//! without a model") on franck-dev2 (skipped visibly without `../shared`, failing under
//! `CI=1`).
//!
//! Models: spk07 (the source, as the page's follower uses it) and GRID targets from their
//! committed `train20.txt` frames. Nothing is built from franck; the follower's rest threshold
//! (`fit::NEUTRAL_MAX_MOVE`) was set on franck-dev, and franck-dev2 (frames 3800-4799) is only
//! measured.

use facemimic_testkit as common;

use facemimic::clone::{luma, CloneOptions, Cloner};
use facemimic::fit::{FaceTracker, FollowOptions, Follower, Observed, ObservedAppearance};
use facemimic::{io, sample_rgb, Model, Stage, TrainingImage};

use super::expression::{spk07, target};

/// A cloner of `source` onto the page's four default GRID targets.
fn onto_default_targets(source: &Model) -> Cloner {
    let mut cloner = Cloner::new(source.clone()).unwrap();
    for name in ["spk02", "spk03", "spk06", "spk10"] {
        cloner.add_target(target(name).clone()).unwrap();
    }
    cloner
}

/// spk07's unseen clip's frames with the most closed and the most open mouth.
fn closed_and_open() -> (TrainingImage, TrainingImage) {
    let dir = common::repo("data/grid/spk07_id2_vcd_swwp2s");
    let mut frames: Vec<(f32, TrainingImage)> = common::clip_frames(&dir)
        .iter()
        .map(|p| {
            let t = io::read_training_image(p).unwrap();
            (facemimic::fit::mouth_opening(&t.landmarks), t)
        })
        .collect();
    frames.sort_by(|a, b| a.0.total_cmp(&b.0));
    let open = frames.pop().unwrap().1;
    (frames.swap_remove(0).1, open)
}

/// `t` sampled into spk07's reference frame at its landmarks.
fn sampled(t: &TrainingImage) -> Vec<f32> {
    let mut out = vec![0.0; spk07().appearance().len()];
    sample_rgb(
        spk07().frame(),
        &t.image.view().unwrap(),
        &t.landmarks,
        &mut out,
    )
    .unwrap();
    out
}

/// The whole displacement from `rest`'s shape to `now`'s, in spk07's coordinates.
fn displacement(rest: &TrainingImage, now: &TrainingImage) -> Vec<f32> {
    let base = &spk07().shape().base;
    let align = |t: &TrainingImage| {
        let mut out = vec![0.0; base.len()];
        facemimic::Similarity::align(&t.landmarks, base).apply(&t.landmarks, &mut out);
        out
    };
    let (a, b) = (align(rest), align(now));
    b.iter().zip(&a).map(|(x, y)| x - y).collect()
}

/// A cloner of spk07 onto spk02 given a face at rest: `look` as both the frame's and the
/// neutral appearance, the displacement `d` and the head's `turn` beside it.
fn at_rest_onto_spk02(look: &[f32], d: &[f32], turn: Option<&[f32]>) -> Cloner {
    let mut c = Cloner::new(spk07().clone()).unwrap();
    c.add_target(target("spk02").clone()).unwrap();
    c.set_observed(Some(Observed {
        appearance: look,
        neutral: look,
        displacement: Some(d),
        turn,
    }))
    .unwrap();
    c
}

#[test]
fn an_observed_face_at_rest_gives_the_target_itself_exactly() {
    let (closed, _) = closed_and_open();
    let x = sampled(&closed);
    let zero = vec![0.0; spk07().shape().base.len()];
    let mut c = at_rest_onto_spk02(&x, &zero, None);
    assert!(c.has_observed());
    c.clone_frame(&spk07().base_params(), &CloneOptions::default())
        .unwrap();
    // The ratio of a face to itself is exactly 1: the target's own appearance, bit for bit.
    assert_eq!(c.target_appearance(0), target("spk02").appearance().base());
    let mut posed = target("spk02").shape().base.clone();
    target("spk02").home_pose().apply_in_place(&mut posed);
    for (a, b) in c.target_shape(0).iter().zip(&posed) {
        assert!((a - b).abs() < 1e-3, "{a} vs {b}");
    }
}

/// The AAM tracker's observed displacement is measured from the person's neutral shape, not
/// from the model's mean: spk07's model (from `spk07_pwij3p/train20.txt`, speech) has parted
/// lips on average, so on the unseen clip `spk07_id2_vcd_swwp2s`, at its most closed mouth
/// (dlib's points, after the first ten frames), `S p` reads the lips closing from the mean
/// while the displacement reads them near the neutral (its inner-lip opening under half of
/// `S p`'s). The turn comes beside it.
#[test]
fn the_aam_trackers_displacement_is_measured_from_the_persons_neutral() {
    use facemimic::fit::{FitOptions, Tracker};
    let model = spk07();
    let dir = common::repo("data/grid/spk07_id2_vcd_swwp2s");
    let frames: Vec<TrainingImage> = common::clip_frames(&dir)
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let mut t = Tracker::new(model, FitOptions::default()).unwrap();
    t.start_from_landmarks(&frames[0].landmarks).unwrap();
    // The inner lips' opening change of a displacement (lower lip down minus upper lip down).
    let opening = |d: &[f32]| {
        [(61, 67), (62, 66), (63, 65)]
            .iter()
            .map(|&(u, l)| d[2 * l + 1] - d[2 * u + 1])
            .sum::<f32>()
            / 3.0
    };
    let n = model.shape().base.len();
    let mut at_closed = None;
    let mut closed = f32::INFINITY;
    for (i, f) in frames.iter().enumerate() {
        let r = t
            .track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
            .unwrap()
            .clone();
        let o = t.observed().expect("a 68-landmark model observes the face");
        let d = o.displacement.expect("the tracker's whole displacement");
        assert_eq!(o.turn.map(|t| t.len()), Some(n), "the turn beside it");
        let m = facemimic::fit::mouth_opening(&f.landmarks);
        if i >= 10 && m < closed {
            closed = m;
            let mut sp = vec![0.0; n];
            for (p, mode) in r
                .params
                .shape
                .iter()
                .zip(model.shape().modes.chunks_exact(n))
            {
                sp.iter_mut().zip(mode).for_each(|(o, v)| *o += p * v);
            }
            at_closed = Some((i, opening(d), opening(&sp)));
        }
    }
    let (i, from_neutral, from_mean) = at_closed.unwrap();
    println!(
        "spk07's most closed mouth (frame {i}): opening change from the neutral {from_neutral:.2}, \
         from the model's mean (S p) {from_mean:.2} (model units)"
    );
    assert!(
        from_mean < -0.5,
        "the model's mean has parted lips: {from_mean:.2}"
    );
    assert!(
        from_neutral.abs() < 0.5 * from_mean.abs(),
        "from the neutral {from_neutral:.2}, from the mean {from_mean:.2}"
    );
}

/// The head's turn a tracker gives beside the displacement (`Observed::turn`, the AAM
/// tracker's) moves a target that follows the pose and no other: at rest with the head turned,
/// the target keeps its own face unless `follow_pose` is on.
#[test]
fn the_turn_beside_the_displacement_reaches_only_a_target_that_follows_the_pose() {
    let (closed, _) = closed_and_open();
    let x = sampled(&closed);
    let zero = vec![0.0; spk07().shape().base.len()];
    // A turn to the side: every point moved sideways by its depth.
    let depth = facemimic::find::IBUG_DEPTH;
    let turn: Vec<f32> = (0..zero.len())
        .map(|k| if k % 2 == 0 { 5.0 * depth[k / 2] } else { 0.0 })
        .collect();
    assert!(turn.iter().any(|v| v.abs() > 1.0), "a visible turn");
    let shape_with = |follow_pose: bool| {
        let mut c = at_rest_onto_spk02(&x, &zero, Some(&turn));
        let options = CloneOptions {
            follow_pose,
            ..CloneOptions::default()
        };
        c.clone_frame(&spk07().base_params(), &options).unwrap();
        c.target_shape(0).to_vec()
    };
    let mut posed = target("spk02").shape().base.clone();
    target("spk02").home_pose().apply_in_place(&mut posed);
    let moved = |s: &[f32]| {
        s.iter()
            .zip(&posed)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max)
    };
    assert!(
        moved(&shape_with(false)) < 1e-3,
        "held pose: the target's own face"
    );
    assert!(
        moved(&shape_with(true)) > 1.0,
        "followed pose: the head turns"
    );
    // A turn of another length, or not a number, is refused.
    let mut c = Cloner::new(spk07().clone()).unwrap();
    let short = vec![0.0; 10];
    let nan = vec![f32::NAN; zero.len()];
    for bad in [&short, &nan] {
        let e = c.set_observed(Some(Observed {
            appearance: &x,
            neutral: &x,
            displacement: Some(&zero),
            turn: Some(bad),
        }));
        assert!(e.is_err());
    }
}

/// The person's colours against their own neutral: a constant offset of zero luminance on both
/// (another skin tone, a white balance) never reaches the target, while the expression does.
#[test]
fn a_tint_of_the_observed_person_never_reaches_the_target() {
    let (closed, open) = closed_and_open();
    let (rest, now) = (sampled(&closed), sampled(&open));
    let d = displacement(&closed, &open);
    let offset = [-0.05f32, 0.05 * 0.299 / 0.587, 0.0];
    assert!(luma(&offset).abs() < 1e-6);
    let tint = |a: &[f32]| -> Vec<f32> {
        a.chunks_exact(3)
            .flat_map(|p| [p[0] + offset[0], p[1] + offset[1], p[2] + offset[2]])
            .collect()
    };
    let (rest_t, now_t) = (tint(&rest), tint(&now));
    let mut out = Vec::new();
    for (a, n) in [(&now, &rest), (&now_t, &rest_t)] {
        let mut c = Cloner::new(spk07().clone()).unwrap();
        c.add_target(target("spk03").clone()).unwrap();
        c.set_observed(Some(Observed {
            appearance: a,
            neutral: n,
            displacement: Some(&d),
            turn: None,
        }))
        .unwrap();
        c.clone_frame(&spk07().base_params(), &CloneOptions::default())
            .unwrap();
        out.push(c.target_appearance(0).to_vec());
    }
    common::pixels::assert_tint_left_out(&out, target("spk03").appearance().base(), "the person");
}

#[test]
fn bad_observed_faces_are_refused_and_change_nothing() {
    let n = spk07().appearance().len();
    let m = spk07().shape().base.len();
    let good = vec![0.5; n];
    let zero = vec![0.0; m];
    let mut nan = good.clone();
    nan[17] = f32::NAN;
    let mut c = Cloner::new(spk07().clone()).unwrap();
    c.add_target(target("spk02").clone()).unwrap();
    for (what, o) in [
        (
            "a short appearance",
            Observed {
                appearance: &good[1..],
                neutral: &good,
                displacement: None,
                turn: None,
            },
        ),
        (
            "a short neutral",
            Observed {
                appearance: &good,
                neutral: &good[..n - 3],
                displacement: None,
                turn: None,
            },
        ),
        (
            "a long displacement",
            Observed {
                appearance: &good,
                neutral: &good,
                displacement: Some(&good),
                turn: None,
            },
        ),
        (
            "a NaN",
            Observed {
                appearance: &nan,
                neutral: &good,
                displacement: Some(&zero),
                turn: None,
            },
        ),
    ] {
        let e = c.set_observed(Some(o)).unwrap_err();
        assert_eq!(e.code(), "bad-params", "{what}: {e}");
        assert!(!c.has_observed(), "{what} was taken");
    }
    c.set_observed(Some(Observed {
        appearance: &good,
        neutral: &good,
        displacement: None,
        turn: None,
    }))
    .unwrap();
    assert!(c.has_observed());
    c.set_observed(None).unwrap();
    assert!(!c.has_observed());
}

#[test]
fn the_neutral_appearance_is_the_persons_face_at_rest() {
    let (closed, open) = closed_and_open();
    let (rest, laugh) = (sampled(&closed), sampled(&open));
    let mut o = ObservedAppearance::new(spk07().frame());
    assert!(o.get().is_none());
    // The open or the closed frame observed at a rest distance.
    let see = |o: &mut ObservedAppearance, t: &TrainingImage, rest: f32| {
        o.observe(&t.image.view().unwrap(), &t.landmarks, rest)
            .unwrap()
    };
    // Seen first with the mouth open, not at rest: that frame is its own neutral (no expression).
    see(&mut o, &open, 3.0);
    let g = o.get().unwrap();
    assert_eq!(g.appearance, g.neutral);
    assert_eq!(o.neutral_frames(), 0);
    // Before the first frame at rest, a frame nearer rest is the neutral (a session that opens
    // laughing shows its laugh against its least laughing moment); a farther one is not.
    see(&mut o, &closed, 2.0);
    assert_eq!(o.get().unwrap().neutral, &rest[..]);
    see(&mut o, &open, 2.5);
    assert_eq!(o.get().unwrap().neutral, &rest[..]);
    assert_eq!(o.get().unwrap().appearance, &laugh[..]);
    assert_eq!(o.neutral_frames(), 0);
    // The first frame at rest replaces it, whatever came before.
    see(&mut o, &open, 1.0);
    assert_eq!(o.get().unwrap().neutral, &laugh[..]);
    assert_eq!(o.neutral_frames(), 1);
    o.reset();
    see(&mut o, &open, 3.0);
    see(&mut o, &closed, 0.0);
    assert_eq!(o.get().unwrap().neutral, &rest[..]);
    // An expression does not move it, while it is observed.
    see(&mut o, &open, 3.0);
    assert_eq!(o.get().unwrap().neutral, &rest[..]);
    assert_eq!(o.get().unwrap().appearance, &laugh[..]);
    // A new person: forgotten.
    o.reset();
    assert!(o.get().is_none());
    // Wrong lengths are refused.
    assert!(o
        .observe(&open.image.view().unwrap(), &open.landmarks[2..], 0.0)
        .is_err());
}

#[test]
fn the_stage_clones_what_its_follower_observes() {
    let mut stage = Stage::new(spk07().clone()).unwrap();
    stage.add_target(target("spk06").clone()).unwrap();
    stage.set_tracker(Some(Box::new(
        Follower::new(spk07(), FollowOptions::default()).unwrap(),
    )));
    let dir = common::repo("data/grid/spk07_id2_vcd_swwp2s");
    for p in common::clip_frames(&dir).iter().take(5) {
        let t = io::read_training_image(p).unwrap();
        stage.track(&t.image.view().unwrap(), 0.04).unwrap();
    }
    assert!(stage.cloner().has_observed());
    assert!(stage.tracker().unwrap().observed().is_some());
    // A frame with no face is not taken: the last good expression is held, its look included.
    let black = facemimic::Image {
        width: 360,
        height: 288,
        data: vec![0; 360 * 288 * 4],
    };
    assert!(!stage.track(&black.view().unwrap(), 0.04).unwrap());
    assert!(stage.cloner().has_observed());
    // Bad parameters change nothing, the observed face included.
    let mut bad = spk07().base_params();
    bad.shape[0] = f32::NAN;
    assert!(stage.set_source_params(&bad).is_err());
    assert!(stage.cloner().has_observed());
    // Parameters given directly are the model's: the observed face is dropped.
    stage.set_source_params(&spk07().base_params()).unwrap();
    assert!(!stage.cloner().has_observed());
}

/// franck-dev2 (in no training list), followed with spk07's model: the targets' inner mouths
/// follow the person's real one (teeth showing or not), and their lip-corner lift and mouth
/// width reach further than through spk07's modes alone, and the width as far as 0.6 of the
/// person's (the follower's neutral held within a mouth at rest: the clip opens laughing). Every frame is followed, every 4th
/// measured.
#[test]
fn a_followed_laugh_arrives_with_the_persons_teeth_and_smile() {
    let Some(dir) = common::shared_data("franck-dev2") else {
        return;
    };
    let paths = common::clip_frames(&dir);
    let mut cloner = onto_default_targets(spk07());
    let m = common::following::follow_expressions(
        &paths,
        4,
        spk07(),
        &mut cloner,
        &CloneOptions::default(),
    );
    let open = m.frames.iter().filter(|f| f.teeth.is_some()).count();
    eprintln!(
        "  franck-dev2, every 4th frame: {} measured, {open} with the mouth open",
        m.frames.len()
    );
    assert!(open >= 50, "{open} open-mouthed frames");
    for t in 0..cloner.n_targets() {
        let r = m.teeth_r(t);
        let (w, l) = (m.spread_ratio(t, 0), m.spread_ratio(t, 1));
        let name = cloner.target(t).name();
        eprintln!(
            "  {name}: inner mouth r {:.2} -> {:.2}; width spread {:.2} -> {:.2}, lift {:.2} -> {:.2} (observed off -> on)",
            r[0], r[1], w[0], w[1], l[0], l[1]
        );
        assert!(r[1] >= 0.7, "{name}: the inner mouth follows at r {}", r[1]);
        assert!(r[0] <= 0.5, "{name}: without the observed face r {}", r[0]);
        assert!(l[1] >= 1.5 * l[0], "{name}: lift {} -> {}", l[0], l[1]);
        assert!(w[1] >= w[0], "{name}: width {} -> {}", w[0], w[1]);
        // The person's neutral held within a mouth at rest (`fit::bound_neutral_mouth`):
        // 0.66-0.72 measured; 0.45-0.50 when the neutral kept the opening laugh's smile.
        assert!(w[1] >= 0.6, "{name}: the width spread is {}", w[1]);
    }
}

/// A session that opens laughing (franck-dev2's first two seconds, in no list; spk07's model):
/// the follower's first neutral has its mouth closed (no more open than `mouth_margin`), not
/// half open as the speech model's base face is, so the opening laugh reads as a laugh: the
/// targets' mouths open with it. Closed only to the base's opening, the laugh's parted tail
/// entered the neutral and hid the smiles that followed (docs/cloning.md, "Where the
/// follower's laugh goes").
#[test]
fn a_session_that_opens_laughing_starts_from_a_closed_mouth() {
    use facemimic::fit::mouth_opening;
    let Some(dir) = common::shared_data("franck-dev2") else {
        return;
    };
    let paths = common::clip_frames(&dir);
    let margin = FollowOptions::default().mouth_margin;
    assert!(
        mouth_opening(&spk07().shape().base) > 2.0 * margin,
        "spk07's base face is half open: the case this is about"
    );
    let first = io::read_training_image(&paths[0]).unwrap();
    assert!(
        mouth_opening(&first.landmarks) > 0.2,
        "the clip opens laughing"
    );
    let mut follower = Follower::new(spk07(), FollowOptions::default()).unwrap();
    let mut cloner = onto_default_targets(spk07());
    let rest: Vec<f32> = (0..cloner.n_targets())
        .map(|t| mouth_opening(&cloner.target(t).shape().base))
        .collect();
    let (mut opened, mut n) = (0.0, 0);
    let (mut shown, mut looks) = (0.0, 0);
    for (i, path) in paths.iter().enumerate().take(51) {
        let t = io::read_training_image(path).unwrap();
        let fit = follower
            .track(&t.image.view().unwrap(), 1.0 / 25.0)
            .unwrap()
            .clone();
        if i == 0 {
            let neutral = mouth_opening(follower.neutral().unwrap());
            assert!(
                neutral <= margin + 0.01,
                "the first neutral is open {neutral}"
            );
        }
        if i >= 10 && i % 5 == 0 {
            // The laugh's look against the neutral look: before the person first rests, the
            // look of the frame nearest rest so far.
            let seen = follower.observed().unwrap();
            let luma =
                |a: &[f32]| -> Vec<f32> { a.chunks_exact(3).map(facemimic::clone::luma).collect() };
            let (a, b) = (luma(seen.appearance), luma(seen.neutral));
            shown += a.iter().zip(&b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32;
            looks += 1;
            cloner.set_observed(follower.observed()).unwrap();
            cloner
                .clone_frame(&fit.params, &CloneOptions::default())
                .unwrap();
            for (k, r) in rest.iter().enumerate() {
                opened += mouth_opening(cloner.target_shape(k)) - r;
                n += 1;
            }
        }
    }
    let opened = opened / n as f32;
    let shown = shown / looks as f32;
    eprintln!("  franck-dev2's opening laugh (frames 10-50): the targets' mouths open {opened:.3} beyond their base; the look differs from the neutral look by {shown:.4} in luminance");
    assert!(opened >= OPENING_LAUGH, "{opened}");
    assert!(shown >= OPENING_LOOK, "{shown}");
}

/// The least accepted mouth opening (inner lips over the outer eye corners' distance) beyond
/// their base faces, averaged over the four targets and franck-dev2's opening laugh (frames
/// 10-50, every 5th): 0.116 measured (28 Nov), 0.059 when the first neutral was closed only to
/// spk07's base face.
const OPENING_LAUGH: f32 = 0.09;

/// Follows `frames` (25 fps) and counts the frames the follower calls covered.
fn covered_frames(frames: impl Iterator<Item = TrainingImage>) -> (usize, usize) {
    let mut f = Follower::new(spk07(), FollowOptions::default()).unwrap();
    let (mut n, mut covered) = (0, 0);
    for t in frames {
        let r = f.track(&t.image.view().unwrap(), 0.04).unwrap();
        if !r.lost {
            n += 1;
            covered += usize::from(r.reasons.contains(facemimic::fit::Reasons::COVERED));
        }
    }
    (covered, n)
}

/// A mouth covered by a skin-coloured patch makes the follower "unsure" ("covered"): the
/// Stage holds the last good expression and its look. spk07's unseen GRID clip, frames 30-39
/// covered by a patch, 40-49 by a hand from the side (which the lip check catches only in
/// part: printed).
#[test]
fn a_covered_mouth_makes_the_follower_unsure_and_the_targets_hold() {
    use super::enrol_quality::{occlude, Occluder};
    let dir = common::repo("data/grid/spk07_id2_vcd_swwp2s");
    let mut stage = Stage::new(spk07().clone()).unwrap();
    stage.add_target(target("spk06").clone()).unwrap();
    stage.set_tracker(Some(Box::new(
        Follower::new(spk07(), FollowOptions::default()).unwrap(),
    )));
    let (mut patch, mut hand, mut false_alarms) = (0, 0, 0);
    let mut before: Vec<f32> = Vec::new();
    for (i, p) in common::clip_frames(&dir).iter().enumerate() {
        let t = io::read_training_image(p).unwrap();
        let t = match i {
            30..40 => occlude(&t, Occluder::Mouth, i as u32),
            40..50 => occlude(&t, Occluder::Hand, i as u32),
            _ => t,
        };
        let taken = stage.track(&t.image.view().unwrap(), 0.04).unwrap();
        let tracker = stage.tracker().unwrap();
        let r = tracker.last().unwrap();
        let unsure = r.reasons.contains(facemimic::fit::Reasons::COVERED);
        assert_eq!(taken, !unsure && !r.lost, "frame {i}");
        let now = tracker.observed().unwrap().appearance.to_vec();
        if unsure {
            // The cover's look is not observed: the last one is held.
            assert_eq!(now, before, "frame {i}: a covered frame's look was taken");
        }
        match i {
            30..40 => patch += usize::from(unsure),
            40..50 => hand += usize::from(unsure),
            _ => false_alarms += usize::from(unsure),
        }
        before = now;
    }
    eprintln!(
        "  covered frames called covered: a patch over the mouth {patch} of 10, a hand from the side {hand} of 10; clean frames: {false_alarms}"
    );
    assert_eq!(patch, 10);
    assert_eq!(false_alarms, 0);
}

/// No clean frame of the real clips is called covered (`../shared`: franck-dev2, all 1000
/// frames, and webcam-dev's; skipped visibly without them).
#[test]
fn clean_real_faces_are_never_called_covered() {
    for clip in ["franck-dev2", "webcam-dev"] {
        let Some(dir) = common::shared_data(clip) else {
            return;
        };
        let paths = common::clip_frames(&dir);
        let (covered, n) =
            covered_frames(paths.iter().map(|p| io::read_training_image(p).unwrap()));
        eprintln!("  {clip}: {covered} of {n} followed frames called covered");
        assert!(covered * 100 <= n, "{clip}: {covered} of {n}");
    }
}

/// A face partly outside the picture keeps the last whole look (its samples there would repeat
/// the picture's edge), while its expression is still followed. spk07's unseen GRID clip, the
/// picture cropped on frames 40-49 so that the face's right third is outside it.
#[test]
fn a_face_leaving_the_picture_keeps_its_last_whole_look() {
    let dir = common::repo("data/grid/spk07_id2_vcd_swwp2s");
    let mut f = Follower::new(spk07(), FollowOptions::default()).unwrap();
    let mut before: Vec<f32> = Vec::new();
    let (mut partial, mut held) = (0, 0);
    for (i, p) in common::clip_frames(&dir).iter().enumerate() {
        let t = io::read_training_image(p).unwrap();
        let image = if (40..50).contains(&i) {
            // Cropped on the right (the rest keeps its place): the face's right third (dlib's
            // points) falls outside.
            let xs = t.landmarks.iter().step_by(2);
            let (x0, x1) = xs.fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            let w = (x1 - (x1 - x0) / 3.0) as u32;
            let h = t.image.height;
            let mut data = Vec::with_capacity((w * h * 4) as usize);
            for y in 0..h {
                let row = (y * t.image.width) as usize * 4;
                data.extend_from_slice(&t.image.data[row..row + w as usize * 4]);
            }
            facemimic::Image {
                width: w,
                height: h,
                data,
            }
        } else {
            t.image.clone()
        };
        let r = f.track(&image.view().unwrap(), 0.04).unwrap();
        if r.lost {
            continue;
        }
        let now = f.observed().unwrap().appearance.to_vec();
        if (40..50).contains(&i) {
            partial += 1;
            held += usize::from(now == before);
        }
        before = now;
    }
    eprintln!("  frames with the face partly outside: {partial} followed, {held} kept the last whole look");
    assert!(partial >= 5, "{partial} partial frames followed");
    assert_eq!(held, partial);
}

/// franck tracked by his own model (the AAM tracker, model from `franck-dev/train20.txt`) on
/// franck-dev2 (in no list), started from its first frame's dlib points, every 4th frame
/// measured: with the frame's own look against his neutral look kept from his frames at rest,
/// the targets' inner mouths follow his real one closer than through the model's synthesis.
#[test]
fn a_tracked_person_shows_their_own_teeth() {
    let (Some(dev), Some(dir)) = (
        common::shared_data("franck-dev"),
        common::shared_data("franck-dev2"),
    ) else {
        return;
    };
    let franck = common::path_list_model(&dev.join("train20.txt"), "franck", false);
    let paths = common::clip_frames(&dir);
    let first = io::read_training_image(&paths[0]).unwrap();
    let mut tracker = facemimic::fit::tracker_for(franck, facemimic::fit::Whose::Own).unwrap();
    tracker.start_from_landmarks(&first.landmarks).unwrap();
    let mut cloner = onto_default_targets(franck);
    let m = common::following::track_expressions(
        &paths,
        4,
        &mut *tracker,
        franck,
        &mut cloner,
        &CloneOptions::default(),
    );
    let open = m.frames.iter().filter(|f| f.teeth.is_some()).count();
    eprintln!(
        "  franck-dev2 tracked by his model, every 4th frame: {} measured, {open} with the mouth open",
        m.frames.len()
    );
    assert!(open >= 50, "{open}");
    for t in 0..cloner.n_targets() {
        let (r, c) = (m.teeth_r(t), m.change(t));
        let name = cloner.target(t).name();
        eprintln!(
            "  {name}: inner mouth r {:.2} -> {:.2}; appearance change between measured frames {:.4} -> {:.4} (synthesis -> observed)",
            r[0], r[1], c[0], c[1]
        );
        assert!(r[1] > r[0] && r[1] >= 0.85, "{name}: r {r:?}");
    }
}

/// franck's own model from `franck-dev/train20.txt`, built about `reference`, tracked through
/// franck-dev and cloned onto the default targets; measured on every 2nd frame that is not one
/// of those 20. `None` without the clip.
fn franck_dev_tracked(
    reference: facemimic::ReferenceChoice,
) -> Option<(Model, common::following::FollowedExpressions, Cloner)> {
    let dev = common::shared_data("franck-dev")?;
    let list = dev.join("train20.txt");
    let built: Vec<usize> = std::fs::read_to_string(&list)
        .unwrap()
        .lines()
        .filter_map(|l| l.trim().parse().ok())
        .collect();
    assert_eq!(built.len(), 20, "{}", list.display());
    let train: Vec<TrainingImage> = io::read_list(&list)
        .unwrap()
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let franck = facemimic::Builder::new(facemimic::BuildOptions {
        name: "franck".into(),
        reference,
        ..facemimic::BuildOptions::default()
    })
    .build(&train, None)
    .unwrap();
    let paths = common::clip_frames(&dev);
    let first = io::read_training_image(&paths[0]).unwrap();
    let mut tracker = facemimic::fit::tracker_for(&franck, facemimic::fit::Whose::Own).unwrap();
    tracker.start_from_landmarks(&first.landmarks).unwrap();
    let mut cloner = onto_default_targets(&franck);
    let mut m = common::following::track_expressions(
        &paths,
        2,
        &mut *tracker,
        &franck,
        &mut cloner,
        &CloneOptions::default(),
    );
    m.frames.retain(|f| !built.contains(&f.index));
    assert!(m.frames.len() >= 450, "{}", m.frames.len());
    Some((franck, m, cloner))
}

/// franck tracked by his own model (model from `franck-dev/train20.txt`, about their mean)
/// through franck-dev, measured on every 2nd frame that is not one of those 20 (the clip's
/// laughs and closed-lip smiles): the lip corners' lift of every target's clone, with the frame
/// observed against his neutral, follows his real one (dlib's points) at r >= 0.95 with a
/// spread (p95 - p5) of at least 0.75 of it. Measured 0.98 and 0.83-0.89 with each frame posed
/// onto the neutral by the points an expression hardly moves; 0.80 and 0.58-0.62 while the
/// fit's own similarity posed it (fitted over all 68 points, it took part of each smile for the
/// head moving).
#[test]
fn a_tracked_persons_smile_keeps_its_lift() {
    let Some((_, m, cloner)) = franck_dev_tracked(facemimic::ReferenceChoice::Mean) else {
        return;
    };
    eprintln!(
        "  franck-dev tracked by his model (about the mean), every 2nd frame not in train20.txt: {} measured",
        m.frames.len()
    );
    for t in 0..cloner.n_targets() {
        let (r, spread) = (m.mouth_r(t, 1)[1], m.spread_ratio(t, 1)[1]);
        let name = cloner.target(t).name();
        eprintln!("  {name}: the clone's lift against the real one r {r:.3}, spread {spread:.2}");
        assert!(r >= 0.95, "{name}: lift r {r:.3}");
        assert!(spread >= 0.75, "{name}: lift spread {spread:.2}");
    }
}

/// The same, with franck's model built about his training frame most at rest
/// (`ReferenceChoice::Rest`, as the page's enrolment builds a person's model): frame 850 of the
/// 20 (frontal, mouth closed, eyes open). His neutral starts there instead of at the mean of
/// frames that laugh and talk (eyes half closed, lips parted), so the whole laugh arrives: the
/// clones' mouth width spreads 0.90-0.97 of his real one (0.72-0.78 about the mean) and the
/// lift 0.97-1.04 (0.83-0.89), asserted at 0.85 and 0.9; the lift follows at r 0.95-0.96
/// (0.98 about the mean), asserted at 0.94.
#[test]
fn a_model_built_about_the_persons_rest_carries_the_whole_laugh() {
    let Some((franck, m, cloner)) = franck_dev_tracked(facemimic::ReferenceChoice::Rest) else {
        return;
    };
    assert_eq!(
        franck.reference(),
        &facemimic::Reference::Training("000850".into())
    );
    for t in 0..cloner.n_targets() {
        let (width, lift) = (m.spread_ratio(t, 0)[1], m.spread_ratio(t, 1)[1]);
        let r = m.mouth_r(t, 1)[1];
        let name = cloner.target(t).name();
        eprintln!("  {name} (franck about his rest): width spread {width:.2}, lift spread {lift:.2}, lift r {r:.3}");
        assert!(width >= 0.85, "{name}: width spread {width:.2}");
        assert!(lift >= 0.9, "{name}: lift spread {lift:.2}");
        assert!(r >= 0.94, "{name}: lift r {r:.3}");
    }
}

/// A change of light during the session (the left half of the picture darkened by a quarter
/// from frame 25 of spk07's unseen clip, tracked by spk07's own model) reads on the targets at
/// first, then fades as the person's neutral look follows it on their frames at rest.
#[test]
fn a_change_of_light_fades_from_the_targets() {
    let dir = common::repo("data/grid/spk07_id2_vcd_swwp2s");
    let frames: Vec<TrainingImage> = common::clip_frames(&dir)
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let run = |shadow: bool| -> Vec<Vec<f32>> {
        let mut stage = Stage::new(spk07().clone()).unwrap();
        stage.add_target(target("spk06").clone()).unwrap();
        let mut tracker = facemimic::fit::tracker_for(spk07(), facemimic::fit::Whose::Own).unwrap();
        tracker.start_from_landmarks(&frames[0].landmarks).unwrap();
        stage.set_tracker(Some(tracker));
        let options = CloneOptions::default();
        stage.set_options(options).unwrap();
        let mut out = Vec::new();
        for (i, t) in frames.iter().enumerate() {
            let mut image = t.image.clone();
            if shadow && i >= 25 {
                let w = image.width as usize;
                for (k, px) in image.data.chunks_exact_mut(4).enumerate() {
                    if k % w < w / 2 {
                        for c in &mut px[..3] {
                            *c = (*c as f32 * 0.75) as u8;
                        }
                    }
                }
            }
            stage.track(&image.view().unwrap(), 0.04).unwrap();
            stage.update().unwrap();
            out.push(stage.cloner().target_appearance(0).to_vec());
        }
        out
    };
    let (clean, shaded) = (run(false), run(true));
    let gap = |r: std::ops::Range<usize>| {
        let n = r.len() as f32;
        r.map(|i| common::pixels::mean_abs_diff_f32(&clean[i], &shaded[i]))
            .sum::<f32>()
            / n
    };
    let windows: Vec<String> = (25..frames.len())
        .step_by(10)
        .map(|a| format!("{:.4}", gap(a..(a + 10).min(frames.len()))))
        .collect();
    eprintln!("  by 10 frames from frame 25: {}", windows.join(", "));
    let (early, late) = (gap(26..36), gap(frames.len() - 10..frames.len()));
    eprintln!("  the light's trace on the target: frames 26-35 {early:.4}, the last 10 {late:.4}");
    assert!(late < 0.5 * early, "{early} -> {late}");
}

/// The least accepted mean luminance difference between the observed look and the neutral
/// look over franck-dev2's opening laugh (frames 10-50, every 5th), before the person first
/// rests: 0.0225 measured with the look of the frame nearest rest so far as the neutral (29
/// Nov), 0.0000 when each frame was its own neutral until then (the laugh showed no shading).
const OPENING_LOOK: f32 = 0.015;

//! The page's live enrolment, simulated over many timings, on webcam-dev or franck-dev2
//! (research data in ../shared, never committed). **Split:** webcam-dev's models are built from
//! frames 0-599 only and tracked over the unseen frames 600-1336; franck-dev2's (never in any
//! training list) from its first half, 3800-4299, and tracked over the second, 4300-4799.
//!
//! The page samples the webcam as fast as its finder worker allows, so which frames it keeps
//! depends on the machine's timing: a search every 4.5-6.5 frames here (150-217 ms at 30 fps,
//! as measured in the e2e test), from a random phase. As the page does (`www/js/enrol.js`):
//! each frame with a face is a candidate (the enrolment finder's points, [`EnrolFinder`]); past
//! 60 candidates they are pruned to the 45 most varied; the model is built from the 20 most
//! varied ([`select_varied`]) with the default build and backdrop. Each model is then tracked
//! as the page tracks (a [`Tracker`] searching, a [`FaceFinder`] offering faces whenever it
//! wants them) and its error against the dlib landmarks printed (mean point distance over the
//! outer-eye-corner distance), with the second opinions taken and kept and the tracking time
//! a frame (the finder's time not counted: in the page it runs in its worker).
//!
//!   cargo run --release --example enrol_sampling -- [samplings (20)] [--recheck N] [--seed S]
//!       [--clip webcam-dev|franck-dev2]
//!
//! `--recheck N` sets [`TrackPolicy::recheck_frames`] (0: no second opinions).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

#[cfg(not(any(target_arch = "wasm32", test)))]
use facemimic_testkit as common;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::fit::FaceTracker;
    use std::path::Path;
    use std::time::Instant;

    use super::common::{self, frame, Rng};
    use facemimic::find::landmark_error;
    use facemimic::fit::{FitOptions, TrackPolicy, Tracker};
    use facemimic::{
        select_varied, with_default_backdrop, BuildOptions, Builder, EnrolFinder, FaceFinder,
        Model, TrainingImage,
    };

    /// The frames one live sampling keeps, in order: a search every 4.5-6.5 frames; past 60
    /// candidates, the 45 most varied are kept.
    fn sample(points: &[Option<Vec<f32>>], rng: &mut Rng) -> Vec<usize> {
        let mut t = rng.uniform(0.0, 5.0);
        let mut kept: Vec<usize> = Vec::new();
        while (t as usize) < points.len() {
            let i = t as usize;
            if points[i].is_some() {
                kept.push(i);
                if kept.len() > 60 {
                    let mut keep = select_varied(&shapes(points, &kept), 45).unwrap();
                    keep.sort_unstable();
                    kept = keep.iter().map(|&k| kept[k]).collect();
                }
            }
            t += rng.uniform(4.5, 6.5);
        }
        kept
    }

    fn shapes<'a>(points: &'a [Option<Vec<f32>>], frames: &[usize]) -> Vec<&'a [f32]> {
        frames
            .iter()
            .map(|&i| points[i].as_deref().expect("a candidate has points"))
            .collect()
    }

    /// What tracking one model did.
    struct Track {
        mean: f32,
        max: f32,
        lost: u32,
        rechecks: (u32, u32),
        ms: f64,
        worst_ms: f64,
    }

    fn track(
        model: &Model,
        test: &[TrainingImage],
        finder: &mut FaceFinder,
        recheck: u32,
    ) -> Track {
        let mut t = Tracker::new(model, FitOptions::default()).unwrap();
        t.set_policy(TrackPolicy {
            recheck_frames: recheck,
            ..TrackPolicy::default()
        })
        .unwrap();
        t.expect_offers(true);
        t.start_searching();
        let (mut errors, mut ms, mut worst_ms) = (Vec::new(), 0.0, 0f64);
        for f in test {
            let view = f.image.view().unwrap();
            common::offer_when_wanted(&mut t, finder, &view);
            let t0 = Instant::now();
            let r = t.track(&view, 1.0 / 30.0).unwrap();
            let dt = t0.elapsed().as_secs_f64() * 1e3;
            ms += dt;
            worst_ms = worst_ms.max(dt);
            errors.push(landmark_error(&r.landmarks, &f.landmarks));
        }
        Track {
            mean: errors.iter().sum::<f32>() / errors.len() as f32,
            max: errors.iter().copied().fold(0.0, f32::max),
            lost: t.sequence().lost_count(),
            rechecks: t.rechecks(),
            ms: ms / test.len() as f64,
            worst_ms,
        }
    }

    pub fn main() {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let value = |flag: &str| {
            args.iter()
                .position(|a| a == flag)
                .map(|i| args[i + 1].parse::<u64>().expect("a whole number"))
        };
        let samplings = args
            .first()
            .filter(|a| !a.starts_with("--"))
            .map_or(20, |a| a.parse().expect("the number of samplings"));
        let recheck =
            value("--recheck").map_or(TrackPolicy::default().recheck_frames, |v| v as u32);
        // The samplings' timings, reproducible from `--seed`.
        let mut rng = Rng::new(value("--seed").unwrap_or(0x9E37_79B9_7F4A_7C15));
        let clip = args
            .iter()
            .position(|a| a == "--clip")
            .map_or("webcam-dev", |i| args[i + 1].as_str());
        let (build, measure) = match clip {
            "webcam-dev" => (0..600, 600..1337),
            "franck-dev2" => (3800..4300, 4300..4800),
            other => panic!("--clip {other}: webcam-dev or franck-dev2"),
        };
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data")
            .join(clip);
        if !dir.is_dir() {
            eprintln!(
                "{} is absent (research data, never committed)",
                dir.display()
            );
            std::process::exit(2);
        }
        let frames: Vec<TrainingImage> = build.clone().map(|i| frame(&dir, i)).collect();
        let test: Vec<TrainingImage> = measure.clone().map(|i| frame(&dir, i)).collect();
        let mut enrol = EnrolFinder::new(1).unwrap();
        let points: Vec<Option<Vec<f32>>> = frames
            .iter()
            .map(|f| {
                let face = enrol.find(&f.image.view().unwrap(), 0.0).unwrap();
                face.map(|f| f.landmarks)
            })
            .collect();
        let mut finder = FaceFinder::new().unwrap();
        println!(
            "{clip}: built from {build:?}, tracked over {measure:?}; recheck_frames {recheck}"
        );
        let mut means = Vec::new();
        for s in 0..samplings {
            let kept = sample(&points, &mut rng);
            let mut pick = select_varied(&shapes(&points, &kept), 20).unwrap();
            pick.sort_unstable();
            let picked: Vec<usize> = pick.iter().map(|&k| kept[k]).collect();
            let named: Vec<usize> = picked.iter().map(|&i| build.start + i).collect();
            let images: Vec<TrainingImage> = picked
                .iter()
                .map(|&i| {
                    let mut f = frames[i].clone();
                    f.landmarks = points[i].clone().unwrap();
                    f
                })
                .collect();
            let options = BuildOptions {
                name: "enrolled".into(),
                ..BuildOptions::default()
            };
            let model = Builder::new(options).build(&images, None).unwrap();
            let model = with_default_backdrop(model, &images, None).unwrap();
            let r = track(&model, &test, &mut finder, recheck);
            println!(
                "sampling {s:2}: {} kept, built from {named:?}: mean {:.4} max {:.3}, {} lost, \
                 second opinions {} taken {} kept, {:.2} ms a frame (slowest {:.1})",
                kept.len(),
                r.mean,
                r.max,
                r.lost,
                r.rechecks.0,
                r.rechecks.1,
                r.ms,
                r.worst_ms
            );
            means.push(r.mean);
        }
        means.sort_by(f32::total_cmp);
        if let (Some(lo), Some(hi)) = (means.first(), means.last()) {
            let over = means.iter().filter(|&&m| m > 0.03).count();
            println!("{samplings} samplings: mean error {lo:.4}-{hi:.4}, {over} over 0.03");
        }
    }
}

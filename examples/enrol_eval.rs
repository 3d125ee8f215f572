//! Where a model built from the face finder's landmarks loses, on webcam-dev (research data in
//! ../shared, never committed). Models from frames 0-599 (every `STEP`th frame searched), 20
//! frames chosen by farthest-point sampling; each tracked over the unseen frames 600-1336 from
//! the finder's landmarks on frame 600; error against the dlib landmarks (mean point distance
//! over the outer-eye-corner distance). Prints the finder's error per landmark group and the
//! tracking error of models built from: dlib landmarks; the finder's; the finder's averaged over
//! several passes (jittered boxes and the mirrored image); the same with the frames where those
//! passes disagree most dropped. `--own` builds in the model's own frame, else the canonical one.
//!
//!   cargo run --release --example enrol_eval -- [--own] [--step 5]
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::fit::FaceTracker;
    use std::path::{Path, PathBuf};

    use facemimic::find::{add_face_offsets, mean_face_offsets};
    use facemimic::fit::{FitOptions, Tracker};
    use facemimic::{
        io, select_varied, BuildOptions, Builder, EnrolFinder, FrameChoice, Model, TrainingImage,
    };

    const GROUPS: [(&str, std::ops::Range<usize>); 7] = [
        ("jaw", 0..17),
        ("brows", 17..27),
        ("nose", 27..36),
        ("eyes", 36..48),
        ("outer lips", 48..60),
        ("inner lips", 60..68),
        ("all", 0..68),
    ];

    fn iod(t: &[f32]) -> f32 {
        ((t[90] - t[72]).powi(2) + (t[91] - t[73]).powi(2)).sqrt()
    }

    fn point_errors(fit: &[f32], truth: &[f32]) -> Vec<f32> {
        let d = iod(truth);
        (0..68)
            .map(|i| {
                ((fit[2 * i] - truth[2 * i]).powi(2) + (fit[2 * i + 1] - truth[2 * i + 1]).powi(2))
                    .sqrt()
                    / d
            })
            .collect()
    }

    fn mean(v: &[f32]) -> f32 {
        v.iter().sum::<f32>() / v.len().max(1) as f32
    }

    fn build(images: &[TrainingImage], frame: FrameChoice) -> Model {
        let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
        let mut keep = select_varied(&shapes, 20).unwrap();
        keep.sort_unstable();
        let chosen: Vec<TrainingImage> = keep.iter().map(|&i| images[i].clone()).collect();
        Builder::new(BuildOptions {
            frame,
            ..BuildOptions::default()
        })
        .build(&chosen, None)
        .unwrap()
    }

    fn track(model: &Model, test: &[TrainingImage], init: &[f32]) -> (f32, Vec<f32>, u32) {
        let mut t = Tracker::new(model, FitOptions::default()).unwrap();
        t.start_from_landmarks(init).unwrap();
        let mut per_point = vec![0.0f32; 68];
        let mut errs = Vec::new();
        for f in test {
            let r = t
                .track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                .unwrap();
            let e = point_errors(&r.landmarks, &f.landmarks);
            for (p, v) in per_point.iter_mut().zip(&e) {
                *p += v / test.len() as f32;
            }
            errs.push(mean(&e));
        }
        (mean(&errs), per_point, t.resets())
    }

    fn groups(per_point: &[f32]) -> String {
        GROUPS
            .iter()
            .map(|(n, r)| format!("{n} {:.4}", mean(&per_point[r.clone()])))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// A frame with a face: (the frame with dlib's landmarks, the finder's, its score, the averaged
    /// landmarks, the passes' spread).
    type Found = (TrainingImage, Vec<f32>, f32, Vec<f32>, f32);

    /// The command line: `--own`, `--step N` (default 5), `--boxes N` (default 1).
    struct Args {
        own: bool,
        step: usize,
        boxes: usize,
    }

    fn args() -> Args {
        let args: Vec<String> = std::env::args().collect();
        let value = |name: &str, default: usize| {
            args.iter()
                .position(|a| a == name)
                .and_then(|i| args.get(i + 1))
                .map(|s| s.parse().unwrap())
                .unwrap_or(default)
        };
        Args {
            own: args.iter().any(|a| a == "--own"),
            step: value("--step", 5),
            boxes: value("--boxes", 1),
        }
    }

    /// The mean error per landmark over pairs of (landmarks, dlib's landmarks).
    fn mean_point_errors<'a>(
        pairs: impl ExactSizeIterator<Item = (&'a [f32], &'a [f32])>,
    ) -> Vec<f32> {
        let n = pairs.len() as f32;
        let mut pp = vec![0.0f32; 68];
        for (lm, truth) in pairs {
            for (p, e) in pp.iter_mut().zip(point_errors(lm, truth)) {
                *p += e / n;
            }
        }
        pp
    }

    /// Every `step`-th frame of 0-599 searched: the frames (with dlib's landmarks) and those
    /// with a face found.
    fn search(
        enrol: &mut EnrolFinder,
        read: &dyn Fn(usize) -> TrainingImage,
        step: usize,
    ) -> (Vec<TrainingImage>, Vec<Found>) {
        let mut dlib = Vec::new();
        let mut found: Vec<Found> = Vec::new();
        for i in (0..600).step_by(step) {
            let f = read(i);
            let view = f.image.view().unwrap();
            let faces = enrol.finder().find(&view);
            if let Some(face) = faces.first() {
                if let Some(avg) = enrol.average(&view, face).unwrap() {
                    found.push((
                        f.clone(),
                        face.landmarks.clone(),
                        face.score,
                        avg.landmarks,
                        avg.spread,
                    ));
                }
            }
            dlib.push(f);
        }
        (dlib, found)
    }

    /// The finder's error per landmark group on the confident faces, raw and averaged; its
    /// scores; whether the passes' spread predicts a bad frame.
    fn report_finder(found: &[Found], confident: &[&Found], boxes: usize) {
        let per = |sel: &dyn Fn(&Found) -> &Vec<f32>| {
            mean_point_errors(confident.iter().map(|f| (&sel(f)[..], &f.0.landmarks[..])))
        };
        println!(
            "finder error on the {} confident faces (score >= 0.5): {}",
            confident.len(),
            groups(&per(&|f| &f.1))
        );
        println!(
            "averaged ({boxes} boxes x image + mirror):               {}",
            groups(&per(&|f| &f.3))
        );
        let spreads: Vec<f32> = confident.iter().map(|f| f.4).collect();
        let errs: Vec<f32> = confident
            .iter()
            .map(|f| mean(&point_errors(&f.3, &f.0.landmarks)))
            .collect();
        // Correlation of spread and error (does the spread predict a bad frame?).
        let (ms, me) = (mean(&spreads), mean(&errs));
        let cov: f32 = spreads
            .iter()
            .zip(&errs)
            .map(|(s, e)| (s - ms) * (e - me))
            .sum();
        let vs: f32 = spreads.iter().map(|s| (s - ms).powi(2)).sum();
        let ve: f32 = errs.iter().map(|e| (e - me).powi(2)).sum();
        let mut scores: Vec<f32> = found.iter().map(|f| f.2).collect();
        scores.sort_by(f32::total_cmp);
        println!(
            "finder scores: min {:.2}, quartiles {:.2} {:.2} {:.2}, max {:.2}",
            scores[0],
            scores[scores.len() / 4],
            scores[scores.len() / 2],
            scores[3 * scores.len() / 4],
            scores[scores.len() - 1]
        );
        println!(
            "pass spread mean {ms:.4}; correlation of spread and averaged error {:.2}",
            cov / (vs * ve).sqrt()
        );
    }

    /// The training sets compared, each named.
    fn training_sets(
        dlib: &[TrainingImage],
        found: &[Found],
    ) -> Vec<(&'static str, Vec<TrainingImage>)> {
        let confident: Vec<_> = found.iter().filter(|f| f.2 >= 0.5).collect();
        let with = |set: &[&Found], which: u8| {
            set.iter()
                .map(|f| {
                    let mut t = f.0.clone();
                    match which {
                        1 => t.landmarks = f.1.clone(),
                        2 => t.landmarks = f.3.clone(),
                        _ => {}
                    }
                    t
                })
                .collect::<Vec<_>>()
        };
        let all: Vec<_> = found.iter().collect();
        let mut sorted = confident.clone();
        sorted.sort_by(|a, b| a.4.total_cmp(&b.4));
        let low_spread: Vec<_> = sorted[..sorted.len() * 3 / 4].to_vec();
        // An oracle: the averaged landmarks with this person's own mean offset from dlib (over
        // the enrolment frames, in each face's frame) removed: what enrolment would give if the
        // finder followed dlib's convention on this face.
        let own_offset = mean_face_offsets(found.iter().map(|f| (&f.3[..], &f.0.landmarks[..])));
        let oracle: Vec<TrainingImage> = found
            .iter()
            .map(|f| {
                let mut t = f.0.clone();
                t.landmarks = f.3.clone();
                add_face_offsets(&mut t.landmarks, &own_offset);
                t
            })
            .collect();
        println!(
            "averaged, every face, own offset removed (oracle):  {}",
            groups(&mean_point_errors(
                oracle
                    .iter()
                    .zip(found)
                    .map(|(t, f)| (&t.landmarks[..], &f.0.landmarks[..]))
            ))
        );
        let scored = |min: f32| found.iter().filter(|f| f.2 >= min).collect::<Vec<_>>();
        vec![
            (
                "finder averaged, every face, own offset removed (oracle)",
                oracle,
            ),
            ("dlib, every searched frame", dlib.to_vec()),
            ("dlib, the confident frames (control)", with(&confident, 0)),
            ("finder, confident", with(&confident, 1)),
            ("finder, every face found", with(&all, 1)),
            ("finder, score >= 0.3", with(&scored(0.3), 1)),
            ("finder averaged, confident", with(&confident, 2)),
            ("finder averaged, every face found", with(&all, 2)),
            ("finder averaged, score >= 0.3", with(&scored(0.3), 2)),
            (
                "finder averaged, confident, 25% highest spread dropped",
                with(&low_spread, 2),
            ),
        ]
    }

    /// Prints a model's tracking error over `test` from `init`.
    fn report_model(name: &str, frames: usize, m: &Model, test: &[TrainingImage], init: &[f32]) {
        let (e, pp, resets) = track(m, test, init);
        println!(
            "{name:55} ({frames} frames): {e:.4} ({resets} resets; {} shape modes) [{}]",
            m.shape().n_modes(),
            groups(&pp)
        );
    }

    pub(crate) fn main() {
        let Args { own, step, boxes } = args();
        let frame = if own {
            FrameChoice::Own
        } else {
            FrameChoice::Canonical
        };
        let dir: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/webcam-dev");
        let read = |i: usize| io::read_training_image(&dir.join(format!("{i:06}.jpg"))).unwrap();
        let mut enrol = EnrolFinder::new(boxes).unwrap();
        let t0 = std::time::Instant::now();
        let (dlib, found) = search(&mut enrol, &read, step);
        println!(
            "searched {} frames of 0-599 (every {step}th), faces on {} ({:.1} s)",
            dlib.len(),
            found.len(),
            t0.elapsed().as_secs_f32()
        );
        let confident: Vec<_> = found.iter().filter(|f| f.2 >= 0.5).collect();
        report_finder(&found, &confident, boxes);

        let test: Vec<TrainingImage> = (600..=1336).map(read).collect();
        let init = enrol
            .finder()
            .find(&test[0].image.view().unwrap())
            .first()
            .expect("a face in frame 600")
            .landmarks
            .clone();
        let runs = training_sets(&dlib, &found);
        println!(
            "frame: {}; tracking 600-1336 from the finder's frame-600 landmarks",
            if own { "own" } else { "canonical" }
        );
        for (name, set) in runs {
            if name == "finder averaged, confident" {
                // "finder averaged, confident", refined once (fit to its own frames, rebuilt from the
                // fitted landmarks).
                let shapes: Vec<&[f32]> = set.iter().map(|t| t.landmarks.as_slice()).collect();
                let chosen: Vec<TrainingImage> = select_varied(&shapes, 20)
                    .unwrap()
                    .iter()
                    .map(|&i| set[i].clone())
                    .collect();
                let m = Builder::new(BuildOptions {
                    frame,
                    ..BuildOptions::default()
                })
                .build_refined(&chosen, None, 1, &mut |_| true)
                .unwrap();
                report_model(
                    "finder averaged, confident, refined once",
                    set.len(),
                    &m,
                    &test,
                    &init,
                );
            }
            report_model(name, set.len(), &build(&set, frame), &test, &init);
        }
        println!("total {:.1} s", t0.elapsed().as_secs_f32());
    }
}

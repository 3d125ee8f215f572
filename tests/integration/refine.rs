//! Refining an enrolled model (build, fit it to its own training frames, rebuild from the fitted
//! landmarks), measured on GRID spk07 with its training landmarks perturbed as a face finder's
//! would be: training frames `data/grid/spk07_pwij3p/train20.txt` (landmarks + uniform noise of
//! +-5.5% of the eye distance per coordinate, mean point error ~0.04 of it, the finder's order);
//! tracking measured on the unseen clip `data/grid/spk07_id2_vcd_swwp2s` (75 frames, none used
//! to build) from its first frame's dlib landmarks. Error = mean landmark distance / outer-eye-
//! corner distance. Prints the figures (`cargo test --release --test integration refine:: -- --nocapture`).
//! Fitting halves the training landmarks' noise, but the rebuilt model tracks the unseen clip
//! worse: refinement stays an option (`build_refined`, `buildModel({refine})`), off by default.

use facemimic::fit::FaceTracker;
use std::path::Path;

use facemimic::find::landmark_error;
use facemimic::fit::{FitOptions, Tracker};
use facemimic::{io, refine_landmarks, BuildOptions, Builder, Model, TrainingImage};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn load(paths: &[std::path::PathBuf]) -> Vec<TrainingImage> {
    paths
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect()
}

fn iod(l: &[f32]) -> f32 {
    ((l[90] - l[72]).powi(2) + (l[91] - l[73]).powi(2)).sqrt()
}

fn mean(v: &[f32]) -> f32 {
    v.iter().sum::<f32>() / v.len() as f32
}

fn track(model: &Model, seq: &[TrainingImage]) -> f32 {
    let mut t = Tracker::new(model, FitOptions::default()).unwrap();
    t.start_from_landmarks(&seq[0].landmarks).unwrap();
    let errs: Vec<f32> = seq
        .iter()
        .map(|f| {
            landmark_error(
                &t.track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                    .unwrap()
                    .landmarks,
                &f.landmarks,
            )
        })
        .collect();
    mean(&errs)
}

#[test]
fn refinement_reduces_landmark_noise() {
    let train = load(&io::read_list(&root().join("data/grid/spk07_pwij3p/train20.txt")).unwrap());
    let mut clip: Vec<_> = std::fs::read_dir(root().join("data/grid/spk07_id2_vcd_swwp2s"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    clip.sort();
    let clip = load(&clip);

    // Finder-like noise, deterministic.
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut rng = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        ((s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) as f32
    };
    let noisy: Vec<TrainingImage> = train
        .iter()
        .map(|t| {
            let a = 0.055 * iod(&t.landmarks);
            let mut n = t.clone();
            n.landmarks.iter_mut().for_each(|v| *v += a * rng());
            n
        })
        .collect();
    let b = Builder::new(BuildOptions {
        name: "spk07".into(),
        ..BuildOptions::default()
    });
    let clean = b.build(&train, None).unwrap();
    let first = b.build(&noisy, None).unwrap();
    let fitted = refine_landmarks(&first, &noisy, &mut |_| true).unwrap();
    let refined = b.build_refined(&noisy, None, 1, &mut |_| true).unwrap();

    let err_noisy: Vec<f32> = noisy
        .iter()
        .zip(&train)
        .map(|(n, t)| landmark_error(&n.landmarks, &t.landmarks))
        .collect();
    let err_fitted: Vec<f32> = fitted
        .iter()
        .zip(&train)
        .map(|(f, t)| landmark_error(f, &t.landmarks))
        .collect();
    let (tc, tn, tr) = (
        track(&clean, &clip),
        track(&first, &clip),
        track(&refined, &clip),
    );
    println!(
        "refine: training landmarks vs dlib {:.4} (noisy) -> {:.4} (fitted); shape modes {} (dlib) {} (noisy) {} (refined); \
         tracking the unseen clip: dlib-built {tc:.4}, noisy-built {tn:.4}, refined {tr:.4}",
        mean(&err_noisy),
        mean(&err_fitted),
        clean.shape().n_modes(),
        first.shape().n_modes(),
        refined.shape().n_modes(),
    );
    assert!(
        mean(&err_noisy) > 0.03,
        "the noise is of the finder's order"
    );
    assert!(
        mean(&err_fitted) < 0.85 * mean(&err_noisy),
        "fitting removes less than 15% of the landmark noise"
    );
    // Measured: the refined model tracks this clip worse than the unrefined one (0.050 against
    // 0.031; docs/fitting.md), which is why the page does not refine by default. Guard against
    // breakage only.
    assert!(
        tr.is_finite() && tr < 0.1,
        "the refined model does not track ({tr})"
    );
    assert!(
        tn < 0.05 && tc < 0.05,
        "models from noisy ({tn}) or dlib ({tc}) landmarks do not track"
    );
}

//! Benchmarks of the AAM fitter: fits per second, native single thread.
//!
//! - `fit/track/grid-spk07`: the spk07 model (built from `train20.txt`) tracking the 75 frames
//!   of the unseen GRID clip (one criterion iteration = one frame, in sequence).
//! - `fit/track/franck`: the franck-dev model tracking its first 200 frames (skipped with a
//!   message when `../shared/data/franck-dev` is absent).
//! - `fit/precompute/*`: `Fitter::new` (the per-model precomputation).
//!
//! Run: `cargo bench --bench fit`. Each tracking benchmark also prints the model sizes.

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use facemimic::fit::{FitOptions, Fitter, Tracker};
use facemimic::{io, Builder, Image, Model, TrainingImage};

fn build(list: &Path) -> Model {
    let paths = io::read_list(list).expect("list");
    let images: Vec<TrainingImage> = paths
        .iter()
        .map(|p| io::read_training_image(p).expect("image"))
        .collect();
    Builder::default().build(&images, None).expect("model")
}

fn frames(dir: &Path, limit: usize) -> Vec<(Image, Vec<f32>)> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    paths.sort();
    paths
        .iter()
        .take(limit)
        .map(|p| {
            let t = io::read_training_image(p).expect("frame");
            (t.image, t.landmarks)
        })
        .collect()
}

fn bench_track(c: &mut Criterion, name: &str, model: &Model, seq: &[(Image, Vec<f32>)]) {
    let options = FitOptions::default();
    let fitter = Fitter::new(model, options.clone()).expect("fitter");
    println!(
        "{name}: {} landmarks, {} shape modes, {} RGB appearance modes, {} frame pixels; \
         fitting {} parameters on {:?} level pixels with {:?} grey appearance images",
        model.landmarks(),
        model.shape().n_modes(),
        model.appearance().n_modes(),
        model.frame().n_pixels(),
        fitter.n_params(),
        fitter.level_pixels(),
        fitter.level_appearance_modes()
    );
    let mut group = c.benchmark_group("fit/track");
    group.throughput(Throughput::Elements(1));
    let mut tracker = Tracker::new(model, options).expect("tracker");
    tracker.start_from_landmarks(&seq[0].1).expect("start");
    let views: Vec<_> = seq
        .iter()
        .map(|(img, _)| img.view().expect("view"))
        .collect();
    let mut i = 0usize;
    group.bench_function(name, |b| {
        b.iter(|| {
            if i == views.len() {
                i = 0;
                tracker.start_from_landmarks(&seq[0].1).expect("start");
            }
            let r = tracker.track(&views[i]).expect("track");
            i += 1;
            r.error
        })
    });
    group.finish();
    let mut group = c.benchmark_group("fit/precompute");
    group.sample_size(10);
    group.bench_function(name, |b| {
        b.iter(|| {
            Fitter::new(model, FitOptions::default())
                .expect("fitter")
                .n_params()
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let grid = build(&root.join("data/grid/spk07_pwij3p/train20.txt"));
    let seq = frames(&root.join("data/grid/spk07_id2_vcd_swwp2s"), 75);
    bench_track(c, "grid-spk07", &grid, &seq);
    let franck = root.join("../shared/data/franck-dev");
    if franck.join("train20.txt").is_file() {
        let model = build(&franck.join("train20.txt"));
        let seq = frames(&franck, 200);
        bench_track(c, "franck", &model, &seq);
    } else {
        println!("skipping franck: {} is absent", franck.display());
    }
}

criterion_group!(fit, benches);
criterion_main!(fit);

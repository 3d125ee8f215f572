//! Benchmarks of the AAM fitter: fits per second, native single thread.
//!
//! - `fit/track/grid-spk07`: the spk07 model (built from `train20.txt`) tracking the 75 frames
//!   of the unseen GRID clip (one criterion iteration = one frame, in sequence).
//! - `fit/track/franck2`: the model built from `franck-dev/train20.txt` tracking the first 300
//!   frames of the unseen `franck-dev2` (head turns; skipped with a message when
//!   `../shared/data` is absent).
//! - `fit/precompute/*`: `Fitter::new` (the per-model precomputation).
//! - `fit/reacquire/*`: what one re-acquisition costs: the face finder on the frame plus the cold
//!   fit from the face found (three coarse starts, 3x the iterations), i.e. `Tracker::start_auto`
//!   then one `track` (franck-dev2 frame 0 with the franck model; webcam-dev frame 600 with a
//!   model from its frames 0, 30, ..., 570); `*-finder-only` times the finder alone, so the
//!   cold fit is the difference.
//!
//! - `fit/follow/grid-spk03`: the person-independent path (`Follower`): spk07's model following
//!   spk03's GRID clip (another person; one criterion iteration = one frame, in sequence: two
//!   landmark passes near the last face, the smoothing, the neutral and the mapping).
//!
//! Run: `cargo bench --bench fit`. Each tracking benchmark also prints the model sizes.

use facemimic::fit::FaceTracker;
use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use facemimic::fit::{FitOptions, Fitter, FollowOptions, Follower, Tracker};
use facemimic::{io, Builder, FaceFinder, Image, Model, TrainingImage};

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

/// `fit/track/NAME`: one criterion iteration tracks the next frame of `seq`, starting again
/// from the first frame's landmarks after the last.
fn track_in_sequence(
    c: &mut Criterion,
    name: &str,
    tracker: &mut Tracker,
    seq: &[(Image, Vec<f32>)],
) {
    let mut group = c.benchmark_group("fit/track");
    group.throughput(Throughput::Elements(1));
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
            let r = tracker
                .track(&views[i], facemimic::fit::DEFAULT_TIME_STEP)
                .expect("track");
            i += 1;
            r.error
        })
    });
    group.finish();
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
    let mut tracker = Tracker::new(model, options).expect("tracker");
    track_in_sequence(c, name, &mut tracker, seq);
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

/// `fit/track` on frames enlarged twice (each pixel a 2x2 block): the tracker fits a copy
/// resampled by about 0.5, so against `grid-spk07` this is the cost of its resampling.
fn bench_track_doubled(c: &mut Criterion, name: &str, model: &Model, seq: &[(Image, Vec<f32>)]) {
    let doubled: Vec<(Image, Vec<f32>)> = seq
        .iter()
        .map(|(img, lm)| {
            let (w, h) = (img.width * 2, img.height * 2);
            let mut data = vec![0u8; (w * h * 4) as usize];
            for y in 0..h {
                for x in 0..w {
                    let s = (((y / 2) * img.width + x / 2) * 4) as usize;
                    let d = ((y * w + x) * 4) as usize;
                    data[d..d + 4].copy_from_slice(&img.data[s..s + 4]);
                }
            }
            let lm = lm.iter().map(|v| 2.0 * (v + 0.5) - 0.5).collect();
            (
                Image {
                    width: w,
                    height: h,
                    data,
                },
                lm,
            )
        })
        .collect();
    let mut tracker = Tracker::new(model, FitOptions::default()).expect("tracker");
    track_in_sequence(c, name, &mut tracker, &doubled);
    println!("{name}: fitted at scale {}", tracker.scale());
}

fn benches(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let grid = build(&root.join("data/grid/spk07_pwij3p/train20.txt"));
    let seq = frames(&root.join("data/grid/spk07_id2_vcd_swwp2s"), 75);
    bench_track(c, "grid-spk07", &grid, &seq);
    bench_track_doubled(c, "grid-spk07-x2", &grid, &seq);
    bench_follow(
        c,
        "grid-spk03",
        &grid,
        &frames(&root.join("data/grid/spk03_lbax4n"), 75),
    );
    let shared = root.join("../shared/data");
    if shared.join("franck-dev/train20.txt").is_file() {
        let model = build(&shared.join("franck-dev/train20.txt"));
        let seq = frames(&shared.join("franck-dev2"), 300);
        bench_track(c, "franck2", &model, &seq);
        bench_reacquire(c, "franck2", &model, &seq[0].0);
        let webcam = shared.join("webcam-dev");
        let train: Vec<TrainingImage> = (0..600)
            .step_by(30)
            .map(|i| io::read_training_image(&webcam.join(format!("{i:06}.jpg"))).expect("frame"))
            .collect();
        let model = Builder::default().build(&train, None).expect("model");
        let frame = io::read_training_image(&webcam.join("000600.jpg")).expect("frame");
        bench_reacquire(c, "webcam", &model, &frame.image);
    } else {
        println!(
            "skipping franck2 and webcam: {} is absent",
            shared.display()
        );
    }
}

/// The person-independent path following `seq` with `model` (a frame per iteration, looping).
fn bench_follow(c: &mut Criterion, name: &str, model: &Model, seq: &[(Image, Vec<f32>)]) {
    let mut follower = Follower::new(model, FollowOptions::default()).expect("follower");
    let views: Vec<_> = seq.iter().map(|(i, _)| i.view().expect("view")).collect();
    let mut group = c.benchmark_group("fit/follow");
    group.throughput(Throughput::Elements(1));
    let mut k = 0;
    group.bench_function(name, |b| {
        b.iter(|| {
            let r = follower
                .track(&views[k % views.len()], 0.04)
                .expect("follow");
            assert!(!r.lost, "lost");
            k += 1;
            r.params.shape[0]
        })
    });
    group.finish();
}

/// One re-acquisition: the face finder, then the cold fit from the face it found.
fn bench_reacquire(c: &mut Criterion, name: &str, model: &Model, image: &Image) {
    let mut tracker = Tracker::new(model, FitOptions::default()).expect("tracker");
    tracker.set_face_source(Box::new(FaceFinder::new().expect("finder")));
    let view = image.view().expect("view");
    let mut group = c.benchmark_group("fit/reacquire");
    group.sample_size(20);
    group.bench_function(name, |b| {
        b.iter(|| {
            tracker.start_auto().expect("auto");
            let r = tracker
                .track(&view, facemimic::fit::DEFAULT_TIME_STEP)
                .expect("track");
            assert!(r.reacquired, "no face found");
            r.error
        })
    });
    // Its first part alone: the face finder on the frame.
    let mut finder = FaceFinder::new().expect("finder");
    group.bench_function(format!("{name}-finder-only"), |b| {
        b.iter(|| finder.find(&view).len())
    });
    group.finish();
}

criterion_group!(fit, benches);
criterion_main!(fit);

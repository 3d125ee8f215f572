//! What the integration tests, the examples, the benchmarks and the fuzz harness share: the one
//! random number generator ([`Rng`]), the landmark perturbation of the fitting measures
//! ([`perturb`]), the synthetic training set ([`synthetic`]), the image comparison
//! ([`pixels`]) and, natively, the research data in `../shared` ([`shared_data`]; see the
//! README, "The quick loop") and the mutation fuzzing engine ([`fuzz`]). A dev-dependency of
//! every crate of the workspace, never a dependency of the product.
#![allow(dead_code)]
#![allow(missing_docs)]
#![allow(clippy::needless_range_loop)]

#[cfg(not(target_arch = "wasm32"))]
pub mod following;
pub mod fuzz;
#[cfg(target_arch = "wasm32")]
pub mod js;
pub mod pixels;
mod rng;
#[cfg(not(target_arch = "wasm32"))]
pub mod sheet;
pub mod synthetic;

pub use rng::Rng;

#[cfg(not(target_arch = "wasm32"))]
use std::path::{Path, PathBuf};

#[cfg(not(target_arch = "wasm32"))]
use facemimic::fit::FaceTracker;

use facemimic::Similarity;
#[cfg(not(target_arch = "wasm32"))]
use facemimic::{
    fit::Tracker, io, select_varied, with_default_backdrop, BuildOptions, Builder, FaceFinder,
    Image, ImageRef, Model, TrainingImage,
};

/// Perturbs landmarks about their centroid: translation up to 5% of the face width (extent of
/// the landmarks along x) in x and y, rotation up to 5 degrees, scale up to 5%; the cold starts
/// of the fitter's convergence-basin measures.
pub fn perturb(lm: &[f32], rng: &mut Rng) -> Vec<f32> {
    let n = lm.len() / 2;
    let (mut cx, mut cy) = (0.0, 0.0);
    for p in lm.chunks_exact(2) {
        cx += p[0] / n as f32;
        cy += p[1] / n as f32;
    }
    let xs = lm.iter().step_by(2);
    let width = xs.clone().copied().fold(f32::MIN, f32::max) - xs.copied().fold(f32::MAX, f32::min);
    let (dx, dy) = (0.05 * width * rng.sym(), 0.05 * width * rng.sym());
    let rot = 5f32.to_radians() * rng.sym();
    let scale = 1.0 + 0.05 * rng.sym();
    let t = Similarity::from_parts(scale, rot, 0.0, 0.0);
    lm.chunks_exact(2)
        .flat_map(|p| {
            let (x, y) = t.apply_point(p[0] - cx, p[1] - cy);
            [x + cx + dx, y + cy + dy]
        })
        .collect()
}

#[cfg(not(target_arch = "wasm32"))]
/// `../shared/data/NAME` beside the repository, or `None` after a visible "SKIPPED" message
/// when it is absent. Under `CI` its absence is a failure: CI always has `../shared`.
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let d = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("../shared/data")
        .join(name);
    if d.is_dir() {
        return Some(d);
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "{} is absent (CI must have ../shared beside the repository)",
        d.display()
    );
    eprintln!("SKIPPED: {} is absent", d.display());
    None
}

#[cfg(not(target_arch = "wasm32"))]
/// A path in the repository.
pub fn repo(p: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(p)
}

#[cfg(not(target_arch = "wasm32"))]
/// The landmarked images of the list file `list` (a repository path; one image a line, e.g.
/// `data/grid/spk07_pwij3p/train20.txt`).
pub fn list_images(list: &str) -> Vec<TrainingImage> {
    io::read_list(&repo(list))
        .unwrap()
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect()
}

#[cfg(not(target_arch = "wasm32"))]
/// The model named `name` built with the default options from the list file `list` (a
/// repository path), with its default backdrop if `backdrop`: built once per test binary and
/// kept for the binary's life.
pub fn list_model(list: &str, name: &str, backdrop: bool) -> &'static Model {
    path_list_model(&repo(list), name, backdrop)
}

#[cfg(not(target_arch = "wasm32"))]
/// [`list_model`] of the list file at `list` (any path, e.g. a clip of `../shared`'s
/// `train20.txt` from [`shared_data`]).
pub fn path_list_model(list: &Path, name: &str, backdrop: bool) -> &'static Model {
    type Built = Vec<((PathBuf, String, bool), &'static Model)>;
    static BUILT: std::sync::Mutex<Built> = std::sync::Mutex::new(Vec::new());
    let key = (list.to_path_buf(), name.to_string(), backdrop);
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(&(_, m)) = built.iter().find(|(k, _)| *k == key) {
        return m;
    }
    let train: Vec<TrainingImage> = io::read_list(list)
        .unwrap()
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let m = Builder::new(BuildOptions {
        name: name.into(),
        ..BuildOptions::default()
    })
    .build(&train, None)
    .unwrap();
    let m = if backdrop {
        with_default_backdrop(m, &train, None).unwrap()
    } else {
        m
    };
    let m: &'static Model = Box::leak(Box::new(m));
    built.push((key, m));
    m
}

#[cfg(not(target_arch = "wasm32"))]
/// The landmarks of the first (most confident) face `finder` finds in `image`, if any.
pub fn first_face(finder: &mut FaceFinder, image: &Image) -> Option<Vec<f32>> {
    finder
        .find(&image.view().unwrap())
        .into_iter()
        .next()
        .map(|f| f.landmarks)
}

#[cfg(not(target_arch = "wasm32"))]
/// As the page's finder worker does: when `tracker` wants faces ([`Tracker::wants_faces`](facemimic::fit::FaceTracker::wants_faces)),
/// the faces `finder` finds in `image` are offered to it.
pub fn offer_when_wanted(tracker: &mut Tracker, finder: &mut FaceFinder, image: &ImageRef) {
    if tracker.wants_faces() {
        let faces = finder
            .find(image)
            .into_iter()
            .map(|f| f.landmarks)
            .collect();
        tracker.offer_faces(faces).unwrap();
    }
}

#[cfg(not(target_arch = "wasm32"))]
/// The `.jpg` frames of the clip folder `dir`, sorted by name.
pub fn clip_frames(dir: &Path) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .collect();
    paths.sort();
    paths
}

#[cfg(not(target_arch = "wasm32"))]
/// The landmarked images at `paths`.
pub fn load(paths: &[PathBuf]) -> Vec<TrainingImage> {
    paths
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect()
}

#[cfg(not(target_arch = "wasm32"))]
/// Frame `i` of the clip in `dir` (`NNNNNN.jpg` and its landmarks).
pub fn frame(dir: &Path, i: usize) -> TrainingImage {
    io::read_training_image(&dir.join(format!("{i:06}.jpg"))).unwrap()
}

#[cfg(not(target_arch = "wasm32"))]
/// The `n` most varied of `images` (farthest-point sampling of their aligned shapes,
/// [`select_varied`]), in the order chosen.
pub fn varied(images: &[TrainingImage], n: usize) -> Vec<TrainingImage> {
    let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
    select_varied(&shapes, n)
        .unwrap()
        .into_iter()
        .map(|i| images[i].clone())
        .collect()
}

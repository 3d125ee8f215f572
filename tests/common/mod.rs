//! Helpers shared by the integration tests that read the research data in `../shared` (see
//! the README, "The research data in `../shared`").
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use facemimic::{io, select_varied, TrainingImage};

/// `../shared/data/NAME` beside the repository, or `None` after a visible "SKIPPED" message
/// when it is absent. Under `CI` its absence is a failure: CI always has `../shared`.
pub fn shared_data(name: &str) -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR"))
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

/// Frame `i` of the clip in `dir` (`NNNNNN.jpg` and its landmarks).
pub fn frame(dir: &Path, i: usize) -> TrainingImage {
    io::read_training_image(&dir.join(format!("{i:06}.jpg"))).unwrap()
}

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

//! Helpers shared by the integration tests that read the research data in `../shared` (see
//! the README, "The research data in `../shared`").
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use facemimic::{io, TrainingImage};

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

//! What the benchmarks share: GRID models built from the committed frames.

use std::path::Path;

use facemimic::{io, BuildOptions, Builder, Model, TrainingImage};

/// The 20 training frames of the GRID clip `folder` (`data/grid/FOLDER/train20.txt`).
pub fn grid_training(folder: &str) -> Vec<TrainingImage> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/grid")
        .join(folder);
    let list = io::read_list(&dir.join("train20.txt")).expect("GRID training list");
    list.iter()
        .map(|p| io::read_training_image(p).expect("GRID frame"))
        .collect()
}

/// The model of `images`, named after the clip's speaker (`spk07_pwij3p` -> `spk07`), in
/// `frame_of`'s frame or the canonical one.
pub fn build(folder: &str, images: &[TrainingImage], frame_of: Option<&Model>) -> Model {
    let name = folder.split('_').next().unwrap_or(folder).to_string();
    Builder::new(BuildOptions {
        name,
        ..BuildOptions::default()
    })
    .build(images, frame_of)
    .expect("GRID model")
}

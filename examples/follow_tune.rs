//! Chooses the person-independent follower's smoothing and neutral rate on webcam-dev frames
//! 0-599 only (the frames `tests/integration/follow.rs` measures, 600-1336, stay unseen): prints each
//! setting's convention-free error, frames over 0.1, raw error, the cloned mouth's correlation
//! with the person's and the frames lost. Research data read from `../shared` (never committed).
//!
//! `cargo run --release --example follow_tune` (a few minutes).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(target_arch = "wasm32"))]
use facemimic_testkit as common;

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    use common::following::{errors, follow, mean, over, pearson, spk07};
    use common::{frame, shared_data};
    use facemimic::fit::{mouth_opening, FollowOptions};
    use facemimic::TrainingImage;

    let Some(dir) = shared_data("webcam-dev") else {
        return;
    };
    let source = spk07();
    let frames: Vec<TrainingImage> = (0..600).map(|i| frame(&dir, i)).collect();
    let person_mouth: Vec<f32> = frames.iter().map(|t| mouth_opening(&t.landmarks)).collect();
    for (min_cutoff, beta, neutral_step) in [
        (1.5, 1.0, 0.05),
        (0.7, 1.0, 0.05),
        (3.0, 1.0, 0.05),
        (1.5, 0.3, 0.05),
        (1.5, 3.0, 0.05),
        (1.5, 1.0, 0.02),
        (1.5, 1.0, 0.1),
        (1000.0, 0.0, 0.05),
    ] {
        let options = FollowOptions {
            min_cutoff,
            beta,
            neutral_step,
            ..FollowOptions::default()
        };
        let f = follow(&source, &frames, options);
        let (free, raw) = errors(&f.landmarks, &frames);
        println!(
            "min_cutoff {min_cutoff}, beta {beta}, neutral_step {neutral_step}: \
             convention-free {:.4} ({} over 0.1), raw {:.4}, mouth r {:.3}, {} lost",
            mean(&free),
            over(&free),
            mean(&raw),
            pearson(&f.target_mouth, &person_mouth),
            f.lost
        );
    }
}

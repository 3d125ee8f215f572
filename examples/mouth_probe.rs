//! The person-independent follower's cloned mouth against the person's, with and without the
//! head-turn split (`FollowOptions::split_head_turns`): spk07's GRID model follows a range of
//! a shared clip and drives spk02 (`map`); prints the Pearson correlation with dlib's inner-lip
//! opening of the followed landmarks' opening, the cloned target's and the source's first
//! shape mode, and the same per 100 frames with `--windows`. Research data read from
//! `../shared` (never committed).
//!
//! `cargo run --release --example mouth_probe -- [CLIP FIRST LAST] [--windows]` (default
//! franck-dev 0 999; `tests/integration/follow.rs` measures franck-dev2 3800 4799 and webcam-dev 600 1336,
//! so choose other frames to tune on).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(target_arch = "wasm32"))]
use facemimic_testkit as common;

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    use common::following::{build, pearson, spk07};
    use common::{frame, shared_data};
    use facemimic::clone::{CloneOptions, Cloner};
    use facemimic::fit::FaceTracker;
    use facemimic::fit::{mouth_opening, FollowOptions, Follower};
    use facemimic::TrainingImage;

    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let windows = args.iter().any(|a| a == "--windows");
    args.retain(|a| a != "--windows");
    let clip = args.first().cloned().unwrap_or_else(|| "franck-dev".into());
    let first: usize = args.get(1).map_or(0, |s| s.parse().expect("FIRST"));
    let last: usize = args.get(2).map_or(999, |s| s.parse().expect("LAST"));
    let Some(dir) = shared_data(&clip) else {
        return;
    };
    let source = spk07();
    let target = build("data/grid/spk02_brbk7n/train20.txt", "spk02");
    let frames: Vec<TrainingImage> = (first..=last).map(|i| frame(&dir, i)).collect();
    let person: Vec<f32> = frames.iter().map(|t| mouth_opening(&t.landmarks)).collect();
    for split in [false, true] {
        let options = FollowOptions {
            split_head_turns: split,
            ..FollowOptions::default()
        };
        let mut follower = Follower::new(&source, options).unwrap();
        let mut cloner = Cloner::new(source.clone()).unwrap();
        cloner.add_target(target.clone()).unwrap();
        let (mut followed, mut cloned, mut mode0) = (vec![], vec![], vec![]);
        for t in &frames {
            let r = follower
                .track(&t.image.view().unwrap(), 1.0 / 25.0)
                .unwrap();
            followed.push(mouth_opening(&r.landmarks));
            mode0.push(r.params.shape[0]);
            cloner
                .clone_frame(&r.params, &CloneOptions::default())
                .unwrap();
            cloned.push(mouth_opening(cloner.target_shape(0)));
        }
        println!(
            "{clip} {first}-{last}, head-turn split {split}: followed {:.3}, cloned {:.3}, \
             mode 0 {:.3}",
            pearson(&followed, &person),
            pearson(&cloned, &person),
            pearson(&mode0, &person)
        );
        if windows {
            for w in (0..frames.len()).step_by(100) {
                let e = (w + 100).min(frames.len());
                println!(
                    "  frames {}-{}: followed {:.2}, cloned {:.2}, mode 0 {:.2}",
                    first + w,
                    first + e - 1,
                    pearson(&followed[w..e], &person[w..e]),
                    pearson(&cloned[w..e], &person[w..e]),
                    pearson(&mode0[w..e], &person[w..e])
                );
            }
        }
    }
}

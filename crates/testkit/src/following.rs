//! Following a clip with the person-independent path ([`Follower`]) and scoring it: what
//! `tests/integration/follow.rs` measures and `examples/follow_tune.rs` tunes with.

use facemimic::clone::{CloneOptions, Cloner, Method};
use facemimic::find::{convention_free_errors, landmark_error};
use facemimic::fit::FaceTracker;
use facemimic::fit::{mouth_opening, FollowOptions, Follower};
use facemimic::{Builder, Model, TrainingImage};

use super::list_images;

/// The model of the images listed in `list` (a repository path), named `name`.
pub fn build(list: &str, name: &str) -> Model {
    let mut m = Builder::default().build(&list_images(list), None).unwrap();
    m.set_name(name);
    m
}

/// spk07's model from its GRID training list (as `scripts/build-models.sh` builds it).
pub fn spk07() -> Model {
    build("data/grid/spk07_pwij3p/train20.txt", "spk07")
}

/// Pearson correlation of `a` and `b`.
pub fn pearson(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len() as f64;
    let ma = a.iter().map(|&v| v as f64).sum::<f64>() / n;
    let mb = b.iter().map(|&v| v as f64).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x as f64 - ma, y as f64 - mb);
        sab += x * y;
        saa += x * x;
        sbb += y * y;
    }
    (sab / (saa * sbb).sqrt()) as f32
}

/// The mean of `v`.
pub fn mean(v: &[f32]) -> f32 {
    v.iter().sum::<f32>() / v.len() as f32
}

/// Frames over 0.1 (or not a number).
pub fn over(v: &[f32]) -> usize {
    v.iter().filter(|e| e.is_nan() || **e > 0.1).count()
}

/// Convention-free and raw errors of `tracked` against `truth`, frame by frame.
pub fn errors(tracked: &[Vec<f32>], truth: &[TrainingImage]) -> (Vec<f32>, Vec<f32>) {
    let pairs: Vec<(&[f32], &[f32])> = tracked
        .iter()
        .zip(truth)
        .map(|(t, g)| (t.as_slice(), g.landmarks.as_slice()))
        .collect();
    let raw = pairs.iter().map(|(t, g)| landmark_error(t, g)).collect();
    (convention_free_errors(&pairs), raw)
}

/// What following a clip gave.
pub struct Followed {
    /// The followed landmarks, per frame.
    pub landmarks: Vec<Vec<f32>>,
    /// spk02's mouth opening, cloned by `map`, per frame.
    pub target_mouth: Vec<f32>,
    /// Frames lost.
    pub lost: u32,
    /// Faces found by the finder.
    pub reacquisitions: u32,
    /// Milliseconds a frame (the follower alone).
    pub ms_per_frame: f64,
}

/// Follows `frames` with `source`'s model (started with no landmarks), cloning spk02 by `map`.
pub fn follow(source: &Model, frames: &[TrainingImage], options: FollowOptions) -> Followed {
    let mut f = Follower::new(source, options).unwrap();
    let mut cloner = Cloner::new(source.clone()).unwrap();
    cloner
        .add_target(build("data/grid/spk02_brbk7n/train20.txt", "spk02"))
        .unwrap();
    let clone_options = CloneOptions {
        method: Method::Map,
        ..CloneOptions::default()
    };
    let mut landmarks = Vec::with_capacity(frames.len());
    let mut target_mouth = Vec::with_capacity(frames.len());
    let mut secs = 0.0;
    for t in frames {
        let view = t.image.view().unwrap();
        let t0 = std::time::Instant::now();
        let r = f.track(&view, 1.0 / 25.0).unwrap();
        secs += t0.elapsed().as_secs_f64();
        landmarks.push(r.landmarks.clone());
        cloner.clone_frame(&r.params, &clone_options).unwrap();
        target_mouth.push(mouth_opening(cloner.target_shape(0)));
    }
    Followed {
        landmarks,
        target_mouth,
        lost: f.sequence().lost_count(),
        reacquisitions: f.sequence().reacquisitions(),
        ms_per_frame: 1e3 * secs / frames.len() as f64,
    }
}

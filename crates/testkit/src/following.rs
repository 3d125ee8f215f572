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
    /// The mouth's width and lip-corner lift ([`mouth_features`]) of the source model's base
    /// shape moved by the follower's observed displacement (what the expressive method
    /// clones), per frame; zeros without one.
    pub displaced_mouth: Vec<[f32; 2]>,
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
    let mut displaced_mouth = Vec::with_capacity(frames.len());
    let mut displaced = source.shape().base.clone();
    let mut secs = 0.0;
    for t in frames {
        let view = t.image.view().unwrap();
        let t0 = std::time::Instant::now();
        let r = f.track(&view, 1.0 / 25.0).unwrap();
        secs += t0.elapsed().as_secs_f64();
        landmarks.push(r.landmarks.clone());
        cloner.clone_frame(&r.params, &clone_options).unwrap();
        target_mouth.push(mouth_opening(cloner.target_shape(0)));
        displaced_mouth.push(match f.observed().and_then(|o| o.displacement) {
            Some(d) => {
                for ((o, b), d) in displaced.iter_mut().zip(&source.shape().base).zip(d) {
                    *o = b + d;
                }
                mouth_features(&displaced)
            }
            None => [0.0; 2],
        });
    }
    Followed {
        landmarks,
        target_mouth,
        displaced_mouth,
        lost: f.sequence().lost_count(),
        reacquisitions: f.sequence().reacquisitions(),
        ms_per_frame: 1e3 * secs / frames.len() as f64,
    }
}

/// A real mouth counts as open from this inner-lip gap (outer eye corners' distances).
pub const OPEN_MOUTH: f32 = 0.08;

/// One measured frame of [`follow_expressions`].
pub struct FollowedFrame {
    /// The frame's index in the clip.
    pub index: usize,
    /// The real frame's inner mouth over its skin (mean luminances, the frame sampled into the
    /// reference frame at dlib's points), when its mouth is open ([`OPEN_MOUTH`]).
    pub teeth: Option<f32>,
    /// The real mouth's width and lip-corner lift ([`mouth_features`]).
    pub real_mouth: [f32; 2],
    /// The tracked source's mouth width and lift (the tracker's landmarks on the frame).
    pub tracked_mouth: [f32; 2],
    /// Per target, the clone's inner mouth over its skin, observed off and on.
    pub target_teeth: Vec<[f32; 2]>,
    /// Per target, the clone's mouth width and lift, observed off and on.
    pub target_mouth: Vec<[[f32; 2]; 2]>,
    /// Per target, the mean absolute change of the clone's appearance from the previous
    /// measured frame (0 on the first), observed off and on: how much it flickers.
    pub target_change: Vec<[f32; 2]>,
}

/// What [`follow_expressions`] measured.
pub struct FollowedExpressions {
    /// The measured frames.
    pub frames: Vec<FollowedFrame>,
}

/// p95 - p5 of `v`.
pub fn spread(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    let at = |q: f32| v[((v.len() - 1) as f32 * q).round() as usize];
    at(0.95) - at(0.05)
}

impl FollowedExpressions {
    /// Target `t`'s inner mouth against the real one, over the frames whose mouth is open
    /// (Pearson r), observed off and on.
    pub fn teeth_r(&self, t: usize) -> [f32; 2] {
        let open: Vec<&FollowedFrame> = self.frames.iter().filter(|f| f.teeth.is_some()).collect();
        let real: Vec<f32> = open.iter().map(|f| f.teeth.unwrap_or(0.0)).collect();
        [0, 1].map(|on| {
            let v: Vec<f32> = open.iter().map(|f| f.target_teeth[t][on]).collect();
            pearson(&real, &v)
        })
    }

    /// Target `t`'s spread (p95 - p5) of mouth feature `k` (0 width, 1 lift) over the real
    /// frames', observed off and on.
    pub fn spread_ratio(&self, t: usize, k: usize) -> [f32; 2] {
        let real = spread(self.frames.iter().map(|f| f.real_mouth[k]).collect());
        [0, 1].map(|on| {
            spread(
                self.frames
                    .iter()
                    .map(|f| f.target_mouth[t][on][k])
                    .collect(),
            ) / real
        })
    }

    /// Target `t`'s mouth feature `k` (0 width, 1 lift) against the real one over the measured
    /// frames (Pearson r), observed off and on.
    pub fn mouth_r(&self, t: usize, k: usize) -> [f32; 2] {
        let real: Vec<f32> = self.frames.iter().map(|f| f.real_mouth[k]).collect();
        [0, 1].map(|on| {
            let v: Vec<f32> = self
                .frames
                .iter()
                .map(|f| f.target_mouth[t][on][k])
                .collect();
            pearson(&real, &v)
        })
    }

    /// The tracked source's spread (p95 - p5) of mouth feature `k` (0 width, 1 lift) over the
    /// real frames': how much of the real motion the tracker read, before any cloning.
    pub fn tracked_spread_ratio(&self, k: usize) -> f32 {
        let real = spread(self.frames.iter().map(|f| f.real_mouth[k]).collect());
        spread(self.frames.iter().map(|f| f.tracked_mouth[k]).collect()) / real
    }

    /// Target `t`'s mean frame-to-frame appearance change, observed off and on.
    pub fn change(&self, t: usize) -> [f32; 2] {
        let n = self.frames.len().saturating_sub(1).max(1) as f32;
        [0, 1].map(|on| {
            self.frames
                .iter()
                .map(|f| f.target_change[t][on])
                .sum::<f32>()
                / n
        })
    }

    /// The clip indices of the tenth of measured frames that laugh most (real mouth width plus
    /// lift), strongest first.
    pub fn laughing(&self) -> Vec<usize> {
        let score = |f: &FollowedFrame| f.real_mouth[0] + f.real_mouth[1];
        let mut idx: Vec<usize> = (0..self.frames.len()).collect();
        idx.sort_by(|&a, &b| score(&self.frames[b]).total_cmp(&score(&self.frames[a])));
        idx.truncate(self.frames.len().div_ceil(10));
        idx.into_iter().map(|k| self.frames[k].index).collect()
    }
}

/// Mouth width and lip-corner lift of 68 points (how far the corners lie above the lips'
/// centre along the face's up direction), in outer eye corners' distances: the core's
/// [`facemimic::fit::mouth_shape`], zeros for a shape without them.
pub fn mouth_features(p: &[f32]) -> [f32; 2] {
    facemimic::fit::mouth_shape(p).unwrap_or([0.0; 2])
}

/// Whether `p` lies inside the polygon of `points`' landmarks `ring` (crossing number).
fn inside(p: [f32; 2], points: &[f32], ring: std::ops::Range<usize>) -> bool {
    let idx: Vec<usize> = ring.collect();
    let mut c = false;
    for k in 0..idx.len() {
        let (a, b) = (idx[k], idx[(k + 1) % idx.len()]);
        let (ax, ay) = (points[2 * a], points[2 * a + 1]);
        let (bx, by) = (points[2 * b], points[2 * b + 1]);
        if (ay > p[1]) != (by > p[1]) && p[0] < ax + (p[1] - ay) / (by - ay) * (bx - ax) {
            c = !c;
        }
    }
    c
}

/// Mean luminance of `app` over `pixels`.
fn mean_luma(app: &[f32], pixels: &[usize]) -> f32 {
    let sum: f32 = pixels
        .iter()
        .map(|&k| facemimic::clone::luma(&app[3 * k..3 * k + 3]))
        .sum();
    sum / pixels.len().max(1) as f32
}

/// Follows the clip `paths` (every frame, in order, at 25 fps) with `source`'s model, and on
/// every `every`-th frame clones it onto `cloner`'s targets with `options`, without and with
/// the follower's observed face ([`Cloner::set_observed`]); measures the real frame (dlib's
/// points) against the clones.
pub fn follow_expressions(
    paths: &[std::path::PathBuf],
    every: usize,
    source: &Model,
    cloner: &mut Cloner,
    options: &CloneOptions,
) -> FollowedExpressions {
    let mut follower = Follower::new(source, FollowOptions::default()).unwrap();
    track_expressions(paths, every, &mut follower, source, cloner, options)
}

/// [`follow_expressions`] with any started tracker of `source`'s model (an AAM `Tracker` of
/// the person's own model, or a `Follower`).
pub fn track_expressions(
    paths: &[std::path::PathBuf],
    every: usize,
    follower: &mut dyn FaceTracker,
    source: &Model,
    cloner: &mut Cloner,
    options: &CloneOptions,
) -> FollowedExpressions {
    let frame = source.frame();
    let v = frame.vertices();
    let (mut mouth, mut skin) = (Vec::new(), Vec::new());
    for (k, px) in frame.pixels().iter().enumerate() {
        let at = [
            px.x as f32 - frame.origin()[0],
            px.y as f32 - frame.origin()[1],
        ];
        if inside(at, v, 60..68) {
            mouth.push(k);
        } else if !inside(at, v, 36..42) && !inside(at, v, 42..48) && !inside(at, v, 48..60) {
            skin.push(k);
        }
    }
    let target_skin: Vec<f32> = (0..cloner.n_targets())
        .map(|t| mean_luma(cloner.target(t).appearance().base(), &skin))
        .collect();
    let mut real = vec![0f32; source.appearance().len()];
    let mut frames = Vec::new();
    let mut previous: Vec<[Vec<f32>; 2]> = (0..cloner.n_targets())
        .map(|_| [Vec::new(), Vec::new()])
        .collect();
    for (i, path) in paths.iter().enumerate() {
        let t = facemimic::io::read_training_image(path).unwrap();
        let view = t.image.view().unwrap();
        let fit = follower.track(&view, 1.0 / 25.0).unwrap().clone();
        if i % every != 0 || fit.status != facemimic::fit::TrackStatus::Tracking {
            continue;
        }
        let teeth = (mouth_opening(&t.landmarks) >= OPEN_MOUTH).then(|| {
            facemimic::sample_rgb(frame, &view, &t.landmarks, &mut real).unwrap();
            mean_luma(&real, &mouth) / mean_luma(&real, &skin)
        });
        let n = cloner.n_targets();
        let (mut target_teeth, mut target_mouth) = (vec![[0f32; 2]; n], vec![[[0f32; 2]; 2]; n]);
        let mut target_change = vec![[0f32; 2]; n];
        for (on, observed) in [(0, None), (1, follower.observed())] {
            cloner.set_observed(observed).unwrap();
            cloner.clone_frame(&fit.params, options).unwrap();
            for k in 0..n {
                target_teeth[k][on] =
                    mean_luma(cloner.target_appearance(k), &mouth) / target_skin[k];
                target_mouth[k][on] = mouth_features(cloner.target_shape(k));
                let app = cloner.target_appearance(k);
                let prev = &mut previous[k][on];
                if prev.len() == app.len() {
                    target_change[k][on] = crate::pixels::mean_abs_diff_f32(prev, app);
                }
                prev.clear();
                prev.extend_from_slice(app);
            }
        }
        frames.push(FollowedFrame {
            index: i,
            teeth,
            real_mouth: mouth_features(&t.landmarks),
            tracked_mouth: mouth_features(&fit.landmarks),
            target_teeth,
            target_mouth,
            target_change,
        });
    }
    cloner.set_observed(None).unwrap();
    FollowedExpressions { frames }
}

//! How sure a tracker is of a frame's fit (issue 33): a [`TrackStatus`] ("tracking",
//! "unsure", "lost") and the [`Reasons`] behind it, and the AAM tracker's [`Confidence`]
//! checks that flag a fit that collapsed, folded or slid off the face while its residual and
//! shape still passed the loss checks.

use serde::{Deserialize, Serialize};

use crate::model::Model;
use crate::similarity::Similarity;

/// How far a frame's fit can be trusted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TrackStatus {
    /// The fit is the face: drive the targets with it.
    #[default]
    Tracking,
    /// The fit may be wrong (see the [`Reasons`]): the targets hold the last good expression
    /// and the tracker works on recovering (a second opinion, a restart from the last good fit).
    Unsure,
    /// No face on this frame: the result is the last good fit.
    Lost,
}

impl TrackStatus {
    /// The status's stable name: `"tracking"`, `"unsure"` or `"lost"` (what the page shows).
    pub fn name(self) -> &'static str {
        match self {
            TrackStatus::Tracking => "tracking",
            TrackStatus::Unsure => "unsure",
            TrackStatus::Lost => "lost",
        }
    }
}

impl std::fmt::Display for TrackStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a fit is doubted or lost: a set of reasons (no allocation; [`Reasons::names`] lists
/// them by their stable names).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Reasons(u16);

impl Reasons {
    /// None: a fit to trust.
    pub const NONE: Reasons = Reasons(0);
    /// "collapsed": the mesh is far smaller than the recent face (or than the model's mean
    /// face at the fit's own scale): the fit shrank onto part of the face.
    pub const COLLAPSED: Reasons = Reasons(1);
    /// "folded": triangles of the mesh turned over, or the lips or eyelids crossed.
    pub const FOLDED: Reasons = Reasons(1 << 1);
    /// "shape": the shape parameters are implausible (Mahalanobis distance from the mean
    /// shape over the bound).
    pub const SHAPE: Reasons = Reasons(1 << 2);
    /// "residual": the residual jumped over the recent good fits' (or over the absolute bound).
    pub const RESIDUAL: Reasons = Reasons(1 << 3);
    /// "jump": the scale or rotation jumped from the previous frame.
    pub const JUMP: Reasons = Reasons(1 << 4);
    /// "finder": the face finder's face on this frame is elsewhere than the fit.
    pub const FINDER: Reasons = Reasons(1 << 5);
    /// "contrast": the picture under the mesh is flat (or far too contrasted) for a face.
    pub const CONTRAST: Reasons = Reasons(1 << 6);
    /// "outside": too many landmarks outside the picture.
    pub const OUTSIDE: Reasons = Reasons(1 << 7);
    /// "no-face": no face acquired yet (a search under way).
    pub const NO_FACE: Reasons = Reasons(1 << 8);
    /// "covered": the lips do not stand out from the skin around them (a hand, a cup or a
    /// mask over the mouth; the enrolment's lip check, `MIN_LIP_CONTRAST`): the follower's
    /// landmarks there are guesses, and its observed look would be the cover's.
    pub const COVERED: Reasons = Reasons(1 << 9);

    /// What is wrong with the mesh itself (collapsed, folded, an unlikely shape): the tracker
    /// fits such a frame again from the last good fit, and starts the next from it.
    pub(crate) const STRUCTURAL: Reasons = Reasons(1 | 1 << 1 | 1 << 2);

    const ALL: [(Reasons, &'static str); 10] = [
        (Reasons::COLLAPSED, "collapsed"),
        (Reasons::FOLDED, "folded"),
        (Reasons::SHAPE, "shape"),
        (Reasons::RESIDUAL, "residual"),
        (Reasons::JUMP, "jump"),
        (Reasons::FINDER, "finder"),
        (Reasons::CONTRAST, "contrast"),
        (Reasons::OUTSIDE, "outside"),
        (Reasons::NO_FACE, "no-face"),
        (Reasons::COVERED, "covered"),
    ];

    /// Whether there is no reason.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether every reason of `other` is in `self`.
    pub fn contains(self, other: Reasons) -> bool {
        self.0 & other.0 == other.0
    }

    /// Whether `self` and `other` share a reason.
    pub fn intersects(self, other: Reasons) -> bool {
        self.0 & other.0 != 0
    }

    /// The reasons' stable names, in a fixed order ("collapsed", "folded", "shape",
    /// "residual", "jump", "finder", "contrast", "outside", "no-face", "covered").
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Reasons::ALL
            .into_iter()
            .filter(move |(r, _)| self.contains(*r))
            .map(|(_, n)| n)
    }
}

impl std::ops::BitOr for Reasons {
    type Output = Reasons;
    fn bitor(self, o: Reasons) -> Reasons {
        Reasons(self.0 | o.0)
    }
}

impl std::ops::BitOrAssign for Reasons {
    fn bitor_assign(&mut self, o: Reasons) {
        self.0 |= o.0;
    }
}

impl std::fmt::Display for Reasons {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, n) in self.names().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(n)?;
        }
        Ok(())
    }
}

/// The bounds of the AAM tracker's "unsure" checks; the defaults were set on the good
/// frames of franck-dev2 and webcam-dev (docs/fitting.md, "A tracker that knows when it is
/// wrong").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ConfidenceBounds {
    /// Collapsed: the mesh's area under this fraction of the recent good fits' (a slow mean),
    /// or of the model's mean face at the fit's own scale.
    pub min_area: f32,
    /// Folded: the turned-over triangles' area over this fraction of the mesh's area.
    pub max_folded: f32,
    /// Folded (68 points): an upper lip or eyelid this many eye distances below its lower one.
    pub max_crossing: f32,
    /// Shape: the shape parameters' RMS in standard deviations over this (a Mahalanobis
    /// bound)...
    pub max_sigmas: f32,
    /// ...or one shape parameter over this many standard deviations.
    pub max_mode_sigmas: f32,
    /// Residual: the error over this multiple of the recent good fits' typical error.
    pub max_error_ratio: f32,
    /// Jump: the scale changing by more than this fraction from the previous frame.
    pub max_scale_step: f32,
    /// Jump: the rotation changing by more than this (radians) from the previous frame.
    pub max_rotation_step: f32,
    /// Finder: the mean distance between the fit's landmarks and the finder's face nearest it
    /// over this fraction of the found face's size (its bounding box's larger side).
    pub max_finder_distance: f32,
}

impl Default for ConfidenceBounds {
    fn default() -> Self {
        ConfidenceBounds {
            min_area: 0.6,
            max_folded: 0.02,
            max_crossing: 0.05,
            max_sigmas: 2.0,
            max_mode_sigmas: 3.2,
            max_error_ratio: 2.5,
            max_scale_step: 0.12,
            max_rotation_step: 0.25,
            max_finder_distance: 0.1,
        }
    }
}

impl ConfidenceBounds {
    /// Bounds that doubt nothing: the tracker as it was before the checks (a fit is tracking
    /// or lost), for comparison.
    pub fn off() -> ConfidenceBounds {
        ConfidenceBounds {
            min_area: 0.0,
            max_folded: f32::INFINITY,
            max_crossing: f32::INFINITY,
            max_sigmas: f32::INFINITY,
            max_mode_sigmas: f32::INFINITY,
            max_error_ratio: f32::INFINITY,
            max_scale_step: f32::INFINITY,
            max_rotation_step: f32::INFINITY,
            max_finder_distance: f32::INFINITY,
        }
    }

    /// Fails with [`crate::Error::Params`] naming the first value that is NaN or negative.
    pub fn check(&self) -> crate::Result<()> {
        for (what, v) in [
            ("min_area", self.min_area),
            ("max_folded", self.max_folded),
            ("max_crossing", self.max_crossing),
            ("max_sigmas", self.max_sigmas),
            ("max_mode_sigmas", self.max_mode_sigmas),
            ("max_error_ratio", self.max_error_ratio),
            ("max_scale_step", self.max_scale_step),
            ("max_rotation_step", self.max_rotation_step),
            ("max_finder_distance", self.max_finder_distance),
        ] {
            if !(v >= 0.0) {
                return Err(crate::Error::Params(format!(
                    "confidence bounds: {what} = {v} must be non-negative"
                )));
            }
        }
        Ok(())
    }
}

/// The AAM tracker's confidence checks on one model: its triangles' orientation and area in
/// the mean shape, and the recent good fits' face area. Checking a fit allocates nothing.
#[derive(Clone, Debug)]
pub(crate) struct Confidence {
    /// Triangles whose orientation in the mean shape is clear, with its sign (+1 or -1).
    tris: Vec<([u32; 3], f32)>,
    /// The mean shape's area (the sum of those triangles' absolute areas), model units.
    base_area: f32,
    /// Shape standard deviations.
    sigmas: Vec<f32>,
    /// The model has the 68 iBUG landmarks (the lips and eyelids are checked).
    ibug: bool,
    /// A slow mean of the recent good fits' mesh areas (pixels), 0 before the first.
    recent_area: f32,
    /// The previous frame's pose when it was good (the jump checks' reference).
    previous: Option<Similarity>,
    pub(crate) bounds: ConfidenceBounds,
}

impl Confidence {
    pub(crate) fn new(model: &Model) -> Confidence {
        let s0 = &model.shape().base;
        let all: Vec<([u32; 3], f32)> = model
            .frame()
            .triangles()
            .iter()
            .map(|&t| (t, signed_area(s0, t)))
            .collect();
        let mean = all.iter().map(|(_, a)| a.abs()).sum::<f32>() / all.len().max(1) as f32;
        // Slivers of the mean shape (a closed mouth's inner lips) turn over with every small
        // movement: only triangles of a fifth of the mean area or more are judged.
        let judged = all.iter().filter(|(_, a)| a.abs() >= 0.2 * mean);
        let base_area = judged.clone().map(|(_, a)| a.abs()).sum();
        let tris = judged.map(|&(t, a)| (t, a.signum())).collect();
        Confidence {
            tris,
            base_area,
            sigmas: model.shape().sigmas(),
            ibug: model.landmarks() == 68,
            recent_area: 0.0,
            previous: None,
            bounds: ConfidenceBounds::default(),
        }
    }

    /// Forgets the recent fits (a new sequence).
    pub(crate) fn restart(&mut self) {
        self.recent_area = 0.0;
        self.previous = None;
    }

    /// The mesh's area (pixels), folded triangles counted negative, and the folded triangles'
    /// area, for interleaved `points`.
    fn areas(&self, points: &[f32]) -> (f32, f32) {
        let (mut area, mut folded) = (0.0, 0.0);
        for &(t, sign) in &self.tris {
            let a = sign * signed_area(points, t);
            area += a;
            if a < 0.0 {
                folded -= a;
            }
        }
        (area, folded)
    }

    /// The doubts about a fit that passed the loss checks: `points` its landmarks (frame
    /// pixels), `pose` its pose, `shape` its shape parameters, `error_ratio` its error over
    /// the recent good fits' typical error (0: none yet), `finder` the face finder's face
    /// nearest it on this frame, if one was found.
    pub(crate) fn doubts(
        &self,
        points: &[f32],
        pose: &Similarity,
        shape: &[f32],
        error_ratio: f32,
        finder: Option<&[f32]>,
    ) -> Reasons {
        let b = &self.bounds;
        let mut r = Reasons::NONE;
        let (area, folded) = self.areas(points);
        let mean_area = pose.scale() * pose.scale() * self.base_area;
        // The finder's face where the fit is: a face that shrank as a whole (moving away from
        // the camera), not a fit that collapsed.
        let confirmed = finder.is_some_and(|f| {
            f.len() == points.len() && mean_distance(points, f) <= b.max_finder_distance * size(f)
        });
        if !(area >= b.min_area * mean_area)
            || (self.recent_area > 0.0 && !(area >= b.min_area * self.recent_area) && !confirmed)
        {
            r |= Reasons::COLLAPSED;
        }
        if !(folded <= b.max_folded * area.abs().max(1e-6)) || self.crossed(points) {
            r |= Reasons::FOLDED;
        }
        let largest = shape
            .iter()
            .zip(&self.sigmas)
            .map(|(p, s)| (p / s.max(1e-12)).abs())
            .fold(0.0, f32::max);
        if !(sigma_rms(shape, &self.sigmas) <= b.max_sigmas && largest <= b.max_mode_sigmas) {
            r |= Reasons::SHAPE;
        }
        if error_ratio > b.max_error_ratio {
            r |= Reasons::RESIDUAL;
        }
        if let Some(p) = &self.previous {
            let ds = (pose.scale() / p.scale().max(1e-12) - 1.0).abs();
            let dr = (pose.rotation() - p.rotation()).abs();
            let dr = dr.min(2.0 * std::f32::consts::PI - dr);
            if !(ds <= b.max_scale_step && dr <= b.max_rotation_step) {
                r |= Reasons::JUMP;
            }
        }
        if finder.is_some_and(|f| f.len() == points.len()) && !confirmed {
            r |= Reasons::FINDER;
        }
        r
    }

    /// Notes the frame's fit: a `good` one moves the recent face area and is the pose the
    /// next frame's jump is measured from (after an unsure one, none is).
    pub(crate) fn note(&mut self, points: &[f32], pose: &Similarity, good: bool) {
        // After an unsure frame the next is not judged for a jump: a fit recovered from a
        // wrong one moves by what the wrong one was off.
        self.previous = good.then_some(*pose);
        if good {
            let area = self.areas(points).0;
            self.recent_area = if self.recent_area > 0.0 {
                0.8 * self.recent_area + 0.2 * area
            } else {
                area
            };
        }
    }

    /// 68 points: an upper lip (outer or inner) or an upper eyelid below its lower one by
    /// more than [`ConfidenceBounds::max_crossing`] eye distances, in the face's frame.
    fn crossed(&self, p: &[f32]) -> bool {
        if !self.ibug {
            return false;
        }
        let pt = |i: usize| (p[2 * i], p[2 * i + 1]);
        let (l, r) = (pt(36), pt(45));
        let (ex, ey) = (r.0 - l.0, r.1 - l.1);
        let d2 = ex * ex + ey * ey;
        if !(d2 > 0.0) {
            return true;
        }
        // How far `lower` is above `upper` along the face's downward axis, in eye distances.
        let above = |upper: usize, lower: usize| {
            let (u, w) = (pt(upper), pt(lower));
            let (dx, dy) = (w.0 - u.0, w.1 - u.1);
            // The face's down axis is the eye line turned by +90 degrees: (-ey, ex).
            -(-ey * dx + ex * dy) / d2
        };
        let pairs: [(usize, usize); 10] = [
            (50, 58),
            (51, 57),
            (52, 56),
            (61, 67),
            (62, 66),
            (63, 65),
            (37, 41),
            (38, 40),
            (43, 47),
            (44, 46),
        ];
        pairs
            .iter()
            .any(|&(u, w)| above(u, w) > self.bounds.max_crossing)
    }
}

/// Signed area of triangle `t` of interleaved `points` (positive counter-clockwise in a y-up
/// frame).
fn signed_area(points: &[f32], t: [u32; 3]) -> f32 {
    let p = |i: u32| (points[2 * i as usize], points[2 * i as usize + 1]);
    let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
    0.5 * ((b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1))
}

/// `sqrt(mean_i (p_i / sigma_i)^2)`: the shape's RMS in standard deviations.
pub(crate) fn sigma_rms(shape: &[f32], sigmas: &[f32]) -> f32 {
    let m = sigmas.len().max(1) as f32;
    let z2: f32 = shape
        .iter()
        .zip(sigmas)
        .map(|(p, s)| (p / s.max(1e-12)).powi(2))
        .sum();
    (z2 / m).sqrt()
}

/// The larger side of the bounding box of interleaved points (at least 1e-6).
fn size(points: &[f32]) -> f32 {
    let b = crate::geometry::BBox::of_points(points);
    b.width.max(b.height).max(1e-6)
}

/// Mean distance between corresponding interleaved points.
fn mean_distance(a: &[f32], b: &[f32]) -> f32 {
    let n = (a.len() / 2).max(1) as f32;
    a.chunks_exact(2)
        .zip(b.chunks_exact(2))
        .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
        .sum::<f32>()
        / n
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;

    /// The tiny model (68 landmarks, spk07) and its mean face at a pose in a frame.
    fn setup() -> (Confidence, Vec<f32>, Similarity, Vec<f32>) {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let bytes = std::fs::read(root.join("tests/data/tiny-v1.fmm")).unwrap();
        let model = crate::format::read_model(&bytes).unwrap();
        let pose = Similarity::from_parts(1.3, 0.1, 40.0, 30.0);
        let mut face = vec![0.0; model.shape().base.len()];
        pose.apply(&model.shape().base, &mut face);
        let shape = vec![0.0; model.shape().n_modes()];
        (Confidence::new(&model), face, pose, shape)
    }

    /// `points` moved by `f` about their centroid.
    fn about_centre(points: &[f32], f: impl Fn(f32, f32) -> (f32, f32)) -> Vec<f32> {
        let n = (points.len() / 2) as f32;
        let cx = points.iter().step_by(2).sum::<f32>() / n;
        let cy = points.iter().skip(1).step_by(2).sum::<f32>() / n;
        let mut out = points.to_vec();
        for p in out.chunks_exact_mut(2) {
            let (x, y) = f(p[0] - cx, p[1] - cy);
            (p[0], p[1]) = (cx + x, cy + y);
        }
        out
    }

    #[test]
    fn a_normal_face_raises_no_doubt() {
        let (mut c, face, pose, shape) = setup();
        assert_eq!(c.doubts(&face, &pose, &shape, 1.0, None), Reasons::NONE);
        c.note(&face, &pose, true);
        // The finder's face a little off (its own convention) agrees.
        let found: Vec<f32> = face.iter().map(|v| v + 1.5).collect();
        let r = c.doubts(&face, &pose, &shape, 1.2, Some(&found));
        assert_eq!(r, Reasons::NONE, "{r}");
    }

    #[test]
    fn a_collapsed_face_is_flagged() {
        let (mut c, face, pose, shape) = setup();
        // Onto half the face: the points squeezed into a third of the width at the pose's
        // scale.
        let half = about_centre(&face, |x, y| (0.3 * x + 10.0, y));
        let r = c.doubts(&half, &pose, &shape, 1.0, None);
        assert!(r.contains(Reasons::COLLAPSED), "{r}");
        // Shrunk as a whole, pose included, far below the recent face.
        c.note(&face, &pose, true);
        let small = about_centre(&face, |x, y| (0.6 * x, 0.6 * y));
        let small_pose = Similarity::from_parts(0.6 * pose.scale(), 0.1, 40.0, 30.0);
        c.previous = None;
        let r = c.doubts(&small, &small_pose, &shape, 1.0, None);
        assert_eq!(r, Reasons::COLLAPSED, "{r}");
        // ...unless the finder finds a face of that size there (the head moved away).
        let r = c.doubts(&small, &small_pose, &shape, 1.0, Some(&small));
        assert_eq!(r, Reasons::NONE, "{r}");
    }

    #[test]
    fn a_folded_face_is_flagged() {
        let (c, face, pose, shape) = setup();
        // The mesh turned over (mirrored left to right).
        let mirrored = about_centre(&face, |x, y| (-x, y));
        let r = c.doubts(&mirrored, &pose, &shape, 1.0, None);
        assert!(r.contains(Reasons::FOLDED), "{r}");
        // Only the lips crossed: the upper lip's points below the lower lip's.
        let mut lips = face.clone();
        for (u, l) in [(50, 58), (51, 57), (52, 56), (61, 67), (62, 66), (63, 65)] {
            for k in 0..2 {
                lips.swap(2 * u + k, 2 * l + k);
            }
        }
        let r = c.doubts(&lips, &pose, &shape, 1.0, None);
        assert!(r.contains(Reasons::FOLDED), "{r}");
    }

    #[test]
    fn a_slid_fit_is_flagged() {
        let (mut c, face, pose, shape) = setup();
        c.note(&face, &pose, true);
        // The finder's face half a face width to the right of the fit.
        let w = crate::geometry::BBox::of_points(&face).width;
        let found: Vec<f32> = face
            .chunks_exact(2)
            .flat_map(|p| [p[0] + 0.5 * w, p[1]])
            .collect();
        assert_eq!(
            c.doubts(&face, &pose, &shape, 1.0, Some(&found)),
            Reasons::FINDER
        );
        // A residual jump, an implausible shape and a sudden turn, each alone.
        assert_eq!(c.doubts(&face, &pose, &shape, 3.0, None), Reasons::RESIDUAL);
        let mut odd = shape.clone();
        odd[0] = 4.0 * c.sigmas[0];
        assert_eq!(c.doubts(&face, &pose, &odd, 1.0, None), Reasons::SHAPE);
        let turned = Similarity::from_parts(pose.scale(), 0.5, 40.0, 30.0);
        let r = c.doubts(&face, &turned, &shape, 1.0, None);
        assert_eq!(r, Reasons::JUMP, "{r}");
    }

    #[test]
    fn statuses_and_reasons_have_stable_names() {
        assert_eq!(TrackStatus::Unsure.name(), "unsure");
        let r = Reasons::FOLDED | Reasons::FINDER;
        assert_eq!(r.names().collect::<Vec<_>>(), ["folded", "finder"]);
        assert_eq!(r.to_string(), "folded, finder");
        assert_eq!(
            serde_json::to_string(&TrackStatus::Lost).unwrap(),
            "\"lost\""
        );
        assert!(ConfidenceBounds::default().check().is_ok());
        assert!(ConfidenceBounds::off().check().is_ok());
        let nan = ConfidenceBounds {
            min_area: f32::NAN,
            ..ConfidenceBounds::default()
        };
        assert!(nan.check().is_err());
    }
}

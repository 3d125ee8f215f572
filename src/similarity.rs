//! 2D similarity transforms (the pose that places a normalised shape in an image).

use serde::{Deserialize, Serialize};

/// A 2D similarity transform `x' = [a -b; b a] x + t`: uniform scale `sqrt(a^2+b^2)`, rotation
/// `atan2(b, a)`, translation `t`.
///
/// Represents the pose of a face: it maps model coordinates (the normalised, Procrustes-aligned
/// shape space, centred on the origin) to image coordinates (0-based pixels, pixel centres on
/// integers). Kept apart from the shape parameters `p`, as the paper's notes require.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "PoseJson", into = "PoseJson")]
pub struct Similarity {
    /// `scale * cos(rotation)`.
    pub a: f32,
    /// `scale * sin(rotation)`.
    pub b: f32,
    /// Translation along x.
    pub tx: f32,
    /// Translation along y.
    pub ty: f32,
}

impl Default for Similarity {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Similarity {
    /// The identity transform.
    pub const IDENTITY: Similarity = Similarity {
        a: 1.0,
        b: 0.0,
        tx: 0.0,
        ty: 0.0,
    };

    /// Builds a transform from scale, rotation (radians) and translation.
    pub fn from_parts(scale: f32, rotation: f32, tx: f32, ty: f32) -> Self {
        Similarity {
            a: scale * rotation.cos(),
            b: scale * rotation.sin(),
            tx,
            ty,
        }
    }

    /// Uniform scale factor.
    pub fn scale(&self) -> f32 {
        (self.a * self.a + self.b * self.b).sqrt()
    }

    /// Rotation in radians.
    pub fn rotation(&self) -> f32 {
        self.b.atan2(self.a)
    }

    /// Maps one point.
    #[inline]
    pub fn apply_point(&self, x: f32, y: f32) -> (f32, f32) {
        (
            self.a * x - self.b * y + self.tx,
            self.b * x + self.a * y + self.ty,
        )
    }

    /// Maps an interleaved shape `(x1, y1, ..., xn, yn)` into `out` (same length).
    pub fn apply(&self, shape: &[f32], out: &mut [f32]) {
        for (src, dst) in shape.chunks_exact(2).zip(out.chunks_exact_mut(2)) {
            let (x, y) = self.apply_point(src[0], src[1]);
            dst[0] = x;
            dst[1] = y;
        }
    }

    /// Maps an interleaved shape in place.
    pub fn apply_in_place(&self, shape: &mut [f32]) {
        for p in shape.chunks_exact_mut(2) {
            let (x, y) = self.apply_point(p[0], p[1]);
            p[0] = x;
            p[1] = y;
        }
    }

    /// The inverse transform (identity-like garbage is avoided: a zero scale yields `None`).
    pub fn inverse(&self) -> Option<Similarity> {
        let d = self.a * self.a + self.b * self.b;
        if !(d > 1e-20) || !d.is_finite() {
            return None;
        }
        let (ia, ib) = (self.a / d, -self.b / d);
        Some(Similarity {
            a: ia,
            b: ib,
            tx: -(ia * self.tx - ib * self.ty),
            ty: -(ib * self.tx + ia * self.ty),
        })
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Similarity) -> Similarity {
        Similarity {
            a: self.a * other.a - self.b * other.b,
            b: self.b * other.a + self.a * other.b,
            tx: self.a * other.tx - self.b * other.ty + self.tx,
            ty: self.b * other.tx + self.a * other.ty + self.ty,
        }
    }

    /// `target ∘ anchor⁻¹ ∘ self`: this pose moved so that where `anchor` puts a shape,
    /// `target` puts it, keeping the motion relative to `anchor` exactly (the page re-centres a
    /// tracked or recorded head on a model's mean placement this way). `None` when `anchor` has
    /// no inverse.
    pub fn recentred(&self, anchor: &Similarity, target: &Similarity) -> Option<Similarity> {
        Some(target.compose(&anchor.inverse()?).compose(self))
    }

    /// The mean of `poses`, the crate's one pose average: the geometric mean of the scales
    /// (the mean of their logarithms), the circular mean of the rotations (the angle of the
    /// summed unit vectors: -179 and 179 degrees average to 180, not 0) and the arithmetic mean
    /// of the translations. Used by the builder (a model's mean training pose) and, through the
    /// wasm `meanPose`, by the page's recorded tracks. `None` for no poses, an invalid pose, or
    /// rotations that cancel out (their unit vectors summing to under 1e-6 a pose).
    pub fn mean(poses: &[Similarity]) -> Option<Similarity> {
        if poses.is_empty() || !poses.iter().all(Similarity::is_valid) {
            return None;
        }
        let n = poses.len() as f64;
        let (mut ls, mut c, mut s, mut tx, mut ty) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for p in poses {
            ls += (p.scale() as f64).ln();
            let r = p.rotation() as f64;
            c += r.cos();
            s += r.sin();
            tx += p.tx as f64;
            ty += p.ty as f64;
        }
        if c.hypot(s) < 1e-6 * n {
            return None;
        }
        Some(Similarity::from_parts(
            (ls / n).exp() as f32,
            s.atan2(c) as f32,
            (tx / n) as f32,
            (ty / n) as f32,
        ))
    }

    /// The pose `u` of the way from `self` to `to` (`u` in `0..=1`), in the convention of
    /// [`Similarity::mean`]: the scale geometrically (its logarithm linearly), the rotation the
    /// short way round (-179 to 179 degrees passes through 180), the translation linearly. The
    /// tracker's pose anchor follows the head this way, and the page blends recorded frames
    /// with it (the wasm `lerpPose`). Either pose invalid: `to`.
    pub fn lerp(&self, to: &Similarity, u: f32) -> Similarity {
        if !(self.is_valid() && to.is_valid()) {
            return *to;
        }
        let (s0, s1) = (self.scale().ln(), to.scale().ln());
        let (r0, r1) = (self.rotation(), to.rotation());
        let dr = (r1 - r0).sin().atan2((r1 - r0).cos());
        Similarity::from_parts(
            (s0 + (s1 - s0) * u).exp(),
            r0 + dr * u,
            self.tx + (to.tx - self.tx) * u,
            self.ty + (to.ty - self.ty) * u,
        )
    }

    /// True when all four numbers are finite and the scale is non-zero.
    pub fn is_valid(&self) -> bool {
        [self.a, self.b, self.tx, self.ty]
            .iter()
            .all(|v| v.is_finite())
            && self.scale() > 0.0
    }

    /// The least-squares similarity that maps `src` onto `dst` (both interleaved, same length):
    /// minimises `sum |T(src_i) - dst_i|^2`. Closed form (Umeyama without reflection; the
    /// crate's one similarity fit, `CentredFit`, also used by the Procrustes alignment).
    pub fn align(src: &[f32], dst: &[f32]) -> Similarity {
        let f = CentredFit::new(src, dst);
        let ([sx, sy], [dx, dy]) = (f.src_mean, f.dst_mean);
        Similarity {
            a: f.a as f32,
            b: f.b as f32,
            tx: (dx - (f.a * sx - f.b * sy)) as f32,
            ty: (dy - (f.b * sx + f.a * sy)) as f32,
        }
    }

    /// [`Similarity::align`] of the points `indices` of `src` onto the same points of `dst`
    /// (both interleaved; e.g. [`crate::landmarks::STABLE_POINTS`]). Indices past either
    /// shape's end are skipped, and at most 68 points are used. Allocates nothing.
    ///
    /// The follower fits a frame's pose so ([`crate::fit::Follower`]), and the expression
    /// prior aligns a face's two photos so ([`crate::clone::expression_displacement`]).
    pub fn align_points(src: &[f32], dst: &[f32], indices: &[usize]) -> Similarity {
        let (mut a, mut b) = ([0f32; 136], [0f32; 136]);
        let mut n = 0;
        for &i in indices {
            if n == 68 || i >= src.len().min(dst.len()) / 2 {
                continue;
            }
            a[2 * n..2 * n + 2].copy_from_slice(&src[2 * i..2 * i + 2]);
            b[2 * n..2 * n + 2].copy_from_slice(&dst[2 * i..2 * i + 2]);
            n += 1;
        }
        Similarity::align(&a[..2 * n], &b[..2 * n])
    }
}

/// The crate's one least-squares similarity fit (Umeyama without reflection), in f64: the
/// similarity mapping `src` onto `dst` (interleaved points, the shorter length counts) is
/// `x -> [[a, -b], [b, a]] (x - src_mean) + dst_mean`, with `a = sum <x_c, u_c> / sum |x_c|^2`
/// and `b = sum (x_c × u_c) / sum |x_c|^2` over the centred points `x_c`, `u_c`. When the
/// source points coincide, `a = 1, b = 0` (a translation). Kept in this centred form so the
/// Procrustes alignment can apply it about the centroids.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CentredFit {
    pub a: f64,
    pub b: f64,
    pub src_mean: [f64; 2],
    pub dst_mean: [f64; 2],
}

impl CentredFit {
    pub fn new<T: Copy + Into<f64>>(src: &[T], dst: &[T]) -> CentredFit {
        let n = (src.len().min(dst.len()) / 2).max(1) as f64;
        let (mut sx, mut sy, mut dx, mut dy) = (0f64, 0f64, 0f64, 0f64);
        for (s, d) in src.chunks_exact(2).zip(dst.chunks_exact(2)) {
            sx += s[0].into();
            sy += s[1].into();
            dx += d[0].into();
            dy += d[1].into();
        }
        let (sx, sy, dx, dy) = (sx / n, sy / n, dx / n, dy / n);
        let (mut num_a, mut num_b, mut den) = (0f64, 0f64, 0f64);
        for (s, d) in src.chunks_exact(2).zip(dst.chunks_exact(2)) {
            let (x, y) = (s[0].into() - sx, s[1].into() - sy);
            let (u, v) = (d[0].into() - dx, d[1].into() - dy);
            num_a += x * u + y * v;
            num_b += x * v - y * u;
            den += x * x + y * y;
        }
        let (a, b) = if den > 0.0 {
            (num_a / den, num_b / den)
        } else {
            (1.0, 0.0)
        };
        CentredFit {
            a,
            b,
            src_mean: [sx, sy],
            dst_mean: [dx, dy],
        }
    }
}

/// The human-readable form of a pose used in JSON (`project`, `--params`): scale, rotation in
/// radians, translation in pixels.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct PoseJson {
    /// Uniform scale from model coordinates to image pixels.
    pub scale: f32,
    /// Rotation in radians (counter-clockwise in a y-down image looks clockwise).
    pub rotation: f32,
    /// Translation along x, pixels.
    pub tx: f32,
    /// Translation along y, pixels.
    pub ty: f32,
}

impl From<Similarity> for PoseJson {
    fn from(s: Similarity) -> Self {
        PoseJson {
            scale: s.scale(),
            rotation: s.rotation(),
            tx: s.tx,
            ty: s.ty,
        }
    }
}

/// A pose read from JSON: the scale must be positive and every value finite (a negative scale
/// would silently become a half-turn rotation).
impl TryFrom<PoseJson> for Similarity {
    type Error = String;
    fn try_from(p: PoseJson) -> std::result::Result<Self, String> {
        if !(p.scale.is_finite() && p.scale > 0.0) {
            return Err(format!(
                "pose.scale is {}, not a positive finite number",
                p.scale
            ));
        }
        for (k, v) in [("rotation", p.rotation), ("tx", p.tx), ("ty", p.ty)] {
            if !v.is_finite() {
                return Err(format!("pose.{k} is {v}, not a finite number"));
            }
        }
        Ok(Similarity::from_parts(p.scale, p.rotation, p.tx, p.ty))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fails unless the two poses' four numbers agree within 1e-4.
    fn assert_close(p: &Similarity, q: &Similarity) {
        for (a, b) in [(p.a, q.a), (p.b, q.b), (p.tx, q.tx), (p.ty, q.ty)] {
            assert!((a - b).abs() < 1e-4, "{p:?} != {q:?}");
        }
    }

    /// A laugh (the jaw 0-16 and the mouth 48-67 dropped by a fifth of the eye distance, the
    /// mouth widened by a tenth) seen through a known head pose: the pose fitted on the
    /// stable points is that head pose, while the one fitted on all 68 points is pulled.
    #[test]
    fn the_stable_points_give_the_heads_pose_whatever_the_laugh() {
        use crate::landmarks::STABLE_POINTS;
        let neutral = crate::canonical_frame().vertices().to_vec();
        let iod = crate::landmarks::eye_line(&neutral)
            .map(|[x, y]| x.hypot(y))
            .unwrap();
        let mouth_x = (48..68).map(|i| neutral[2 * i]).sum::<f32>() / 20.0;
        let mut laugh = neutral.clone();
        for i in (0..17).chain(48..68) {
            laugh[2 * i + 1] += 0.2 * iod;
        }
        for i in 48..68 {
            laugh[2 * i] = mouth_x + 1.1 * (laugh[2 * i] - mouth_x);
        }
        let head = Similarity::from_parts(1.3, 0.2, 40.0, -25.0);
        let mut seen = laugh.clone();
        head.apply_in_place(&mut seen);
        assert_close(
            &Similarity::align_points(&neutral, &seen, &STABLE_POINTS),
            &head,
        );
        let all = Similarity::align(&neutral, &seen);
        let off = (all.scale() / head.scale() - 1.0).abs() + (all.ty - head.ty).abs() / iod;
        assert!(off > 0.02, "all 68 points: {all:?} against {head:?}");
        // Indices past the shapes' end are skipped.
        let some = Similarity::align_points(&neutral, &seen, &[27, 30, 36, 45, 500, usize::MAX]);
        assert_close(&some, &head);
    }

    #[test]
    fn mean_of_poses_is_geometric_in_scale_and_circular_in_angle() {
        let deg = |d: f32| d.to_radians();
        let p = |s: f32, r: f32, tx: f32, ty: f32| Similarity::from_parts(s, deg(r), tx, ty);
        let m = Similarity::mean(&[p(1.0, 10.0, 0.0, 4.0), p(4.0, 20.0, 10.0, 8.0)]).unwrap();
        assert!((m.scale() - 2.0).abs() < 1e-5, "{}", m.scale());
        assert!((m.rotation() - deg(15.0)).abs() < 1e-5);
        assert_eq!((m.tx, m.ty), (5.0, 6.0));
        // Across the +-180 degree cut: 180, not 0.
        let m = Similarity::mean(&[p(1.0, 179.0, 0.0, 0.0), p(1.0, -179.0, 0.0, 0.0)]).unwrap();
        assert!(
            (m.rotation().abs() - deg(180.0)).abs() < 1e-4,
            "{}",
            m.rotation()
        );
        // One pose is itself; none, an invalid one or cancelling angles give None.
        let one = p(1.5, 30.0, 2.0, 3.0);
        let m = Similarity::mean(&[one]).unwrap();
        assert!((m.a - one.a).abs() < 1e-6 && (m.b - one.b).abs() < 1e-6);
        assert!(Similarity::mean(&[]).is_none());
        assert!(Similarity::mean(&[one, Similarity { a: f32::NAN, ..one }]).is_none());
        assert!(Similarity::mean(&[p(1.0, 0.0, 0.0, 0.0), p(1.0, 180.0, 0.0, 0.0)]).is_none());
    }

    #[test]
    fn lerp_is_geometric_in_scale_and_short_way_round_in_angle() {
        let deg = |d: f32| d.to_radians();
        let a = Similarity::from_parts(1.0, deg(179.0), 0.0, 10.0);
        let b = Similarity::from_parts(4.0, deg(-179.0), 10.0, 20.0);
        let m = a.lerp(&b, 0.5);
        assert!((m.scale() - 2.0).abs() < 1e-5, "{}", m.scale());
        assert!(
            (m.rotation().abs() - deg(180.0)).abs() < 1e-4,
            "{}",
            m.rotation()
        );
        assert!((m.tx - 5.0).abs() < 1e-5 && (m.ty - 15.0).abs() < 1e-5);
        // Halfway is the mean of the two.
        let mean = Similarity::mean(&[a, b]).unwrap();
        assert!((m.a - mean.a).abs() < 1e-5 && (m.b - mean.b).abs() < 1e-5);
        // The ends are the poses.
        let e = a.lerp(&b, 1.0);
        assert!((e.a - b.a).abs() < 1e-5 && (e.b - b.b).abs() < 1e-5 && e.tx == b.tx);
        let s = a.lerp(&b, 0.0);
        assert!((s.a - a.a).abs() < 1e-5 && (s.b - a.b).abs() < 1e-5);
        let bad = Similarity { a: f32::NAN, ..a };
        assert_eq!(bad.lerp(&b, 0.5), b);
    }

    #[test]
    fn recentred_maps_the_anchor_onto_the_target() {
        let anchor = Similarity::from_parts(1.7, 0.2, 40.0, 25.0);
        let target = Similarity::from_parts(0.9, -0.05, 180.0, 144.0);
        // The anchor itself lands on the target...
        let r = anchor.recentred(&anchor, &target).unwrap();
        assert_close(&r, &target);
        // ...and a pose moved from the anchor keeps its motion relative to it: the same point
        // maps to the same place relative to where the anchor / target map it.
        let moved = Similarity::from_parts(1.8, 0.25, 45.0, 20.0);
        let m = moved.recentred(&anchor, &target).unwrap();
        let rel = anchor.inverse().unwrap().compose(&moved);
        let rel2 = target.inverse().unwrap().compose(&m);
        assert_close(&rel, &rel2);
        let degenerate = Similarity {
            a: 0.0,
            b: 0.0,
            tx: 1.0,
            ty: 1.0,
        };
        assert!(moved.recentred(&degenerate, &target).is_none());
    }

    #[test]
    fn json_pose_needs_a_positive_finite_scale() {
        let ok: Similarity =
            serde_json::from_str(r#"{"scale":2,"rotation":0.1,"tx":3,"ty":4}"#).unwrap();
        assert!((ok.scale() - 2.0).abs() < 1e-6);
        for bad in [
            r#"{"scale":-1,"rotation":0,"tx":0,"ty":0}"#,
            r#"{"scale":0,"rotation":0,"tx":0,"ty":0}"#,
        ] {
            let e = serde_json::from_str::<Similarity>(bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains("pose.scale"), "{e}");
        }
    }

    #[test]
    fn inverse_and_compose() {
        let s = Similarity::from_parts(2.0, 0.3, 5.0, -7.0);
        let i = s.inverse().unwrap();
        let id = s.compose(&i);
        assert!((id.a - 1.0).abs() < 1e-6 && id.b.abs() < 1e-6 && id.tx.abs() < 1e-5);
    }

    #[test]
    fn align_recovers_transform() {
        let src = [0.0, 0.0, 1.0, 0.0, 0.0, 2.0, -1.0, 1.0];
        let t = Similarity::from_parts(1.7, -0.4, 3.0, 9.0);
        let mut dst = [0.0; 8];
        t.apply(&src, &mut dst);
        let r = Similarity::align(&src, &dst);
        assert!((r.a - t.a).abs() < 1e-5 && (r.b - t.b).abs() < 1e-5);
        assert!((r.tx - t.tx).abs() < 1e-4 && (r.ty - t.ty).abs() < 1e-4);
    }
}

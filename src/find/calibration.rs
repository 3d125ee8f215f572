//! The finder's points moved onto the iBUG / dlib convention the rest of the project uses (the
//! `.pts` files the default models are built from, the figures' ground truth).
//!
//! The face mesh's vertices chosen as iBUG points (`mesh_table.rs`) sit a little off dlib's
//! points in the same way on every face (the jaw vertices on the skin rather than on the
//! outline, the brows' vertices higher, ...). The offsets below are that mean difference,
//! measured in each face's own frame (centred, scaled by the points' RMS radius, rotated so the
//! outer eye corners 36-45 are level) on the GRID frames committed in `data/grid` (330 frames,
//! 10 speakers, CC BY 4.0). Adding them back in each face's frame removes the shared part of
//! the difference; what is left varies from face to face (docs/finding.md measures both on
//! clips none of whose frames the offsets came from).
//!
//! Regenerate with `cargo run --release --example finder_data -- calibration` (it writes
//! `src/find/calibration_table.rs`); `table_is_reproducible` checks that the committed table
//! is what the committed frames give.

include!("calibration_table.rs");

/// The committed offsets [`FaceFinder`](super::FaceFinder) adds to its net's points in each
/// face's frame (`calibration_table.rs`, made by `examples/finder_data.rs`; the argument of
/// [`add_face_offsets`]).
pub const NET_OFFSETS: &[f32; 136] = &OFFSETS;

/// The face frame of 68 points (the frame of [`face_offsets`]): centroid, RMS radius, and the
/// cosine and sine of the angle of the line from point 36 to point 45. `None` for a
/// degenerate or non-finite shape, or one of another length than 136 values.
pub fn face_frame(points: &[f32]) -> Option<([f32; 2], f32, f32, f32)> {
    if points.len() != 136 {
        return None;
    }
    let n = (points.len() / 2) as f32;
    let cx = points.iter().step_by(2).sum::<f32>() / n;
    let cy = points.iter().skip(1).step_by(2).sum::<f32>() / n;
    let r = (points
        .chunks_exact(2)
        .map(|p| (p[0] - cx).powi(2) + (p[1] - cy).powi(2))
        .sum::<f32>()
        / n)
        .sqrt();
    let [dx, dy] = crate::landmarks::eye_line(points)?;
    let len = (dx * dx + dy * dy).sqrt();
    if !(r.is_finite() && r > 0.0 && len.is_finite() && len > 0.0) {
        return None;
    }
    Some(([cx, cy], r, dx / len, dy / len))
}

/// Adds the convention offsets ([`OFFSETS`], in the face's frame) to 68 points in place; a
/// degenerate shape is left as it is.
pub(crate) fn apply(points: &mut [f32]) {
    add_face_offsets(points, &OFFSETS);
}

/// How another placement of the same 68 points differs from `points`: `other - points` per
/// point, expressed in the face frame of `points` (centred on their centroid, in units of their
/// RMS radius, rotated so the outer eye corners 36-45 are level), interleaved `x0, y0, ...`.
/// This is what the finder's calibration averages over faces (its table is the mean of these
/// for the net's points against dlib's), and what [`add_face_offsets`] adds back.
///
/// Requires two shapes of 68 points (136 values); `None` when they are not, or when `points`
/// is degenerate (not finite, all in one place, or the eye corners coincide).
pub fn face_offsets(points: &[f32], other: &[f32]) -> Option<Vec<f32>> {
    if points.len() != 136 || other.len() != 136 {
        return None;
    }
    let (_, r, c, s) = face_frame(points)?;
    let out: Vec<f32> = points
        .chunks_exact(2)
        .zip(other.chunks_exact(2))
        .flat_map(|(p, o)| {
            let (dx, dy) = (o[0] - p[0], o[1] - p[1]);
            [(c * dx + s * dy) / r, (-s * dx + c * dy) / r]
        })
        .collect();
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Adds `offsets` (in the face frame of `points`, as [`face_offsets`] gives them) to the 68
/// `points` in place. Returns `false`, leaving `points` unchanged, when the lengths are not
/// 136 or `points` is degenerate.
pub fn add_face_offsets(points: &mut [f32], offsets: &[f32]) -> bool {
    if points.len() != 136 || offsets.len() != 136 {
        return false;
    }
    let Some((_, r, c, s)) = face_frame(points) else {
        return false;
    };
    for (p, o) in points.chunks_exact_mut(2).zip(offsets.chunks_exact(2)) {
        p[0] += r * (c * o[0] - s * o[1]);
        p[1] += r * (s * o[0] + c * o[1]);
    }
    true
}

/// The mean of [`face_offsets`] over pairs `(points, other)` (degenerate pairs skipped; zeros
/// when none is left): one placement's mean offset from another, e.g. the table the finder
/// adds to its points (the net's points against dlib's), or one person's own offset.
pub fn mean_face_offsets<'a>(pairs: impl IntoIterator<Item = (&'a [f32], &'a [f32])>) -> Vec<f32> {
    let mut sum = vec![0f64; 136];
    let mut n = 0usize;
    for o in pairs.into_iter().filter_map(|(p, t)| face_offsets(p, t)) {
        for (a, v) in sum.iter_mut().zip(o) {
            *a += v as f64;
        }
        n += 1;
    }
    sum.iter().map(|v| (v / n.max(1) as f64) as f32).collect()
}

/// Per frame, the landmark error of `tracked` against `truth` (as [`super::landmark_error`]:
/// mean point distance over the truth's outer-eye-corner distance) after each point's mean
/// offset over all the frames is removed: the **convention-free** error.
///
/// Represents how far a placement wanders from the truth beyond a constant per-point
/// difference of convention. Each frame's offsets `tracked - truth` are expressed in the
/// truth's face frame with the eye line (points 36-45) horizontal and unit eye distance; their
/// mean over the frames is subtracted from each frame's offsets, and the error is the mean
/// length of what is left. A landmarker (or a model built from one) whose points sit off
/// another's by the same amount in every face frame scores 0: cloning never sees such a
/// constant, since it works from deviations from the model's own mean.
///
/// Requires 68-point shapes (136 values). Ensures one value per pair, in order: NaN for a pair
/// of another length, with non-finite values or a degenerate truth (eye corners coinciding);
/// such pairs do not enter the mean offset.
pub fn convention_free_errors(pairs: &[(&[f32], &[f32])]) -> Vec<f32> {
    // The offsets of one pair in the truth's eye frame, written into `out`; false if invalid.
    fn eye_frame_offsets(tracked: &[f32], truth: &[f32], out: &mut [f64; 136]) -> bool {
        if tracked.len() != 136 || !tracked.iter().chain(truth).all(|v| v.is_finite()) {
            return false;
        }
        let Some([dx, dy]) = crate::landmarks::eye_line(truth) else {
            return false;
        };
        let (dx, dy) = (dx as f64, dy as f64);
        let len2 = dx * dx + dy * dy;
        if !(len2 > 0.0 && len2.is_finite()) {
            return false;
        }
        // Rotating by minus the eye line's angle and dividing by its length: the vector
        // (dx, dy) / len2 does both in one complex product with the conjugate.
        let (c, s) = (dx / len2, dy / len2);
        for ((o, t), g) in out
            .chunks_exact_mut(2)
            .zip(tracked.chunks_exact(2))
            .zip(truth.chunks_exact(2))
        {
            let (ex, ey) = ((t[0] - g[0]) as f64, (t[1] - g[1]) as f64);
            o[0] = c * ex + s * ey;
            o[1] = -s * ex + c * ey;
        }
        true
    }
    let mut mean = [0f64; 136];
    let mut n = 0usize;
    let mut o = [0f64; 136];
    for (t, g) in pairs {
        if eye_frame_offsets(t, g, &mut o) {
            mean.iter_mut().zip(&o).for_each(|(m, v)| *m += v);
            n += 1;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n.max(1) as f64);
    pairs
        .iter()
        .map(|(t, g)| {
            if !eye_frame_offsets(t, g, &mut o) {
                return f32::NAN;
            }
            let s: f64 = o
                .chunks_exact(2)
                .zip(mean.chunks_exact(2))
                .map(|(v, m)| ((v[0] - m[0]).powi(2) + (v[1] - m[1]).powi(2)).sqrt())
                .sum();
            (s / 68.0) as f32
        })
        .collect()
}

/// [`mean_face_offsets`] over owned pairs (the table's tests).
#[cfg(all(test, not(target_arch = "wasm32")))]
fn offsets(pairs: &[(Vec<f32>, Vec<f32>)]) -> Vec<f32> {
    mean_face_offsets(pairs.iter().map(|(r, t)| (r.as_slice(), t.as_slice())))
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;
    use crate::find::{landmark_error, FaceFinder};
    use crate::io::{read_image, read_landmarks};
    use std::path::{Path, PathBuf};

    fn frames(dir: &Path) -> Vec<PathBuf> {
        crate::io::annotated_images(dir).unwrap()
    }

    /// The uncalibrated points of the most confident face of each frame, with the frame's
    /// dlib points, and the frame's path.
    fn raw_pairs(paths: &[PathBuf]) -> Vec<(PathBuf, Vec<f32>, Vec<f32>)> {
        let mut finder = FaceFinder::new().unwrap();
        finder.set_calibrated(false);
        paths
            .iter()
            .filter_map(|p| {
                let img = read_image(p).unwrap();
                let truth =
                    read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
                let face = finder.find(&img.view().unwrap()).into_iter().next()?;
                Some((p.clone(), face.landmarks, truth))
            })
            .collect()
    }

    fn committed() -> Vec<(Vec<f32>, Vec<f32>)> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid");
        raw_pairs(&frames(&dir))
            .into_iter()
            .map(|(_, r, t)| (r, t))
            .collect()
    }

    #[test]
    fn table_is_reproducible() {
        let o = offsets(&committed());
        for (i, (a, b)) in o.iter().zip(OFFSETS.iter()).enumerate() {
            assert!(
                (a - b).abs() < 1e-4,
                "offset {i}: computed {a}, committed {b}"
            );
        }
        // Small corrections, not a different shape: under a fifth of the face's radius.
        assert!(OFFSETS.iter().all(|v| v.is_finite() && v.abs() < 0.2));
    }

    #[test]
    fn apply_moves_with_the_face() {
        // A shape, and the same shape rotated by 30 degrees, doubled and moved.
        let base: Vec<f32> = (0..68)
            .flat_map(|i| {
                let a = i as f32 * 0.37;
                [100.0 + 40.0 * a.cos() + i as f32, 80.0 + 30.0 * a.sin()]
            })
            .collect();
        let (c, s) = (30f32.to_radians().cos(), 30f32.to_radians().sin());
        let moved: Vec<f32> = base
            .chunks(2)
            .flat_map(|p| {
                [
                    2.0 * (c * p[0] - s * p[1]) + 7.0,
                    2.0 * (s * p[0] + c * p[1]) - 3.0,
                ]
            })
            .collect();
        let (mut a, mut b) = (base.clone(), moved.clone());
        apply(&mut a);
        apply(&mut b);
        for i in 0..68 {
            let (dx, dy) = (a[2 * i] - base[2 * i], a[2 * i + 1] - base[2 * i + 1]);
            let (ex, ey) = (b[2 * i] - moved[2 * i], b[2 * i + 1] - moved[2 * i + 1]);
            assert!((2.0 * (c * dx - s * dy) - ex).abs() < 1e-3, "point {i}");
            assert!((2.0 * (s * dx + c * dy) - ey).abs() < 1e-3, "point {i}");
        }
        // Degenerate shapes are left alone.
        let mut flat = vec![5.0f32; 136];
        apply(&mut flat);
        assert!(flat.iter().all(|&v| v == 5.0));
    }

    #[test]
    fn face_offsets_round_trip_and_refuse_bad_shapes() {
        // A face-like ring of 68 points, tilted, and another placement of it.
        let points: Vec<f32> = (0..68)
            .flat_map(|i| {
                let a = i as f32 * 0.37;
                [
                    100.0 + 40.0 * a.cos() + 0.2 * i as f32,
                    80.0 + 50.0 * a.sin(),
                ]
            })
            .collect();
        let other: Vec<f32> = points
            .iter()
            .enumerate()
            .map(|(k, v)| v + (k % 7) as f32 * 0.5 - 1.0)
            .collect();
        let o = face_offsets(&points, &other).unwrap();
        let mut back = points.clone();
        assert!(add_face_offsets(&mut back, &o));
        for (a, b) in back.iter().zip(&other) {
            assert!((a - b).abs() < 1e-3, "{a} against {b}");
        }
        // The mean over two pairs of the same offset is that offset.
        let m = mean_face_offsets([(&points[..], &other[..]), (&points[..], &other[..])]);
        assert!(m.iter().zip(&o).all(|(a, b)| (a - b).abs() < 1e-6));
        // Wrong lengths and degenerate shapes: nothing, and nothing changed.
        assert!(face_offsets(&points[..134], &other[..134]).is_none());
        assert!(face_frame(&points[..40]).is_none());
        assert!(face_offsets(&vec![5.0; 136], &other).is_none());
        let mut flat = vec![5.0f32; 136];
        assert!(!add_face_offsets(&mut flat, &o));
        assert!(flat.iter().all(|&v| v == 5.0));
        let mut nan = points.clone();
        nan[3] = f32::NAN;
        assert!(face_offsets(&nan, &other).is_none());
        assert!(!add_face_offsets(&mut back, &o[..10]));
        // No shape at all: zeros.
        assert!(mean_face_offsets(std::iter::empty())
            .iter()
            .all(|&v| v == 0.0));
    }

    #[test]
    fn convention_free_errors_remove_a_constant_offset_in_the_face_frame() {
        // A face-like ring with its eye corners 40 px apart, tilted by 0.3 rad and scaled
        // differently in each frame; the tracked points sit off by the same offset in the face
        // frame every time (plus, on the last frame, a wobble).
        let base: Vec<f32> = (0..68)
            .flat_map(|i| {
                let a = i as f32 * 0.37;
                [40.0 * a.cos() + 0.3 * i as f32, 50.0 * a.sin()]
            })
            .collect();
        let offset: Vec<f32> = (0..136).map(|k| ((k % 5) as f32 - 2.0) * 0.03).collect();
        let mut truths = Vec::new();
        let mut tracked = Vec::new();
        for f in 0..4 {
            let (scale, angle) = (1.0 + 0.2 * f as f32, 0.3 * f as f32 - 0.4);
            let sim =
                crate::similarity::Similarity::from_parts(scale, angle, 100.0 + f as f32, 80.0);
            let mut g = base.clone();
            sim.apply_in_place(&mut g);
            let [dx, dy] = crate::landmarks::eye_line(&g).unwrap();
            let iod = (dx * dx + dy * dy).sqrt();
            let (c, s) = (dx / iod, dy / iod);
            let mut t = g.clone();
            for (p, o) in t.chunks_exact_mut(2).zip(offset.chunks_exact(2)) {
                p[0] += iod * (c * o[0] - s * o[1]);
                p[1] += iod * (s * o[0] + c * o[1]);
            }
            truths.push(g);
            tracked.push(t);
        }
        // The errors of tracked points against the truths, frame by frame.
        let errors_of = |tracked: &[Vec<f32>]| {
            let pairs: Vec<(&[f32], &[f32])> = tracked
                .iter()
                .zip(&truths)
                .map(|(t, g)| (t.as_slice(), g.as_slice()))
                .collect();
            convention_free_errors(&pairs)
        };
        let e = errors_of(&tracked);
        assert!(e.iter().all(|v| v.abs() < 1e-4), "{e:?}");
        // The raw error is the offset's.
        assert!(landmark_error(&tracked[0], &truths[0]) > 0.03);
        // A wobble on one frame is what is left (shared with the mean: 3/4 of it there).
        let mut wobbly = tracked.clone();
        wobbly[3][0] += 4.0;
        let e = errors_of(&wobbly);
        let [dx, dy] = crate::landmarks::eye_line(&truths[3]).unwrap();
        let want = 0.75 * 4.0 / (dx * dx + dy * dy).sqrt() / 68.0;
        assert!((e[3] - want).abs() < 1e-4, "{} against {want}", e[3]);
        // Bad pairs: NaN, and left out of the mean.
        let short = &tracked[0][..134];
        let flat = vec![5.0f32; 136];
        let mut nan = tracked[1].clone();
        nan[7] = f32::NAN;
        let e = convention_free_errors(&[
            (short, &truths[0]),
            (&tracked[1], &flat),
            (&nan, &truths[1]),
            (&tracked[2], &truths[2]),
        ]);
        assert!(e[0].is_nan() && e[1].is_nan() && e[2].is_nan());
        assert!(e[3].abs() < 1e-5);
    }
}

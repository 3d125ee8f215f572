//! The landmark net's points moved onto the iBUG / dlib convention the rest of the project
//! uses (the `.pts` files the default models are built from, the figures' ground truth).
//!
//! face-api.js's 68-point net was trained on other annotations than dlib's: its points sit a
//! little off dlib's in the same way on every face (brows higher, the jaw wider, ...). The
//! offsets below are that mean difference, measured in each face's own frame (centred, scaled
//! by the points' RMS radius, rotated so the outer eye corners 36-45 are level) on the GRID
//! frames committed in `data/grid` (330 frames, 10 speakers, CC BY 4.0). Adding them back in
//! each face's frame removes the shared part of the difference; what is left varies from face
//! to face. Measured (docs/finding.md): the finder's mean error against dlib drops from
//! 0.033-0.047 to 0.024-0.034 on the shared clips, none of whose frames the offsets came from.
//!
//! Regenerate with `cargo test --release --lib find::calibration::write_table -- --ignored`
//! (it writes `src/find/calibration_table.rs`); `table_is_reproducible` checks that the
//! committed table is what the committed frames give.

include!("calibration_table.rs");

/// The face frame of 68 points: centroid, RMS radius, and the cosine and sine of the angle of
/// the line from point 36 to point 45. `None` for a degenerate or non-finite shape.
fn face_frame(points: &[f32]) -> Option<([f32; 2], f32, f32, f32)> {
    let n = (points.len() / 2) as f32;
    let cx = points.iter().step_by(2).sum::<f32>() / n;
    let cy = points.iter().skip(1).step_by(2).sum::<f32>() / n;
    let r = (points
        .chunks_exact(2)
        .map(|p| (p[0] - cx).powi(2) + (p[1] - cy).powi(2))
        .sum::<f32>()
        / n)
        .sqrt();
    let (dx, dy) = (points[90] - points[72], points[91] - points[73]);
    let len = (dx * dx + dy * dy).sqrt();
    if !(r.is_finite() && r > 0.0 && len.is_finite() && len > 0.0) {
        return None;
    }
    Some(([cx, cy], r, dx / len, dy / len))
}

/// Adds the convention offsets ([`OFFSETS`], in the face's frame) to 68 points in place; a
/// degenerate shape is left as it is.
pub(crate) fn apply(points: &mut [f32]) {
    debug_assert_eq!(points.len(), 136);
    let Some((_, r, c, s)) = face_frame(points) else {
        return;
    };
    for (p, o) in points.chunks_exact_mut(2).zip(OFFSETS.chunks_exact(2)) {
        p[0] += r * (c * o[0] - s * o[1]);
        p[1] += r * (s * o[0] + c * o[1]);
    }
}

/// The mean of `truth - raw` over pairs of 68-point shapes, each difference expressed in its
/// raw shape's face frame: the table [`apply`] adds. Degenerate shapes are skipped.
#[cfg(all(test, not(target_arch = "wasm32")))]
fn offsets(pairs: &[(Vec<f32>, Vec<f32>)]) -> Vec<f32> {
    let mut sum = vec![0f64; 136];
    let mut n = 0usize;
    for (raw, truth) in pairs {
        let Some((_, r, c, s)) = face_frame(raw) else {
            continue;
        };
        for i in 0..68 {
            let (dx, dy) = (truth[2 * i] - raw[2 * i], truth[2 * i + 1] - raw[2 * i + 1]);
            sum[2 * i] += ((c * dx + s * dy) / r) as f64;
            sum[2 * i + 1] += ((-s * dx + c * dy) / r) as f64;
        }
        n += 1;
    }
    sum.iter().map(|v| (v / n.max(1) as f64) as f32).collect()
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;
    use crate::find::{landmark_error, FaceFinder};
    use crate::io::{read_image, read_landmarks};
    use std::path::{Path, PathBuf};

    /// Every `.jpg` with a `.pts` under `dir`, sorted.
    fn frames(dir: &Path) -> Vec<PathBuf> {
        let mut out = Vec::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else if p.extension().is_some_and(|x| x == "jpg")
                    && p.with_extension("pts").exists()
                {
                    out.push(p);
                }
            }
        }
        out.sort();
        out
    }

    /// The uncalibrated points of the most confident face of each frame, with the frame's
    /// dlib points, and the frame's path.
    fn raw_pairs(paths: &[PathBuf]) -> Vec<(PathBuf, Vec<f32>, Vec<f32>)> {
        let mut finder = FaceFinder::new().unwrap();
        finder.calibrate = false;
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
    #[ignore = "writes src/find/calibration_table.rs"]
    fn write_table() {
        let pairs = committed();
        let o = offsets(&pairs);
        let mut text = format!(
            "// Generated by `cargo test --release --lib find::calibration::write_table -- --ignored`\n\
             // from the {} committed GRID frames of data/grid: see calibration.rs.\n\n\
             /// Per point, x then y: the mean dlib-minus-net offset in the face's frame.\n\
             const OFFSETS: [f32; 136] = [\n",
            pairs.len()
        );
        for p in o.chunks(2) {
            text.push_str(&format!("    {:.6}, {:.6},\n", p[0], p[1]));
        }
        text.push_str("];\n");
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/find/calibration_table.rs");
        std::fs::write(path, text).unwrap();
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

    /// On the shared GRID frames (825, ../shared), split by speaker: offsets from speakers
    /// 1-5 measured on 6-10 and the other way round; and the committed table on the other
    /// shared clips. Prints the figures of docs/finding.md and checks the offsets help.
    #[test]
    #[ignore = "needs ../shared; prints the calibration figures"]
    fn held_out_figures() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        let grid = raw_pairs(&frames(&root.join("grid")));
        let speaker = |p: &Path| -> u32 {
            let d = p
                .parent()
                .unwrap()
                .file_name()
                .unwrap()
                .to_string_lossy()
                .to_string();
            d[3..5].parse().unwrap()
        };
        let err = |pairs: &[&(PathBuf, Vec<f32>, Vec<f32>)], table: Option<&[f32]>| -> f32 {
            let mut sum = 0.0;
            for (_, r, t) in pairs {
                let mut p = r.clone();
                if let Some(o) = table {
                    let (_, rad, c, s) = face_frame(&p).unwrap();
                    for (q, o) in p.chunks_exact_mut(2).zip(o.chunks_exact(2)) {
                        q[0] += rad * (c * o[0] - s * o[1]);
                        q[1] += rad * (s * o[0] + c * o[1]);
                    }
                }
                sum += landmark_error(&p, t);
            }
            sum / pairs.len() as f32
        };
        for (train, test) in [((1, 5), (6, 10)), ((6, 10), (1, 5))] {
            let tr: Vec<_> = grid
                .iter()
                .filter(|(p, ..)| (train.0..=train.1).contains(&speaker(p)))
                .map(|(_, r, t)| (r.clone(), t.clone()))
                .collect();
            let te: Vec<_> = grid
                .iter()
                .filter(|(p, ..)| (test.0..=test.1).contains(&speaker(p)))
                .collect();
            let o = offsets(&tr);
            let (before, after) = (err(&te, None), err(&te, Some(&o)));
            println!(
                "grid: offsets from speakers {train:?} ({} frames), measured on {test:?} ({} frames): {before:.4} -> {after:.4}",
                tr.len(),
                te.len()
            );
            assert!(after < before);
        }
        for set in ["franck-dev", "franck-dev2", "webcam-dev"] {
            let pairs = raw_pairs(&frames(&root.join(set)));
            let all: Vec<_> = pairs.iter().collect();
            let (before, after) = (err(&all, None), err(&all, Some(&OFFSETS)));
            println!("{set}: {} frames: {before:.4} -> {after:.4}", all.len());
            assert!(after < before);
        }
    }
}

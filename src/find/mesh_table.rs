//! The 68 iBUG points from MediaPipe's 468-point face mesh: each point a fixed blend of
//! [`BLEND`] mesh vertices.
//!
//! The table is learned, not drawn by hand, on the 330 GRID frames committed in `data/grid`
//! (10 speakers), in the face frame (centred, scaled by the RMS radius, eye line level):
//! - each point's main vertex is the one whose offset from dlib's point has the least
//!   variance plus half its squared mean;
//! - the [`BLEND`] - 1 vertices nearest dlib's mean point join it, with weights that sum to 1,
//!   fitted by ridge least squares so that the blend follows dlib's point from face to face
//!   (for the jaw, a little beyond the main vertex, away from its neighbours inside the face:
//!   dlib's outline lies outside the mesh's).
//!
//! Weights that sum to 1 make the blend move with the face (a translation, rotation or scale of
//! the mesh moves the point the same way). The mean offset that remains is removed by the
//! calibration (`calibration.rs`), as for any landmarker. Regenerate with `cargo run --release
//! --example mesh_table` (it rewrites `mesh_table_data.rs`), then the calibration; the figures
//! are in docs/finding.md.

/// Mesh vertices blended per iBUG point.
pub(crate) const BLEND: usize = 3;

include!("mesh_table_data.rs");

/// For each of the 68 iBUG points, its depth: away from the camera, in units of the face's RMS
/// radius, 0 on average over the points (the jaw's ends about 1.2, the nose tip about -0.7).
/// The mean, over the committed GRID frames, of the blend of its mesh vertices' depths (the
/// mesh's third coordinate), learned with the table. What tells a turn of the head from an
/// expression ([`crate::fit::split_head_turn`]).
pub const IBUG_DEPTH: &[f32; 68] = &IBUG_DEPTH_DATA;

/// The 68 iBUG points (interleaved x, y) of a 468-point mesh (x, y, z interleaved).
pub(crate) fn to_ibug(mesh: &[f32], out: &mut [f32]) {
    for ((o, verts), weights) in out
        .chunks_exact_mut(2)
        .zip(MESH_TO_IBUG.iter())
        .zip(MESH_WEIGHTS.iter())
    {
        let (mut x, mut y) = (0.0, 0.0);
        for (&v, &w) in verts.iter().zip(weights) {
            let p = &mesh[v as usize * 3..][..2];
            x += w * p[0];
            y += w * p[1];
        }
        o[0] = x;
        o[1] = y;
    }
}

/// The jaw points (0-16) of a face turned by `yaw` moved out to where its outline is seen.
///
/// dlib's jaw points follow the face's visible outline; the mesh's vertices are fixed on the
/// skin. Seen turned by an angle `a` about its vertical axis, a jaw of roughly circular
/// cross-section keeps its outline at its radius from the axis while the vertices that are
/// the outline seen from the front move in to `cos a` of it, on both sides (the vertices of the
/// side turned away slip behind the outline, those of the near side in front of it). So each
/// jaw point is moved away from the midpoint of points 0 and 16, along the eye line, by
/// `1 / cos a` of its distance, with `a` the mesh's own turn: the angle of the line between
/// its cheek-edge vertices 234 and 454 out of the image plane (their depth difference against
/// their distance along the eye line). No constant is fitted; on frontal faces it does
/// nothing (GRID's mean turn is 3 degrees: 0.1% of a point's distance).
///
/// Requires the 468-point `mesh` (x, y, z) the 68 `points` came from; leaves the points as
/// they are for a degenerate mesh or a turn over 60 degrees.
pub(crate) fn silhouette(mesh: &[f32], points: &mut [f32]) {
    if mesh.len() < 455 * 3 || points.len() != 136 {
        return;
    }
    // The eye line's direction `u`.
    let Some((_, _, ux, uy)) = super::face_frame(points) else {
        return;
    };
    let (a, b) = (&mesh[234 * 3..][..3], &mesh[454 * 3..][..3]);
    let across = (b[0] - a[0]) * ux + (b[1] - a[1]) * uy;
    let cos = across / across.hypot(b[2] - a[2]);
    if !(cos.is_finite() && cos >= 0.5) {
        return;
    }
    let stretch = 1.0 / cos - 1.0;
    let (mx, my) = (
        0.5 * (points[0] + points[32]),
        0.5 * (points[1] + points[33]),
    );
    for p in points[..34].chunks_exact_mut(2) {
        let d = (p[0] - mx) * ux + (p[1] - my) * uy;
        p[0] += stretch * d * ux;
        p[1] += stretch * d * uy;
    }
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;

    #[test]
    fn table_indexes_the_mesh_with_weights_that_sum_to_one() {
        for (j, (verts, weights)) in MESH_TO_IBUG.iter().zip(MESH_WEIGHTS.iter()).enumerate() {
            assert!(
                verts
                    .iter()
                    .all(|&v| (v as usize) < super::super::mesh::MESH_POINTS),
                "point {j}"
            );
            let sum: f32 = weights.iter().sum();
            assert!((sum - 1.0).abs() < 1e-4, "point {j}: weights sum to {sum}");
            // A blend near its vertices, not a far extrapolation.
            assert!(
                weights.iter().map(|w| w.abs()).sum::<f32>() < 3.0,
                "point {j}: {weights:?}"
            );
        }
        // The eye corners are distinct (the face frame needs them apart).
        assert_ne!(MESH_TO_IBUG[36], MESH_TO_IBUG[45]);
    }

    #[test]
    fn a_turned_face_has_its_jaw_moved_out_to_the_outline() {
        // A flat mesh (depth 0 everywhere): a face seen from the front, nothing moves.
        let mut mesh: Vec<f32> = (0..468 * 3)
            .map(|i| {
                if i % 3 == 2 {
                    0.0
                } else {
                    (i as f32 * 0.37).sin() * 50.0
                }
            })
            .collect();
        // Eye corners level, cheek edges 100 apart across the face.
        let mut points = [0.0f32; 136];
        for i in 0..68 {
            points[2 * i] = (i as f32 - 34.0) * 2.0;
            points[2 * i + 1] = (i as f32 * 0.5).cos() * 30.0;
        }
        points[72] = -30.0;
        points[73] = 0.0;
        points[90] = 30.0;
        points[91] = 0.0;
        mesh[234 * 3] = -50.0;
        mesh[454 * 3] = 50.0;
        let front = points;
        silhouette(&mesh, &mut points);
        assert_eq!(points, front);
        // Turned by 37 degrees (cosine 0.8: the cheek edges 80 apart across, 60 in depth): the jaw points
        // move away from the midpoint of points 0 and 16 by a quarter of their distance along
        // the eye line; the rest stay.
        mesh[454 * 3] = 30.0;
        mesh[454 * 3 + 2] = 60.0;
        let mid = 0.5 * (front[0] + front[32]);
        silhouette(&mesh, &mut points);
        for i in 0..17 {
            let want = front[2 * i] + 0.25 * (front[2 * i] - mid);
            assert!(
                (points[2 * i] - want).abs() < 1e-3,
                "point {i}: {}",
                points[2 * i]
            );
            assert_eq!(points[2 * i + 1], front[2 * i + 1]);
        }
        assert_eq!(points[34..], front[34..]);
        // Turned further than 60 degrees, or a degenerate mesh: left alone.
        let mut p = front;
        mesh[454 * 3 + 2] = 500.0;
        silhouette(&mesh, &mut p);
        assert_eq!(p, front);
        mesh[454 * 3 + 2] = f32::NAN;
        silhouette(&mesh, &mut p);
        assert_eq!(p, front);
        silhouette(&mesh[..100], &mut p);
        assert_eq!(p, front);
    }

    #[test]
    fn a_blend_moves_with_the_mesh() {
        // Any mesh, and the same mesh scaled by 2 and moved by (5, -3): every blended point
        // is scaled and moved the same way, because the weights sum to 1.
        let mesh: Vec<f32> = (0..468 * 3)
            .map(|i| (i as f32 * 0.37).sin() * 50.0)
            .collect();
        let moved: Vec<f32> = mesh
            .chunks_exact(3)
            .flat_map(|p| [2.0 * p[0] + 5.0, 2.0 * p[1] - 3.0, p[2]])
            .collect();
        let (mut a, mut b) = ([0.0; 136], [0.0; 136]);
        to_ibug(&mesh, &mut a);
        to_ibug(&moved, &mut b);
        for i in 0..68 {
            assert!((2.0 * a[2 * i] + 5.0 - b[2 * i]).abs() < 1e-3, "point {i}");
            assert!(
                (2.0 * a[2 * i + 1] - 3.0 - b[2 * i + 1]).abs() < 1e-3,
                "point {i}"
            );
        }
    }
}

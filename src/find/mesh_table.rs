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

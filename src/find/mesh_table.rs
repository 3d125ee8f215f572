//! The 68 iBUG points from MediaPipe's 468-point face mesh: one mesh vertex per iBUG point.
//!
//! The table is learned, not drawn by hand: for each iBUG point, the mesh vertex whose offset
//! from dlib's point (in dlib's face frame: centred, scaled by the RMS radius, eye line level)
//! over the 330 GRID frames committed in `data/grid` (10 speakers) has the least variance plus
//! half its squared mean. The mean offset that remains
//! is then removed by the calibration (`calibration.rs`), as for any
//! landmarker. Regenerate with `cargo run --release --example
//! mesh_table` (it rewrites `mesh_table_data.rs`), then the calibration.

include!("mesh_table_data.rs");

/// The 68 iBUG points (interleaved x, y) of a 468-point mesh (x, y, z interleaved).
pub(crate) fn to_ibug(mesh: &[f32], out: &mut [f32]) {
    for (o, &v) in out.chunks_exact_mut(2).zip(MESH_TO_IBUG.iter()) {
        let p = &mesh[v as usize * 3..][..2];
        o.copy_from_slice(p);
    }
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;

    #[test]
    fn table_indexes_the_mesh() {
        assert!(MESH_TO_IBUG
            .iter()
            .all(|&v| (v as usize) < super::super::mesh::MESH_POINTS));
        // The eye corners are distinct (the face frame needs them apart).
        assert_ne!(MESH_TO_IBUG[36], MESH_TO_IBUG[45]);
    }
}

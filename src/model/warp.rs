//! Sampling an image at a shape into the reference frame (the inverse piecewise-affine warp).

use crate::error::{check_len, Result};
use crate::image::ImageRef;
use crate::model::frame::ReferenceFrame;

/// Samples `image` at the mesh placed by `image_shape` (the frame's landmarks in image
/// coordinates) into the frame: for every frame pixel, its barycentric coordinates in its
/// triangle locate the corresponding image point, which is sampled bilinearly. Writes RGB in
/// `0..=1` into `out` (`3N` values). Allocates nothing.
///
/// This is the shape-normalisation step of Eq. 2 (the appearance `A(x)` over `x in s0`).
pub fn sample_rgb(
    frame: &ReferenceFrame,
    image: &ImageRef<'_>,
    image_shape: &[f32],
    out: &mut [f32],
) -> Result<()> {
    check_len("shape", image_shape, frame.vertices().len())?;
    check_len("appearance buffer", out, frame.n_pixels() * 3)?;
    let tris = frame.triangles();
    for (px, o) in frame.pixels().iter().zip(out.chunks_exact_mut(3)) {
        let t = tris[px.triangle as usize];
        let (mut x, mut y) = (0.0, 0.0);
        for k in 0..3 {
            let v = t[k] as usize;
            x += px.bary[k] * image_shape[2 * v];
            y += px.bary[k] * image_shape[2 * v + 1];
        }
        o.copy_from_slice(&image.sample_rgb(x, y));
    }
    Ok(())
}

//! The shape model (Eq. 1) and generalised Procrustes alignment.

use crate::error::{check_len, Result};
use crate::model::linear::LinearModel;
use crate::similarity::{CentredFit, Similarity};

/// A linear shape model `s = s0 + S p` (the paper's Eq. 1) in model coordinates: a
/// [`LinearModel`] (it dereferences to one for the base, the modes, the variances and the
/// shared operations).
///
/// Represents: the base shape `s0` (interleaved `2n` values, centred on the origin), `m`
/// orthonormal modes (row-major: mode `i` is `modes[i*2n..(i+1)*2n]`, i.e. the columns of `S`),
/// and the variance `gamma_i` of each mode. The similarity pose is not part of it.
/// Ensures (when built by [`crate::Builder`] or loaded from a file): modes orthonormal to
/// within float precision, variances positive and descending.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeModel(pub LinearModel);

crate::model::linear::linear_newtype!(ShapeModel);

impl ShapeModel {
    /// Number of landmarks `n`.
    pub fn landmarks(&self) -> usize {
        self.base.len() / 2
    }

    /// Eq. 1, `s = s0 + sum_i p_i s_i`, written into `out` (length `2n`). Allocates nothing.
    /// Requires `p.len() == m`, `out.len() == 2n`, finite `p` (all checked); fails with
    /// [`crate::error::Error::Overflow`] if the instance overflows.
    pub fn instance(&self, p: &[f32], out: &mut [f32]) -> Result<()> {
        self.0.instance_checked("shape parameters", p, out)
    }

    /// Splits an image shape into pose and parameters: aligns `s0` to the image shape by least
    /// squares (the pose), maps the image shape back into model coordinates and projects it.
    /// Returns the pose and writes `p` into `out`.
    pub fn project_image_shape(&self, image_shape: &[f32], out: &mut [f32]) -> Result<Similarity> {
        check_len("landmarks", image_shape, self.base.len())?;
        crate::model::limits::check_landmarks(image_shape)?;
        // Pose and parameters jointly by alternating least squares: the pose that places the
        // current instance `s0 + S p` best onto the landmarks, then `p` from the landmarks
        // mapped back through it, until the pose settles. (A pose fitted to `s0` alone is off
        // at second order in scale, so even a training shape would leave the model's span.)
        let degenerate = || {
            crate::error::Error::Landmarks("landmarks are degenerate (all points coincide)".into())
        };
        let mut pose = Similarity::align(&self.base, image_shape);
        let mut normalised = image_shape.to_vec();
        let mut instance = self.base.clone();
        for _ in 0..50 {
            let inv = pose.inverse().ok_or_else(degenerate)?;
            normalised.copy_from_slice(image_shape);
            inv.apply_in_place(&mut normalised);
            self.project(&normalised, out);
            self.instance_unchecked(out, &mut instance);
            let next = Similarity::align(&instance, image_shape);
            let change = (next.a - pose.a).abs() + (next.b - pose.b).abs();
            let shift = (next.tx - pose.tx).abs() + (next.ty - pose.ty).abs();
            pose = next;
            if !(change > 1e-7 * pose.scale() || shift > 1e-5 * pose.scale()) {
                break;
            }
        }
        let inv = pose.inverse().ok_or_else(degenerate)?;
        normalised.copy_from_slice(image_shape);
        inv.apply_in_place(&mut normalised);
        self.project(&normalised, out);
        Ok(pose)
    }
}

/// Moves a shape's centroid to the origin and scales it to unit Frobenius norm.
fn normalise(shape: &mut [f64]) {
    let n = (shape.len() / 2).max(1) as f64;
    let (mut cx, mut cy) = (0.0, 0.0);
    for p in shape.chunks_exact(2) {
        cx += p[0];
        cy += p[1];
    }
    cx /= n;
    cy /= n;
    for p in shape.chunks_exact_mut(2) {
        p[0] -= cx;
        p[1] -= cy;
    }
    let norm = shape.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm > 0.0 {
        shape.iter_mut().for_each(|v| *v /= norm);
    }
}

/// Least-squares similarity alignment of `src` onto `dst` in f64 (in place on `src`).
fn align_to(src: &mut [f64], dst: &[f64]) {
    let CentredFit {
        a,
        b,
        src_mean: [sx, sy],
        dst_mean: [dx, dy],
    } = CentredFit::new(src, dst);
    for p in src.chunks_exact_mut(2) {
        let (x, y) = (p[0] - sx, p[1] - sy);
        p[0] = a * x - b * y + dx;
        p[1] = b * x + a * y + dy;
    }
}

/// Rotates a centred shape into its canonical orientation, so that the result does not depend
/// on how the training shapes were rotated. For the 68-point iBUG scheme the outer eye corners
/// (landmarks 36 and 45) lie on a horizontal line, left eye on the left; for other schemes the
/// principal axis of the points lies along x, with landmark 0 on the negative side.
fn canonical_orientation(shape: &mut [f64]) {
    let n = shape.len() / 2;
    let angle = if n == 68 {
        let [l, r] = crate::landmarks::OUTER_EYE_CORNERS;
        let (dx, dy) = (
            shape[2 * r] - shape[2 * l],
            shape[2 * r + 1] - shape[2 * l + 1],
        );
        dy.atan2(dx)
    } else {
        let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
        for p in shape.chunks_exact(2) {
            sxx += p[0] * p[0];
            syy += p[1] * p[1];
            sxy += p[0] * p[1];
        }
        let mut a = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        let (c, s) = (a.cos(), a.sin());
        if shape[0] * c + shape[1] * s > 0.0 {
            a += std::f64::consts::PI;
        }
        a
    };
    let (c, s) = ((-angle).cos(), (-angle).sin());
    for p in shape.chunks_exact_mut(2) {
        let (x, y) = (p[0], p[1]);
        p[0] = c * x - s * y;
        p[1] = s * x + c * y;
    }
}

/// Generalised Procrustes analysis (GPA), iterated to convergence.
///
/// With `reference = None`: every shape is centred and scaled to unit norm, then aligned to the
/// current mean estimate (initially the first shape); the mean is re-estimated, normalised and
/// put into its canonical orientation (the gauge), until it moves by less than 1e-10. Returns
/// the aligned shapes and the unit-norm mean.
///
/// With `reference = Some(r)`: every shape is aligned directly to the fixed `r` (used to build a
/// model in another model's reference frame so both live in one coordinate system); the mean of
/// the aligned shapes is returned as it is.
///
/// Ensures: each returned shape is a similarity transform of its input, and the result does not
/// depend on the inputs' individual poses (rotation, scale, translation).
pub fn generalised_procrustes(
    shapes: &[Vec<f64>],
    reference: Option<&[f64]>,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mut aligned: Vec<Vec<f64>> = shapes.to_vec();
    if aligned.is_empty() {
        return (aligned, reference.map(<[f64]>::to_vec).unwrap_or_default());
    }
    if let Some(r) = reference {
        for s in &mut aligned {
            align_to(s, r);
        }
        let mean = crate::pca::mean(&aligned);
        return (aligned, mean);
    }
    aligned.iter_mut().for_each(|s| normalise(s));
    let mut mean = aligned[0].clone();
    canonical_orientation(&mut mean);
    for _ in 0..200 {
        for s in &mut aligned {
            align_to(s, &mean);
        }
        let mut new_mean = crate::pca::mean(&aligned);
        normalise(&mut new_mean);
        canonical_orientation(&mut new_mean);
        let change: f64 = new_mean
            .iter()
            .zip(&mean)
            .map(|(a, b)| (a - b).powi(2))
            .sum();
        mean = new_mean;
        if change < 1e-20 {
            break;
        }
    }
    for s in &mut aligned {
        align_to(s, &mean);
    }
    (aligned, mean)
}

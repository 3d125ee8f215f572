//! The limits of the values that enter the library, and their checks (re-exported by
//! [`crate::model::bounds`], which adds the model-level checks and the memory budget).

use crate::error::{Error, Result};
use crate::image::MAX_IMAGE_SIDE;
use crate::model::frame::MAX_FRAME_SIDE;
use crate::similarity::Similarity;

/// Largest magnitude of a base shape coordinate or frame origin (model coordinates): the frame
/// holding the mesh is at most [`MAX_FRAME_SIDE`] wide, so twice that leaves room for any
/// origin.
pub const MAX_SHAPE_COORD: f32 = 2.0 * MAX_FRAME_SIDE as f32;
/// Base appearance values (RGB, nominally `0..=1`) must lie in `[MIN_APPEARANCE, MAX_APPEARANCE]`.
pub const MIN_APPEARANCE: f32 = -1.0;
/// See [`MIN_APPEARANCE`].
pub const MAX_APPEARANCE: f32 = 2.0;
/// Pose scale (model coordinates to image pixels) of a model's mean pose and of any pose given
/// with parameters: `MIN_POSE_SCALE..=MAX_POSE_SCALE`.
pub const MIN_POSE_SCALE: f32 = 1e-4;
/// See [`MIN_POSE_SCALE`].
pub const MAX_POSE_SCALE: f32 = 1e4;
/// Largest magnitude of a pose translation (image pixels).
pub const MAX_POSE_SHIFT: f32 = 1e6;
/// Largest magnitude of a shape or appearance parameter given to the library. A real face is
/// within a few standard deviations (at most a few thousand model units); this bound only
/// keeps `s0 + S p` and `A0 + A lambda` far from `f32` overflow.
pub const MAX_PARAM: f32 = 1e6;
// Landmark files are read with the same bound (the landmark parser sits below the model).
const _: () = assert!(MAX_PARAM == crate::landmarks::MAX_COORDINATE);
/// Largest magnitude of a cloning gain (global or per mode) and of the constraint's `k`.
pub const MAX_GAIN: f32 = 1e3;

/// The explicit limits a model file must respect (see `docs/model-format.md`, "Limits"; [`crate::model::format`] checks them on read).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Landmarks `n`: `3..=max_landmarks`.
    pub max_landmarks: u32,
    /// Triangles `t`: `1..=max_triangles`.
    pub max_triangles: u32,
    /// Frame width and height: `1..=max_frame_side` (= [`MAX_FRAME_SIDE`]).
    pub max_frame_side: u32,
    /// Frame pixels inside the mesh `N`: `1..=max_pixels`.
    pub max_pixels: u32,
    /// Shape modes `m`: `0..=max_shape_modes` (and `m <= 2n`).
    pub max_shape_modes: u32,
    /// Appearance modes `l`: `0..=max_appearance_modes` (and `l <= 3N`).
    pub max_appearance_modes: u32,
    /// Model name: at most this many bytes of UTF-8.
    pub max_name_bytes: u32,
    /// Reference image name: at most this many bytes of UTF-8.
    pub max_reference_name_bytes: u32,
    /// Training image width and height: `1..=max_image_side` (= [`MAX_IMAGE_SIDE`]).
    pub max_image_side: u32,
    /// Frame grid area: `width * height <= area_per_pixel * N + area_slack`, so that a small
    /// file cannot make the reader allocate a large grid.
    pub area_per_pixel: u64,
    /// See [`Limits::area_per_pixel`].
    pub area_slack: u64,
    /// Rasterisation work: the sum over triangles of their bounding boxes (in grid cells,
    /// clipped to the grid) must be at most `coverage_per_cell * width * height +
    /// coverage_per_triangle * t`.
    pub coverage_per_cell: u64,
    /// See [`Limits::coverage_per_cell`].
    pub coverage_per_triangle: u64,
    /// Tolerance of the mode checks: `|<s_i, s_j> - delta_ij| <= orthonormal_tolerance` for the
    /// shape modes (every pair), `| |A_i|^2 - 1 | <=` it for the appearance modes (norms only).
    pub orthonormal_tolerance: f32,
}

/// The limits of the model file format (every version).
pub const LIMITS: Limits = Limits {
    max_landmarks: 1024,
    max_triangles: 8192,
    max_frame_side: MAX_FRAME_SIDE,
    max_pixels: 4_194_304,
    max_shape_modes: 256,
    max_appearance_modes: 256,
    max_name_bytes: 256,
    max_reference_name_bytes: 256,
    max_image_side: MAX_IMAGE_SIDE,
    area_per_pixel: 4,
    area_slack: 2048,
    coverage_per_cell: 16,
    coverage_per_triangle: 64,
    orthonormal_tolerance: 1e-3,
};

/// NaN-safe clamp: `v` limited to `[-lim, lim]`; a NaN `v` becomes 0 (the mean), a NaN or
/// negative `lim` counts as 0, an infinite one as `f32::MAX`. Always returns a finite number.
pub fn clamp_symmetric(v: f32, lim: f32) -> f32 {
    // An infinite limit (k x sigma overflowed) is the largest finite one: the result stays
    // finite even for an infinite `v`.
    let lim = if lim >= 0.0 { lim.min(f32::MAX) } else { 0.0 };
    if v > lim {
        lim
    } else if v < -lim {
        -lim
    } else if v.is_nan() {
        0.0
    } else {
        v
    }
}

/// Fails with [`Error::Params`] unless every value is finite and at most [`MAX_PARAM`] in
/// magnitude, naming the first bad one.
pub fn check_param_values(what: &str, values: &[f32]) -> Result<()> {
    match values.iter().position(|v| !(v.abs() <= MAX_PARAM)) {
        None => Ok(()),
        Some(i) if values[i].is_finite() => Err(Error::Params(format!(
            "{what}[{i}] is {}, beyond the limit +-{MAX_PARAM:e}",
            values[i]
        ))),
        Some(i) => Err(Error::Params(format!(
            "{what}[{i}] is not finite ({})",
            values[i]
        ))),
    }
}

/// Fails with [`Error::Params`] unless the pose is finite with a scale in
/// `MIN_POSE_SCALE..=MAX_POSE_SCALE` and a translation within `+-MAX_POSE_SHIFT`.
pub fn check_pose_range(what: &str, pose: &Similarity) -> Result<()> {
    let v = [pose.a, pose.b, pose.tx, pose.ty];
    if v.iter().any(|x| !x.is_finite()) {
        return Err(Error::Params(format!("{what} is not finite ({v:?})")));
    }
    let s = pose.scale();
    if !(MIN_POSE_SCALE..=MAX_POSE_SCALE).contains(&s) {
        return Err(Error::Params(format!(
            "{what} has scale {s}, outside {MIN_POSE_SCALE:e}..={MAX_POSE_SCALE:e}"
        )));
    }
    if !(pose.tx.abs() <= MAX_POSE_SHIFT && pose.ty.abs() <= MAX_POSE_SHIFT) {
        return Err(Error::Params(format!(
            "{what} has translation ({}, {}), beyond +-{MAX_POSE_SHIFT:e}",
            pose.tx, pose.ty
        )));
    }
    Ok(())
}

/// Fails with [`Error::Params`] unless `g` is finite and within `+-MAX_GAIN`.
pub fn check_gain(what: &str, g: f32) -> Result<()> {
    if g.abs() <= MAX_GAIN {
        Ok(())
    } else {
        Err(Error::Params(format!(
            "{what} {g} is not a finite number within +-{MAX_GAIN}"
        )))
    }
}

/// Fails with [`Error::Landmarks`] unless every landmark coordinate is finite and within
/// `+-MAX_PARAM` pixels (a larger coordinate is no image's).
pub fn check_landmarks(values: &[f32]) -> Result<()> {
    match values.iter().position(|v| !(v.abs() <= MAX_PARAM)) {
        None => Ok(()),
        Some(i) => Err(Error::Landmarks(format!(
            "coordinate {i} is {}, not a finite number within +-{MAX_PARAM:e} pixels",
            values[i]
        ))),
    }
}

/// [`crate::error::check_len`] then [`check_landmarks`]: fails unless `values` holds `len`
/// landmark coordinates, each finite and within `+-MAX_PARAM` pixels.
pub(crate) fn check_landmarks_len(what: &str, values: &[f32], len: usize) -> Result<()> {
    crate::error::check_len(what, values, len)?;
    check_landmarks(values)
}

/// Fails with [`Error::Params`] unless a face box (left, top, width, height) is finite, within
/// the parameter bounds and at least 4x4.
pub(crate) fn check_face_box(x: f32, y: f32, w: f32, h: f32) -> Result<()> {
    check_param_values("box", &[x, y, w, h])?;
    if !(w >= 4.0 && h >= 4.0) {
        return Err(Error::Params(format!(
            "box {w}x{h} is too small (at least 4x4)"
        )));
    }
    Ok(())
}

/// Fails with [`Error::Overflow`] naming `what` unless every value of an output is finite.
pub fn check_output(what: &str, values: &[f32]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::Overflow(format!(
            "{what}[{i}] overflowed ({}); the inputs are too large for this model",
            values[i]
        ))),
    }
}

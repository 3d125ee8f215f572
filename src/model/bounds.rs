//! Bounds on every number that enters the library, and the memory budget.
//!
//! Two promises are kept here (see `docs/model-format.md`, "Value bounds" and "Memory budget"):
//!
//! 1. **Finite or a typed error.** A model file may only declare values a real model can have
//!    ([`check_model_values`], run by [`crate::model::format::read_model`] and before every write), and
//!    parameters, poses and gains are bounded on entry ([`check_param_values`],
//!    [`check_pose_range`], [`MAX_GAIN`]). With these bounds every instance, mapping and
//!    synthesis stays far inside the `f32` range; outputs are checked anyway where overflow is
//!    conceivable ([`check_output`]), and an overflow is [`Error::Overflow`] naming what
//!    overflowed, never a NaN.
//! 2. **Memory bounded by the input.** Everything allocated because of a model is at most
//!    [`MODEL_BYTES_FACTOR`] times the model's size in bytes plus [`FIXED_ALLOWANCE`]
//!    ([`model_budget`]); everything allocated because of an image is bounded by the image limit
//!    ([`crate::MAX_IMAGE_SIDE`]). Files are read through a size cap ([`MAX_MODEL_FILE_BYTES`],
//!    [`MAX_IMAGE_FILE_BYTES`]). The tracker checks its precomputation against the budget before
//!    allocating it ([`check_tracking_budget`]).

pub use crate::model::limits::{
    check_gain, check_landmarks, check_output, check_param_values, check_pose_range,
    clamp_symmetric, Limits, LIMITS, MAX_APPEARANCE, MAX_GAIN, MAX_PARAM, MAX_POSE_SCALE,
    MAX_POSE_SHIFT, MAX_SHAPE_COORD, MIN_APPEARANCE, MIN_POSE_SCALE,
};

use crate::error::{Error, FormatError, Result};
use crate::image::MAX_IMAGE_SIDE;
use crate::model::{Model, Reference};

/// Memory budget: allocations because of a model are at most this many times its size in
/// bytes ...
pub const MODEL_BYTES_FACTOR: u64 = 8;
/// ... plus this fixed allowance (bytes).
pub const FIXED_ALLOWANCE: u64 = 64 << 20;
/// Loading a model: [`crate::model::format::read_model`] allocates at most `LOAD_BYTES_FACTOR x file
/// bytes + LOAD_ALLOWANCE` (asserted by the fuzz harness). The factor is larger than
/// [`MODEL_BYTES_FACTOR`] because compact (version 2) files store a pixel's appearance in about
/// 3 bytes that expand to 12 in memory, next to the frame's per-pixel tables.
pub const LOAD_BYTES_FACTOR: u64 = 16;
/// See [`LOAD_BYTES_FACTOR`].
pub const LOAD_ALLOWANCE: u64 = 96 << 10;
/// Largest model file read (bytes): the largest model the format's limits allow is smaller.
pub const MAX_MODEL_FILE_BYTES: u64 = 2 << 30;
/// Largest image file read (bytes).
pub const MAX_IMAGE_FILE_BYTES: u64 = 256 << 20;
/// Largest landmark, list or parameter file read (bytes).
pub const MAX_TEXT_FILE_BYTES: u64 = 16 << 20;

/// The memory budget of everything allocated because of a model of `model_bytes` bytes:
/// `MODEL_BYTES_FACTOR * model_bytes + FIXED_ALLOWANCE`.
pub fn model_budget(model_bytes: u64) -> u64 {
    MODEL_BYTES_FACTOR
        .saturating_mul(model_bytes)
        .saturating_add(FIXED_ALLOWANCE)
}

/// The size in bytes of `model`'s data as stored in a file (the arrays and names; within a
/// few hundred bytes of the file's length).
pub fn model_bytes(model: &Model) -> u64 {
    let floats = model.shape().base.len()
        + model.shape().modes.len()
        + model.shape().variances.len()
        + model.frame().vertices().len()
        + 3 * model.frame().triangles().len()
        + model.appearance().len()
        + model.appearance().len() * model.appearance().n_modes()
        + model.appearance().n_modes();
    let names = model.name().len()
        + match &model.reference() {
            Reference::Mean => 0,
            Reference::Training(s) => s.len(),
        };
    4 * floats as u64 + names as u64 + 128
}

/// The value bounds of a model (checked on load and before writing): mean pose in range,
/// base shape and frame origin within `+-MAX_SHAPE_COORD`, base appearance within
/// `MIN_APPEARANCE..=MAX_APPEARANCE`, variances no larger than the base's own range allows
/// (shape: `2n (2 MAX_SHAPE_COORD)^2`; appearance: `3N (MAX_APPEARANCE - MIN_APPEARANCE)^2`),
/// image size within `1..=MAX_IMAGE_SIDE`, the names within the format's limits.
pub fn check_model_values(model: &Model) -> std::result::Result<(), FormatError> {
    check_name_lengths(model)?;
    check_image_size(model)?;
    check_mean_pose(model)?;
    check_arrays(model)
}

/// The error of an out-of-range `value` at `index` of `array`, `range` saying what is allowed.
fn out_of_range(array: &'static str, index: usize, value: f32, range: String) -> FormatError {
    FormatError::OutOfRange {
        array,
        index: index as u64,
        value,
        range,
    }
}

/// [`check_model_values`]: the model's and the reference's names within the format's limits.
fn check_name_lengths(model: &Model) -> std::result::Result<(), FormatError> {
    let lim = &LIMITS;
    for (name, bytes, max) in [
        ("model name length", model.name().len(), lim.max_name_bytes),
        (
            "reference name length",
            match &model.reference() {
                Reference::Mean => 0,
                Reference::Training(s) => s.len(),
            },
            lim.max_reference_name_bytes,
        ),
    ] {
        if bytes as u64 > max as u64 {
            return Err(FormatError::LimitExceeded {
                what: name,
                value: bytes as u64,
                limit: max as u64,
            });
        }
    }
    Ok(())
}

/// [`check_model_values`]: the image size within `1..=MAX_IMAGE_SIDE`.
fn check_image_size(model: &Model) -> std::result::Result<(), FormatError> {
    for (i, &v) in model.image_size().iter().enumerate() {
        if v == 0 || v > MAX_IMAGE_SIDE {
            return Err(FormatError::LimitExceeded {
                what: if i == 0 {
                    "image width"
                } else {
                    "image height"
                },
                value: v as u64,
                limit: MAX_IMAGE_SIDE as u64,
            });
        }
    }
    Ok(())
}

/// [`check_model_values`]: the mean pose finite, its scale within
/// `MIN_POSE_SCALE..=MAX_POSE_SCALE` and its translation within `+-MAX_POSE_SHIFT`.
fn check_mean_pose(model: &Model) -> std::result::Result<(), FormatError> {
    let p = &model.mean_pose();
    for (i, v) in [p.a, p.b, p.tx, p.ty].into_iter().enumerate() {
        if !v.is_finite() {
            return Err(FormatError::NonFinite {
                array: "mean pose",
                index: i as u64,
            });
        }
    }
    let s = p.scale();
    if !(MIN_POSE_SCALE..=MAX_POSE_SCALE).contains(&s) {
        return Err(out_of_range(
            "mean pose scale",
            0,
            s,
            format!("{MIN_POSE_SCALE:e}..={MAX_POSE_SCALE:e}"),
        ));
    }
    for (i, v) in [p.tx, p.ty].into_iter().enumerate() {
        if !(v.abs() <= MAX_POSE_SHIFT) {
            return Err(out_of_range(
                "mean pose translation",
                i,
                v,
                format!("+-{MAX_POSE_SHIFT:e}"),
            ));
        }
    }
    Ok(())
}

/// Every value of `array` (`v`) within `lo..=hi`: the first that is not, as
/// [`FormatError::NonFinite`] or [`FormatError::OutOfRange`].
fn check_in_range(
    array: &'static str,
    v: &[f32],
    lo: f32,
    hi: f32,
) -> std::result::Result<(), FormatError> {
    match v.iter().position(|x| !(*x >= lo && *x <= hi)) {
        None => Ok(()),
        Some(i) if !v[i].is_finite() => Err(FormatError::NonFinite {
            array,
            index: i as u64,
        }),
        Some(i) => Err(out_of_range(array, i, v[i], format!("{lo}..={hi}"))),
    }
}

/// [`check_model_values`]: the base shape and frame origin within `+-MAX_SHAPE_COORD`, the
/// base appearance within `MIN_APPEARANCE..=MAX_APPEARANCE`, and the variances no larger than
/// the base's own range allows.
fn check_arrays(model: &Model) -> std::result::Result<(), FormatError> {
    check_in_range(
        "shape base",
        &model.shape().base,
        -MAX_SHAPE_COORD,
        MAX_SHAPE_COORD,
    )?;
    check_in_range(
        "frame origin",
        &model.frame().origin(),
        -MAX_SHAPE_COORD,
        MAX_SHAPE_COORD,
    )?;
    check_in_range(
        "appearance base",
        model.appearance().base(),
        MIN_APPEARANCE,
        MAX_APPEARANCE,
    )?;
    let n2 = model.shape().base.len() as f32;
    let max_shape_var = n2 * (2.0 * MAX_SHAPE_COORD).powi(2);
    check_in_range(
        "shape variances",
        &model.shape().variances,
        0.0,
        max_shape_var,
    )?;
    let span = MAX_APPEARANCE - MIN_APPEARANCE;
    let max_app_var = model.appearance().len() as f32 * span * span;
    check_in_range(
        "appearance variances",
        model.appearance().variances(),
        0.0,
        max_app_var,
    )
}

/// Bytes the fitter's precomputation needs for `model` with `levels` pyramid levels and
/// `channels` colour channels (an upper estimate: per level the shape Jacobians `(m + 4) x N`
/// in x and y, the smoothed appearance modes `(l + 1) x N x channels`, the f64 smoothing grids
/// and the `(m + 4)^2` normal matrices).
pub fn tracking_bytes(model: &Model, levels: usize, channels: usize) -> u64 {
    let n = model.frame().n_pixels() as u64;
    let k = model.shape().n_modes() as u64 + 4;
    let l = model.appearance().n_modes() as u64 + 1;
    let grid = model.frame().width() as u64 * model.frame().height() as u64;
    let c = channels.max(1) as u64;
    let per_level = 8 * k * n + 8 * l * n * c + 8 * grid * (2 + c) + 16 * k * k + 64 * n * c;
    per_level.saturating_mul(levels.max(1) as u64)
}

/// Fails with [`Error::Budget`] when the tracker's precomputation for `model` would exceed the
/// memory budget of the model ([`model_budget`] of [`model_bytes`]); checked before anything
/// is allocated.
pub fn check_tracking_budget(model: &Model, levels: usize, channels: usize) -> Result<()> {
    let need = tracking_bytes(model, levels, channels);
    let budget = model_budget(model_bytes(model));
    if need > budget {
        return Err(Error::Budget(format!(
            "tracking model '{}' ({} shape modes x {} pixels, {} levels) needs about {} MB of \
             precomputation, more than its memory budget of {} MB ({} x the model's {} KB + {} MB)",
            model.name(),
            model.shape().n_modes(),
            model.frame().n_pixels(),
            levels,
            need >> 20,
            budget >> 20,
            MODEL_BYTES_FACTOR,
            model_bytes(model) >> 10,
            FIXED_ALLOWANCE >> 20
        )));
    }
    Ok(())
}

/// Largest canvas (pixels) drawn at a model's declared training-image size when the caller
/// gives none: 2048 x 2048 (a larger canvas must be asked for explicitly, up to the image
/// limit), so that a size a model declares cannot make a render allocate more.
pub const MAX_DEFAULT_CANVAS_PIXELS: u64 = 2048 * 2048;

/// The default canvas for rendering `model` when the caller names no size: the model's
/// training-image size, if at most [`MAX_DEFAULT_CANVAS_PIXELS`]; otherwise an
/// [`Error::Budget`] asking for an explicit size.
pub fn default_canvas(model: &Model) -> Result<(u32, u32)> {
    let [w, h] = model.image_size();
    if w as u64 * h as u64 > MAX_DEFAULT_CANVAS_PIXELS {
        return Err(Error::Budget(format!(
            "the model declares a {w}x{h} image, larger than the default canvas limit of {} \
             pixels; give the canvas size explicitly (width and height, at most {MAX_IMAGE_SIDE} each)",
            MAX_DEFAULT_CANVAS_PIXELS
        )));
    }
    Ok((w, h))
}

/// Reads a whole file through a size cap: refuses what is not a regular file (directories,
/// FIFOs, devices such as `/dev/zero`) and files larger than `cap` bytes, before reading.
#[cfg(not(target_arch = "wasm32"))]
pub fn read_file_capped(path: &std::path::Path, cap: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let shown = path.display();
    let meta = std::fs::metadata(path).map_err(|e| Error::Io(format!("{shown}: {e}")))?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(Error::Io(format!("{shown}: is {kind}")));
    }
    if meta.len() > cap {
        return Err(Error::Io(format!(
            "{shown}: {} bytes, more than the limit of {cap} bytes",
            meta.len()
        )));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::Io(format!("{shown}: {e}")))?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // The cap holds even if the file grows while it is read.
    file.take(cap + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::Io(format!("{shown}: {e}")))?;
    if bytes.len() as u64 > cap {
        return Err(Error::Io(format!(
            "{shown}: more than the limit of {cap} bytes"
        )));
    }
    Ok(bytes)
}

/// [`read_file_capped`] for text files (UTF-8).
#[cfg(not(target_arch = "wasm32"))]
pub fn read_text_capped(path: &std::path::Path, cap: u64) -> Result<String> {
    let bytes = read_file_capped(path, cap)?;
    String::from_utf8(bytes)
        .map_err(|_| Error::Io(format!("{}: not valid UTF-8 text", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamp_is_nan_safe() {
        assert_eq!(clamp_symmetric(f32::NAN, 1.0), 0.0);
        assert_eq!(clamp_symmetric(5.0, f32::NAN), 0.0);
        assert_eq!(clamp_symmetric(5.0, -1.0), 0.0);
        assert_eq!(clamp_symmetric(-5.0, 2.0), -2.0);
        assert_eq!(clamp_symmetric(f32::INFINITY, 2.0), 2.0);
        assert_eq!(clamp_symmetric(0.5, f32::INFINITY), 0.5);
        assert_eq!(clamp_symmetric(f32::NEG_INFINITY, f32::INFINITY), -f32::MAX);
        assert_eq!(clamp_symmetric(1.5, 2.0), 1.5);
    }

    #[test]
    fn param_bounds() {
        assert!(check_param_values("p", &[0.0, -1e6, 1e6]).is_ok());
        assert!(check_param_values("p", &[1e30]).is_err());
        assert!(check_param_values("p", &[f32::NAN]).is_err());
        assert!(check_gain("gain", 1e30).is_err());
        assert!(check_gain("gain", f32::NAN).is_err());
        assert!(check_gain("gain", -3.0).is_ok());
    }
}

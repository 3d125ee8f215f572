//! Landmark files and the landmark error, as the CLI and the native tests have them: the page's
//! enrolment and photo targets read `.pts` files with [`parse_pts`], and the end-to-end tests
//! measure with [`landmark_error`] rather than a JavaScript copy of it.

use crate::JsError;
use wasm_bindgen::prelude::*;

use super::{install_panic_hook, js_err};

/// Parses an iBUG `.pts` file (the crate's parser, as the CLI reads them): its 1-based points as
/// 0-based image coordinates (`2n` values). Throws for a malformed file, a non-finite value or
/// more points than the limit.
#[wasm_bindgen(js_name = parsePts)]
pub fn parse_pts(text: &str) -> Result<js_sys::Float32Array, JsError> {
    install_panic_hook();
    let v = facemimic::landmarks::parse_pts(text).map_err(js_err)?;
    Ok(js_sys::Float32Array::from(&v[..]))
}

/// The landmark error of the project's figures (`facemimic::find::landmark_error`): the mean
/// distance between two 68-point shapes `a` and `truth` (interleaved x, y) over `truth`'s
/// outer-eye-corner distance (points 36 and 45). NaN unless both have 68 points (and not finite
/// when `truth`'s eye corners coincide).
#[wasm_bindgen(js_name = landmarkError)]
pub fn landmark_error(a: &[f32], truth: &[f32]) -> f32 {
    install_panic_hook();
    facemimic::find::landmark_error(a, truth)
}

//! `FaceFinder` for JavaScript: every face in an RGBA frame with its 68 landmarks.

use js_sys::{Array, Float32Array, Object, Reflect};
use wasm_bindgen::prelude::*;

use super::install_panic_hook;
use crate::{FaceFinder, ImageRef};

#[wasm_bindgen(typescript_custom_section)]
const TS_FIND: &'static str = r##"
/** A face found by `FaceFinder.find`. */
export interface FoundFace {
  /** The face's box, image pixels. */
  box: { x: number; y: number; width: number; height: number };
  /** Confidence in 0..1. */
  score: number;
  /** The 68 iBUG landmarks, 0-based image pixels, x0, y0, x1, y1, ... */
  landmarks: Float32Array;
}
"##;

/// Finds faces (face-api.js's tiny detector and 68-point landmark net, embedded weights).
#[wasm_bindgen(js_name = FaceFinder)]
pub struct JsFaceFinder {
    inner: FaceFinder,
}

fn set(o: &Object, k: &str, v: &JsValue) -> Result<(), JsError> {
    Reflect::set(o, &JsValue::from_str(k), v)
        .map(|_| ())
        .map_err(|_| JsError::new("FaceFinder: cannot build the result"))
}

#[wasm_bindgen(js_class = FaceFinder)]
impl JsFaceFinder {
    /// A finder with the shipped weights.
    #[wasm_bindgen(constructor)]
    pub fn new() -> Result<JsFaceFinder, JsError> {
        install_panic_hook();
        FaceFinder::new()
            .map(|inner| JsFaceFinder { inner })
            .map_err(|e| JsError::new(&format!("FaceFinder: {e}")))
    }

    /// Every face in a straight RGBA frame, most confident first.
    #[wasm_bindgen(unchecked_return_type = "FoundFace[]")]
    pub fn find(&mut self, rgba: &[u8], width: u32, height: u32) -> Result<Array, JsError> {
        let img = ImageRef::new(width, height, rgba)
            .map_err(|e| JsError::new(&format!("FaceFinder.find: {e}")))?;
        let out = Array::new();
        for f in self.inner.find(&img) {
            let o = Object::new();
            let b = Object::new();
            set(&b, "x", &f.bbox.x.into())?;
            set(&b, "y", &f.bbox.y.into())?;
            set(&b, "width", &f.bbox.width.into())?;
            set(&b, "height", &f.bbox.height.into())?;
            set(&o, "box", &b)?;
            set(&o, "score", &f.score.into())?;
            set(
                &o,
                "landmarks",
                &Float32Array::from(f.landmarks.as_slice()).into(),
            )?;
            out.push(&o);
        }
        Ok(out)
    }
}

impl std::fmt::Debug for JsFaceFinder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JsFaceFinder")
            .field("inner", &self.inner)
            .finish()
    }
}

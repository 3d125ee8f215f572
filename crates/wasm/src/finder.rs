//! `FaceFinder` for JavaScript: every face in an RGBA frame with its 68 landmarks.

use crate::JsError;
use js_sys::{Array, Float32Array, Object, Reflect};
use wasm_bindgen::prelude::*;

use super::install_panic_hook;
use facemimic::find::BBox;
use facemimic::{EnrolFinder, ImageRef};

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

/// Finds faces (MediaPipe's BlazeFace detector and 468-point face mesh, embedded weights; 68
/// iBUG points in dlib's convention).
/// Holds one finder for `find`, `landmarks` and `enrol` (a page's worker serves both tracking
/// and enrolment with one copy of the nets).
#[wasm_bindgen(js_name = FaceFinder)]
pub struct JsFaceFinder {
    inner: EnrolFinder,
    /// `find` averages each face over the image and its mirror (`FindOptions::mirror`).
    precise: bool,
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
        EnrolFinder::new(facemimic::ENROL_BOXES)
            .map(|inner| JsFaceFinder {
                inner,
                precise: false,
            })
            .map_err(|e| JsError::core("FaceFinder", e))
    }

    /// Whether `find` averages each face over the frame and its mirror image: closer to dlib's
    /// points on every measured set, about twice the time of a find (false by default: the
    /// speed of a frame). `enrol` always averages.
    #[wasm_bindgen(getter)]
    pub fn precise(&self) -> bool {
        self.precise
    }

    /// Sets [`precise`](Self::precise).
    #[wasm_bindgen(setter)]
    pub fn set_precise(&mut self, on: bool) {
        self.precise = on;
    }

    /// Every face in a straight RGBA frame, most confident first.
    #[wasm_bindgen(unchecked_return_type = "FoundFace[]")]
    pub fn find(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] rgba: &[u8],
        width: u32,
        height: u32,
    ) -> Result<Array, JsError> {
        let img =
            ImageRef::new(width, height, rgba).map_err(|e| JsError::core("FaceFinder.find", e))?;
        let out = Array::new();
        // The mirror only for this call: `enrol` averages its own passes.
        let finder = self.inner.finder();
        let mut options = finder.options();
        options.mirror = self.precise;
        finder.set_options(options);
        let faces = finder.find(&img);
        options.mirror = false;
        finder.set_options(options);
        for f in faces {
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

    /// The 68 landmarks of the face inside `box` (`{x, y, width, height}`, image pixels) of a
    /// straight RGBA frame: two passes of the face mesh, no detection and no check that a face
    /// is there.
    #[wasm_bindgen(unchecked_return_type = "Float32Array")]
    pub fn landmarks(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] rgba: &[u8],
        width: u32,
        height: u32,
        #[wasm_bindgen(
            js_name = "box",
            unchecked_param_type = "{ x: number; y: number; width: number; height: number }"
        )]
        bbox: JsValue,
    ) -> Result<Float32Array, JsError> {
        let img = ImageRef::new(width, height, rgba)
            .map_err(|e| JsError::core("FaceFinder.landmarks", e))?;
        let b: BBox = serde_wasm_bindgen::from_value(bbox).map_err(|e| {
            JsError::new(&format!(
                "FaceFinder.landmarks: box must be {{x, y, width, height}} in numbers: {e}"
            ))
        })?;
        let points = self
            .inner
            .finder()
            .landmarks(&img, b)
            .map_err(|e| JsError::core("FaceFinder.landmarks", e))?;
        Ok(Float32Array::from(points.as_slice()))
    }

    /// The face `buildModel` would use in a straight RGBA frame, as the free `enrolFace` returns
    /// it (the most confident face scoring at least `minScore`, default 0, its points averaged
    /// with a pass on the mirrored image; `null` when there is none), with this finder.
    #[wasm_bindgen(unchecked_return_type = "EnrolFace | null")]
    pub fn enrol(
        &mut self,
        #[wasm_bindgen(unchecked_param_type = "Uint8Array | Uint8ClampedArray")] rgba: &[u8],
        width: u32,
        height: u32,
        #[wasm_bindgen(js_name = "minScore")] min_score: Option<f32>,
    ) -> Result<JsValue, JsError> {
        super::build::enrol_with(
            &mut self.inner,
            "FaceFinder.enrol",
            rgba,
            width,
            height,
            min_score,
        )
    }
}

impl std::fmt::Debug for JsFaceFinder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JsFaceFinder")
            .field("inner", &self.inner)
            .finish()
    }
}

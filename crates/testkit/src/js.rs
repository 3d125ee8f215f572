//! What the wasm tests in the browser share: JS errors' messages and parameters as JS values.

use facemimic::Params;
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use web_sys::{OffscreenCanvas, OffscreenCanvasRenderingContext2d};

/// The message of a JS `Error` thrown by the package (empty when it is not an `Error`).
pub fn message(e: impl Into<JsValue>) -> String {
    let v: JsValue = e.into();
    v.dyn_into::<js_sys::Error>()
        .map(|e| String::from(e.message()))
        .unwrap_or_default()
}

/// The `code` of a JS `Error` thrown by the package (empty when it has none).
pub fn code(e: impl Into<JsValue>) -> String {
    let v: JsValue = e.into();
    js_sys::Reflect::get(&v, &JsValue::from_str("code"))
        .ok()
        .and_then(|c| c.as_string())
        .unwrap_or_default()
}

/// Parameters as the package takes them from JS.
pub fn params_js(p: &Params) -> JsValue {
    serde_wasm_bindgen::to_value(p).unwrap()
}

/// A `w`x`h` offscreen canvas and its 2D context.
pub fn offscreen_ctx(w: u32, h: u32) -> (OffscreenCanvas, OffscreenCanvasRenderingContext2d) {
    let canvas = OffscreenCanvas::new(w, h).expect("OffscreenCanvas");
    let ctx = canvas
        .get_context("2d")
        .expect("getContext")
        .expect("a 2d context")
        .dyn_into::<OffscreenCanvasRenderingContext2d>()
        .expect("an OffscreenCanvasRenderingContext2D");
    (canvas, ctx)
}

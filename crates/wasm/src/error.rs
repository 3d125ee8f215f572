//! The package's one error type: a JS `Error` with a stable `code` beside its message.
//!
//! Every entry point returns `Result<_, JsError>` with this crate's [`JsError`] (it shadows
//! wasm-bindgen's, whose errors carry a message only). Thrown into JS it is an `Error` whose
//! `message` names the problem and whose `code` is one of [`CODES`]: the core's
//! [`facemimic::Error::code`] for what the core rejects, `bad-argument` for an argument this
//! layer rejects, `bad-frame` for pixels of the wrong size, `busy` for a re-entrant call,
//! `internal` for a bug. The package's JS entry adds the codes only JS can see
//! (`not-initialised`, `freed`, `fetch-failed`, `detached-buffer`, `frame-unavailable`).

use wasm_bindgen::prelude::JsValue;

/// Every code this layer throws (the JS entry's list in `npm/facemimic.js` adds its own).
pub const CODES: &[&str] = &[
    "bad-argument",
    "bad-frame",
    "busy",
    "internal",
    "bad-landmarks",
    "bad-model",
    "training",
    "mismatched-models",
    "bad-params",
    "io",
    "cancelled",
    "bad-weights",
    "overflow",
    "too-large",
];

/// An error thrown into JS: a message naming the problem and a stable code.
#[derive(Debug, Clone, PartialEq)]
pub struct JsError {
    code: &'static str,
    message: String,
}

impl JsError {
    /// A rejected argument (`code` "bad-argument"); the message names it.
    pub fn new(message: &str) -> JsError {
        JsError::coded("bad-argument", message)
    }

    /// An error with an explicit code (one of [`CODES`]).
    pub fn coded(code: &'static str, message: impl Into<String>) -> JsError {
        debug_assert!(CODES.contains(&code), "unlisted error code {code}");
        JsError {
            code,
            message: message.into(),
        }
    }

    /// An error of the core (or of reading a JS value), its message prefixed with where it
    /// happened, its code kept.
    pub fn core(context: &str, e: impl Into<JsError>) -> JsError {
        let e = e.into();
        JsError::coded(e.code, format!("{context}: {}", e.message))
    }

    /// The code (see [`CODES`]).
    pub fn code(&self) -> &'static str {
        self.code
    }
}

impl From<facemimic::Error> for JsError {
    fn from(e: facemimic::Error) -> JsError {
        JsError::coded(e.code(), e.to_string())
    }
}

impl From<serde_wasm_bindgen::Error> for JsError {
    fn from(e: serde_wasm_bindgen::Error) -> JsError {
        JsError::new(&e.to_string())
    }
}

impl From<JsError> for JsValue {
    fn from(e: JsError) -> JsValue {
        let error = js_sys::Error::new(&e.message);
        // Setting a property on a fresh Error object cannot fail.
        let _ = js_sys::Reflect::set(&error, &"code".into(), &e.code.into());
        error.into()
    }
}

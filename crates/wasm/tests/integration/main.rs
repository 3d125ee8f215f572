#![cfg(target_arch = "wasm32")]
//! The npm package's wasm API, one test binary (in the manner of tiny-skia's
//! `tests/integration`), a module per area, all in headless Chromium (chromedriver on PATH):
//!
//! ```text
//! cargo test -p facemimic-wasm --target wasm32-unknown-unknown                    # all of them
//! cargo test -p facemimic-wasm --target wasm32-unknown-unknown wasm_tracker::     # one area
//! ```
//!
//! `browser*` need the DOM and OffscreenCanvas; the `wasm_*` modules need only JavaScript's
//! built-ins (they ran under Node when each was its own binary) and run in the page too.

use wasm_bindgen_test::wasm_bindgen_test_configure;

wasm_bindgen_test_configure!(run_in_browser);

mod browser;
mod browser_composite;
mod browser_hostile;
mod policy;
mod wasm_enrol;
mod wasm_find;
mod wasm_tracker;

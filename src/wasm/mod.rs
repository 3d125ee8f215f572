//! The wasm-bindgen glue (wasm32 only). Being written: see issue 4.

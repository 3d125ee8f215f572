#![cfg(not(target_arch = "wasm32"))]
//! The `facemimic` command line's tests, one binary (in the manner of tiny-skia's
//! `tests/integration`), a module per area; each runs the built binary as a process. Filter
//! by area with the module path: `cargo test -p facemimic-cli --test integration cli_find::`.

mod cli;
mod cli_find;
mod cli_hostile;

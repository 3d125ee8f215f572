//! Learns the generic expression prior shipped in `data/weights/expression_prior.fmep` from
//! the landmarks committed under `data/` (the London set's 60 neutral -> smiling pairs and
//! GRID's ten speakers, both CC BY 4.0), and writes it; `tests/integration/expression.rs` learns it again
//! and compares the bytes.
//!
//! ```sh
//! cargo run --release --example expression_prior
//! ```

#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(target_arch = "wasm32"))]
fn main() -> facemimic::Result<()> {
    use std::path::Path;
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    let (london, speakers) = facemimic::io::expression_sets(&data, &[])?;
    let frame = facemimic::canonical_frame();
    let prior = facemimic::clone::learn_prior(&london, &speakers, frame.vertices())?;
    let out = data.join("weights/expression_prior.fmep");
    let bytes = prior.to_bytes();
    std::fs::write(&out, &bytes)
        .map_err(|e| facemimic::Error::Io(format!("{}: {e}", out.display())))?;
    println!(
        "{}: {} bytes, {} modes, limit {:.3} ({} London pairs, {} GRID speakers)",
        out.display(),
        bytes.len(),
        prior.n_modes(),
        prior.limit(),
        london.len(),
        speakers.len()
    );
    Ok(())
}

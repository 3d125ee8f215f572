//! Writes `src/canonical_frame.txt`: the reference frame of GRID speaker 7's model built in its
//! own frame from `data/grid/spk07_pwij3p/train20.txt` (the original default source).
//!
//! Run from the repository root: `cargo run --example canonical_frame [OUT]`.
//! Changing the canonical frame makes every model built in the old one incompatible with new
//! ones; the file in the repository is the definition, this is how it was made.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {

    use std::path::Path;

    use facemimic::canonical::write_frame;
    use facemimic::{io, BuildOptions, Builder, FrameChoice};

    pub(crate) fn main() -> facemimic::Result<()> {
        let out = std::env::args()
            .nth(1)
            .unwrap_or_else(|| "src/canonical_frame.txt".into());
        let list = Path::new("data/grid/spk07_pwij3p/train20.txt");
        let images = io::read_list(list)?
            .iter()
            .map(|p| io::read_training_image(p))
            .collect::<facemimic::Result<Vec<_>>>()?;
        let model = Builder::new(BuildOptions {
            name: "spk07".into(),
            frame: FrameChoice::Own,
            ..BuildOptions::default()
        })
        .build(&images, None)?;
        let text = write_frame(
            model.frame(),
            "facemimic canonical reference frame (68 landmarks, iBUG layout), model coordinates.\n\
             The frame of GRID speaker 7's model from data/grid/spk07_pwij3p/train20.txt, base face\n\
             150 px wide; made by `cargo run --example canonical_frame`.\n\
             Lines: fingerprint (hex), grid size W H, origin (grid position of the model origin),\n\
             vertices N then N lines 'x y', triangles T then T lines 'i j k' (0-based vertex indices).",
        );
        std::fs::write(&out, text).map_err(|e| facemimic::Error::Io(e.to_string()))?;
        eprintln!(
            "canonical frame {:016x}: {}x{}, {} pixels -> {out}",
            model.frame().fingerprint(),
            model.frame().width(),
            model.frame().height(),
            model.frame().n_pixels()
        );
        Ok(())
    }
}

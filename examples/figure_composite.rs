//! Draws the README's composited figure, `docs/img/composited.png`: a frame of spk07's unseen
//! clip (`data/grid/spk07_id2_vcd_swwp2s/000024.jpg`), then that expression and head pose
//! cloned (`map-residual`, follow-pose) onto the bundled targets spk02, spk03, spk06 and spk10,
//! each composited into its own picture, then onto a one-photo target (spk05's first training
//! frame, substitution); every tile 180x144 (half the GRID frame).
//!
//! Needs the bundled models: `bash scripts/build-models.sh`, then
//! `cargo run --release --example figure_composite [OUT.png]`.

#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::path::Path;

    use facemimic::clone::{CloneOptions, Cloner, Method};
    use facemimic::tiny_skia::{Color, FilterQuality, Pixmap, PixmapPaint, Transform};
    use facemimic::{io, photo_model, picture_view, Compositor, DrawOptions, Model, Result};

    const TILE: (u32, u32) = (180, 144);

    pub fn main() -> Result<()> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let out = std::env::args()
            .nth(1)
            .unwrap_or_else(|| root.join("docs/img/composited.png").display().to_string());
        let model = |name: &str| io::read_model_file(&root.join(format!("www/models/{name}.fmm")));
        let source = model("spk07")?;
        let frame =
            io::read_training_image(&root.join("data/grid/spk07_id2_vcd_swwp2s/000024.jpg"))?;
        let params = source.project(&frame.image.view()?, &frame.landmarks)?;
        let list = io::read_list(&root.join("data/grid/spk05_lrwp9a/train20.txt"))?;
        let photo = io::read_training_image(&list[0])?;
        let photo = photo_model(
            "spk05-photo",
            &photo.image.view()?,
            &photo.landmarks,
            source.frame(),
        )?;
        let mut targets: Vec<Model> = ["spk02", "spk03", "spk06", "spk10"]
            .iter()
            .map(|n| model(n))
            .collect::<Result<_>>()?;
        targets.push(photo);
        let mut cloner = Cloner::new(source.clone())?;
        for t in &targets {
            cloner.add_target(t.clone())?;
        }
        cloner.clone_frame(
            &params,
            &CloneOptions {
                method: Method::MapResidual,
                follow_pose: true,
                ..CloneOptions::default()
            },
        )?;

        let n = 1 + targets.len() as u32;
        let mut strip = Pixmap::new(TILE.0 * n, TILE.1).expect("strip size");
        strip.fill(Color::from_rgba8(32, 32, 36, 255));
        // The source frame, scaled to the tile.
        let mut src = Pixmap::new(frame.image.width, frame.image.height).expect("frame size");
        for (d, s) in src
            .pixels_mut()
            .iter_mut()
            .zip(frame.image.data.chunks_exact(4))
        {
            *d = facemimic::tiny_skia::ColorU8::from_rgba(s[0], s[1], s[2], 255).premultiply();
        }
        let k = TILE.0 as f32 / frame.image.width as f32;
        let paint = PixmapPaint {
            quality: FilterQuality::Bilinear,
            ..PixmapPaint::default()
        };
        strip.draw_pixmap(
            0,
            0,
            src.as_ref(),
            &paint,
            Transform::from_scale(k, k),
            None,
        );
        for (i, t) in targets.iter().enumerate() {
            let mut tile = Pixmap::new(TILE.0, TILE.1).expect("tile size");
            let mut c = Compositor::new(t, DrawOptions::default())?;
            let (w, h) = c.size();
            c.draw(
                t,
                cloner.target_appearance(i),
                cloner.target_shape(i),
                &picture_view(w, h, TILE.0, TILE.1),
                &mut tile.as_mut(),
            )?;
            strip.draw_pixmap(
                (TILE.0 * (i as u32 + 1)) as i32,
                0,
                tile.as_ref(),
                &PixmapPaint::default(),
                Transform::identity(),
                None,
            );
        }
        io::write_png(
            Path::new(&out),
            strip.width(),
            strip.height(),
            &facemimic::demultiply(&strip),
        )?;
        println!("wrote {out}");
        Ok(())
    }
}

#![cfg(not(target_arch = "wasm32"))]
//! Golden-image test of a render: the spk07 model (built from `data/grid/spk07_pwij3p/
//! train20.txt`) at a fixed instance (shape mode 1 at +1.5 sigma, mode 2 at -1 sigma,
//! appearance mode 1 at +1 sigma), posed at the model's mean training pose and scaled 1.5x
//! about the face centre onto a 200x220 canvas, compared with `tests/golden/spk07_instance.png`.
//!
//! Tolerance: a pixel differs when a channel is off by more than 3 levels (float rounding in
//! PCA or rasterisation on another CPU may move a value by one or two); at most 0.5% of the
//! pixels may differ. Regenerate (after an intended change only) with
//! `FACEMIMIC_BLESS=1 cargo test --release --test golden`, and look at the image.

use std::path::{Path, PathBuf};

use facemimic::tiny_skia::{Color, Pixmap};
use facemimic::{io, BuildOptions, Builder, Renderer, Similarity};

const TOLERANCE: i32 = 3;
const MAX_DIFFERING_SHARE: f64 = 0.005;
const SIZE: (u32, u32) = (200, 220);

fn golden_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/spk07_instance.png")
}

/// The deterministic render (straight RGBA8).
fn render() -> Vec<u8> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let paths = io::read_list(&root.join("data/grid/spk07_pwij3p/train20.txt")).unwrap();
    let images: Vec<_> = paths
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let model = Builder::new(BuildOptions {
        name: "spk07".into(),
        ..BuildOptions::default()
    })
    .build(&images, None)
    .unwrap();
    assert!(model.shape().n_modes() >= 2 && model.appearance().n_modes() >= 1);
    let mut params = model.base_params();
    let (ss, sa) = (model.shape().sigmas(), model.appearance().sigmas());
    params.shape[0] = 1.5 * ss[0];
    params.shape[1] = -ss[1];
    params.appearance[0] = sa[0];
    // View: the face centre (the pose's translation) to the canvas centre, magnified 1.5x.
    let k = 1.5;
    let (cx, cy) = (params.pose.tx, params.pose.ty);
    let view = Similarity {
        a: k,
        b: 0.0,
        tx: SIZE.0 as f32 / 2.0 - k * cx,
        ty: SIZE.1 as f32 / 2.0 - k * cy,
    };
    let mut pixmap = Pixmap::new(SIZE.0, SIZE.1).unwrap();
    pixmap.fill(Color::from_rgba8(32, 32, 36, 255));
    let mut renderer = Renderer::new(model.frame()).unwrap();
    renderer
        .render(&model, &params, &view, &mut pixmap.as_mut())
        .unwrap();
    facemimic::demultiply(&pixmap)
}

#[test]
fn render_matches_golden_image() {
    let got = render();
    let path = golden_path();
    if std::env::var_os("FACEMIMIC_BLESS").is_some_and(|v| v == "1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        io::write_png(&path, SIZE.0, SIZE.1, &got).unwrap();
        println!("wrote {}", path.display());
        return;
    }
    let golden = io::read_image(&path).unwrap_or_else(|e| {
        panic!("{e}: no golden image; create it with FACEMIMIC_BLESS=1 and look at it")
    });
    assert_eq!((golden.width, golden.height), SIZE, "golden image size");
    let (mut differing, mut worst) = (0usize, 0i32);
    let mut background = 0usize;
    for (a, b) in got.chunks_exact(4).zip(golden.data.chunks_exact(4)) {
        let d = a
            .iter()
            .zip(b)
            .map(|(x, y)| (*x as i32 - *y as i32).abs())
            .max()
            .unwrap();
        worst = worst.max(d);
        if d > TOLERANCE {
            differing += 1;
        }
        if a == [32, 32, 36, 255] {
            background += 1;
        }
    }
    let total = (SIZE.0 * SIZE.1) as usize;
    let share = differing as f64 / total as f64;
    println!(
        "golden: {differing} of {total} pixels differ by more than {TOLERANCE} (worst {worst})"
    );
    assert!(
        share <= MAX_DIFFERING_SHARE,
        "{differing} pixels ({:.2}%) differ by more than {TOLERANCE} levels (worst {worst})",
        share * 100.0
    );
    // The face covers a good part of the canvas (a blank or tiny render is not a match by
    // accident of a blank golden image).
    assert!(
        background < total * 3 / 4,
        "the render is mostly background ({background} of {total})"
    );
}

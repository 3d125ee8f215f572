//! Core benchmarks (criterion): building the spk07 model from its 20 training frames, rendering
//! one 360x288 frame, sampling an image into the reference frame, appearance synthesis, and
//! the parts of a render (upload, warp) and of a projection.
//!
//! `cargo bench --bench core -- --warm-up-time 1 --measurement-time 3`. Images are decoded
//! outside the timed loops. Figures: docs/core-figures.md.

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use facemimic::tiny_skia::{Color, Pixmap};
use facemimic::{io, BuildOptions, Builder, Renderer, Similarity};

fn benches(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk07_pwij3p");
    let paths = io::read_list(&root.join("train20.txt")).expect("spk07 train20 list");
    let images: Vec<_> = paths
        .iter()
        .map(|p| io::read_training_image(p).expect("training frame"))
        .collect();
    let builder = Builder::new(BuildOptions {
        name: "spk07".into(),
        ..BuildOptions::default()
    });
    let model = builder.build(&images, None).expect("model builds");
    // An unseen frame of the clip (not in train20).
    let probe = io::read_training_image(&root.join("000030.jpg")).expect("frame 30");
    let view = probe.image.view().unwrap();
    let params = model.project(&view, &probe.landmarks).unwrap();

    c.bench_function("build spk07 (20 images)", |b| {
        b.iter(|| black_box(builder.build(black_box(&images), None).unwrap()))
    });

    let mut renderer = Renderer::new(&model.frame).unwrap();
    let mut pixmap = Pixmap::new(360, 288).unwrap();
    pixmap.fill(Color::from_rgba8(32, 32, 36, 255));
    c.bench_function("render 360x288 (synthesis + upload + warp)", |b| {
        b.iter(|| {
            renderer
                .render(
                    &model,
                    black_box(&params),
                    &Similarity::IDENTITY,
                    &mut pixmap.as_mut(),
                )
                .unwrap();
        })
    });

    let mut appearance = vec![0f32; model.appearance.len()];
    c.bench_function("appearance synthesis (Eq. 2)", |b| {
        b.iter(|| {
            model
                .appearance
                .instance_unchecked(black_box(&params.appearance), &mut appearance)
        })
    });

    c.bench_function("upload appearance to texture", |b| {
        b.iter(|| {
            renderer
                .upload(&model.frame, black_box(&appearance))
                .unwrap()
        })
    });

    let mut shape = vec![0f32; model.landmarks() * 2];
    model.image_shape(&params, &mut shape).unwrap();
    c.bench_function("warp texture onto 360x288 (tiny-skia)", |b| {
        b.iter(|| {
            renderer
                .warp(
                    &model.frame,
                    black_box(&shape),
                    &Similarity::IDENTITY,
                    &mut pixmap.as_mut(),
                )
                .unwrap()
        })
    });

    let mut g = vec![0f32; model.appearance.len()];
    c.bench_function("sample_rgb image -> frame", |b| {
        b.iter(|| {
            facemimic::sample_rgb(&model.frame, &view, black_box(&probe.landmarks), &mut g).unwrap()
        })
    });

    c.bench_function("project (pose, shape, appearance)", |b| {
        b.iter(|| black_box(model.project(&view, black_box(&probe.landmarks)).unwrap()))
    });
}

criterion_group!(core, benches);
criterion_main!(core);

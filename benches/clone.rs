//! Per-frame cost of expression cloning: `Cloner::clone_frame` (mapping +
//! synthesising every target's shape and appearance) for 1 and 8 targets, next to the cost of
//! rendering one target (Renderer upload + warp onto a 360x288 pixmap).
//!
//! Models: GRID spk07 (source, from `data/grid/spk07_pwij3p/train20.txt`) and spk02 / spk10
//! (targets, built in spk07's frame); 8 targets = the two repeated. The source parameters are
//! frame 17 of the unseen spk07 clip.
//!
//! `cargo bench --bench clone -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use facemimic::clone::{CloneOptions, Cloner, Method};
use facemimic::tiny_skia::Pixmap;
use facemimic::{io, Model, Params, Renderer, Similarity};

mod common;

fn build(folder: &str, frame_of: Option<&Model>) -> Model {
    common::build(folder, &common::grid_training(folder), frame_of)
}

fn setup() -> (Model, Vec<Model>, Params) {
    let source = build("spk07_pwij3p", None);
    let targets = vec![
        build("spk02_brbk7n", Some(&source)),
        build("spk10_swiz3n", Some(&source)),
    ];
    let frame =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk07_id2_vcd_swwp2s/000017.jpg");
    let t = io::read_training_image(&frame).expect("clip frame");
    let params = source
        .project(&t.image.view().expect("image"), &t.landmarks)
        .expect("projection");
    (source, targets, params)
}

fn bench(c: &mut Criterion) {
    let (source, targets, params) = setup();
    eprintln!(
        "source spk07: {} shape / {} appearance modes, {} frame pixels; targets {}",
        source.shape().n_modes(),
        source.appearance().n_modes(),
        source.frame().n_pixels(),
        targets
            .iter()
            .map(|t| format!(
                "{} ({} / {} modes)",
                t.name(),
                t.shape().n_modes(),
                t.appearance().n_modes()
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // Two frames in turn: the expressive method keeps a frame's source side (its synthesis and
    // ratio image) for the same frame again, as a video never repeats. The second is the same
    // face, its expression a little weaker.
    let mut other = params.clone();
    other.shape.iter_mut().for_each(|p| *p *= 0.9);
    other.appearance.iter_mut().for_each(|p| *p *= 0.9);
    let frames = [params.clone(), other];
    let mut group = c.benchmark_group("clone_frame");
    for n in [1usize, 8] {
        let mut cloner = Cloner::new(source.clone()).unwrap();
        for k in 0..n {
            cloner
                .add_target(targets[k % targets.len()].clone())
                .unwrap();
        }
        for method in Method::ALL {
            let o = CloneOptions {
                method,
                ..CloneOptions::default()
            };
            let mut i = 0;
            group.bench_function(format!("{method}/{n}_targets"), |b| {
                b.iter(|| {
                    i ^= 1;
                    cloner.clone_frame(black_box(&frames[i]), &o).unwrap()
                })
            });
        }
    }
    group.finish();

    let mut cloner = Cloner::new(source.clone()).unwrap();
    cloner.add_target(targets[0].clone()).unwrap();
    cloner
        .clone_frame(
            &params,
            &CloneOptions {
                method: Method::MapResidual,
                ..CloneOptions::default()
            },
        )
        .unwrap();
    let frame = cloner.target(0).frame().clone();
    let mut renderer = Renderer::new(&frame).unwrap();
    let mut pixmap = Pixmap::new(360, 288).unwrap();
    let mut group = c.benchmark_group("render_one_target");
    group.bench_function("upload", |b| {
        b.iter(|| {
            renderer
                .upload(&frame, black_box(cloner.target_appearance(0)))
                .unwrap()
        })
    });
    // The target's shape warped unmoved into the pixmap with the uploaded appearance.
    let warp = |renderer: &mut Renderer, pixmap: &mut Pixmap| {
        renderer
            .warp(
                &frame,
                black_box(cloner.target_shape(0)),
                &Similarity::IDENTITY,
                &mut pixmap.as_mut(),
            )
            .unwrap()
    };
    group.bench_function("warp_360x288", |b| {
        b.iter(|| warp(&mut renderer, &mut pixmap))
    });
    group.bench_function("upload+warp_360x288", |b| {
        b.iter(|| {
            renderer
                .upload(&frame, cloner.target_appearance(0))
                .unwrap();
            warp(&mut renderer, &mut pixmap)
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

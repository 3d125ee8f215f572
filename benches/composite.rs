//! Per-frame cost of compositing at 640x480 with follow-pose on: one target drawn face only
//! (`FaceDrawer::draw`, the paper's view) next to the same target composited into its backdrop
//! (`Compositor::draw`: the static picture, the head warped by the extended mesh, the
//! colour-matched, feathered face), with each rasteriser; and the whole frame the page draws
//! by default: cloning onto 4 targets plus drawing the source and the 4 composited targets,
//! each into its own 640x480 canvas. The difference of the first two is the compositing cost
//! per face written in the README.
//!
//! Models: GRID spk07 (source, `data/grid/spk07_pwij3p/train20.txt`) and spk02, spk03, spk06,
//! spk10 (the page's default targets, each with its default backdrop: the training frame
//! closest to its mean). The source parameters are frames of the unseen clip
//! `spk07_id2_vcd_swwp2s`, projected from their landmarks, cycled, with follow-pose on (the
//! head moves in every picture).
//!
//! `cargo bench --bench composite -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use facemimic::clone::{CloneOptions, Cloner, Method};
use facemimic::tiny_skia::{Color, Pixmap};
use facemimic::{
    canvas_view, io, picture_view, with_default_backdrop, Compositor, DrawOptions, FaceDrawer,
    Model, Params, Rasterizer,
};

const W: u32 = 640;
const H: u32 = 480;

mod common;

/// A GRID model with its default backdrop (the training frame closest to its mean).
fn build(folder: &str) -> Model {
    let images = common::grid_training(folder);
    let m = common::build(folder, &images, None);
    with_default_backdrop(m, &images, None).expect("a backdrop")
}

fn track(source: &Model) -> Vec<Params> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk07_id2_vcd_swwp2s");
    (0..75)
        .step_by(5)
        .map(|i| {
            let t = io::read_training_image(&dir.join(format!("{i:06}.jpg"))).expect("frame");
            source
                .project(&t.image.view().expect("image"), &t.landmarks)
                .expect("projection")
        })
        .collect()
}

fn canvas() -> Pixmap {
    let mut p = Pixmap::new(W, H).unwrap();
    p.fill(Color::from_rgba8(32, 32, 36, 255));
    p
}

fn bench(c: &mut Criterion) {
    let source = build("spk07_pwij3p");
    let targets: Vec<Model> = [
        "spk02_brbk7n",
        "spk03_lbax4n",
        "spk06_lwbsza",
        "spk10_swiz3n",
    ]
    .iter()
    .map(|f| build(f))
    .collect();
    let frames = track(&source);
    let options = CloneOptions {
        method: Method::Map,
        follow_pose: true,
        ..CloneOptions::default()
    };
    let mut cloner = Cloner::new(source.clone()).unwrap();
    for t in &targets {
        cloner.add_target(t.clone()).unwrap();
    }
    cloner.clone_frame(&frames[3], &options).unwrap();
    bench_one_target(c, &targets[0], &cloner);
    bench_frame(c, &source, &targets, &mut cloner, &frames, &options);
}

/// One target's face drawn alone and composited, with each rasteriser (`cloner` holds the
/// cloned frame; the target is its first).
fn bench_one_target(c: &mut Criterion, t: &Model, cloner: &Cloner) {
    let mut group = c.benchmark_group("one_target_640x480");
    for raster in [Rasterizer::TinySkia, Rasterizer::Scanline] {
        let draw = DrawOptions {
            rasterizer: raster,
            mesh: false,
        };
        let b = t.backdrop().unwrap();
        let view = picture_view(b.width(), b.height(), W, H);
        let mut pixmap = canvas();
        let mut drawer = FaceDrawer::new(t.frame(), draw).unwrap();
        group.bench_function(format!("face_only/{raster:?}"), |bench| {
            bench.iter(|| {
                pixmap.fill(Color::from_rgba8(32, 32, 36, 255));
                drawer
                    .draw(
                        t.frame(),
                        cloner.target_appearance(0),
                        black_box(cloner.target_shape(0)),
                        &view,
                        &mut pixmap.as_mut(),
                    )
                    .unwrap()
            })
        });
        let mut compositor = Compositor::new(t, draw).unwrap();
        group.bench_function(format!("composite/{raster:?}"), |bench| {
            bench.iter(|| {
                compositor
                    .draw(
                        t,
                        cloner.target_appearance(0),
                        black_box(cloner.target_shape(0)),
                        &view,
                        &mut pixmap.as_mut(),
                    )
                    .unwrap()
            })
        });
    }
    group.finish();
}

/// The page's default frame with each rasteriser: clone `frames` in turn onto the 4 targets,
/// draw the source face and the 4 targets composited, every picture 640x480.
fn bench_frame(
    c: &mut Criterion,
    source: &Model,
    targets: &[Model],
    cloner: &mut Cloner,
    frames: &[Params],
    options: &CloneOptions,
) {
    let mut group = c.benchmark_group("frame_source_and_4_composited_640x480");
    for raster in [Rasterizer::TinySkia, Rasterizer::Scanline] {
        let draw = DrawOptions {
            rasterizer: raster,
            mesh: false,
        };
        let mut source_drawer = FaceDrawer::new(source.frame(), draw).unwrap();
        let source_view = canvas_view(source, W, H);
        let mut compositors: Vec<Compositor> = targets
            .iter()
            .map(|t| Compositor::new(t, draw).unwrap())
            .collect();
        let views: Vec<_> = targets
            .iter()
            .map(|t| {
                let b = t.backdrop().unwrap();
                picture_view(b.width(), b.height(), W, H)
            })
            .collect();
        let mut pixmaps: Vec<Pixmap> = (0..5).map(|_| canvas()).collect();
        let mut k = 0usize;
        group.bench_function(format!("{raster:?}"), |bench| {
            bench.iter(|| {
                let p = &frames[k % frames.len()];
                k += 1;
                cloner.clone_frame(black_box(p), options).unwrap();
                let (first, rest) = pixmaps.split_first_mut().unwrap();
                first.fill(Color::from_rgba8(32, 32, 36, 255));
                source_drawer
                    .render(source, p, &source_view, &mut first.as_mut())
                    .unwrap();
                for (i, pix) in rest.iter_mut().enumerate() {
                    compositors[i]
                        .draw(
                            &targets[i],
                            cloner.target_appearance(i),
                            cloner.target_shape(i),
                            &views[i],
                            &mut pix.as_mut(),
                        )
                        .unwrap();
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

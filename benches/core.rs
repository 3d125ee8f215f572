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
use facemimic::{
    io, BuildOptions, Builder, DrawOptions, FaceDrawer, ImageRef, Model, Params, Similarity,
};

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

    let mut renderer = FaceDrawer::new(model.frame(), DrawOptions::default()).unwrap();
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

    let appearance = bench_synthesis(c, &model, &params);
    bench_upload_warp(c, &mut renderer, &mut pixmap, &model, &params, &appearance);
    bench_sampling(c, &model, &view, &probe.landmarks);
}

/// Appearance synthesis (Eq. 2) from the expanded f32 modes and straight from the compact
/// storages; returns the i6 synthesis (checked against the f32 one).
fn bench_synthesis(c: &mut Criterion, model: &Model, params: &Params) -> Vec<f32> {
    let mut appearance = vec![0f32; model.appearance().len()];
    c.bench_function("appearance synthesis (Eq. 2)", |b| {
        b.iter(|| {
            model
                .appearance()
                .instance_unchecked(black_box(&params.appearance), &mut appearance)
        })
    });

    // Synthesis straight from the compact storages (what a per-frame reader of the packed file
    // would do), against the f32 expansion the library does once on load (above).
    let d = model.appearance().len();
    let (base, modes, _) = model.appearance().clone().into_arrays();
    let compact = Compact::new(&base, &modes, d);
    c.bench_function("appearance synthesis from i8 storage (no expansion)", |b| {
        b.iter(|| compact.synthesise_i8(black_box(&params.appearance), &mut appearance))
    });
    c.bench_function("appearance synthesis from i6 storage (no expansion)", |b| {
        b.iter(|| compact.synthesise_i6(black_box(&params.appearance), &mut appearance))
    });
    let mut expanded = vec![0f32; model.appearance().len()];
    model
        .appearance()
        .instance_unchecked(&params.appearance, &mut expanded);
    compact.synthesise_i6(&params.appearance, &mut appearance);
    let worst = expanded
        .iter()
        .zip(&appearance)
        .fold(0f32, |a, (x, y)| a.max((x - y).abs()));
    assert!(worst < 0.05, "i6 synthesis off by {worst}");

    appearance
}

/// The parts of a render: the upload of `appearance` and the warp at `params`' shape.
fn bench_upload_warp(
    c: &mut Criterion,
    renderer: &mut FaceDrawer,
    pixmap: &mut Pixmap,
    model: &Model,
    params: &Params,
    appearance: &[f32],
) {
    c.bench_function("upload appearance to texture", |b| {
        b.iter(|| {
            renderer
                .upload(model.frame(), black_box(appearance))
                .unwrap()
        })
    });

    let mut shape = vec![0f32; model.landmarks() * 2];
    model.image_shape(params, &mut shape).unwrap();
    c.bench_function("warp texture onto 360x288 (tiny-skia)", |b| {
        b.iter(|| {
            renderer
                .warp(
                    model.frame(),
                    black_box(&shape),
                    &Similarity::IDENTITY,
                    &mut pixmap.as_mut(),
                )
                .unwrap()
        })
    });
}

/// Sampling the probe image into the reference frame at its `landmarks`, and the projection
/// (pose, shape, appearance) from them.
fn bench_sampling(c: &mut Criterion, model: &Model, view: &ImageRef<'_>, landmarks: &[f32]) {
    let mut g = vec![0f32; model.appearance().len()];
    c.bench_function("sample_rgb image -> frame", |b| {
        b.iter(|| {
            facemimic::numerics::sample_rgb(model.frame(), view, black_box(landmarks), &mut g)
                .unwrap()
        })
    });

    c.bench_function("project (pose, shape, appearance)", |b| {
        b.iter(|| black_box(model.project(view, black_box(landmarks)).unwrap()))
    });
}

/// The appearance in the file's compact forms: base as u8 levels, modes as i8 values with a
/// per-mode scale, and the same values packed in 6 bits (as `docs/model-format.md` specifies).
struct Compact {
    base: Vec<u8>,
    scales: Vec<f32>,
    scales6: Vec<f32>,
    q8: Vec<i8>,
    q6: Vec<u8>,
    d: usize,
}

impl Compact {
    fn new(base: &[f32], modes: &[f32], d: usize) -> Compact {
        let (mut scales, mut scales6) = (Vec::new(), Vec::new());
        let (mut q8, mut q6bits) = (Vec::new(), Vec::new());
        for mode in modes.chunks_exact(d) {
            let peak = mode.iter().fold(0f32, |a, &v| a.max(v.abs()));
            let s = peak / 127.0;
            q8.extend(mode.iter().map(|&v| (v / s).round() as i8));
            scales.push(s);
            scales6.push(peak / 31.0);
            q6bits.extend(mode.iter().map(|&v| (v / (peak / 31.0)).round() as i8));
        }
        let mut q6 = Vec::new();
        let (mut acc, mut n) = (0u32, 0u32);
        for &k in &q6bits {
            acc |= (k as i32 as u32 & 63) << n;
            n += 6;
            while n >= 8 {
                q6.push(acc as u8);
                acc >>= 8;
                n -= 8;
            }
        }
        q6.extend([acc as u8, 0, 0, 0, 0, 0, 0, 0, 0]);
        Compact {
            base: base.iter().map(|&v| (v * 255.0).round() as u8).collect(),
            scales,
            scales6,
            q8,
            q6,
            d,
        }
    }

    /// `A0 + sum_i w_i s_i q_i`, blocked like `facemimic::numerics::synthesise`.
    fn synthesise_i8(&self, w: &[f32], out: &mut [f32]) {
        const BLOCK: usize = 2048;
        let d = self.d;
        let mut start = 0;
        while start < d {
            let end = (start + BLOCK).min(d);
            let o = &mut out[start..end];
            for (a, &b) in o.iter_mut().zip(&self.base[start..end]) {
                *a = b as f32 * (1.0 / 255.0);
            }
            for (i, (&wi, &s)) in w.iter().zip(&self.scales).enumerate() {
                let ws = wi * s;
                for (a, &q) in o.iter_mut().zip(&self.q8[i * d + start..i * d + end]) {
                    *a += ws * q as f32;
                }
            }
            start = end;
        }
    }

    /// The same from the 6-bit stream (value `j` at stream bit `6 j`).
    fn synthesise_i6(&self, w: &[f32], out: &mut [f32]) {
        let d = self.d;
        for (a, &b) in out.iter_mut().zip(&self.base) {
            *a = b as f32 * (1.0 / 255.0);
        }
        for (i, (&wi, &s)) in w.iter().zip(&self.scales6).enumerate() {
            let ws = wi * s;
            for (k, a) in out.iter_mut().enumerate() {
                let bit = (i * d + k) * 6;
                let byte = bit / 8;
                let word = u16::from_le_bytes([self.q6[byte], self.q6[byte + 1]]) as u32;
                let q = (((word >> (bit % 8)) << 26) as i32) >> 26;
                *a += ws * q as f32;
            }
        }
    }
}

criterion_group!(core, benches);
criterion_main!(core);

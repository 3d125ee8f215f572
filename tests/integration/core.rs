//! Numeric tests of the AAM core on synthetic data: Procrustes invariance, PCA properties,
//! projection / reconstruction, the piecewise-affine warp (sample then render) and crack-free
//! rendering.
//!
//! Every test body runs natively (`cargo test --test integration core::`) and in wasm under Node
//! (`cargo test --target wasm32-unknown-unknown --test integration core::`): the data are generated in the
//! test (a deterministic RNG, a 68-point template compiled in with `include_str!`), no files
//! are read at run time.

use facemimic_testkit as common;

use common::pixels::in_triangle;
use common::Rng;
use facemimic::numerics::pca;
use facemimic::tiny_skia::Pixmap;
use facemimic::{
    BuildOptions, Builder, Image, Model, ReferenceFrame, Renderer, Similarity, TrainingImage,
};
use wasm_bindgen_test::wasm_bindgen_test;

/// A real 68-point iBUG annotation (GRID spk07, frame 0), used as the face template.
const TEMPLATE_PTS: &str = include_str!("../../data/grid/spk07_pwij3p/000000.pts");

/// The template, centred on its centroid (0-based pixel units, ~70 px wide).
fn template() -> Vec<f64> {
    let t = facemimic::landmarks::parse_pts(TEMPLATE_PTS).expect("template parses");
    let n = t.len() / 2;
    let cx = t.iter().step_by(2).map(|&v| v as f64).sum::<f64>() / n as f64;
    let cy = t.iter().skip(1).step_by(2).map(|&v| v as f64).sum::<f64>() / n as f64;
    t.chunks_exact(2)
        .flat_map(|p| [p[0] as f64 - cx, p[1] as f64 - cy])
        .collect()
}

/// `count` synthetic expressions of the template (no pose): three articulated modes (jaw and
/// mouth opening, brow raise, smile) with random weights, plus independent per-point jitter so
/// that the training set has full rank.
fn expressions(rng: &mut Rng, count: usize) -> Vec<Vec<f64>> {
    let t = template();
    (0..count)
        .map(|_| {
            let (open, brow, smile) = (rng.normal() * 3.0, rng.normal() * 1.5, rng.normal() * 1.5);
            let mut s = t.clone();
            for i in 0..68 {
                let (dx, dy) = match i {
                    5..=11 | 56..=59 | 65..=67 => (0.0, open),
                    48 | 54 | 60 | 64 => (
                        if i == 48 || i == 60 { -smile } else { smile },
                        -0.5 * smile + 0.3 * open,
                    ),
                    17..=26 => (0.0, -brow),
                    _ => (0.0, 0.0),
                };
                s[2 * i] += dx + 0.3 * rng.normal();
                s[2 * i + 1] += dy + 0.3 * rng.normal();
            }
            s
        })
        .collect()
}

/// Applies a similarity (scale, rotation, translation) to an interleaved shape.
fn pose(s: &[f64], scale: f64, rot: f64, tx: f64, ty: f64) -> Vec<f32> {
    let (c, n) = (scale * rot.cos(), scale * rot.sin());
    s.chunks_exact(2)
        .flat_map(|p| {
            [
                (c * p[0] - n * p[1] + tx) as f32,
                (n * p[0] + c * p[1] + ty) as f32,
            ]
        })
        .collect()
}

/// A smooth RGB test image (sums of low-frequency sinusoids, full 0..255 range used).
fn smooth_image(width: u32, height: u32) -> Image {
    let mut data = Vec::with_capacity((width * height * 4) as usize);
    for y in 0..height {
        for x in 0..width {
            let (fx, fy) = (x as f32, y as f32);
            let r = 128.0 + 90.0 * (fx / 13.0).sin() * (fy / 17.0).cos();
            let g = 128.0 + 90.0 * ((fx + fy) / 19.0).sin();
            let b = 128.0 + 60.0 * (fy / 11.0).sin() + 30.0 * (fx / 23.0).cos();
            data.extend_from_slice(&[r.round() as u8, g.round() as u8, b.round() as u8, 255]);
        }
    }
    Image {
        width,
        height,
        data,
    }
}

fn training_set(shapes: &[Vec<f32>], image: &Image) -> Vec<TrainingImage> {
    shapes
        .iter()
        .enumerate()
        .map(|(i, s)| TrainingImage {
            name: format!("s{i:02}"),
            image: image.clone(),
            landmarks: s.clone(),
        })
        .collect()
}

fn build(images: &[TrainingImage], shape_variance: f64, appearance_variance: f64) -> Model {
    Builder::new(BuildOptions {
        name: "synthetic".into(),
        shape_variance,
        appearance_variance,
        face_width: 60.0,
        // These tests check the builder's own Procrustes gauge and scale.
        frame: facemimic::FrameChoice::Own,
        // ...and its variance fractions, so no cap on the number of modes.
        max_shape_modes: 64,
        // ...of the training shapes' own variance (no mirrored deviations).
        symmetric_shapes: false,
        ..BuildOptions::default()
    })
    .build(images, None)
    .expect("synthetic model builds")
}

fn dot(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| *x as f64 * *y as f64).sum()
}

fn norm(a: &[f32]) -> f64 {
    dot(a, a).sqrt()
}

/// Procrustes: posing each training shape at its own random similarity (scale 0.5-2,
/// rotation +-60 degrees, translation +-100 px) must not change the model: same base shape,
/// same variances, and the same modes up to sign.
#[wasm_bindgen_test(unsupported = test)]
fn procrustes_removes_pose() {
    let mut rng = Rng(0x5eed_0001);
    let shapes = expressions(&mut rng, 20);
    let image = smooth_image(64, 64);
    let plain: Vec<Vec<f32>> = shapes
        .iter()
        .map(|s| pose(s, 1.0, 0.0, 180.0, 140.0))
        .collect();
    let posed: Vec<Vec<f32>> = shapes
        .iter()
        .map(|s| {
            let (k, r) = (rng.uniform(0.5, 2.0), rng.uniform(-1.05, 1.05));
            pose(
                s,
                k,
                r,
                rng.uniform(-100.0, 100.0),
                rng.uniform(-100.0, 100.0),
            )
        })
        .collect();
    let a = build(&training_set(&plain, &image), 0.98, 0.98);
    let b = build(&training_set(&posed, &image), 0.98, 0.98);
    let (sa, sb) = (&a.shape(), &b.shape());
    assert!(
        sa.n_modes() >= 3,
        "the three articulated modes are found ({})",
        sa.n_modes()
    );
    assert_eq!(sa.n_modes(), sb.n_modes(), "same number of shape modes");
    let base_err = sa
        .base
        .iter()
        .zip(&sb.base)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    assert!(
        base_err < 1e-3,
        "base shapes differ by {base_err} model units (face 60 wide)"
    );
    for i in 0..sa.n_modes() {
        let c = dot(sa.mode(i).unwrap(), sb.mode(i).unwrap()).abs();
        assert!((c - 1.0).abs() < 1e-3, "mode {i}: |<m, m'>| = {c}");
        let (va, vb) = (sa.variances[i], sb.variances[i]);
        assert!(
            (va - vb).abs() <= 1e-3 * va,
            "mode {i}: variance {va} vs {vb}"
        );
    }
    // The base is centred and in canonical orientation: outer eye corners level.
    let cx: f32 = sa.base.iter().step_by(2).sum::<f32>() / 68.0;
    let cy: f32 = sa.base.iter().skip(1).step_by(2).sum::<f32>() / 68.0;
    assert!(
        cx.abs() < 1e-3 && cy.abs() < 1e-3,
        "base centroid ({cx}, {cy})"
    );
    assert!(
        (sa.base[73] - sa.base[91]).abs() < 1e-3,
        "eye corners level"
    );
    assert!(sa.base[72] < sa.base[90], "left eye corner on the left");
    let xs = sa.base.iter().step_by(2);
    let width = xs.clone().fold(f32::MIN, |m, &v| m.max(v)) - xs.fold(f32::MAX, |m, &v| m.min(v));
    // The base is the mean of the aligned shapes, a little narrower than their unit-norm
    // Procrustes mean that the builder scales to the face width.
    assert!(
        (width - 60.0).abs() < 0.6,
        "base face width {width}, asked for 60"
    );
}

/// Checks the properties of one PCA result against an independent computation from the
/// samples: orthonormal modes, descending variances equal to the variance of the samples'
/// projections, and the variance fraction honoured exactly (the kept modes reach it, one fewer
/// would not).
fn check_pca(samples: &[Vec<f64>], centre: &[f64], fraction: f64) {
    let dim = centre.len();
    let r = pca(samples, centre, fraction, usize::MAX).unwrap();
    let k = r.variances.len();
    assert!(k >= 1 && r.modes.len() == k * dim);
    let denom = (samples.len() - 1) as f64;
    let total: f64 = samples
        .iter()
        .map(|s| {
            s.iter()
                .zip(centre)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
        })
        .sum::<f64>()
        / denom;
    assert!(
        (r.total_variance - total).abs() < 1e-9 * total,
        "total {} vs {total}",
        r.total_variance
    );
    let mode = |i: usize| &r.modes[i * dim..(i + 1) * dim];
    for i in 0..k {
        for j in 0..=i {
            let d = dot(mode(i), mode(j));
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((d - want).abs() < 1e-5, "<m{i}, m{j}> = {d}");
        }
        if i > 0 {
            assert!(
                r.variances[i] <= r.variances[i - 1],
                "variances not descending at {i}"
            );
        }
        // The variance of the samples along the mode is the stored variance.
        let var: f64 = samples
            .iter()
            .map(|s| {
                s.iter()
                    .zip(centre)
                    .zip(mode(i))
                    .map(|((a, b), m)| (a - b) * *m as f64)
                    .sum::<f64>()
                    .powi(2)
            })
            .sum::<f64>()
            / denom;
        let v = r.variances[i] as f64;
        assert!(
            (var - v).abs() < 1e-4 * total,
            "mode {i}: stored variance {v}, projected {var}"
        );
    }
    let kept: f64 = r.variances.iter().map(|&v| v as f64).sum();
    assert!(
        kept >= fraction * total * (1.0 - 1e-6),
        "kept {kept} of {total} < {fraction}"
    );
    if k > 1 {
        let fewer = kept - *r.variances.last().unwrap() as f64;
        assert!(
            fewer < fraction * total,
            "{} modes already reach {fraction}",
            k - 1
        );
    }
}

/// PCA through both of its paths (covariance: more samples than dimensions; Gram/snapshot:
/// fewer), about the mean and about one sample (the reference-face extension), at several
/// variance fractions.
#[wasm_bindgen_test(unsupported = test)]
fn pca_properties() {
    let mut rng = Rng(0x5eed_0002);
    // Anisotropic data: dimension j has standard deviation 1 / (1 + j / 3).
    let gen = |rng: &mut Rng, n: usize, dim: usize| -> Vec<Vec<f64>> {
        (0..n)
            .map(|_| {
                (0..dim)
                    .map(|j| rng.normal() / (1.0 + j as f64 / 3.0) + 0.1 * j as f64)
                    .collect()
            })
            .collect()
    };
    for (n, dim) in [(60, 12), (12, 300)] {
        let samples = gen(&mut rng, n, dim);
        let mean: Vec<f64> = (0..dim)
            .map(|j| samples.iter().map(|s| s[j]).sum::<f64>() / n as f64)
            .collect();
        for f in [0.5, 0.9, 0.98] {
            check_pca(&samples, &mean, f);
            check_pca(&samples, &samples[3], f);
        }
    }
}

/// The built models honour the variance fractions (shape and appearance), and with fraction
/// 1.0 a training shape projected and reconstructed returns itself (relative error < 1e-4),
/// as does a training appearance (relative error < 1e-3, f32 storage over ~10k values).
#[wasm_bindgen_test(unsupported = test)]
fn projection_reconstructs_training_faces() {
    let mut rng = Rng(0x5eed_0003);
    let shapes = expressions(&mut rng, 16);
    let image = smooth_image(160, 160);
    let posed: Vec<Vec<f32>> = shapes
        .iter()
        .map(|s| pose(s, rng.uniform(0.9, 1.1), rng.uniform(-0.1, 0.1), 80.0, 80.0))
        .collect();
    let images = training_set(&posed, &image);
    let full = build(&images, 1.0, 1.0);
    assert_eq!(
        full.shape().n_modes(),
        15,
        "16 shapes of 136 values span 15 dimensions"
    );
    let mut buf = vec![0f32; 136];
    for t in &images {
        check_reconstruction(&full, &image, t, &mut buf);
    }
    // The fractions of the built models, checked against totals computed here.
    for f in [0.6, 0.9, 0.98] {
        check_variance_fraction(&images, &image, f);
    }
}

/// [`projection_reconstructs_training_faces`]: training face `t` (on `image`) projected onto
/// the full model and reconstructed returns its shape (relative error < 1e-4) and its
/// appearance (< 1e-3). `buf` is shape scratch.
fn check_reconstruction(full: &Model, image: &Image, t: &TrainingImage, buf: &mut [f32]) {
    let params = full.project(&image.view().unwrap(), &t.landmarks).unwrap();
    full.image_shape(&params, buf).unwrap();
    let err: Vec<f32> = buf.iter().zip(&t.landmarks).map(|(a, b)| a - b).collect();
    let (cx, cy) = centroid(&t.landmarks);
    let spread: Vec<f32> = t
        .landmarks
        .chunks_exact(2)
        .flat_map(|p| [p[0] - cx, p[1] - cy])
        .collect();
    let rel = norm(&err) / norm(&spread);
    assert!(
        rel < 1e-4,
        "{}: shape reconstruction relative error {rel}",
        t.name
    );

    let mut g = vec![0f32; full.appearance().len()];
    facemimic::numerics::sample_rgb(full.frame(), &image.view().unwrap(), &t.landmarks, &mut g)
        .unwrap();
    let mut rec = vec![0f32; g.len()];
    full.appearance()
        .instance(&params.appearance, &mut rec)
        .unwrap();
    let e: Vec<f32> = rec.iter().zip(&g).map(|(a, b)| a - b).collect();
    let d: Vec<f32> = g
        .iter()
        .zip(full.appearance().base())
        .map(|(a, b)| a - b)
        .collect();
    let rel = norm(&e) / norm(&d);
    assert!(
        rel < 1e-3,
        "{}: appearance reconstruction relative error {rel}",
        t.name
    );
}

/// [`projection_reconstructs_training_faces`]: the model built to fraction `f` keeps at least
/// `f` of the training set's shape and appearance variance (computed here), with one mode
/// fewer not reaching it.
fn check_variance_fraction(images: &[TrainingImage], image: &Image, f: f64) {
    let m = build(images, f, f);
    let mut shape_total = 0.0;
    let mut app_total = 0.0;
    let mut g = vec![0f32; m.appearance().len()];
    for t in images {
        // The training shape in model coordinates, as the builder aligned it (least
        // squares onto the base, which is the scaled Procrustes mean).
        let to_model = Similarity::align(&t.landmarks, &m.shape().base);
        let mut s = t.landmarks.clone();
        to_model.apply_in_place(&mut s);
        shape_total += s
            .iter()
            .zip(&m.shape().base)
            .map(|(a, b)| ((a - b) as f64).powi(2))
            .sum::<f64>();
        facemimic::numerics::sample_rgb(m.frame(), &image.view().unwrap(), &t.landmarks, &mut g)
            .unwrap();
        app_total += g
            .iter()
            .zip(m.appearance().base())
            .map(|(a, b)| ((a - b) as f64).powi(2))
            .sum::<f64>();
    }
    let denom = (images.len() - 1) as f64;
    for (what, vars, total) in [
        ("shape", &m.shape().variances[..], shape_total / denom),
        ("appearance", m.appearance().variances(), app_total / denom),
    ] {
        let kept: f64 = vars.iter().map(|&v| v as f64).sum();
        let fewer = kept - *vars.last().unwrap() as f64;
        assert!(
            kept >= f * total * (1.0 - 1e-4),
            "{what} {f}: kept {kept} of {total}"
        );
        assert!(
            fewer < f * total,
            "{what} {f}: {} modes already reach it",
            vars.len() - 1
        );
    }
}

fn centroid(s: &[f32]) -> (f32, f32) {
    let n = (s.len() / 2) as f32;
    (
        s.iter().step_by(2).sum::<f32>() / n,
        s.iter().skip(1).step_by(2).sum::<f32>() / n,
    )
}

/// Per pixel of a `width x height` canvas: 2 = centre inside the mesh placed at `shape`
/// (image coordinates, pixel centres on integers), 0 = outside, 1 = within 0.05 px of the
/// mesh's outer boundary (not checked: the rasteriser snaps vertices to 1/64 px).
fn mesh_mask(frame: &ReferenceFrame, shape: &[f32], width: u32, height: u32) -> Vec<u8> {
    let mut mask = vec![0u8; (width * height) as usize];
    let p = |i: u32| (shape[2 * i as usize], shape[2 * i as usize + 1]);
    let mut edges: Vec<(u32, u32)> = Vec::new();
    for t in frame.triangles() {
        for (i, j) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            edges.push((i.min(j), i.max(j)));
        }
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        let x0 = a.0.min(b.0).min(c.0).floor().max(0.0) as u32;
        let x1 = (a.0.max(b.0).max(c.0).ceil().max(0.0) as u32).min(width - 1);
        let y0 = a.1.min(b.1).min(c.1).floor().max(0.0) as u32;
        let y1 = (a.1.max(b.1).max(c.1).ceil().max(0.0) as u32).min(height - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                if in_triangle((x as f32, y as f32), a, b, c, 0.0) {
                    mask[(y * width + x) as usize] = 2;
                }
            }
        }
    }
    // Edges used by one triangle only form the outer boundary.
    edges.sort_unstable();
    let boundary: Vec<(u32, u32)> = edges
        .iter()
        .enumerate()
        .filter(|&(k, e)| (k == 0 || edges[k - 1] != *e) && edges.get(k + 1) != Some(e))
        .map(|(_, e)| *e)
        .collect();
    for (i, j) in boundary {
        let (a, b) = (p(i), p(j));
        let x0 = (a.0.min(b.0) - 1.0).floor().max(0.0) as u32;
        let x1 = ((a.0.max(b.0) + 1.0).ceil().max(0.0) as u32).min(width - 1);
        let y0 = (a.1.min(b.1) - 1.0).floor().max(0.0) as u32;
        let y1 = ((a.1.max(b.1) + 1.0).ceil().max(0.0) as u32).min(height - 1);
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dy * dy;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (qx, qy) = (x as f32 - a.0, y as f32 - a.1);
                let t = ((qx * dx + qy * dy) / len2).clamp(0.0, 1.0);
                let d = ((qx - t * dx).powi(2) + (qy - t * dy).powi(2)).sqrt();
                if d < 0.05 {
                    mask[(y * width + x) as usize] = 1;
                }
            }
        }
    }
    mask
}

/// Rendering a constant appearance through a rotated, magnified pose paints every pixel whose
/// centre is inside the warped mesh, with exactly the constant colour (no cracks, no seams, no
/// blending with the transparent background), and nothing clearly outside it.
#[wasm_bindgen_test(unsupported = test)]
fn constant_appearance_leaves_no_holes() {
    let t = template();
    let scale = 150.0 / 70.0;
    let base: Vec<f32> = t.iter().map(|&v| (v * scale) as f32).collect();
    let frame = ReferenceFrame::from_base(&base).unwrap();
    let colour = [51u8, 153, 204];
    let appearance: Vec<f32> = (0..frame.n_pixels())
        .flat_map(|_| colour.map(|c| c as f32 / 255.0))
        .collect();
    let mut renderer = Renderer::new(&frame).unwrap();
    renderer.upload(&frame, &appearance).unwrap();
    let (w, h) = (420u32, 400u32);
    let mut checked = 0usize;
    for (k, rot, tx, ty) in [
        (1.37f32, 0.37f32, 211.3f32, 196.7f32),
        (0.61, -0.23, 100.2, 90.9),
        (2.03, 3.0, 209.9, 201.4),
    ] {
        let mut shape = base.clone();
        Similarity::from_parts(k, rot, tx, ty).apply_in_place(&mut shape);
        let mut pixmap = Pixmap::new(w, h).unwrap();
        renderer
            .warp(&frame, &shape, &Similarity::IDENTITY, &mut pixmap.as_mut())
            .unwrap();
        let mask = mesh_mask(&frame, &shape, w, h);
        for (i, (px, m)) in pixmap.pixels().iter().zip(&mask).enumerate() {
            let (x, y) = (i as u32 % w, i as u32 / w);
            let got = [px.red(), px.green(), px.blue(), px.alpha()];
            match m {
                2 => {
                    checked += 1;
                    assert_eq!(
                        got,
                        [colour[0], colour[1], colour[2], 255],
                        "pose {k}/{rot}: pixel ({x}, {y}) inside the mesh"
                    );
                }
                0 => assert_eq!(
                    got[3], 0,
                    "pose {k}/{rot}: pixel ({x}, {y}) outside the mesh was painted"
                ),
                _ => {}
            }
        }
    }
    assert!(checked > 20_000, "only {checked} inside pixels checked");
}

/// Renders `g` (an appearance on `frame`) at `shape` and compares the pixels whose centres are
/// inside the mesh with `image`: (mean abs error, max abs error, pixels compared), 0..255.
fn render_error(
    frame: &ReferenceFrame,
    g: &[f32],
    shape: &[f32],
    view: &Similarity,
    image: &Image,
) -> (f64, f64, usize) {
    let (w, h) = (image.width, image.height);
    let mut renderer = Renderer::new(frame).unwrap();
    renderer.upload(frame, g).unwrap();
    let mut pixmap = Pixmap::new(w, h).unwrap();
    renderer
        .warp(frame, shape, view, &mut pixmap.as_mut())
        .unwrap();
    let mask = mesh_mask(frame, shape, w, h);
    let (mut sum, mut max, mut count) = (0f64, 0f64, 0usize);
    for (i, px) in pixmap.pixels().iter().enumerate() {
        if mask[i] != 2 {
            continue;
        }
        let src = &image.data[i * 4..i * 4 + 3];
        let got = if px.alpha() == 255 {
            [px.red(), px.green(), px.blue()]
        } else {
            [0, 0, 0]
        };
        for (a, b) in got.iter().zip(src) {
            let e = (*a as f64 - *b as f64).abs();
            sum += e;
            max = max.max(e);
        }
        count += 1;
    }
    (sum / (3 * count.max(1)) as f64, max, count)
}

/// Sampling a smooth image at its landmarks into the frame and rendering the result back at
/// the same landmarks reproduces the face region. Two bilinear resamplings of this image
/// (sinusoids of periods >= 69 px) at a frame-to-image scale of ~1 leave a mean absolute
/// error of 0.05-0.06 levels and a max of 5-7 (measured); the bounds (mean 0.25, max 12) are
/// checked to fail when the render is off by half a pixel.
#[wasm_bindgen_test(unsupported = test)]
fn sample_then_render_round_trip() {
    let t = template();
    let scale = 150.0 / 70.0;
    let base: Vec<f32> = t.iter().map(|&v| (v * scale) as f32).collect();
    let frame = ReferenceFrame::from_base(&base).unwrap();
    let image = smooth_image(240, 260);
    let view = image.view().unwrap();
    for (k, rot) in [(1.0f32, 0.0f32), (0.93, 0.11)] {
        let mut shape = base.clone();
        Similarity::from_parts(k, rot, 119.6, 131.2).apply_in_place(&mut shape);
        let mut g = vec![0f32; frame.n_pixels() * 3];
        facemimic::numerics::sample_rgb(&frame, &view, &shape, &mut g).unwrap();
        let (mean, max, count) = render_error(&frame, &g, &shape, &Similarity::IDENTITY, &image);
        println!("synthetic round trip (scale {k}, rotation {rot}): mean abs error {mean:.3}, max {max}, {count} pixels");
        assert!(count > 15_000, "face region has only {count} pixels");
        assert!(mean < 0.25, "mean abs error {mean}");
        assert!(max <= 12.0, "max abs error {max}");
        // The same comparison with the render half a pixel off must fail the bound.
        let off = Similarity {
            a: 1.0,
            b: 0.0,
            tx: 0.5,
            ty: 0.0,
        };
        let (mean_off, _, _) = render_error(&frame, &g, &shape, &off, &image);
        println!("  rendered half a pixel off: mean abs error {mean_off:.3}");
        assert!(
            mean_off > 0.25,
            "the bound does not detect a half-pixel offset ({mean_off})"
        );
    }
}

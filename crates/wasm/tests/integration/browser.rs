//! The canvas path in headless Chromium (wasm-bindgen-test, `run_in_browser`):
//! `cargo test -p facemimic-wasm --target wasm32-unknown-unknown browser::` (chromedriver on PATH).
//!
//! Models are built in the test from GRID landmarks (spk07 source, spk02 target in the
//! source's frame) with procedural images, so the test needs neither image decoding nor the
//! model file format. It checks that a face is painted into an `OffscreenCanvas` and an
//! on-screen `<canvas>` with no unpainted pixel inside the warped mesh (no cracks on shared
//! edges), that the picture follows the source parameters and the method, that the mesh
//! overlay and `renderMode` draw, and that bad input (a corrupt model file, NaN parameters,
//! a wrong context, an unknown method) throws a JS `Error` and leaves the module working.

use facemimic_testkit as common;

use common::js::{code, message, offscreen_ctx, params_js};
use common::pixels::{in_triangle, mean_abs_diff};
use facemimic::landmarks::parse_pts;
use facemimic::{BuildOptions, Builder, Image, Model, Params, Similarity, TrainingImage};
use facemimic_wasm::{canvas_view, render_mode, JsCloner, JsModel, RenderOptionsArg};
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use wasm_bindgen_test::*;

#[wasm_bindgen(inline_js = "export function html_ctx(w, h) {
  const c = document.createElement('canvas');
  c.width = w; c.height = h;
  document.body.appendChild(c);
  return c.getContext('2d');
}
export function read_pixels(ctx) {
  const c = ctx.canvas;
  return new Uint8Array(ctx.getImageData(0, 0, c.width, c.height).data.buffer);
}")]
extern "C" {
    fn html_ctx(w: u32, h: u32) -> JsValue;
    fn read_pixels(ctx: &JsValue) -> Vec<u8>;
}

const W: u32 = 360;
const H: u32 = 288;
const MAGENTA: [u8; 3] = [255, 0, 255];

const SPK07: [&str; 8] = [
    include_str!("../../../../data/grid/spk07_pwij3p/000000.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000004.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000011.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000012.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000019.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000028.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000035.pts"),
    include_str!("../../../../data/grid/spk07_pwij3p/000045.pts"),
];
const SPK02: [&str; 6] = [
    include_str!("../../../../data/grid/spk02_brbk7n/000002.pts"),
    include_str!("../../../../data/grid/spk02_brbk7n/000010.pts"),
    include_str!("../../../../data/grid/spk02_brbk7n/000012.pts"),
    include_str!("../../../../data/grid/spk02_brbk7n/000015.pts"),
    include_str!("../../../../data/grid/spk02_brbk7n/000018.pts"),
    include_str!("../../../../data/grid/spk02_brbk7n/000020.pts"),
];

/// A procedural 360x288 picture that varies with the image index (so the appearance model
/// has modes) and has texture everywhere (so a painted face is not one colour).
fn picture(k: usize, tint: f32) -> Image {
    let mut data = Vec::with_capacity((W * H * 4) as usize);
    let kf = k as f32;
    for y in 0..H {
        for x in 0..W {
            let (xf, yf) = (x as f32, y as f32);
            let r = 0.5 + 0.35 * (xf * 0.071 + kf * 0.4).sin();
            let g = 0.5 + 0.35 * (yf * 0.053 - kf * 0.3).cos();
            let b = tint * ((xf + yf) / (W + H) as f32) + 0.1 * (kf * 0.7).sin();
            for v in [r, g, b] {
                data.push((v.clamp(0.0, 1.0) * 255.0) as u8);
            }
            data.push(255);
        }
    }
    Image {
        width: W,
        height: H,
        data,
    }
}

fn training(files: &[&str], tint: f32) -> Vec<TrainingImage> {
    files
        .iter()
        .enumerate()
        .map(|(k, text)| TrainingImage {
            name: format!("{k:06}"),
            image: picture(k, tint),
            landmarks: parse_pts(text).expect("valid .pts"),
        })
        .collect()
}

fn models() -> (Model, Model) {
    let build = |name: &str| {
        Builder::new(BuildOptions {
            name: name.into(),
            ..BuildOptions::default()
        })
    };
    let source = build("spk07")
        .build(&training(&SPK07, 0.8), None)
        .expect("source model");
    let target = build("spk02")
        .build(&training(&SPK02, 0.3), Some(&source))
        .expect("target model");
    (source, target)
}

/// Options with the default rasteriser (no `raster` key).
fn options(background: &str, mesh: bool) -> Option<RenderOptionsArg> {
    options_with(background, mesh, "")
}

/// Options with `raster` set (unless empty).
fn options_with(background: &str, mesh: bool, raster: &str) -> Option<RenderOptionsArg> {
    let o = js_sys::Object::new();
    if !raster.is_empty() {
        js_sys::Reflect::set(&o, &"raster".into(), &raster.into()).unwrap();
    }
    js_sys::Reflect::set(&o, &"background".into(), &background.into()).unwrap();
    js_sys::Reflect::set(&o, &"mesh".into(), &mesh.into()).unwrap();
    Some(JsValue::from(o).unchecked_into())
}

/// Distance from `p` to segment `ab`.
fn seg_dist(p: (f32, f32), a: (f32, f32), b: (f32, f32)) -> f32 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (qx, qy) = (a.0 + t * dx, a.1 + t * dy);
    ((p.0 - qx).powi(2) + (p.1 - qy).powi(2)).sqrt()
}

/// Canvas pixels whose centres lie inside the warped mesh, at least 1 px from its outline
/// (pixels along interior, shared triangle edges are included: that is where cracks show).
fn inside_pixels(
    model: &Model,
    shape: &[f32],
    view: &Similarity,
    w: u32,
    h: u32,
) -> Vec<(u32, u32)> {
    let pts: Vec<(f32, f32)> = shape
        .chunks_exact(2)
        .map(|p| view.apply_point(p[0], p[1]))
        .collect();
    let tris = model.frame().triangles();
    let mut count = std::collections::HashMap::new();
    for t in tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    // The outline: edges of one triangle only, plus every edge of a triangle the instance
    // folds over (its orientation differs from the frame's), since a fold moves the outline.
    let v = model.frame().vertices();
    let area = |p: [(f32, f32); 3]| {
        (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1)
    };
    let mut outline: Vec<((f32, f32), (f32, f32))> = count
        .iter()
        .filter(|(_, &n)| n == 1)
        .map(|(&(a, b), _)| (pts[a as usize], pts[b as usize]))
        .collect();
    for t in tris {
        let src = t.map(|i| (v[2 * i as usize], v[2 * i as usize + 1]));
        let dst = t.map(|i| pts[i as usize]);
        if area(src) * area(dst) <= 0.0 {
            outline.extend([(dst[0], dst[1]), (dst[1], dst[2]), (dst[2], dst[0])]);
        }
    }
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let p = (x as f32, y as f32);
            let inside = tris.iter().any(|t| {
                let [a, b, c] = t.map(|i| pts[i as usize]);
                in_triangle(p, a, b, c, 1e-4)
            });
            if inside && outline.iter().all(|&(a, b)| seg_dist(p, a, b) >= 1.0) {
                out.push((x, y));
            }
        }
    }
    out
}

fn rgb_at(px: &[u8], w: u32, x: u32, y: u32) -> [u8; 3] {
    let i = ((y * w + x) * 4) as usize;
    [px[i], px[i + 1], px[i + 2]]
}

/// Asserts a face is painted: every inside pixel painted (not the magenta background), the
/// inside a sizeable share of the canvas, many colours, and the outside left as background.
fn assert_face(px: &[u8], model: &Model, shape: &[f32], w: u32, h: u32, what: &str) {
    let view = canvas_view(model, w, h);
    let inside = inside_pixels(model, shape, &view, w, h);
    assert!(
        inside.len() as f32 > 0.15 * (w * h) as f32,
        "{what}: the face covers only {} of {} pixels",
        inside.len(),
        w * h
    );
    let holes: Vec<_> = inside
        .iter()
        .filter(|&&(x, y)| rgb_at(px, w, x, y) == MAGENTA)
        .collect();
    assert!(
        holes.is_empty(),
        "{what}: {} unpainted pixels inside the mesh, e.g. {:?}",
        holes.len(),
        &holes[..holes.len().min(5)]
    );
    let colours: std::collections::HashSet<[u8; 3]> =
        inside.iter().map(|&(x, y)| rgb_at(px, w, x, y)).collect();
    assert!(
        colours.len() > 500,
        "{what}: only {} colours inside the face",
        colours.len()
    );
    assert_eq!(
        rgb_at(px, w, 0, 0),
        MAGENTA,
        "{what}: the corner should show the background"
    );
    let alpha_ok = px.chunks_exact(4).all(|p| p[3] == 255);
    assert!(
        alpha_ok,
        "{what}: an opaque background must give an opaque canvas"
    );
}

/// Renders `cloner`'s target 0 (`target`) on magenta into `ctx` and asserts a face is painted
/// (`assert_face`); returns the pixels.
fn target_face(cloner: &mut JsCloner, target: &Model, ctx: &JsValue, what: &str) -> Vec<u8> {
    cloner
        .render_target(0, ctx.clone().unchecked_into(), options("#ff00ff", false))
        .expect(what);
    let px = read_pixels(ctx);
    assert_face(&px, target, cloner.cloner().target_shape(0), W, H, what);
    px
}

#[wasm_bindgen_test]
fn cloner_paints_faces_without_holes_and_follows_the_source() {
    let (source, target) = models();
    let js_source = JsModel::from(source.clone());
    let js_target = JsModel::from(target.clone());
    let mut cloner = JsCloner::new(&js_source).expect("cloner");
    assert_eq!(cloner.add_target(&js_target).expect("compatible target"), 0);
    // The default is the expressive method; this test follows the paper's map.
    assert_eq!(cloner.method(), "expressive");
    cloner.set_method("map").expect("method");

    // Source and target at base parameters.
    cloner.update().expect("update");
    let (_c, ctx) = offscreen_ctx(W, H);
    let ctx: JsValue = ctx.into();
    let base = target_face(&mut cloner, &target, &ctx, "target at base");

    let (_c2, sctx) = offscreen_ctx(W, H);
    let sctx: JsValue = sctx.into();
    cloner
        .render_source(sctx.clone().unchecked_into(), options("#ff00ff", false))
        .expect("render source");
    let mut shape = vec![0.0; source.shape().base.len()];
    source
        .image_shape(&source.base_params(), &mut shape)
        .unwrap();
    assert_face(&read_pixels(&sctx), &source, &shape, W, H, "source at base");

    // Move the source 2 sigma along its first shape and appearance modes: the target changes.
    let mut p = source.base_params();
    p.shape[0] = 2.0 * source.shape().variances[0].sqrt();
    if let Some(a) = p.appearance.first_mut() {
        *a = 2.0 * source.appearance().variances()[0].sqrt();
    }
    cloner.set_source_params(params_js(&p)).expect("params");
    cloner.update().expect("update");
    let moved = target_face(&mut cloner, &target, &ctx, "target moved");
    let d = mean_abs_diff(&base, &moved);
    assert!(d > 0.5, "target barely changed with the source ({d})");

    // The method changes the picture, and the compare view does not change the cloner.
    cloner.set_method("substitute").expect("method");
    cloner.update().unwrap();
    cloner
        .render_target(0, ctx.clone().unchecked_into(), options("#ff00ff", false))
        .unwrap();
    let substituted = read_pixels(&ctx);
    assert!(
        mean_abs_diff(&moved, &substituted) > 0.1,
        "substitute looks like map"
    );
    cloner
        .render_target_with_method(
            0,
            "map",
            ctx.clone().unchecked_into(),
            options("#ff00ff", false),
        )
        .unwrap();
    let compare_map = read_pixels(&ctx);
    assert_eq!(
        mean_abs_diff(&compare_map, &moved),
        0.0,
        "compare view (map) differs from map"
    );
    assert_eq!(cloner.method(), "substitute");

    // Timings are accounted per stage: each a finite duration, and the frame's work (mapping,
    // synthesis, rasterising and blitting every face drawn since update()) took some time.
    let t = cloner.timings().unwrap();
    let mut total = 0.0;
    for k in ["mapMs", "synthMs", "rasterMs", "blitMs"] {
        let v = js_sys::Reflect::get(&t, &k.into())
            .unwrap()
            .as_f64()
            .unwrap();
        assert!(v.is_finite() && v >= 0.0, "{k} = {v}");
        total += v;
    }
    assert!(total > 0.0, "no time accounted to the frame's stages");

    // ImageData output has the requested size and the same face.
    cloner.set_method("map").unwrap();
    cloner.update().unwrap();
    let img = cloner
        .render_target_image_data(0, W, H, options("#ff00ff", false))
        .unwrap();
    assert_eq!((img.width(), img.height()), (W, H));
    assert_eq!(mean_abs_diff(&img.data().0, &moved), 0.0);
}

#[wasm_bindgen_test]
fn html_canvas_mesh_overlay_and_render_mode() {
    let (source, _) = models();
    let model = JsModel::from(source.clone());
    let mut cloner = JsCloner::new(&model).unwrap();
    // A canvas at 2x device pixels: the face scales with the canvas.
    let ctx = html_ctx(2 * W, 2 * H);
    cloner
        .render_source(ctx.clone().unchecked_into(), options("#ff00ff", false))
        .expect("html canvas");
    let plain = read_pixels(&ctx);
    let mut shape = vec![0.0; source.shape().base.len()];
    source
        .image_shape(&source.base_params(), &mut shape)
        .unwrap();
    assert_face(&plain, &source, &shape, 2 * W, 2 * H, "html canvas 2x");

    cloner
        .render_source(ctx.clone().unchecked_into(), options("#ff00ff", true))
        .unwrap();
    let meshed = read_pixels(&ctx);
    let changed = plain
        .chunks_exact(4)
        .zip(meshed.chunks_exact(4))
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 2000, "mesh overlay changed only {changed} pixels");

    // renderMode: base, then +3 sigma along shape mode 0 and appearance mode 0.
    let (_c, octx) = offscreen_ctx(W, H);
    let octx: JsValue = octx.into();
    // The picture of mode 0 of `kind` at `sigmas`.
    let mode_0 = |kind: &str, sigmas: f32| {
        render_mode(
            &model,
            kind,
            0,
            sigmas,
            octx.clone().unchecked_into(),
            options("#ff00ff", false),
        )
        .unwrap();
        read_pixels(&octx)
    };
    let m0 = mode_0("shape", 0.0);
    source
        .image_shape(&source.base_params(), &mut shape)
        .unwrap();
    assert_face(&m0, &source, &shape, W, H, "renderMode base");
    // How far mode 0 of `kind` at 3 sigma moves the picture from the base face.
    let mode_0_change = |kind: &str| mean_abs_diff(&m0, &mode_0(kind, 3.0));
    assert!(
        mode_0_change("shape") > 0.5,
        "shape mode 0 does not move the face"
    );
    if source.appearance().n_modes() > 0 {
        assert!(
            mode_0_change("appearance") > 0.5,
            "appearance mode 0 changes nothing"
        );
    }
    let e = render_mode(
        &model,
        "shape",
        999,
        1.0,
        octx.clone().unchecked_into(),
        None,
    )
    .unwrap_err();
    assert!(message(e).contains("out of range"));
    let e = render_mode(
        &model,
        "colour",
        0,
        1.0,
        octx.clone().unchecked_into(),
        None,
    )
    .unwrap_err();
    assert!(message(e).contains("kind"));

    // Transparent background: straight alpha, transparent corners.
    cloner
        .render_source(octx.clone().unchecked_into(), options("transparent", false))
        .unwrap();
    let px = read_pixels(&octx);
    assert_eq!(px[3], 0, "corner not transparent");
    let (cx, cy) = (W / 2, H / 2);
    assert_eq!(
        px[((cy * W + cx) * 4 + 3) as usize],
        255,
        "face centre not opaque"
    );
}

#[wasm_bindgen_test]
fn bad_input_throws_and_the_module_keeps_working() {
    // A corrupt model file is a JS Error naming the problem, not a panic.
    for bytes in [&b""[..], &b"not a model at all"[..], &[0u8; 64][..]] {
        let e = JsModel::from_bytes(bytes).expect_err("a corrupt file must fail");
        let m = message(e);
        assert!(m.starts_with("model file:"), "unexpected message {m:?}");
    }
    let (source, target) = models();
    let model = JsModel::from(source.clone());
    let mut cloner = JsCloner::new(&model).unwrap();
    let (_c, ctx) = offscreen_ctx(W, H);
    let ctx: JsValue = ctx.into();

    bad_params_are_refused(&mut cloner, &source);
    bad_render_calls_are_refused(&mut cloner, &ctx);
    incompatible_target_is_refused(&mut cloner);

    // After all that, everything still works.
    cloner.add_target(&JsModel::from(target.clone())).unwrap();
    cloner.update().unwrap();
    cloner
        .render_target(0, ctx.clone().unchecked_into(), options("#ff00ff", false))
        .unwrap();
    assert_face(
        &read_pixels(&ctx),
        &target,
        cloner.cloner().target_shape(0),
        W,
        H,
        "after errors",
    );
}

/// [`bad_input_throws_and_the_module_keeps_working`]: NaN and wrong-length parameters,
/// typed arrays, a missing pose field, and bad gains, clamp, method and mode gains.
fn bad_params_are_refused(cloner: &mut JsCloner, source: &Model) {
    // NaN and wrong-length parameters are refused and the old ones kept.
    let mut p = source.base_params();
    p.shape[0] = f32::NAN;
    let e = cloner.set_source_params(params_js(&p)).unwrap_err();
    assert_eq!(code(e.clone()), "bad-params");
    assert!(message(e).contains("not finite"));
    let mut p = source.base_params();
    p.shape.push(1.0);
    assert!(message(cloner.set_source_params(params_js(&p)).unwrap_err()).contains("parameters"));
    assert!(message(
        cloner
            .set_source_params(JsValue::from_str("x"))
            .unwrap_err()
    )
    .contains("parameters"));
    // Typed arrays are accepted; a missing pose field is named.
    let mut p = source.base_params();
    p.shape[1] = 0.5 * source.shape().variances[1].sqrt();
    let v = params_js(&p);
    let typed = js_sys::Float32Array::from(&p.shape[..]);
    js_sys::Reflect::set(&v, &"shape".into(), &typed).unwrap();
    cloner
        .set_source_params(v.clone())
        .expect("typed array parameters");
    let back: Params = serde_wasm_bindgen::from_value(cloner.source_params().unwrap()).unwrap();
    assert_eq!(back.shape, p.shape);
    let pose = js_sys::Reflect::get(&v, &"pose".into()).unwrap();
    js_sys::Reflect::delete_property(&pose.into(), &"tx".into()).unwrap();
    let e = cloner.set_source_params(v).unwrap_err();
    assert!(message(e).contains("pose.tx"));
    let back: Params = serde_wasm_bindgen::from_value(cloner.source_params().unwrap()).unwrap();
    assert_eq!(
        back.shape, p.shape,
        "a failed call must keep the old parameters"
    );
    assert!(cloner.set_gain(f32::INFINITY).is_err());
    assert!(cloner.set_clamp(Some(-1.0)).is_err());
    let e = cloner.set_method("blend").unwrap_err();
    assert_eq!(code(e.clone()), "bad-argument");
    assert!(message(e).contains("unknown cloning method"));
    assert!(cloner.set_shape_gains(&vec![1.0; 500]).is_err());
}

/// [`bad_input_throws_and_the_module_keeps_working`]: a wrong context, bad options, bad
/// indices and bad sizes.
fn bad_render_calls_are_refused(cloner: &mut JsCloner, ctx: &JsValue) {
    // Wrong context, bad options, bad indices.
    let e = cloner
        .render_source(JsValue::from_f64(3.0).unchecked_into(), None)
        .unwrap_err();
    assert!(message(e).contains("CanvasRenderingContext2D"));
    let e = cloner
        .render_source(ctx.clone().unchecked_into(), options("red", false))
        .unwrap_err();
    assert!(message(e).contains("background"));
    assert!(message(
        cloner
            .render_target(0, ctx.clone().unchecked_into(), None)
            .unwrap_err()
    )
    .contains("out of range"));
    assert!(cloner.remove_target(3).is_err());
    let e = cloner
        .render_source_image_data(8000, 8000, None)
        .unwrap_err();
    assert!(message(e).contains("pixels"));
    assert!(cloner.render_source_image_data(0, 10, None).is_err());
}

/// [`bad_input_throws_and_the_module_keeps_working`]: a target in its own frame is refused,
/// naming the problem, and not added.
fn incompatible_target_is_refused(cloner: &mut JsCloner) {
    // An incompatible target (its own frame) names the problem.
    let alien = Builder::new(BuildOptions {
        name: "alien".into(),
        frame: facemimic::FrameChoice::Own,
        ..BuildOptions::default()
    })
    .build(&training(&SPK02, 0.3), None)
    .unwrap();
    let e = cloner.add_target(&JsModel::from(alien)).unwrap_err();
    assert_eq!(code(e.clone()), "mismatched-models");
    assert!(
        message(e).contains("incompatible models"),
        "add_target error"
    );
    assert_eq!(cloner.target_count(), 0);
}

#[wasm_bindgen_test]
fn scanline_and_tiny_skia_rasterisers_agree() {
    let (source, target) = models();
    let mut cloner = JsCloner::new(&JsModel::from(source.clone())).unwrap();
    cloner.add_target(&JsModel::from(target.clone())).unwrap();
    let mut p = source.base_params();
    p.shape[0] = 1.5 * source.shape().variances[0].sqrt();
    p.pose = Similarity::from_parts(p.pose.scale() * 1.1, 0.2, p.pose.tx + 7.0, p.pose.ty - 5.0);
    cloner.set_source_params(params_js(&p)).unwrap();
    cloner.set_follow_pose(true);
    cloner.update().unwrap();
    let (_a, a) = offscreen_ctx(W, H);
    let (_b, b) = offscreen_ctx(W, H);
    let (a, b): (JsValue, JsValue) = (a.into(), b.into());
    cloner
        .render_target(
            0,
            a.clone().unchecked_into(),
            options_with("#ff00ff", false, "scanline"),
        )
        .unwrap();
    cloner
        .render_target(
            0,
            b.clone().unchecked_into(),
            options_with("#ff00ff", false, "tiny-skia"),
        )
        .unwrap();
    let (pa, pb) = (read_pixels(&a), read_pixels(&b));
    // The default is tiny-skia.
    cloner
        .render_target(0, a.clone().unchecked_into(), options("#ff00ff", false))
        .unwrap();
    assert!(
        read_pixels(&a) == pb,
        "the default rasteriser is not tiny-skia"
    );
    let shape = cloner.cloner().target_shape(0).to_vec();
    assert_face(&pa, &target, &shape, W, H, "scanline");
    assert_face(&pb, &target, &shape, W, H, "tiny-skia");
    let (mut both, mut either, mut diff) = (0usize, 0usize, 0f64);
    for (x, y) in pa.chunks_exact(4).zip(pb.chunks_exact(4)) {
        let (fa, fb) = (x[..3] != MAGENTA, y[..3] != MAGENTA);
        if fa || fb {
            either += 1;
        }
        if fa && fb {
            both += 1;
            diff += (0..3)
                .map(|c| (x[c] as f64 - y[c] as f64).abs())
                .sum::<f64>()
                / 3.0;
        }
    }
    let coverage_mismatch = (either - both) as f64 / either as f64;
    assert!(
        coverage_mismatch < 0.01,
        "coverage differs on {:.3}% of the face",
        100.0 * coverage_mismatch
    );
    let mean = diff / both as f64;
    assert!(mean < 1.5, "colours differ by {mean:.2} levels on average");
    let e = cloner
        .render_target(
            0,
            a.clone().unchecked_into(),
            options_with("#000", false, "gpu"),
        )
        .unwrap_err();
    assert!(message(e).contains("raster"));
}

/// `drawFrame` draws every registered canvas as the per-canvas calls do (the compare view
/// too, and `shown` skips a canvas), and `sourceFromTracker` takes a tracker's good fit inside
/// wasm: the same parameters as `setSourceParams` with the fit's `placed` pose.
#[wasm_bindgen_test]
fn draw_frame_and_source_from_tracker_match_the_per_canvas_calls() {
    let (source, target) = models();
    let js_source = JsModel::from(source.clone());
    let mut cloner = JsCloner::new(&js_source).expect("cloner");
    cloner.add_target(&JsModel::from(target)).unwrap();
    let ctxs: Vec<JsValue> = (0..6).map(|_| offscreen_ctx(W, H).1.into()).collect();
    let arg = |k: usize| Some(ctxs[k].clone().unchecked_into());
    cloner
        .set_source_canvas(arg(0), options("#ff00ff", false))
        .unwrap();
    cloner
        .set_target_canvas(0, arg(1), options("#102030", true))
        .unwrap();
    cloner
        .set_compare_canvas("map", arg(2), options("#ff00ff", false))
        .unwrap();
    cloner.set_compare_target(Some(0)).unwrap();
    assert!(cloner.set_target_canvas(1, arg(1), None).is_err());
    assert!(cloner.set_compare_canvas("nope", arg(2), None).is_err());

    // A tracker with no frame yet gives nothing: the parameters stay.
    let mut p = source.base_params();
    p.shape[0] = 1.5 * source.shape().variances[0].sqrt();
    cloner.set_source_params(params_js(&p)).unwrap();
    let tracker = facemimic_wasm::WasmTracker::from_model(&js_source).unwrap();
    assert!(!cloner.source_from_tracker(&tracker).unwrap());
    cloner.draw_frame(None).unwrap();

    let (frame, per_call): (Vec<Vec<u8>>, Vec<Vec<u8>>) = {
        let frame = ctxs[..3].iter().map(read_pixels).collect();
        cloner
            .render_source(ctxs[3].clone().unchecked_into(), options("#ff00ff", false))
            .unwrap();
        cloner
            .render_target(
                0,
                ctxs[4].clone().unchecked_into(),
                options("#102030", true),
            )
            .unwrap();
        cloner
            .render_target_with_method(
                0,
                "map",
                ctxs[5].clone().unchecked_into(),
                options("#ff00ff", false),
            )
            .unwrap();
        (frame, ctxs[3..].iter().map(read_pixels).collect())
    };
    for (k, (a, b)) in frame.iter().zip(&per_call).enumerate() {
        assert!(
            a == b,
            "canvas {k}: drawFrame differs from the per-canvas call"
        );
    }
    // A canvas not shown keeps its last picture.
    p.shape[0] = -p.shape[0];
    cloner.set_source_params(params_js(&p)).unwrap();
    cloner
        .draw_frame(Some(vec![1, 0, 1].into_boxed_slice()))
        .unwrap();
    assert!(
        read_pixels(&ctxs[1]) == frame[1],
        "a hidden target is not drawn"
    );
    assert!(read_pixels(&ctxs[0]) != frame[0], "the source is drawn");
    // Unregistered, a canvas is left alone; removing the target drops its registration.
    cloner.set_source_canvas(None, None).unwrap();
    cloner.remove_target(0).unwrap();
    cloner.draw_frame(None).unwrap();
}

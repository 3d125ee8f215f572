//! Compositing and photo targets through the wasm API, in headless Chromium
//! (wasm-bindgen-test, `run_in_browser`): `Model.fromPhoto` on a GRID frame (spk03, decoded in
//! the test from the repository's JPEG and `.pts`), `ModelInfo.backdrop` / `isPhoto` /
//! `backdropNotice`, `renderTarget` with `composite: true` (the whole picture) and without (the
//! face alone on the background), the head following the source's pose, and bad photos
//! throwing a JS `Error` with the module still working.
//!
//! The source is spk07 built in the test from 8 of its GRID training frames
//! (`data/grid/spk07_pwij3p`).

// `expect_err` would need `Debug` on the JS classes, which the package does not derive.
#![allow(clippy::err_expect)]

use facemimic_testkit as common;

use common::js::{message, params_js};
use facemimic::landmarks::parse_pts;
use facemimic::{BuildOptions, Builder, Image, Model, TrainingImage};
use facemimic_wasm::{JsCloner, JsError, JsModel, RenderOptionsArg};
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use wasm_bindgen_test::*;
use web_sys::OffscreenCanvas;

#[wasm_bindgen(inline_js = "export function read_pixels(ctx) {
  const c = ctx.canvas;
  return new Uint8Array(ctx.getImageData(0, 0, c.width, c.height).data.buffer);
}")]
extern "C" {
    fn read_pixels(ctx: &JsValue) -> Vec<u8>;
}

const W: u32 = 360;
const H: u32 = 288;

const SPK07: [(&[u8], &str); 8] = [
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000000.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000000.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000004.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000004.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000011.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000011.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000012.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000012.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000019.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000019.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000028.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000028.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000035.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000035.pts"),
    ),
    (
        include_bytes!("../../../../data/grid/spk07_pwij3p/000045.jpg"),
        include_str!("../../../../data/grid/spk07_pwij3p/000045.pts"),
    ),
];
const PHOTO: (&[u8], &str) = (
    include_bytes!("../../../../data/grid/spk03_lbax4n/000000.jpg"),
    include_str!("../../../../data/grid/spk03_lbax4n/000000.pts"),
);

fn decode((jpeg, pts): (&[u8], &str), name: &str) -> TrainingImage {
    let img = image::load_from_memory(jpeg)
        .expect("a GRID JPEG")
        .to_rgba8();
    TrainingImage {
        name: name.into(),
        image: Image {
            width: img.width(),
            height: img.height(),
            data: img.into_raw(),
        },
        landmarks: parse_pts(pts).expect("GRID landmarks"),
    }
}

fn source() -> Model {
    let images: Vec<_> = SPK07
        .iter()
        .enumerate()
        .map(|(i, f)| decode(*f, &format!("spk07-{i}")))
        .collect();
    Builder::new(BuildOptions {
        name: "spk07".into(),
        ..BuildOptions::default()
    })
    .build(&images, None)
    .expect("source model")
}

fn photo(name: &str, landmarks: &[f32]) -> Result<JsModel, JsError> {
    let t = decode(PHOTO, "photo");
    JsModel::from_photo(
        name,
        &t.image.data,
        t.image.width,
        t.image.height,
        landmarks,
    )
}

/// A `w`x`h` offscreen canvas and its 2D context as a JS value.
fn offscreen_ctx(w: u32, h: u32) -> (OffscreenCanvas, JsValue) {
    let (canvas, ctx) = common::js::offscreen_ctx(w, h);
    (canvas, ctx.into())
}

fn options(composite: bool) -> Option<RenderOptionsArg> {
    let o = js_sys::Object::new();
    js_sys::Reflect::set(&o, &"background".into(), &"#ff00ff".into()).unwrap();
    js_sys::Reflect::set(&o, &"composite".into(), &composite.into()).unwrap();
    Some(JsValue::from(o).unchecked_into())
}

fn get(v: &JsValue, key: &str) -> JsValue {
    js_sys::Reflect::get(v, &key.into()).unwrap()
}

/// Share of the pixels of the 12-pixel border of an RGBA image that are the magenta background.
fn border_background_share(px: &[u8], w: u32, h: u32) -> f32 {
    let (mut bg, mut all) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            if x >= 12 && x < w - 12 && y >= 12 && y < h - 12 {
                continue;
            }
            let i = 4 * (y * w + x) as usize;
            all += 1;
            if px[i..i + 3] == [255, 0, 255] {
                bg += 1;
            }
        }
    }
    bg as f32 / all as f32
}

#[wasm_bindgen_test]
fn a_photo_target_is_composited_into_its_photo_and_follows_the_source() {
    let t = decode(PHOTO, "photo");
    let target = photo("spk03-photo", &t.landmarks).expect("a photo target");
    let info = target.info().expect("info");
    assert_eq!(get(&info, "isPhoto").as_bool(), Some(true));
    let b = get(&info, "backdrop");
    assert_eq!(get(&b, "width").as_f64(), Some(360.0));
    assert_eq!(get(&b, "height").as_f64(), Some(288.0));
    assert!(get(&b, "bytes").as_f64().unwrap() > 4000.0);
    assert!(get(&info, "backdropNotice").is_null());

    let src = source();
    let js_source = JsModel::from(src.clone());
    let mut cloner = JsCloner::new(&js_source).expect("cloner");
    cloner
        .add_target(&target)
        .expect("the photo is a compatible target");
    cloner.update().expect("update");
    let (_c, ctx) = offscreen_ctx(W, H);
    // Target 0 rendered into `ctx`, composited or not; its pixels.
    let render = |cloner: &mut JsCloner, composite: bool| {
        cloner
            .render_target(0, ctx.clone().unchecked_into(), options(composite))
            .expect("render");
        read_pixels(&ctx)
    };

    // Face only: the background all round; composited: the photo all round.
    let face = render(&mut cloner, false);
    assert!(border_background_share(&face, W, H) > 0.95);
    let still = render(&mut cloner, true);
    assert_eq!(border_background_share(&still, W, H), 0.0);
    // At the base parameters the composite is the photo itself, near enough.
    let diff = still
        .chunks_exact(4)
        .zip(t.image.data.chunks_exact(4))
        .map(|(a, b)| {
            (0..3)
                .map(|c| (a[c] as i32 - b[c] as i32).abs())
                .sum::<i32>() as f64
        })
        .sum::<f64>()
        / (3.0 * (W * H) as f64);
    assert!(
        diff < 6.0,
        "the base composite differs from the photo by {diff:.1} levels"
    );

    // The source's first mode at 2 sigma changes the face (by substitution, whatever the
    // method), and the picture round it stays.
    let mut p = src.base_params();
    p.shape[0] = 2.0 * src.shape().variances[0].sqrt();
    cloner.set_source_params(params_js(&p)).expect("params");
    cloner.set_method("map").expect("map");
    cloner.update().expect("update");
    let moved = render(&mut cloner, true);
    assert_ne!(moved, still, "the expression did not reach the photo");
    let corner = |px: &[u8]| px[..4 * 20].to_vec();
    assert_eq!(corner(&moved), corner(&still), "the room moved");

    // Follow-pose: a source moved 20 px right moves the head in the picture.
    let mut q = p.clone();
    q.pose.tx += 20.0;
    cloner.set_follow_pose(true);
    cloner.set_source_params(params_js(&q)).expect("params");
    cloner.update().expect("update");
    let followed = render(&mut cloner, true);
    assert_ne!(followed, moved, "the head did not follow the pose");
    assert_eq!(border_background_share(&followed, W, H), 0.0);
}

#[wasm_bindgen_test]
fn bad_photos_throw_and_a_damaged_backdrop_is_a_notice() {
    let t = decode(PHOTO, "photo");
    let mut outside = t.landmarks.clone();
    outside[0] = -40.0;
    let e = message(photo("x", &outside).err().expect("landmarks outside"));
    assert!(e.contains("outside"), "{e}");
    let small: Vec<f32> = t
        .landmarks
        .chunks_exact(2)
        .flat_map(|p| [150.0 + p[0] * 0.2, 100.0 + p[1] * 0.2])
        .collect();
    let e = message(photo("x", &small).err().expect("a small face"));
    assert!(e.contains("64"), "{e}");
    let mut nan = t.landmarks.clone();
    nan[7] = f32::NAN;
    assert!(photo("x", &nan).is_err());
    assert!(photo("x", &t.landmarks[..10]).is_err());
    let e = message(
        JsModel::from_photo("x", &t.image.data[..100], 360, 288, &t.landmarks)
            .err()
            .expect("short pixels"),
    );
    assert!(!e.is_empty());

    // The module still works; a file with a damaged backdrop loads with a notice and renders
    // face only even when composited.
    let good = photo("p", &t.landmarks).expect("photo");
    let mut bytes = good.to_bytes().expect("bytes");
    let tag = facemimic::format::SECTION_BACKDROP.to_le_bytes();
    let at = bytes
        .windows(4)
        .rposition(|w| w == tag)
        .expect("a backdrop section");
    let jpeg_at = at + 8 + 12 + 8 * 68 + 4;
    for v in &mut bytes[jpeg_at..jpeg_at + 64] {
        *v = 0;
    }
    let n = bytes.len() - 4;
    let crc = facemimic::format::crc32(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
    let damaged = JsModel::from_bytes(&bytes).expect("loads without its backdrop");
    let info = damaged.info().unwrap();
    assert!(get(&info, "backdrop").is_null());
    let notice = get(&info, "backdropNotice").as_string().expect("a notice");
    assert!(notice.contains("backdrop"), "{notice}");

    let js_source = JsModel::from(source());
    let mut cloner = JsCloner::new(&js_source).expect("cloner");
    cloner.add_target(&damaged).expect("target");
    cloner.update().expect("update");
    let (_c, ctx) = offscreen_ctx(W, H);
    cloner
        .render_target(0, ctx.clone().unchecked_into(), options(true))
        .expect("face only");
    assert!(border_background_share(&read_pixels(&ctx), W, H) > 0.95);
}

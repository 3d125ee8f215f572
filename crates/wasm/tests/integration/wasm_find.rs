//! The wasm `FaceFinder` in headless Chromium (wasm-bindgen-test):
//! `cargo test -p facemimic-wasm --target wasm32-unknown-unknown wasm_find::`.
//!
//! - A GRID frame (`data/grid/spk01_bbaf2n/000004`, committed; the finder's nets were trained by
//!   MediaPipe on other data, so the frame is unseen): one face, 68 finite landmarks, close
//!   to the frame's dlib `.pts` (mean distance below 0.1 of the outer-eye-corner distance).
//! - A flat grey image: an empty array.
//! - Bad input (a buffer of the wrong length, 0x0, sizes over the limit and `u32::MAX`): a JS
//!   `Error` (a `JsError`) naming the problem, never a trap; the finder keeps working after.

use facemimic_testkit as common;

use common::js::message;
use facemimic::landmarks::parse_pts;
use facemimic_wasm::JsFaceFinder;
use js_sys::{Array, Float32Array, Reflect};
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use wasm_bindgen_test::wasm_bindgen_test;

const JPG: &[u8] = include_bytes!("../../../../data/grid/spk01_bbaf2n/000004.jpg");
const PTS: &str = include_str!("../../../../data/grid/spk01_bbaf2n/000004.pts");

fn frame() -> (Vec<u8>, u32, u32) {
    let img = image::load_from_memory_with_format(JPG, image::ImageFormat::Jpeg)
        .expect("GRID frame")
        .to_rgba8();
    let (w, h) = img.dimensions();
    (img.into_raw(), w, h)
}

fn get(o: &JsValue, k: &str) -> JsValue {
    Reflect::get(o, &JsValue::from_str(k)).expect(k)
}

fn num(o: &JsValue, k: &str) -> f64 {
    get(o, k)
        .as_f64()
        .unwrap_or_else(|| panic!("{k} is not a number"))
}

#[wasm_bindgen_test]
fn finds_the_face_of_a_grid_frame_near_its_landmarks() {
    let (rgba, w, h) = frame();
    let truth = parse_pts(PTS).expect("pts");
    assert_eq!(truth.len(), 136);
    let mut finder = JsFaceFinder::new().expect("finder");
    let faces: Array = finder.find(&rgba, w, h).expect("find");
    assert_eq!(faces.length(), 1, "one face expected");
    let face = faces.get(0);
    let score = num(&face, "score");
    assert!(score > 0.0 && score <= 1.0, "score {score}");
    let b = get(&face, "box");
    let (bx, by, bw, bh) = (
        num(&b, "x"),
        num(&b, "y"),
        num(&b, "width"),
        num(&b, "height"),
    );
    assert!(bw > 20.0 && bh > 20.0, "box {bw}x{bh}");
    let points: Vec<f32> = get(&face, "landmarks")
        .dyn_into::<Float32Array>()
        .expect("landmarks is a Float32Array")
        .to_vec();
    assert_eq!(points.len(), 136);
    assert!(points.iter().all(|v| v.is_finite()));
    // The box holds the truth's centre.
    let n = 68.0;
    let cx = truth.iter().step_by(2).sum::<f32>() as f64 / n;
    let cy = truth.iter().skip(1).step_by(2).sum::<f32>() as f64 / n;
    assert!(cx > bx && cx < bx + bw && cy > by && cy < by + bh);
    let err = facemimic::find::landmark_error(&points, &truth);
    assert!(err < 0.1, "mean landmark error {err} of the eye distance");
}

/// `precise`: the mean over the frame and its mirror; the same face, its points moved a
/// little, and off again after.
#[wasm_bindgen_test]
fn precise_finds_average_the_frame_and_its_mirror() {
    let (rgba, w, h) = frame();
    let truth = parse_pts(PTS).expect("pts");
    let mut finder = JsFaceFinder::new().expect("finder");
    assert!(!finder.precise());
    let points = |finder: &mut JsFaceFinder| -> Vec<f32> {
        let faces: Array = finder.find(&rgba, w, h).expect("find");
        assert_eq!(faces.length(), 1, "one face expected");
        get(&faces.get(0), "landmarks")
            .dyn_into::<Float32Array>()
            .expect("landmarks is a Float32Array")
            .to_vec()
    };
    let one_look = points(&mut finder);
    finder.set_precise(true);
    assert!(finder.precise());
    let precise = points(&mut finder);
    assert!(precise.iter().all(|v| v.is_finite()));
    let apart = facemimic::find::landmark_error(&precise, &one_look);
    assert!(
        apart > 0.0 && apart < 0.05,
        "precise points {apart} from one look's"
    );
    let err = facemimic::find::landmark_error(&precise, &truth);
    assert!(err < 0.1, "mean landmark error {err} of the eye distance");
    finder.set_precise(false);
    assert_eq!(points(&mut finder), one_look);
}

#[wasm_bindgen_test]
fn a_flat_image_has_no_face() {
    let (w, h) = (320u32, 240u32);
    let mut rgba = vec![128u8; (w * h * 4) as usize];
    rgba.iter_mut().skip(3).step_by(4).for_each(|a| *a = 255);
    let mut finder = JsFaceFinder::new().expect("finder");
    let faces = finder.find(&rgba, w, h).expect("find");
    assert_eq!(faces.length(), 0);
}

#[wasm_bindgen_test]
fn bad_sizes_are_js_errors() {
    let mut finder = JsFaceFinder::new().expect("finder");
    let small = vec![0u8; 64];
    // A buffer of the wrong length.
    let e = message(finder.find(&small, 10, 10).unwrap_err());
    assert!(
        e.contains("FaceFinder.find") && e.contains("64 bytes"),
        "{e}"
    );
    let e = message(finder.find(&vec![0u8; 399], 10, 10).unwrap_err());
    assert!(e.contains("expected 400"), "{e}");
    // 0x0 (and an empty buffer), a zero side.
    let e = message(finder.find(&[], 0, 0).unwrap_err());
    assert!(e.contains("0x0"), "{e}");
    assert!(finder.find(&[], 0, 10).is_err());
    // Huge sizes: over the side limit, u32::MAX (whose byte count would overflow 32 bits).
    let e = message(finder.find(&small, 100_000, 100_000).unwrap_err());
    assert!(e.contains("100000x100000"), "{e}");
    assert!(finder.find(&small, u32::MAX, u32::MAX).is_err());
    assert!(finder.find(&small, u32::MAX, 1).is_err());
    // The largest allowed size with a short buffer: refused before any allocation.
    assert!(finder.find(&small, 8192, 8192).is_err());
    // The finder still works.
    let (rgba, w, h) = frame();
    assert_eq!(finder.find(&rgba, w, h).expect("find").length(), 1);
}

/// A `{x, y, width, height}` object.
fn js_box(x: f64, y: f64, w: f64, h: f64) -> JsValue {
    let o = js_sys::Object::new();
    for (k, v) in [("x", x), ("y", y), ("width", w), ("height", h)] {
        Reflect::set(&o, &JsValue::from_str(k), &JsValue::from_f64(v)).expect("set");
    }
    o.into()
}

#[wasm_bindgen_test]
fn landmarks_in_the_found_box_match_the_found_face() {
    let (rgba, w, h) = frame();
    let truth = parse_pts(PTS).expect("pts");
    let mut finder = JsFaceFinder::new().expect("finder");
    let faces: Array = finder.find(&rgba, w, h).expect("find");
    let b = get(&faces.get(0), "box");
    let bx = js_box(
        num(&b, "x"),
        num(&b, "y"),
        num(&b, "width"),
        num(&b, "height"),
    );
    let points = finder
        .landmarks(&rgba, w, h, bx)
        .expect("landmarks")
        .to_vec();
    assert_eq!(points.len(), 136);
    let err = facemimic::find::landmark_error(&points, &truth);
    assert!(err < 0.1, "mean landmark error {err} of the eye distance");
}

#[wasm_bindgen_test]
fn landmarks_with_a_bad_box_are_js_errors() {
    let (rgba, w, h) = frame();
    let mut finder = JsFaceFinder::new().expect("finder");
    let e = message(finder.landmarks(&rgba, w, h, JsValue::NULL).unwrap_err());
    assert!(e.contains("FaceFinder.landmarks: box must be"), "{e}");
    // A box without its height.
    let partial = js_box(1.0, 2.0, 50.0, 50.0);
    Reflect::delete_property(
        partial.unchecked_ref::<js_sys::Object>(),
        &JsValue::from_str("height"),
    )
    .unwrap();
    let e = message(finder.landmarks(&rgba, w, h, partial).unwrap_err());
    assert!(e.contains("height"), "{e}");
    let e = message(
        finder
            .landmarks(&rgba, w, h, js_box(10.0, 10.0, f64::NAN, 50.0))
            .unwrap_err(),
    );
    assert!(e.contains("FaceFinder.landmarks"), "{e}");
    let e = message(
        finder
            .landmarks(&rgba, w, h, js_box(10.0, 10.0, -5.0, 50.0))
            .unwrap_err(),
    );
    assert!(e.contains("invalid face box"), "{e}");
    assert!(finder
        .landmarks(&rgba[..100], w, h, js_box(0.0, 0.0, 50.0, 50.0))
        .is_err());
}

/// `FaceFinder.enrol` is the free `enrolFace` run by the finder object (one finder for a page's
/// worker): the same face on the GRID frame, `null` on a flat image, bad input a JS error.
#[wasm_bindgen_test]
fn enrol_is_enrol_face_with_this_finder() {
    let (rgba, w, h) = frame();
    let mut finder = JsFaceFinder::new().expect("finder");
    let a = finder.enrol(&rgba, w, h, None).expect("enrol");
    let b = facemimic_wasm::enrol_face(&rgba, w, h, None).expect("enrolFace");
    let la = Float32Array::from(get(&a, "landmarks")).to_vec();
    let lb = Float32Array::from(get(&b, "landmarks")).to_vec();
    assert_eq!(la.len(), 136);
    assert_eq!(la, lb, "the same landmarks as enrolFace");
    assert_eq!(num(&a, "score"), num(&b, "score"));
    assert_eq!(num(&a, "spread"), num(&b, "spread"));
    // The most confident face only when it scores at least minScore.
    assert!(finder
        .enrol(&rgba, w, h, Some(1.0))
        .expect("enrol")
        .is_null());
    let flat = vec![128u8; (w * h * 4) as usize];
    assert!(finder.enrol(&flat, w, h, None).expect("enrol").is_null());
    let e = message(finder.enrol(&rgba, w, h, Some(2.0)).unwrap_err());
    assert!(
        e.contains("FaceFinder.enrol") && e.contains("minScore"),
        "{e}"
    );
    let e = message(finder.enrol(&rgba[..64], w, h, None).unwrap_err());
    assert!(e.contains("FaceFinder.enrol"), "{e}");
    // find still works on the same object.
    assert_eq!(finder.find(&rgba, w, h).expect("find").length(), 1);
}

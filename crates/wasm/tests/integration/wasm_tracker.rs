//! The tracking policy as the npm package exposes it, in headless Chromium (wasm-bindgen-test):
//! `cargo test -p facemimic-wasm --target wasm32-unknown-unknown wasm_tracker::`.
//!
//! Model: `tests/data/tiny-v1.fmm` (6 frames of GRID spk07, 68 landmarks, a 28-pixel face).
//! - `Tracker.fitScale` is the core's `Tracker::fit_scale`; `policy` / `setPolicy` read and
//!   change the `TrackPolicy`, and refuse values out of range (an `Error`, nothing changed).
//! - `startSearching` / `wantsFaces` / `offerFaces`: faces from a `FaceFinder`-like result
//!   (objects with `landmarks`) or plain arrays; wrong lengths or non-finite points throw.
//! - `Tracker.follower` (the person-independent landmark path) is the same class with the same
//!   calls: offers checked the same way, `wantsFaces`; a blank frame is lost; a NaN time step,
//!   a bad image or box throw (nothing panics); calls that mean nothing for it answer
//!   neutrally (`resets` 0, `scale` and `fitScale` 1). `Tracker.forModel` / `kindFor` are the
//!   core's policy ("aam" for one's own model, "landmarks" for anyone else's).
//! - `PoseDamper` is the core's `PoseAnchor` (head-motion damping of the call page).
//! - `recentrePose` is `Similarity::recentred`, `lerpPose` is `Similarity::lerp`;
//!   `Model.checkParams` is `Model::check_params` (a non-positive pose scale is refused by name).
//! - `Tracker.track` on frames at their own size gives the CLI's track: the golden file
//!   `tests/data/tiny-track.csv` that `crates/cli/tests/integration/cli.rs` checks `facemimic fit` against (landmarks,
//!   pose and `placed` in the frame's pixels, the fit scale chosen by the tracker).

use facemimic_testkit as common;

use common::js::message;
use facemimic_wasm::{lerp_pose, recentre_pose, JsModel, JsPoseDamper, WasmTracker};
use js_sys::{Array, Float32Array, Object, Reflect};
use wasm_bindgen::prelude::*;
use wasm_bindgen_test::wasm_bindgen_test;

const TINY: &[u8] = include_bytes!("../../../../tests/data/tiny-v1.fmm");

fn get(o: &JsValue, k: &str) -> f64 {
    Reflect::get(o, &JsValue::from_str(k))
        .expect(k)
        .as_f64()
        .expect(k)
}

fn obj(pairs: &[(&str, JsValue)]) -> JsValue {
    let o = Object::new();
    for (k, v) in pairs {
        Reflect::set(&o, &JsValue::from_str(k), v).unwrap();
    }
    o.into()
}

fn pose(scale: f64, rotation: f64, tx: f64, ty: f64) -> JsValue {
    obj(&[
        ("scale", scale.into()),
        ("rotation", rotation.into()),
        ("tx", tx.into()),
        ("ty", ty.into()),
    ])
}

/// The model's mean landmarks and their height.
fn mean_landmarks(model: &JsModel) -> (Vec<f32>, f32) {
    let lm = model
        .landmarks_of(model.base_params().unwrap())
        .expect("mean landmarks");
    let ys: Vec<f32> = lm.iter().skip(1).step_by(2).copied().collect();
    let h =
        ys.iter().copied().fold(f32::MIN, f32::max) - ys.iter().copied().fold(f32::MAX, f32::min);
    (lm, h)
}

#[wasm_bindgen_test]
fn fit_scale_and_policy() {
    let model = JsModel::from_bytes(TINY).unwrap();
    let mut t = WasmTracker::from_model(&model).unwrap();
    let (_, h) = mean_landmarks(&model);
    assert_eq!(t.fit_scale(h, 640, 480, 0.0), 1.0);
    assert!((t.fit_scale(2.0 * h, 640, 480, 0.0) - 0.5).abs() < 1e-5);
    assert_eq!(
        t.fit_scale(2.2 * h, 640, 480, 0.5),
        0.5,
        "the current scale is kept"
    );
    let p = t.policy().unwrap();
    assert_eq!(get(&p, "appearanceLimit"), 3.0);
    assert_eq!(get(&p, "maxFitSide"), 1280.0);
    // A partial change keeps the other values.
    t.set_policy(obj(&[("maxUpscale", 1.5.into())])).unwrap();
    let p = t.policy().unwrap();
    assert_eq!(get(&p, "maxUpscale"), 1.5);
    assert_eq!(get(&p, "appearanceLimit"), 3.0);
    assert!((t.fit_scale(0.25 * h, 640, 480, 0.0) - 1.5).abs() < 1e-5);
    // Out of range, unknown or mistyped: an Error, nothing changed.
    for bad in [
        obj(&[("appearanceLimit", (-1.0).into())]),
        obj(&[("minFitSide", 1.0.into())]),
        obj(&[("rescale", 0.1.into())]),
        obj(&[("nativeBand", "wide".into())]),
    ] {
        let e = message(t.set_policy(bad).unwrap_err());
        assert!(
            e.contains("setPolicy") || e.contains("tracking policy"),
            "{e}"
        );
    }
    assert_eq!(get(&t.policy().unwrap(), "maxUpscale"), 1.5);
    // The pose anchor's time constant.
    assert_eq!(get(&t.policy().unwrap(), "recentreTau"), 4.0);
    t.set_policy(obj(&[("recentreTau", 0.0.into())])).unwrap();
    assert_eq!(get(&t.policy().unwrap(), "recentreTau"), 0.0);
    assert!(t
        .set_policy(obj(&[("recentreTau", (-1.0).into())]))
        .is_err());
    // Second opinions: every 15 tracked frames by default, 0 turns them off.
    assert_eq!(get(&t.policy().unwrap(), "recheckFrames"), 15.0);
    t.set_policy(obj(&[("recheckFrames", 0.0.into())])).unwrap();
    assert_eq!(get(&t.policy().unwrap(), "recheckFrames"), 0.0);
    assert!(t.set_policy(obj(&[("recheckFrames", 1e6.into())])).is_err());
    assert_eq!((t.rechecks(), t.rechecks_kept()), (0, 0));
}

/// The frames of the golden track (`crates/cli/tests/integration/cli.rs`, `GOLDEN_TRACK`).
const GOLDEN_FRAMES: [&[u8]; 6] = [
    include_bytes!("../../../../data/grid/spk07_id2_vcd_swwp2s/000000.jpg"),
    include_bytes!("../../../../data/grid/spk07_id2_vcd_swwp2s/000001.jpg"),
    include_bytes!("../../../../data/grid/spk07_id2_vcd_swwp2s/000002.jpg"),
    include_bytes!("../../../../data/grid/spk07_id2_vcd_swwp2s/000003.jpg"),
    include_bytes!("../../../../data/grid/spk07_id2_vcd_swwp2s/000004.jpg"),
    include_bytes!("../../../../data/grid/spk07_id2_vcd_swwp2s/000005.jpg"),
];

#[wasm_bindgen_test]
fn tracks_the_golden_frames_as_the_cli() {
    let golden = include_str!("../../../../tests/data/tiny-track.csv");
    // The CLI's frames: enlarged twice, each pixel a 2x2 block (crates/cli/tests/integration/cli.rs `doubled`).
    let doubled = |jpeg: &[u8]| {
        let img = image::load_from_memory(jpeg).unwrap().to_rgba8();
        image::RgbaImage::from_fn(img.width() * 2, img.height() * 2, |x, y| {
            let p = img.get_pixel(x / 2, y / 2);
            image::Rgba([p[0], p[1], p[2], 255])
        })
    };
    let init: Vec<f32> = facemimic::landmarks::parse_pts(include_str!(
        "../../../../data/grid/spk07_id2_vcd_swwp2s/000000.pts"
    ))
    .unwrap()
    .iter()
    .map(|v| 2.0 * (v + 0.5) - 0.5)
    .collect();
    let model = JsModel::from_bytes(TINY).unwrap();
    let mut t = WasmTracker::from_model(&model).unwrap();
    t.start_from_landmarks(&init).unwrap();
    let mut lines = golden.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let mut worst = 0.0f64;
    for (i, (jpeg, line)) in GOLDEN_FRAMES.iter().zip(lines).enumerate() {
        let img = doubled(jpeg);
        let r = t
            .track(img.as_raw(), img.width(), img.height(), Some(1.0 / 25.0))
            .unwrap();
        let want: Vec<&str> = line.split(',').collect();
        let lost = Reflect::get(&r, &"lost".into()).unwrap().as_bool().unwrap();
        assert_eq!(lost.to_string(), want[1], "frame {i}: lost");
        let lm = Float32Array::new(&Reflect::get(&r, &"landmarks".into()).unwrap()).to_vec();
        for (j, v) in lm.iter().enumerate() {
            let w: f64 = want[col("x0") + j].parse().unwrap();
            worst = worst.max((*v as f64 - w).abs());
        }
        let (pose, placed) = (
            Reflect::get(&r, &"pose".into()).unwrap(),
            Reflect::get(&r, &"placed".into()).unwrap(),
        );
        for (o, prefix) in [(&pose, ""), (&placed, "placed_")] {
            for k in ["scale", "rotation", "tx", "ty"] {
                let w: f64 = want[col(&format!("{prefix}{k}"))].parse().unwrap();
                let d = (get(o, k) - w).abs();
                assert!(
                    d <= 1e-4 * (1.0 + w.abs()),
                    "frame {i}: {prefix}{k} {} vs the CLI's {w}",
                    get(o, k)
                );
            }
        }
    }
    // The same decoder, resampler and fit on another target: the same numbers (the CSV
    // prints every f32 exactly).
    assert!(worst < 0.001, "landmarks {worst} px off the CLI's");
    assert!(
        t.scale() > 0.0 && t.scale() < 0.9,
        "fit scale {}",
        t.scale()
    );
    // A bad time step is refused by name.
    let img = doubled(GOLDEN_FRAMES[0]);
    let e = message(
        t.track(img.as_raw(), img.width(), img.height(), Some(f32::NAN))
            .unwrap_err(),
    );
    assert!(e.contains("time step"), "{e}");
}

#[wasm_bindgen_test]
fn offered_faces() {
    let model = JsModel::from_bytes(TINY).unwrap();
    let mut t = WasmTracker::new(TINY).unwrap();
    assert!(!t.wants_faces());
    t.start_searching();
    assert!(t.wants_faces());
    let (lm, _) = mean_landmarks(&model);
    // Not an array, a face without landmarks, a wrong length, a NaN: Errors, nothing kept.
    assert!(message(t.offer_faces(JsValue::from(3)).unwrap_err()).contains("array"));
    let no_landmarks: JsValue = Array::of1(&obj(&[("score", 0.9.into())])).into();
    assert!(message(t.offer_faces(no_landmarks).unwrap_err()).contains("face 0"));
    let short: JsValue = Array::of1(&Float32Array::from(&lm[..10]).into()).into();
    assert!(message(t.offer_faces(short).unwrap_err()).contains("offered face landmarks"));
    let mut nan = lm.clone();
    nan[5] = f32::NAN;
    let nan: JsValue = Array::of1(&Float32Array::from(nan.as_slice()).into()).into();
    assert!(!message(t.offer_faces(nan).unwrap_err()).is_empty());
    assert!(t.wants_faces(), "a refused offer was kept");
    // A FaceFinder-like result is accepted: no more faces wanted until it is used.
    let face = obj(&[
        ("score", 0.9.into()),
        ("landmarks", Float32Array::from(lm.as_slice()).into()),
    ]);
    t.offer_faces(Array::of1(&face).into()).unwrap();
    assert!(!t.wants_faces());
    // Plain number arrays too.
    let plain: Array = lm.iter().map(|v| JsValue::from(*v)).collect();
    t.offer_faces(Array::of1(&plain).into()).unwrap();
}

#[wasm_bindgen_test]
fn the_landmark_path_has_the_same_calls_and_refuses_bad_input() {
    let model = JsModel::from_bytes(TINY).unwrap();
    let mut f = WasmTracker::follower(&model).unwrap();
    let (lm, h) = mean_landmarks(&model);
    assert_eq!(f.path(), "landmarks");
    assert!(f.last().unwrap().is_null(), "no frame yet");
    // Calls that mean nothing for the landmark path answer neutrally.
    assert_eq!((f.resets(), f.rechecks(), f.rechecks_kept()), (0, 0, 0));
    assert_eq!((f.scale(), f.fit_scale(2.0 * h, 640, 480, 0.0)), (1.0, 1.0));
    assert_eq!(get(&f.policy().unwrap(), "recentreTau"), 4.0);
    f.expect_offers(true);
    assert!(f.wants_faces());
    let short: JsValue = Array::of1(&Float32Array::from(&lm[..10]).into()).into();
    assert!(message(f.offer_faces(short).unwrap_err()).contains("offered face landmarks"));
    assert!(f.wants_faces());
    // A blank frame with nothing offered: lost, no exception.
    let blank = vec![128u8; 64 * 48 * 4];
    let r = f.track(&blank, 64, 48, None).unwrap();
    assert!(Reflect::get(&r, &"lost".into()).unwrap().as_bool().unwrap());
    assert_eq!((f.lost_count(), f.frames(), f.reacquisitions()), (1, 1, 0));
    assert!(!f.last().unwrap().is_null());
    // Bad input: an Error naming it.
    assert!(message(f.track(&blank, 64, 48, Some(f32::NAN)).unwrap_err()).contains("time step"));
    assert!(!message(f.track(&blank[..10], 64, 48, None).unwrap_err()).is_empty());
    assert!(message(f.start_from_box(f32::NAN, 0.0, 10.0, 10.0).unwrap_err()).contains("box"));
    assert!(!message(f.start_from_landmarks(&lm[..10]).unwrap_err()).is_empty());
    f.start_from_landmarks(&lm).unwrap();
    assert!(!f.wants_faces());
    f.start_searching();
    assert!(f.wants_faces());
}

#[wasm_bindgen_test]
fn the_policy_chooses_the_kind() {
    let model = JsModel::from_bytes(TINY).unwrap();
    assert_eq!(WasmTracker::kind_for(&model, true), "aam");
    assert_eq!(WasmTracker::kind_for(&model, false), "landmarks");
    assert_eq!(WasmTracker::for_model(&model, true).unwrap().path(), "aam");
    assert_eq!(
        WasmTracker::for_model(&model, false).unwrap().path(),
        "landmarks"
    );
    assert_eq!(WasmTracker::new(TINY).unwrap().path(), "aam");
}

#[wasm_bindgen_test]
fn pose_damper_scales_the_deviation_from_the_running_anchor() {
    let still = pose(2.0, 0.1, 100.0, 50.0);
    let moved = pose(2.0, 0.1, 120.0, 50.0);
    let mut d0 = JsPoseDamper::new(Some(2.0)).unwrap();
    let mut d5 = JsPoseDamper::new(Some(2.0)).unwrap();
    let mut d1 = JsPoseDamper::new(None).unwrap();
    for i in 0..300 {
        let t = 33.0 * i as f64;
        d0.apply(still.clone(), t, 0.0).unwrap();
        d5.apply(still.clone(), t, 0.5).unwrap();
        d1.apply(still.clone(), t, 1.0).unwrap();
    }
    let t = 33.0 * 300.0;
    assert!((get(&d0.apply(moved.clone(), t, 0.0).unwrap(), "tx") - 100.0).abs() < 0.5);
    assert!((get(&d5.apply(moved.clone(), t, 0.5).unwrap(), "tx") - 110.0).abs() < 0.5);
    assert!((get(&d1.apply(moved.clone(), t, 1.0).unwrap(), "tx") - 120.0).abs() < 1e-3);
    // Bad input: an Error, nothing panics.
    assert!(JsPoseDamper::new(Some(f32::NAN)).is_err());
    assert!(d0.apply(pose(-1.0, 0.0, 0.0, 0.0), t, 0.5).is_err());
    assert!(d0.apply(still.clone(), f64::NAN, 0.5).is_err());
    assert!(d0.apply(still, t, f32::INFINITY).is_err());
    d0.reset();
    let r = d0.apply(moved, t + 33.0, 0.0).unwrap();
    assert!(
        (get(&r, "tx") - 120.0).abs() < 1e-3,
        "a reset anchor starts at the pose"
    );
}

#[wasm_bindgen_test]
fn recentre_pose_and_check_params() {
    let anchor = pose(1.7, 0.2, 40.0, 25.0);
    let target = pose(0.9, -0.05, 180.0, 144.0);
    let r = recentre_pose(anchor.clone(), anchor.clone(), target).unwrap();
    assert!((get(&r, "scale") - 0.9).abs() < 1e-5);
    assert!((get(&r, "rotation") + 0.05).abs() < 1e-5);
    assert!((get(&r, "tx") - 180.0).abs() < 1e-3);
    let e = message(
        recentre_pose(pose(-1.0, 0.0, 0.0, 0.0), anchor, pose(1.0, 0.0, 0.0, 0.0)).unwrap_err(),
    );
    assert!(e.contains("pose.scale"), "{e}");
    // lerpPose: halfway between 179 and -179 degrees is 180, the scale geometric.
    let (a, b) = (pose(1.0, 3.124, 0.0, 10.0), pose(4.0, -3.124, 10.0, 20.0));
    let m = lerp_pose(a.clone(), b, 0.5).unwrap();
    assert!((get(&m, "scale") - 2.0).abs() < 1e-5);
    assert!((get(&m, "rotation").abs() - std::f64::consts::PI).abs() < 1e-4);
    assert!((get(&m, "tx") - 5.0).abs() < 1e-5);
    assert!(!message(lerp_pose(a.clone(), a, f32::NAN).unwrap_err()).is_empty());

    let model = JsModel::from_bytes(TINY).unwrap();
    let p = model.base_params().unwrap();
    model.check_params(p.clone()).unwrap();
    Reflect::set(&p, &JsValue::from_str("pose"), &pose(-2.0, 0.0, 1.0, 1.0)).unwrap();
    let e = message(model.check_params(p).unwrap_err());
    assert!(e.contains("pose.scale"), "{e}");
    let short = model.base_params().unwrap();
    Reflect::set(
        &short,
        &JsValue::from_str("shape"),
        &Array::of1(&0.5.into()),
    )
    .unwrap();
    let e = message(model.check_params(short).unwrap_err());
    assert!(e.contains("shape"), "{e}");
}

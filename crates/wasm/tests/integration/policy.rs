//! `policy()` is the core's front-end policy, and `modelSummary()` what a model file's header
//! says, without building the model.

use facemimic::clone::CloneOptions;
use facemimic::fit::WORK_SIDE;
use facemimic::{EnrolSampling, PHOTO_FIT_PASSES, PHOTO_MAX_SIDE};
use facemimic_testkit::js::message;
use facemimic_wasm::{model_summary, policy, JsModel};
use wasm_bindgen::JsValue;
use wasm_bindgen_test::wasm_bindgen_test;

const TINY: &[u8] = include_bytes!("../../../../tests/data/tiny-v1.fmm");

fn get(v: &JsValue, path: &str) -> JsValue {
    path.split('.').fold(v.clone(), |o, k| {
        js_sys::Reflect::get(&o, &k.into()).expect(k)
    })
}

fn num(v: &JsValue, path: &str) -> f64 {
    get(v, path)
        .as_f64()
        .unwrap_or_else(|| panic!("{path} is not a number"))
}

#[wasm_bindgen_test]
fn the_policy_is_the_cores() {
    let p = policy().unwrap();
    let s = EnrolSampling::DEFAULT;
    let c = CloneOptions::default();
    assert_eq!(num(&p, "workSide"), WORK_SIDE as f64);
    assert_eq!(num(&p, "photo.maxSide"), PHOTO_MAX_SIDE as f64);
    assert_eq!(num(&p, "photo.findSide"), WORK_SIDE as f64);
    assert_eq!(num(&p, "photo.fitPasses"), PHOTO_FIT_PASSES as f64);
    assert_eq!(num(&p, "enrol.want"), s.want as f64);
    assert_eq!(num(&p, "enrol.minFrames"), s.min_frames as f64);
    assert_eq!(num(&p, "enrol.maxCandidates"), s.max_candidates as f64);
    assert_eq!(num(&p, "enrol.sampleMs"), s.sample_ms as f64);
    assert_eq!(num(&p, "enrol.videoSamples"), s.video_samples as f64);
    assert_eq!(
        get(&p, "clone.method").as_string().unwrap(),
        c.method.name()
    );
    assert_eq!(num(&p, "clone.gain"), c.gain as f64);
    match c.clamp {
        Some(k) => assert_eq!(num(&p, "clone.clamp"), k as f64),
        None => assert!(get(&p, "clone.clamp").is_null()),
    }
    assert_eq!(get(&p, "clone.followPose").as_bool(), Some(c.follow_pose));
    assert_eq!(num(&p, "clone.mouth"), c.regions.mouth as f64);
    assert_eq!(num(&p, "clone.style"), c.style as f64);
}

#[wasm_bindgen_test]
fn a_model_summary_agrees_with_the_model_and_refuses_what_is_not_one() {
    let s = model_summary(TINY).unwrap();
    let info = JsModel::from_bytes(TINY).unwrap().info().unwrap();
    for key in [
        "name",
        "shapeModes",
        "appearanceModes",
        "fingerprint",
        "isPhoto",
        "landmarks",
    ] {
        assert_eq!(
            format!("{:?}", get(&s, key)),
            format!("{:?}", get(&info, key)),
            "{key}"
        );
    }
    assert_eq!(num(&s, "fileBytes"), TINY.len() as f64);
    let mut bad = TINY.to_vec();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x10;
    let e = message(model_summary(&bad).unwrap_err());
    assert!(e.contains("checksum") || e.contains("CRC"), "{e}");
    assert!(!message(model_summary(b"<!doctype html>").unwrap_err()).is_empty());
    assert!(!message(model_summary(&[]).unwrap_err()).is_empty());
}

/// The cloner's head damping takes the call's settings and refuses bad ones with a message.
#[wasm_bindgen_test]
fn head_damping_settings_are_checked() {
    let model = JsModel::from_bytes(TINY).unwrap();
    let mut cloner = facemimic_wasm::JsCloner::new(&model).unwrap();
    cloner.set_head_damping(2.0, 0.5).unwrap();
    cloner.set_head_damping(0.0, 1.5).unwrap();
    let e = message(cloner.set_head_damping(-1.0, 1.0).unwrap_err());
    assert!(e.contains("tau"), "{e}");
    let e = message(cloner.set_head_damping(2.0, f32::NAN).unwrap_err());
    assert!(e.contains("factor"), "{e}");
    cloner.clear_head_damping();
}

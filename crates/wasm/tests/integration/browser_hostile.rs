//! Hostile input through the wasm API in headless Chromium (wasm-bindgen-test,
//! `run_in_browser`): `cargo test -p facemimic-wasm --target wasm32-unknown-unknown browser_hostile::`.
//!
//! Each case of the hostile-input review gives a JS `Error` (a `JsError`), never a trap that
//! kills the page: models with a huge mean pose, base appearance, base shape or declared size
//! of no real model; parameters and gains of 1e30; a clamp of NaN; a model whose tracker
//! precomputation is over its memory budget; a model name the reader would reject. After each,
//! the module keeps working.

use facemimic_testkit as common;
use facemimic_testkit::fuzz as engine;

use common::js::{code, message, params_js};
use facemimic::format::write_model;
use facemimic::{Model, ModelParts, Similarity};
use facemimic_wasm::{JsCloner, JsModel, WasmTracker};
use wasm_bindgen_test::*;

fn seeds() -> &'static engine::Seeds {
    static S: std::sync::OnceLock<engine::Seeds> = std::sync::OnceLock::new();
    S.get_or_init(engine::Seeds::new)
}

fn load_err(m: &Model) -> String {
    let bytes = facemimic::format::write_model_as(m, facemimic::format::Storage::F32);
    let e = JsModel::from_bytes(&bytes).expect_err("refused");
    assert_eq!(code(e.clone()), "bad-model", "{}", message(e.clone()));
    message(e)
}

#[wasm_bindgen_test]
fn hostile_models_are_js_errors() {
    let base = &seeds().models[0];
    // `base` with a part changed (still a `Model`: finite, dimensions that agree).
    let edited = |change: &dyn Fn(&mut ModelParts)| {
        let mut parts = base.clone().into_parts();
        change(&mut parts);
        Model::new(parts).unwrap()
    };
    let m = edited(&|p| {
        p.mean_pose = Similarity {
            a: 3e38,
            b: 0.0,
            tx: 0.0,
            ty: 0.0,
        }
    });
    assert!(load_err(&m).contains("mean pose scale"));
    let m = edited(&|p| {
        let (mut b, m, v) = p.appearance.clone().into_arrays();
        b[0] = f32::MAX;
        p.appearance = facemimic::AppearanceModel::new(b, m, v);
    });
    assert!(load_err(&m).contains("appearance base"));
    let m = edited(&|p| p.shape.base.iter_mut().for_each(|v| *v *= 1e30));
    assert!(!load_err(&m).contains("degenerate"));
    // A 300-byte name: toBytes refuses what fromBytes would reject.
    let mut m = base.clone();
    m.set_name("x".repeat(300));
    let e = message(JsModel::from(m).to_bytes().expect_err("refused"));
    assert!(e.contains("model name length"), "{e}");
    // The module keeps working.
    assert!(JsModel::from_bytes(&write_model(base)).is_ok());
}

#[wasm_bindgen_test]
fn huge_parameters_gains_and_clamps_are_js_errors() {
    let s = &seeds().models;
    let source = JsModel::from(s[0].clone());
    let mut cloner = JsCloner::new(&source).unwrap();
    cloner.add_target(&JsModel::from(s[1].clone())).unwrap();
    let mut p = s[0].base_params();
    p.shape.iter_mut().for_each(|v| *v = 1e30);
    let e = message(cloner.set_source_params(params_js(&p)).unwrap_err());
    assert!(e.contains("shape parameters[0]"), "{e}");
    assert!(cloner.set_gain(1e30).is_err());
    assert!(cloner.set_clamp(Some(f32::NAN)).is_err());
    assert!(cloner.set_shape_gains(&[1e30]).is_err());
    // The largest accepted values: finite output.
    p.shape.iter_mut().for_each(|v| *v = 1e6);
    cloner.set_source_params(params_js(&p)).unwrap();
    cloner.set_gain(1e3).unwrap();
    cloner.set_clamp(None).unwrap();
    cloner.update().unwrap();
    let lm = cloner.target_landmarks(0).unwrap().to_vec();
    assert!(lm.iter().all(|v| v.is_finite()));
}

#[wasm_bindgen_test]
fn tracker_over_budget_is_a_js_error_not_an_out_of_memory_trap() {
    let m = engine::over_budget_model();
    let bytes = write_model(&m);
    let e = message(WasmTracker::new(&bytes).expect_err("refused"));
    assert!(e.contains("memory budget:"), "{e}");
    let js = JsModel::from_bytes(&bytes).unwrap();
    assert!(WasmTracker::from_model(&js).is_err());
    // A model within its budget tracks.
    assert!(WasmTracker::new(&write_model(&seeds().models[0])).is_ok());
}

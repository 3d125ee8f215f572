//! The wasm `buildModel` is a thin shell over the core enrolment pipeline
//! ([`facemimic::enrol`]): from the same frames without landmarks (the face finder places
//! them), with selection and the default backdrop, both give the same model, byte for byte.
//! The CLI's side of the same claim is `crates/cli/tests/integration/cli.rs` `build_find_faces_is_the_core_pipeline`.
//!
//! Frames: 8 of GRID spk02's training frames (`data/grid/spk02_brbk7n`, CC BY 4.0), decoded in
//! the test; runs in headless Chromium with the others (`cargo test -p facemimic-wasm --target wasm32-unknown-unknown wasm_enrol::`).

use facemimic::format::write_model_checked;
use facemimic::{enrol, BuildOptions, EnrolFrame, EnrolOptions, Image};
use facemimic_wasm::build_model;
use wasm_bindgen::prelude::*;
use wasm_bindgen::JsCast;
use wasm_bindgen_test::*;

const FRAMES: [&[u8]; 8] = [
    include_bytes!("../../../../data/grid/spk02_brbk7n/000002.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000010.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000012.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000015.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000018.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000020.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000021.jpg"),
    include_bytes!("../../../../data/grid/spk02_brbk7n/000022.jpg"),
];

fn decode(jpeg: &[u8]) -> Image {
    let img = image::load_from_memory(jpeg)
        .expect("a GRID JPEG")
        .to_rgba8();
    Image {
        width: img.width(),
        height: img.height(),
        data: img.into_raw(),
    }
}

fn set(o: &js_sys::Object, k: &str, v: &JsValue) {
    js_sys::Reflect::set(o, &k.into(), v).expect("set a property");
}

#[wasm_bindgen_test]
fn build_model_is_the_core_pipeline() {
    let images: Vec<Image> = FRAMES.iter().map(|j| decode(j)).collect();

    // The shell: frames without landmarks, keep 6, the third frame as the reference.
    let frames = js_sys::Array::new();
    for img in &images {
        let f = js_sys::Object::new();
        set(&f, "rgba", &js_sys::Uint8Array::from(&img.data[..]).into());
        set(&f, "width", &img.width.into());
        set(&f, "height", &img.height.into());
        frames.push(&f);
    }
    let options = js_sys::Object::new();
    set(&options, "frames", &frames);
    set(&options, "name", &"spk02-enrolled".into());
    set(&options, "select", &6.into());
    set(&options, "reference", &2.into());
    let shell = build_model(options.unchecked_into(), None)
        .map_err(JsValue::from)
        .expect("buildModel");

    // The core, called directly with the same frames and choices.
    let frames: Vec<EnrolFrame> = images
        .into_iter()
        .enumerate()
        .map(|(i, image)| EnrolFrame {
            name: format!("frame{i}"),
            image,
            landmarks: None,
        })
        .collect();
    let options = EnrolOptions {
        build: BuildOptions {
            name: "spk02-enrolled".into(),
            reference: facemimic::ReferenceChoice::Named("frame2".into()),
            ..BuildOptions::default()
        },
        select: Some(6),
        ..EnrolOptions::default()
    };
    let core = enrol(frames, &options, None, None, &mut |_| true).expect("enrol");
    assert_eq!(core.images.len(), 6, "6 frames kept");
    assert!(core.used.contains(&2), "the reference frame is kept");
    assert!(core.model.backdrop().is_some(), "a default backdrop");

    let a = shell.to_bytes().map_err(JsValue::from).expect("toBytes");
    let b = write_model_checked(&core.model).expect("write");
    assert_eq!(a.len(), b.len(), "model files of different lengths");
    assert!(a == b, "buildModel and enrol give different models");
}

//! The nets against TensorFlow.js: raw outputs of face-api.js's own code on the same inputs
//! (`scripts/finder-reference.mjs`), for GRID frames (`tests/data/finder/README.md`). The inputs
//! are made by `cargo run --example finder_data -- inputs`.

use super::nets::{Detector, LandmarkNet, Scratch, DETECTOR_MEAN, LANDMARK_MEAN};
use super::nn::Map;
use super::{DETECTOR_WEIGHTS, LANDMARK_WEIGHTS};

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/finder");

fn input(name: &str, n: usize, mean: [f32; 3]) -> Map {
    let bytes = std::fs::read(format!("{DIR}/{name}.rgb")).unwrap();
    assert_eq!(bytes.len(), n * n * 3);
    Map {
        h: n,
        w: n,
        c: 3,
        data: bytes
            .iter()
            .enumerate()
            .map(|(i, &b)| (b as f32 - mean[i % 3]) / 255.0)
            .collect(),
    }
}

fn reference(name: &str) -> (Vec<usize>, Vec<f32>) {
    let text = std::fs::read_to_string(format!("{DIR}/{name}.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let shape = v["shape"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_u64().unwrap() as usize)
        .collect();
    let data = v["data"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_f64().unwrap() as f32)
        .collect();
    (shape, data)
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn detector_grid_matches_tfjs() {
    let det = Detector::load(DETECTOR_WEIGHTS).unwrap();
    let x = input("grid-detector-160", 160, DETECTOR_MEAN);
    let mut out = Map::default();
    det.run(&x, &mut Scratch::default(), &mut out);
    let (shape, want) = reference("grid-detector-160");
    assert_eq!(shape, vec![1, out.h, out.w, out.c]);
    let d = max_abs_diff(&out.data, &want);
    let range = want.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    assert!(
        d < 1e-3 * range.max(1.0),
        "max |diff| {d} (outputs up to {range})"
    );
}

#[test]
fn landmark_outputs_match_tfjs() {
    let net = LandmarkNet::load(LANDMARK_WEIGHTS).unwrap();
    let mut s = Scratch::default();
    for name in ["grid-landmark-a-112", "grid-landmark-b-112"] {
        let x = input(name, 112, LANDMARK_MEAN);
        let mut out = [0.0; 136];
        net.run(&x, &mut s, &mut out);
        let (shape, want) = reference(name);
        assert_eq!(shape, vec![1, 136]);
        let d = max_abs_diff(&out, &want);
        // Outputs are fractions of the 112-pixel input: 1e-4 is a hundredth of a pixel.
        assert!(d < 1e-4, "{name}: max |diff| {d}");
    }
}

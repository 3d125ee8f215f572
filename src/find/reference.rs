//! The nets against their reference runtime: MediaPipe's TFLite files run by the TFLite
//! interpreter on the same inputs (`scripts/mediapipe-reference.py`), for GRID frames
//! (`tests/data/finder/README.md`).

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/finder");

fn json(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(format!("{DIR}/{name}.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The items of the JSON array `v`, each read by `item`.
fn array<T>(v: &serde_json::Value, item: impl Fn(&serde_json::Value) -> T) -> Vec<T> {
    v.as_array().unwrap().iter().map(item).collect()
}

fn floats(v: &serde_json::Value) -> Vec<f32> {
    array(v, |d| d.as_f64().unwrap() as f32)
}

fn sizes(v: &serde_json::Value) -> Vec<usize> {
    array(v, |d| d.as_u64().unwrap() as usize)
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// MediaPipe's nets against the TFLite interpreter (`scripts/mediapipe-reference.py`): every
/// layer's mean, largest magnitude and 16 sampled values, then the final outputs, with the
/// float16 weights TFLite computes with; then the shipped int8 weights' final outputs
/// (`scripts/quantise-fmw.py`), within measured bounds.
mod mediapipe {
    use super::super::graph::{Graph, GraphScratch};
    use super::super::mesh::{
        MeshNets, BLAZEFACE_WEIGHTS, BLAZEFACE_WEIGHTS_F16, DETECTOR_INPUT, MESH_INPUT,
        MESH_WEIGHTS, MESH_WEIGHTS_F16,
    };
    use super::{floats, json, max_abs_diff, sizes, DIR};

    /// Runs `graph` on the fixture `name` (`norm` maps a byte to the net's input) and checks
    /// every layer; returns the worst difference relative to the layer's largest magnitude.
    fn check_layers(
        graph: &Graph,
        name: &str,
        n: usize,
        norm: impl Fn(u8) -> f32,
    ) -> (GraphScratch, serde_json::Value) {
        let want = json(name);
        let layers = want["layers"].as_array().unwrap();
        assert_eq!(layers.len(), graph.slots.len(), "{name}: layer count");
        let mut s = fixture(name, n, norm);
        let mut worst = (0.0f32, 0);
        graph
            .run(&mut s, |i, y| {
                let l = &layers[i];
                let shape = sizes(&l["shape"]);
                // Shapes are [h, w, c] (or, for none here, fewer dims).
                assert_eq!(
                    y.data.len(),
                    shape.iter().product::<usize>(),
                    "{name} layer {i}"
                );
                let max_abs = l["max_abs"].as_f64().unwrap() as f32;
                let scale = max_abs.max(1e-3);
                let got_max = y.data.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                let mean = y.data.iter().map(|&v| v as f64).sum::<f64>() / y.data.len() as f64;
                let mut d = (got_max - max_abs).abs();
                d = d.max((mean as f32 - l["mean"].as_f64().unwrap() as f32).abs());
                let idx = l["index"].as_array().unwrap();
                for (k, v) in idx.iter().zip(floats(&l["values"])) {
                    d = d.max((y.data[k.as_u64().unwrap() as usize] - v).abs());
                }
                if d / scale > worst.0 {
                    worst = (d / scale, i);
                }
                // Float32 throughout, other summation orders: measured under 1e-6 of the range.
                assert!(
                    d <= 1e-5 * scale,
                    "{name} layer {i}: off by {d} (largest magnitude {max_abs})"
                );
            })
            .unwrap();
        eprintln!(
            "{name}: {} layers, worst {:.2e} of the layer's range (layer {})",
            layers.len(),
            worst.0,
            worst.1
        );
        (s, want)
    }

    #[test]
    fn blazeface_matches_tflite_layer_by_layer() {
        let nets = MeshNets::load(BLAZEFACE_WEIGHTS_F16, MESH_WEIGHTS_F16).unwrap();
        let (det, _) = nets.graphs();
        let (s, want) = check_layers(det, "mp-detector-128", DETECTOR_INPUT, |b| {
            b as f32 / 127.5 - 1.0
        });
        let cls = outputs(&s, det, [2, 3]);
        let want_cls = floats(&want["scores"]);
        assert_eq!(cls.len(), 896);
        let d = max_abs_diff(&cls, &want_cls);
        assert!(d < 1e-3, "score logits off by {d}");
        let reg = outputs(&s, det, [0, 1]);
        let rows = want["regressions"].as_object().unwrap();
        assert!(!rows.is_empty(), "the reference finds the face");
        for (i, v) in rows {
            let i: usize = i.parse().unwrap();
            for (a, b) in reg[i * 16..][..16].iter().zip(floats(v)) {
                // In pixels of the 128-pixel input.
                assert!((a - b).abs() < 1e-3, "anchor {i}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn face_mesh_matches_tflite_layer_by_layer() {
        let nets = MeshNets::load(BLAZEFACE_WEIGHTS_F16, MESH_WEIGHTS_F16).unwrap();
        let (_, mesh) = nets.graphs();
        for name in ["mp-mesh-a-192", "mp-mesh-b-192"] {
            let (s, want) = check_layers(mesh, name, MESH_INPUT, |b| b as f32 / 255.0);
            let lm = &s.output(mesh, 0).data;
            let want_lm = floats(&want["landmarks"]);
            let d = max_abs_diff(lm, &want_lm);
            // In pixels of the 192-pixel crop: a thousandth of a pixel.
            assert!(d < 1e-3, "{name}: points off by {d} px");
            let face = s.output(mesh, 1).data[0];
            let want_face = want["face"].as_f64().unwrap() as f32;
            assert!(
                (face - want_face).abs() < 1e-3,
                "{name}: face logit {face} vs {want_face}"
            );
            assert!(want_face > 5.0, "the fixture is a face");
        }
    }

    /// Scratch holding the fixture `name` (`n x n` RGB bytes) as the net's input, each byte
    /// mapped by `norm`.
    fn fixture(name: &str, n: usize, norm: impl Fn(u8) -> f32) -> GraphScratch {
        let bytes = std::fs::read(format!("{DIR}/{name}.rgb")).unwrap();
        assert_eq!(bytes.len(), n * n * 3);
        let mut s = GraphScratch::default();
        let x = s.input();
        x.reset(n, n, 3);
        for (o, &b) in x.data.iter_mut().zip(&bytes) {
            *o = norm(b);
        }
        s
    }

    /// Runs `graph` on the fixture `name` (no layer checks).
    fn run(graph: &Graph, name: &str, n: usize, norm: impl Fn(u8) -> f32) -> GraphScratch {
        let mut s = fixture(name, n, norm);
        graph.run(&mut s, |_, _| {}).unwrap();
        s
    }

    /// The graph's outputs `ks`, one after the other (the detector's two score or two
    /// regression maps).
    fn outputs<const N: usize>(s: &GraphScratch, graph: &Graph, ks: [usize; N]) -> Vec<f32> {
        ks.iter()
            .flat_map(|&k| s.output(graph, k).data.iter().copied())
            .collect()
    }

    fn sigmoid(x: f32) -> f32 {
        1.0 / (1.0 + (-x).exp())
    }

    /// The shipped detector (int8 filters but op77, op81 and op83, see
    /// `scripts/quantise-fmw.py`) against TFLite's float16 net. Measured: the face's anchors'
    /// score logits off by 0.134 (logits 1.6 to 3.2), every anchor's score (after the sigmoid)
    /// by 0.015, the face's anchors' boxes and keypoints by 0.563 px of the 128-pixel input.
    /// (Far from the face the logits differ by up to 7, e.g. -47 for -55: scores of 1e-21.)
    /// The bounds are about twice those.
    #[test]
    fn int8_blazeface_stays_near_tflite() {
        let nets = MeshNets::load(BLAZEFACE_WEIGHTS, MESH_WEIGHTS).unwrap();
        let (det, _) = nets.graphs();
        let name = "mp-detector-128";
        let s = run(det, name, DETECTOR_INPUT, |b| b as f32 / 127.5 - 1.0);
        let want = json(name);
        let cls = outputs(&s, det, [2, 3]);
        let want_cls = floats(&want["scores"]);
        assert_eq!(cls.len(), want_cls.len());
        let d_score = cls
            .iter()
            .zip(&want_cls)
            .map(|(&a, &b)| (sigmoid(a) - sigmoid(b)).abs())
            .fold(0.0f32, f32::max);
        let reg = outputs(&s, det, [0, 1]);
        let rows = want["regressions"].as_object().unwrap();
        assert!(!rows.is_empty(), "the reference finds the face");
        let (mut d_face, mut d_reg) = (0.0f32, 0.0f32);
        for (i, v) in rows {
            let i: usize = i.parse().unwrap();
            d_face = d_face.max((cls[i] - want_cls[i]).abs());
            d_reg = d_reg.max(max_abs_diff(&reg[i * 16..][..16], &floats(v)));
        }
        eprintln!(
            "{name} int8: the face's score logits off by {d_face}, scores by {d_score}, the \
             face's boxes and keypoints by {d_reg} px"
        );
        assert!(d_face < 0.3, "the face's score logits off by {d_face}");
        assert!(d_score < 0.03, "scores off by {d_score}");
        assert!(
            d_reg < 1.2,
            "the face's boxes and keypoints off by {d_reg} px"
        );
    }

    /// The shipped face mesh (every filter int8) against TFLite's float16 net. Measured on the
    /// two fixtures: points (x, y) off by 0.119 and 0.142 px of the 192-pixel crop on average,
    /// 0.363 and 0.369 px at most; z by 0.425 and 0.397 at most; the face logit (24.5 and 23.8)
    /// by 0.11 and 0.23. Half of the points' deviation is the output layer's (op96). The bounds
    /// are about twice those.
    #[test]
    fn int8_face_mesh_stays_near_tflite() {
        let nets = MeshNets::load(BLAZEFACE_WEIGHTS, MESH_WEIGHTS).unwrap();
        let (_, mesh) = nets.graphs();
        for name in ["mp-mesh-a-192", "mp-mesh-b-192"] {
            let s = run(mesh, name, MESH_INPUT, |b| b as f32 / 255.0);
            let want = json(name);
            let lm = &s.output(mesh, 0).data;
            let want_lm = floats(&want["landmarks"]);
            assert_eq!(lm.len(), want_lm.len());
            let pairs = || lm.chunks_exact(3).zip(want_lm.chunks_exact(3));
            let dist: Vec<f32> = pairs()
                .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
                .collect();
            let worst = dist.iter().fold(0.0f32, |m, &d| m.max(d));
            let mean = dist.iter().sum::<f32>() / dist.len() as f32;
            let dz = pairs()
                .map(|(a, b)| (a[2] - b[2]).abs())
                .fold(0.0f32, f32::max);
            let face = s.output(mesh, 1).data[0];
            let want_face = want["face"].as_f64().unwrap() as f32;
            eprintln!(
                "{name} int8: points off by {mean} px on average, {worst} px at most, z by \
                 {dz}; face logit {face} vs {want_face}"
            );
            assert!(mean < 0.25, "{name}: points off by {mean} px on average");
            assert!(worst < 0.75, "{name}: a point off by {worst} px");
            assert!(dz < 0.85, "{name}: z off by {dz}");
            assert!(
                (face - want_face).abs() < 0.5,
                "{name}: face logit {face} vs {want_face}"
            );
        }
    }
}

//! Choosing varied frames (farthest-point sampling of aligned shapes), build progress and
//! cancelling. Runs natively and under Node (wasm).

use facemimic::{
    coverage, select_varied, BuildOptions, Builder, Error, FrameChoice, Image, Similarity,
    TrainingImage,
};
use wasm_bindgen_test::wasm_bindgen_test;

/// A 10-point shape: a base outline with mode `k` (0, 1, 2) moved by `amount`, then posed.
fn shape(k: usize, amount: f32, pose: Similarity) -> Vec<f32> {
    let mut s: Vec<f32> = (0..10)
        .flat_map(|i| {
            let a = i as f32 / 10.0 * std::f32::consts::TAU;
            [30.0 * a.cos(), 40.0 * a.sin()]
        })
        .collect();
    for (i, v) in s.iter_mut().enumerate() {
        // Three different deformations (distinct point sets move).
        let moved = match k {
            0 => i == 1 || i == 3,
            1 => i == 8 || i == 10,
            _ => i == 15 || i == 17,
        };
        if moved {
            *v += amount;
        }
    }
    pose.apply_in_place(&mut s);
    s
}

/// Three clusters of nearly identical shapes (each in many poses): three picks take one from
/// each cluster, whatever the poses; choices are distinct and deterministic.
#[wasm_bindgen_test(unsupported = test)]
fn picks_one_of_each_cluster_whatever_the_pose() {
    let mut shapes = Vec::new();
    let mut cluster = Vec::new();
    for i in 0..30usize {
        let k = i % 3;
        let pose = Similarity::from_parts(
            0.5 + i as f32 * 0.05,
            0.02 * i as f32,
            100.0 + i as f32,
            50.0,
        );
        shapes.push(shape(k, 6.0 + 0.01 * i as f32, pose));
        cluster.push(k);
    }
    let refs: Vec<&[f32]> = shapes.iter().map(Vec::as_slice).collect();
    let pick = select_varied(&refs, 3).unwrap();
    let mut ks: Vec<usize> = pick.iter().map(|&i| cluster[i]).collect();
    ks.sort_unstable();
    assert_eq!(ks, vec![0, 1, 2], "picked {pick:?}");
    assert_eq!(select_varied(&refs, 3).unwrap(), pick, "deterministic");
    let all = select_varied(&refs, 100).unwrap();
    let mut sorted = all.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..30).collect::<Vec<_>>());
    // Coverage grows with the choice and is 1 for all of them.
    let c1 = coverage(&refs, &pick[..1]).unwrap();
    let c3 = coverage(&refs, &pick).unwrap();
    assert!(c3 > c1 && c3 > 0.9, "coverage {c1} -> {c3}");
    assert_eq!(coverage(&refs, &all).unwrap(), 1.0);
}

#[wasm_bindgen_test(unsupported = test)]
fn bad_shapes_are_errors() {
    let a = shape(0, 1.0, Similarity::IDENTITY);
    let short = vec![1.0f32; 4];
    let nan = vec![f32::NAN; a.len()];
    assert!(select_varied(&[], 2).is_err());
    assert!(select_varied(&[&a, &short], 2).is_err());
    assert!(select_varied(&[&a, &nan], 2).is_err());
    assert!(coverage(&[&a], &[]).is_err());
    assert!(coverage(&[&a], &[3]).is_err());
}

/// Progress is reported once per step, and returning false cancels with no model.
#[wasm_bindgen_test(unsupported = test)]
fn progress_and_cancel() {
    let images: Vec<TrainingImage> = (0..5)
        .map(|i| {
            let lm = shape(
                i % 3,
                3.0 * i as f32,
                Similarity::from_parts(1.0, 0.0, 60.0, 60.0),
            );
            TrainingImage {
                name: format!("f{i}"),
                image: Image {
                    width: 120,
                    height: 120,
                    data: (0..120 * 120 * 4)
                        .map(|k| ((k * 7 + i * 13) % 251) as u8)
                        .collect(),
                },
                landmarks: lm,
            }
        })
        .collect();
    let b = Builder::new(BuildOptions {
        frame: FrameChoice::Own,
        face_width: 40.0,
        ..BuildOptions::default()
    });
    let mut seen = Vec::new();
    b.build_with_progress(&images, None, &mut |p| {
        seen.push((p.done, p.total));
        true
    })
    .unwrap();
    assert_eq!(seen, (1..=7).map(|d| (d, 7)).collect::<Vec<_>>());
    let r = b.build_with_progress(&images, None, &mut |p| p.done < 3);
    assert!(matches!(r, Err(Error::Cancelled)), "{r:?}");
}

//! Expression cloning: the eight tests of the issue plus gain, pose, validation and
//! reference-expression tests. Every numeric test runs natively (`cargo test`) and under Node
//! (`cargo test --target wasm32-unknown-unknown`) on small synthetic models built in memory;
//! the real-data test (GRID) is native only.

use facemimic_testkit as common;

use common::Rng;
use facemimic::clone::{
    add_residual, apply_gains, constrain, inner_products, map_params, map_shape,
    residual_directions, CloneOptions, Cloner, Method, Pair,
};
use facemimic::numerics::synthesise;
use facemimic::{
    AppearanceModel, BuildOptions, Builder, Error, Image, LandmarkScheme, Model, ModelParts,
    Params, Reference, ReferenceChoice, ReferenceFrame, ShapeModel, Similarity, TrainingImage,
};
use wasm_bindgen_test::wasm_bindgen_test;

// ---------------------------------------------------------------------------------------
// Synthetic models.

/// Gram-Schmidt (in f64) of `k` rows of length `dim`, orthonormal on return.
fn orthonormalise(rows: &[f32], dim: usize) -> Vec<f32> {
    let mut out: Vec<Vec<f64>> = Vec::new();
    for r in rows.chunks_exact(dim) {
        let mut v: Vec<f64> = r.iter().map(|&x| x as f64).collect();
        for _ in 0..2 {
            for u in &out {
                let d: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(a, b)| *a -= d * b);
            }
        }
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.iter_mut().for_each(|x| *x /= n);
        out.push(v);
    }
    out.into_iter().flatten().map(|x| x as f32).collect()
}

/// A 12-landmark face-ish base shape about 40 model units wide.
fn base_shape() -> Vec<f32> {
    let mut s = Vec::new();
    for k in 0..10 {
        let a = k as f32 / 10.0 * std::f32::consts::TAU;
        s.push(20.0 * a.cos());
        s.push(24.0 * a.sin());
    }
    s.extend_from_slice(&[-6.0, 2.0, 7.0, -3.0]);
    s
}

/// A synthetic model: `m` shape modes, `l` appearance modes, random orthonormal bases, on
/// `frame` (or its own frame when `None`).
fn synthetic(name: &str, seed: u64, m: usize, l: usize, frame: Option<&ReferenceFrame>) -> Model {
    Model::new(synthetic_parts(name, seed, m, l, frame)).unwrap()
}

/// The parts of [`synthetic`] (unchecked: a test may take one of them alone).
fn synthetic_parts(
    name: &str,
    seed: u64,
    m: usize,
    l: usize,
    frame: Option<&ReferenceFrame>,
) -> ModelParts {
    let mut rng = Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    let mut base = base_shape();
    let frame = match frame {
        Some(f) => {
            // Another person in the same frame: a slightly different base shape.
            base.iter_mut().for_each(|v| *v += 0.8 * rng.sym());
            f.clone()
        }
        None => ReferenceFrame::from_base(&base).unwrap(),
    };
    let d = base.len();
    let da = frame.n_pixels() * 3;
    let shape = ShapeModel(facemimic::LinearModel {
        base,
        modes: orthonormalise(&rng.vec(m * d), d),
        variances: (0..m).map(|i| 9.0 / (1.0 + i as f32)).collect(),
    });
    let appearance = AppearanceModel::new(
        (0..da).map(|_| 0.5 + 0.3 * rng.sym()).collect(),
        orthonormalise(&rng.vec(l * da), da),
        (0..l).map(|i| 4.0 / (1.0 + i as f32)).collect(),
    );
    ModelParts {
        name: name.into(),
        scheme: LandmarkScheme::for_count(d / 2),
        shape,
        appearance,
        frame,
        reference: Reference::Mean,
        mean_pose: Similarity::from_parts(1.5 + 0.1 * rng.sym(), 0.05 * rng.sym(), 90.0, 70.0),
        image_size: [200, 160],
    }
}

/// Random parameters for `model`, each about `spread` sigmas, at a pose near its mean pose.
fn random_params(model: &Model, seed: u64, spread: f32) -> Params {
    let mut rng = Rng(seed | 1);
    let mut draw = |sigmas: Vec<f32>| sigmas.iter().map(|s| spread * s * rng.sym()).collect();
    let shape = draw(model.shape().sigmas());
    let appearance = draw(model.appearance().sigmas());
    let pose = model.mean_pose().compose(&Similarity::from_parts(
        1.0 + 0.1 * rng.sym(),
        0.2 * rng.sym(),
        5.0 * rng.sym(),
        3.0 * rng.sym(),
    ));
    Params {
        pose,
        shape,
        appearance,
    }
}

/// The source's own instance: posed shape (image coordinates) and appearance.
fn instance(model: &Model, params: &Params) -> (Vec<f32>, Vec<f32>) {
    let mut s = vec![0.0; model.shape().base.len()];
    model.image_shape(params, &mut s).unwrap();
    let mut a = vec![0.0; model.appearance().len()];
    model
        .appearance()
        .instance(&params.appearance, &mut a)
        .unwrap();
    (s, a)
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// A synthetic source (`seed`; `modes`: shape and appearance), a target in its frame (`seed + 1`,
/// `target_modes`) and a cloner of the pair.
fn source_target(
    seed: u64,
    modes: (usize, usize),
    target_modes: (usize, usize),
) -> (Model, Model, Cloner) {
    let source = synthetic("src", seed, modes.0, modes.1, None);
    let (m, l) = target_modes;
    let target = synthetic("tgt", seed + 1, m, l, Some(source.frame()));
    let c = one_target(&source, &target);
    (source, target, c)
}

fn opts(method: Method, clamp: Option<f32>, follow_pose: bool) -> CloneOptions {
    CloneOptions {
        method,
        clamp,
        follow_pose,
        ..CloneOptions::default()
    }
}

fn one_target(source: &Model, target: &Model) -> Cloner {
    let mut c = Cloner::new(source.clone()).unwrap();
    c.add_target(target.clone()).unwrap();
    c
}

/// A model whose shape and appearance modes are `Q` times the source's (same span), with the
/// same bases and pose, and variances carried along (`var*_j = sum_i Q_ji^2 var_i`).
fn remixed(source: &Model, q_shape: &[f32], q_app: &[f32]) -> Model {
    let mix = |modes: &[f32], dim: usize, q: &[f32], var: &[f32]| -> (Vec<f32>, Vec<f32>) {
        let k = var.len();
        let mut out = vec![0f32; k * dim];
        let mut v = vec![0f32; k];
        for j in 0..k {
            for i in 0..k {
                let c = q[j * k + i];
                v[j] += c * c * var[i];
                for x in 0..dim {
                    out[j * dim + x] += c * modes[i * dim + x];
                }
            }
        }
        (out, v)
    };
    let mut t = source.clone().into_parts();
    t.name = "remixed".into();
    let (m, v) = mix(
        &source.shape().modes,
        source.shape().base.len(),
        q_shape,
        &source.shape().variances,
    );
    t.shape.modes = m;
    t.shape.variances = v;
    let (base, modes, variances) = source.appearance().clone().into_arrays();
    let (m, v) = mix(&modes, base.len(), q_app, &variances);
    t.appearance = AppearanceModel::new(base, m, v);
    Model::new(t).unwrap()
}

fn permutation_with_signs(k: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed | 1);
    let mut perm: Vec<usize> = (0..k).collect();
    for i in (1..k).rev() {
        let j = ((rng.sym() + 1.0) * 0.5 * (i + 1) as f32) as usize % (i + 1);
        perm.swap(i, j);
    }
    let mut q = vec![0f32; k * k];
    for (j, &i) in perm.iter().enumerate() {
        q[j * k + i] = if rng.sym() < 0.0 { -1.0 } else { 1.0 };
    }
    q
}

// ---------------------------------------------------------------------------------------
// The tests.

/// Test 1: a model cloned onto itself with `map` or `map-residual` is the source instance
/// (R is the identity).
#[wasm_bindgen_test(unsupported = test)]
fn self_clone_map_is_identity() {
    let source = synthetic("src", 1, 6, 5, None);
    let mut c = one_target(&source, &source);
    let r = c.pair(0).unwrap().shape_map();
    for j in 0..6 {
        for i in 0..6 {
            let e = if i == j { 1.0 } else { 0.0 };
            assert!(
                (r[j * 6 + i] - e).abs() < 1e-6,
                "R[{j}][{i}] = {}",
                r[j * 6 + i]
            );
        }
    }
    assert!(c
        .pair(0)
        .unwrap()
        .residual_norms()
        .iter()
        .all(|&n| n < 1e-5));
    for seed in 1..4 {
        // Within the constraint, so the clamp changes nothing.
        let params = random_params(&source, seed, 1.0);
        let (s, a) = instance(&source, &params);
        for method in [Method::Map, Method::MapResidual] {
            c.clone_frame(&params, &opts(method, Some(3.0), true))
                .unwrap();
            assert!(max_diff(c.target_shape(0), &s) < 2e-4, "{method}: shape");
            assert!(
                max_diff(c.target_appearance(0), &a) < 2e-5,
                "{method}: appearance"
            );
            assert!(max_diff(&c.target_params(0).shape, &params.shape) < 1e-5);
            assert!(max_diff(&c.target_params(0).appearance, &params.appearance) < 1e-5);
        }
    }
}

/// Test 2: a target whose basis is the source's with modes negated, permuted or mixed by any
/// orthogonal matrix (same span) gives back the source instance.
#[wasm_bindgen_test(unsupported = test)]
fn same_span_any_signs_order_or_mixing() {
    let source = synthetic("src", 2, 5, 4, None);
    let mut rng = Rng(77);
    let negate = |k: usize| -> Vec<f32> {
        (0..k * k)
            .map(|x| {
                if x % (k + 1) == 0 {
                    if (x / k) % 2 == 0 {
                        -1.0
                    } else {
                        1.0
                    }
                } else {
                    0.0
                }
            })
            .collect()
    };
    let cases: Vec<(&str, Vec<f32>, Vec<f32>)> = vec![
        ("negated", negate(5), negate(4)),
        (
            "permuted and negated",
            permutation_with_signs(5, 3),
            permutation_with_signs(4, 4),
        ),
        (
            "orthogonal mix",
            orthonormalise(&rng.vec(25), 5),
            orthonormalise(&rng.vec(16), 4),
        ),
    ];
    for (what, qs, qa) in cases {
        let target = remixed(&source, &qs, &qa);
        let mut c = one_target(&source, &target);
        let params = random_params(&source, 11, 1.5);
        let (s, a) = instance(&source, &params);
        for method in [Method::Map, Method::MapResidual] {
            c.clone_frame(&params, &opts(method, None, true)).unwrap();
            let ds = max_diff(c.target_shape(0), &s);
            let da = max_diff(c.target_appearance(0), &a);
            assert!(
                ds < 2e-4 && da < 2e-5,
                "{what}, {method}: shape {ds}, appearance {da}"
            );
        }
        // The mapped parameters are Q p: the target describes the same face in its own basis.
        c.clone_frame(&params, &opts(Method::Map, None, false))
            .unwrap();
        let mut qp = vec![0.0; 5];
        map_params(&qs, &params.shape, &mut qp);
        assert!(
            max_diff(&c.target_params(0).shape, &qp) < 1e-5,
            "{what}: p* = Q p"
        );
    }
}

/// Test 3: without the constraint, `map-residual`'s shape displacement equals the source's
/// displacement, for a target whose span does not contain the source's; `map` alone does not.
#[wasm_bindgen_test(unsupported = test)]
fn residual_restores_the_source_displacement() {
    let (source, target, mut c) = source_target(3, (6, 4), (5, 4));
    assert!(
        c.pair(0).unwrap().residual_norms().iter().all(|&n| n > 0.1),
        "spans must differ"
    );
    let id = CloneOptions {
        follow_pose: false,
        clamp: None,
        ..CloneOptions::default()
    };
    for seed in 1..4 {
        let params = random_params(&source, seed, 2.0);
        let mut src_disp = vec![0.0; source.shape().base.len()];
        source
            .shape()
            .instance(&params.shape, &mut src_disp)
            .unwrap();
        src_disp
            .iter_mut()
            .zip(&source.shape().base)
            .for_each(|(d, b)| *d -= b);
        let inv = target.mean_pose().inverse().unwrap();
        let disp = |c: &Cloner| -> Vec<f32> {
            let mut s = c.target_shape(0).to_vec();
            inv.apply_in_place(&mut s);
            s.iter()
                .zip(&target.shape().base)
                .map(|(a, b)| a - b)
                .collect()
        };
        c.clone_frame(
            &params,
            &CloneOptions {
                method: Method::MapResidual,
                ..id.clone()
            },
        )
        .unwrap();
        let scale = src_disp.iter().fold(1f32, |m, v| m.max(v.abs()));
        let err = max_diff(&disp(&c), &src_disp);
        // 1e-6 relative to the displacement, plus the f32 rounding of posing and unposing
        // coordinates of ~100 pixels.
        assert!(
            err <= 1e-6 * scale + 3e-5,
            "map-residual displacement off by {err}"
        );
        c.clone_frame(
            &params,
            &CloneOptions {
                method: Method::Map,
                ..id.clone()
            },
        )
        .unwrap();
        let err = max_diff(&disp(&c), &src_disp);
        assert!(
            err > 0.1,
            "map alone should under-articulate (off by {err})"
        );
    }
    // The same identity at the level of the named functions, without any pose.
    let d = source.shape().base.len();
    let r = inner_products(&target.shape().modes, &source.shape().modes, d);
    let delta = residual_directions(&target.shape().modes, &source.shape().modes, d);
    let p = [1.5f32, -2.0, 0.5, 3.0, -1.0, 0.25];
    let mut mapped = vec![0.0; 5];
    map_params(&r, &p, &mut mapped);
    let mut acc = vec![0f64; d];
    map_shape(&vec![0.0; d], &target.shape().modes, &mapped, &mut acc);
    add_residual(&delta, &p, &mut acc);
    let mut direct = vec![0f32; d];
    synthesise(&vec![0.0; d], &source.shape().modes, &p, &mut direct);
    for (a, b) in acc.iter().zip(&direct) {
        assert!((*a as f32 - b).abs() < 1e-5, "{a} vs {b}");
    }
}

/// Test 4: with the constraint, every mapped parameter is within `+-k sigma*` (and the
/// constraint is active, i.e. some parameters would exceed it).
#[wasm_bindgen_test(unsupported = test)]
fn constraint_bounds_every_mapped_parameter() {
    let (source, target, mut c) = source_target(5, (6, 5), (4, 3));
    let (ss, sa) = (target.shape().sigmas(), target.appearance().sigmas());
    for &k in &[0.5f32, 1.0, 3.0] {
        let mut clipped = 0;
        for seed in 1..6 {
            let params = random_params(&source, seed, 40.0);
            c.clone_frame(&params, &opts(Method::Map, None, false))
                .unwrap();
            let free = c.target_params(0).clone();
            for method in [Method::Map, Method::MapResidual] {
                c.clone_frame(&params, &opts(method, Some(k), false))
                    .unwrap();
                let t = c.target_params(0);
                for (j, (&p, &s)) in t.shape.iter().zip(&ss).enumerate() {
                    assert!(
                        p.abs() <= k * s * (1.0 + 1e-6),
                        "{method} k={k}: p*[{j}] = {p}, limit {}",
                        k * s
                    );
                    if free.shape[j].abs() > k * s {
                        clipped += 1;
                        assert_eq!(p, (k * s).copysign(free.shape[j]));
                    } else {
                        assert_eq!(p, free.shape[j]);
                    }
                }
                for (j, (&p, &s)) in t.appearance.iter().zip(&sa).enumerate() {
                    assert!(
                        p.abs() <= k * s * (1.0 + 1e-6),
                        "{method} k={k}: lambda*[{j}] = {p}"
                    );
                }
            }
        }
        assert!(
            clipped > 0,
            "k = {k}: the test never exercised the constraint"
        );
    }
}

/// Test 5: `substitute` onto the source itself is the source instance.
#[wasm_bindgen_test(unsupported = test)]
fn substitute_onto_itself_is_the_source_instance() {
    let source = synthetic("src", 7, 5, 4, None);
    let mut c = one_target(&source, &source);
    for (seed, clamp) in [(1, None), (2, Some(3.0)), (3, None)] {
        let params = random_params(&source, seed, 1.0);
        let (s, a) = instance(&source, &params);
        c.clone_frame(&params, &opts(Method::Substitute, clamp, true))
            .unwrap();
        assert!(max_diff(c.target_shape(0), &s) < 2e-4);
        // Same function, same order of summation: bit-identical appearance.
        assert_eq!(c.target_appearance(0), &a[..]);
    }
}

/// Test 5b: `substitute` onto another target uses the target's bases with the SOURCE's modes.
#[wasm_bindgen_test(unsupported = test)]
fn substitute_uses_target_bases_and_source_modes() {
    let (source, target, mut c) = source_target(8, (4, 3), (5, 6));
    let params = random_params(&source, 5, 1.0);
    c.clone_frame(&params, &opts(Method::Substitute, None, false))
        .unwrap();
    let mut s = vec![0.0; target.shape().base.len()];
    synthesise(
        &target.shape().base,
        &source.shape().modes,
        &params.shape,
        &mut s,
    );
    target.mean_pose().apply_in_place(&mut s);
    assert!(max_diff(c.target_shape(0), &s) < 1e-4);
    let mut a = vec![0.0; target.appearance().len()];
    source
        .appearance()
        .instance_on(target.appearance().base(), &params.appearance, &mut a);
    assert_eq!(c.target_appearance(0), &a[..]);
    // target_params holds the projection onto the target model: R p, Ra lambda.
    let pair = c.pair(0).unwrap();
    let mut rp = vec![0.0; 5];
    map_params(pair.shape_map(), &params.shape, &mut rp);
    assert_eq!(c.target_params(0).shape, rp);
}

/// Test 6: one source onto N targets equals N single-pair calls (bit for bit), for every
/// method, and the targets differ from each other.
#[wasm_bindgen_test(unsupported = test)]
fn many_targets_equal_single_pairs() {
    let source = synthetic("src", 10, 6, 5, None);
    let targets: Vec<Model> = (0..4)
        .map(|k| {
            synthetic(
                &format!("t{k}"),
                20 + k,
                3 + k as usize,
                2 + k as usize,
                Some(source.frame()),
            )
        })
        .collect();
    let mut all = Cloner::new(source.clone()).unwrap();
    for t in &targets {
        all.add_target(t.clone()).unwrap();
    }
    assert_eq!(all.n_targets(), 4);
    let mut singles: Vec<Cloner> = targets.iter().map(|t| one_target(&source, t)).collect();
    for method in Method::ALL {
        for seed in 1..3 {
            let o = CloneOptions {
                method,
                gain: 1.3,
                shape_gains: vec![1.0, 0.5],
                follow_pose: seed == 2,
                ..CloneOptions::default()
            };
            let params = random_params(&source, seed, 2.5);
            all.clone_frame(&params, &o).unwrap();
            for (i, s) in singles.iter_mut().enumerate() {
                s.clone_frame(&params, &o).unwrap();
                assert_eq!(
                    all.target_shape(i),
                    s.target_shape(0),
                    "{method} target {i}"
                );
                assert_eq!(all.target_appearance(i), s.target_appearance(0));
                assert_eq!(all.target_params(i), s.target_params(0));
            }
            assert!(max_diff(all.target_shape(0), all.target_shape(1)) > 0.1);
        }
    }
}

/// Test 8: incompatible pairs are refused with `Error::Incompatible` naming what differs;
/// failed calls change nothing.
#[wasm_bindgen_test(unsupported = test)]
fn incompatible_pairs_are_refused() {
    let source = synthetic("src", 12, 4, 3, None);
    // Different landmark count.
    let mut other = synthetic("eleven", 13, 4, 3, None).into_parts();
    other.shape.base.truncate(22);
    other.shape.modes = orthonormalise(&Rng(5).vec(4 * 22), 22);
    other.scheme = LandmarkScheme::for_count(11);
    other.frame = ReferenceFrame::from_base(&other.shape.base).unwrap();
    other.appearance = synthetic_parts("x", 1, 1, 3, Some(&other.frame)).appearance;
    let other = Model::new(other).unwrap();
    let mut c = Cloner::new(source.clone()).unwrap();
    match c.add_target(other.clone()) {
        Err(Error::Incompatible(m)) => {
            assert!(m.contains("12 landmarks") && m.contains("11"), "{m}")
        }
        r => panic!("expected Incompatible, got {r:?}"),
    }
    // Same landmark count, another frame (its own).
    let own = synthetic("own-frame", 14, 4, 3, None);
    let mut moved = own.clone().into_parts();
    moved.shape.base.iter_mut().for_each(|v| *v *= 1.2);
    moved.frame = ReferenceFrame::from_base(&moved.shape.base).unwrap();
    moved.appearance = synthetic_parts("y", 2, 1, 3, Some(&moved.frame)).appearance;
    let moved = Model::new(moved).unwrap();
    match c.add_target(moved.clone()) {
        Err(Error::Incompatible(m)) => assert!(
            m.contains("reference frames") && m.contains("fingerprints"),
            "{m}"
        ),
        r => panic!("expected Incompatible, got {r:?}"),
    }
    assert_eq!(c.n_targets(), 0);
    // A compatible target, then failing set_source / replace_target keep the old state.
    let good = synthetic("good", 15, 3, 2, Some(source.frame()));
    assert_eq!(c.add_target(good.clone()).unwrap(), 0);
    let params = random_params(&source, 3, 1.0);
    c.clone_frame(&params, &CloneOptions::default()).unwrap();
    let before = (c.target_shape(0).to_vec(), c.target_params(0).clone());
    assert!(matches!(
        c.set_source(moved.clone()),
        Err(Error::Incompatible(_))
    ));
    assert!(matches!(
        c.replace_target(0, other.clone()),
        Err(Error::Incompatible(_))
    ));
    assert_eq!(c.source().name(), "src");
    assert_eq!(c.target(0).name(), "good");
    assert_eq!(
        (c.target_shape(0).to_vec(), c.target_params(0).clone()),
        before
    );
    assert!(matches!(c.remove_target(3), Err(Error::Params(_))));
    assert!(matches!(
        c.replace_target(1, good.clone()),
        Err(Error::Params(_))
    ));
    assert!(c.get_target(1).is_none());
    // An internally inconsistent model is refused without a panic.
    // (a `Model` is checked when it is made, so the cloner never sees one).
    let mut broken = good.clone().into_parts();
    let (b, mut m, v) = broken.appearance.into_arrays();
    m.pop();
    broken.appearance = AppearanceModel::new(b, m, v);
    assert!(matches!(Model::new(broken), Err(Error::Incompatible(_))));
    // Compatible operations work.
    c.replace_target(0, synthetic("good2", 16, 2, 2, Some(source.frame())))
        .unwrap();
    assert_eq!(c.target(0).name(), "good2");
    assert_eq!(c.remove_target(0).unwrap().name(), "good2");
    assert_eq!(c.n_targets(), 0);
    c.add_target(good).unwrap();
    c.set_source(synthetic("src2", 17, 5, 5, Some(source.frame())))
        .unwrap();
    assert_eq!(c.source().name(), "src2");
    c.clone_frame(&random_params(c.source(), 1, 1.0), &CloneOptions::default())
        .unwrap();
}

// ---------------------------------------------------------------------------------------
// Gain, pose, validation.

/// Gain 0 gives the target's reference face for every method; gain 2 doubles the displacement
/// (no clamp); per-mode gains act per source mode.
#[wasm_bindgen_test(unsupported = test)]
fn gains() {
    let (source, target, mut c) = source_target(30, (5, 4), (4, 4));
    let params = random_params(&source, 9, 2.0);
    let mut base = target.shape().base.clone();
    target.mean_pose().apply_in_place(&mut base);
    for method in Method::ALL {
        c.clone_frame(
            &params,
            &CloneOptions {
                method,
                gain: 0.0,
                ..CloneOptions::default()
            },
        )
        .unwrap();
        assert!(max_diff(c.target_shape(0), &base) < 1e-4, "{method}");
        assert_eq!(c.target_appearance(0), target.appearance().base());
        let disp = |c: &Cloner| -> Vec<f32> {
            c.target_shape(0)
                .iter()
                .zip(&base)
                .map(|(a, b)| a - b)
                .collect()
        };
        c.clone_frame(
            &params,
            &CloneOptions {
                method,
                clamp: None,
                ..CloneOptions::default()
            },
        )
        .unwrap();
        let one = disp(&c);
        c.clone_frame(
            &params,
            &CloneOptions {
                method,
                clamp: None,
                gain: 2.0,
                ..CloneOptions::default()
            },
        )
        .unwrap();
        let two: Vec<f32> = disp(&c).iter().map(|v| v * 0.5).collect();
        assert!(max_diff(&one, &two) < 1e-4, "{method}: gain 2");
        // Per-mode gains: zeroing mode 0's gain equals zeroing p_0.
        let mut zeroed = params.clone();
        zeroed.shape[0] = 0.0;
        zeroed.appearance[1] = 0.0;
        c.clone_frame(&zeroed, &opts(method, Some(3.0), false))
            .unwrap();
        let expect = (c.target_shape(0).to_vec(), c.target_appearance(0).to_vec());
        let o = CloneOptions {
            method,
            shape_gains: vec![0.0],
            appearance_gains: vec![1.0, 0.0],
            ..CloneOptions::default()
        };
        c.clone_frame(&params, &o).unwrap();
        assert_eq!(
            (c.target_shape(0).to_vec(), c.target_appearance(0).to_vec()),
            expect
        );
    }
    let mut out = [0.0; 3];
    apply_gains(&[1.0, 2.0, 3.0], 2.0, &[0.5], &mut out);
    assert_eq!(out, [1.0, 4.0, 6.0]);
    let mut p = [5.0, -5.0, 0.5];
    constrain(&mut p, &[1.0, 2.0, 1.0], 3.0);
    assert_eq!(p, [3.0, -5.0, 0.5]);
}

/// Pose: `follow_pose = false` keeps the target at its mean pose; `true` applies the source's
/// pose relative to the source's mean pose around the target's mean pose.
#[wasm_bindgen_test(unsupported = test)]
fn pose_follows_or_stays() {
    let (source, target, mut c) = source_target(40, (3, 2), (3, 2));
    let rel = Similarity::from_parts(1.2, 0.3, 4.0, -2.0);
    let mut params = source.base_params();
    params.pose = source.mean_pose().compose(&rel);
    c.clone_frame(&params, &opts(Method::Map, None, false))
        .unwrap();
    let mut expect = target.shape().base.clone();
    target.mean_pose().apply_in_place(&mut expect);
    assert!(max_diff(c.target_shape(0), &expect) < 1e-4);
    assert_eq!(c.target_params(0).pose, target.mean_pose());
    c.clone_frame(&params, &opts(Method::Map, None, true))
        .unwrap();
    let want = target.mean_pose().compose(&rel);
    let got = c.target_params(0).pose;
    for (a, b) in [
        (got.a, want.a),
        (got.b, want.b),
        (got.tx, want.tx),
        (got.ty, want.ty),
    ] {
        assert!((a - b).abs() < 1e-4, "{got:?} vs {want:?}");
    }
    let mut expect = target.shape().base.clone();
    want.apply_in_place(&mut expect);
    assert!(max_diff(c.target_shape(0), &expect) < 1e-3);
}

/// Bad input gives typed errors, never a panic, and leaves the outputs untouched.
#[wasm_bindgen_test(unsupported = test)]
fn bad_input_is_refused() {
    let (source, _, mut c) = source_target(50, (3, 2), (3, 2));
    let good = random_params(&source, 1, 1.0);
    c.clone_frame(&good, &CloneOptions::default()).unwrap();
    let before = c.target_shape(0).to_vec();
    let mut nan = good.clone();
    nan.shape[1] = f32::NAN;
    let mut inf = good.clone();
    inf.appearance[0] = f32::INFINITY;
    let mut short = good.clone();
    short.shape.pop();
    let mut bad_pose = good.clone();
    bad_pose.pose.a = f32::NAN;
    let mut zero_pose = good.clone();
    zero_pose.pose = Similarity {
        a: 0.0,
        b: 0.0,
        tx: 1.0,
        ty: 1.0,
    };
    let mut huge_pose = good.clone();
    huge_pose.pose = Similarity::from_parts(3e38, 0.0, 0.0, 0.0);
    for p in [&nan, &inf, &short, &bad_pose, &zero_pose] {
        assert!(
            matches!(
                c.clone_frame(p, &CloneOptions::default()),
                Err(Error::Params(_))
            ),
            "{p:?}"
        );
    }
    assert!(matches!(
        c.clone_frame(&huge_pose, &opts(Method::Map, None, true)),
        Err(Error::Params(_))
    ));
    let bad_opts = [
        CloneOptions {
            gain: f32::NAN,
            ..CloneOptions::default()
        },
        CloneOptions {
            shape_gains: vec![1.0; 4],
            ..CloneOptions::default()
        },
        CloneOptions {
            appearance_gains: vec![f32::INFINITY],
            ..CloneOptions::default()
        },
        CloneOptions {
            clamp: Some(-1.0),
            ..CloneOptions::default()
        },
        CloneOptions {
            clamp: Some(f32::NAN),
            ..CloneOptions::default()
        },
    ];
    for o in &bad_opts {
        assert!(
            matches!(c.clone_frame(&good, o), Err(Error::Params(_))),
            "{o:?}"
        );
    }
    assert_eq!(c.target_shape(0), &before[..]);
}

#[wasm_bindgen_test(unsupported = test)]
fn method_names() {
    for m in Method::ALL {
        assert_eq!(m.to_string().parse::<Method>().unwrap(), m);
    }
    assert_eq!(
        "map-residual".parse::<Method>().unwrap(),
        Method::MapResidual
    );
    assert_eq!(Method::default(), Method::Expressive);
    assert_eq!("expressive".parse::<Method>().unwrap(), Method::Expressive);
    assert!(matches!(
        "mapresidual".parse::<Method>(),
        Err(Error::Params(_))
    ));
    // The list: names unique, every method described.
    for (i, a) in Method::ALL.iter().enumerate() {
        assert!(!a.label().is_empty() && a.description().len() > 20);
        for b in &Method::ALL[i + 1..] {
            assert_ne!(a.name(), b.name());
        }
    }
    let d = CloneOptions::default();
    assert_eq!(
        (d.method, d.gain, d.clamp, d.follow_pose, d.style),
        (Method::Expressive, 1.0, Some(3.0), false, 1.0)
    );
    assert_eq!(d.regions, facemimic::clone::RegionGains::default());
    assert!(d.shape_gains.is_empty() && d.appearance_gains.is_empty());
}

/// The (cache-blocked) synthesis equals the straightforward loop bit for bit, over several
/// blocks, skipping zero weights.
#[wasm_bindgen_test(unsupported = test)]
fn blocked_synthesis_matches() {
    let mut rng = Rng(99);
    let d = 5000;
    let base = rng.vec(d);
    let modes = rng.vec(7 * d);
    let w = [0.5, 0.0, -1.25, 2.0, 0.0, 0.125, 3.0];
    let mut plain = base.clone();
    for (i, &wi) in w.iter().enumerate() {
        if wi != 0.0 {
            for k in 0..d {
                plain[k] += wi * modes[i * d + k];
            }
        }
    }
    let mut blocked = vec![0.0; d];
    synthesise(&base, &modes, &w, &mut blocked);
    assert_eq!(plain, blocked);
}

// ---------------------------------------------------------------------------------------
// The reference expression (section 5).

/// Synthetic landmarked images: a textured 96x96 image and a 12-point shape that opens and
/// closes (an expression) and moves (a pose).
fn training_set(seed: u64, k: usize) -> Vec<TrainingImage> {
    let mut rng = Rng(seed | 1);
    (0..k)
        .map(|i| {
            let (w, h) = (96u32, 96u32);
            let mut data = Vec::with_capacity((w * h * 4) as usize);
            let phase = rng.sym();
            for y in 0..h {
                for x in 0..w {
                    let v = ((x as f32 * 0.3 + phase * 3.0).sin() * (y as f32 * 0.2).cos() * 100.0
                        + 128.0) as u8;
                    data.extend_from_slice(&[v, 255 - v, (x * 2) as u8, 255]);
                }
            }
            let open = rng.sym();
            let (s, r) = (0.8 + 0.1 * rng.sym(), 0.1 * rng.sym());
            let pose = Similarity::from_parts(s, r, 48.0 + 3.0 * rng.sym(), 48.0 + 3.0 * rng.sym());
            let mut lm = base_shape();
            for p in lm.chunks_exact_mut(2) {
                p[1] *= 1.0 + 0.2 * open;
                p[0] += 0.6 * rng.sym();
            }
            pose.apply_in_place(&mut lm);
            TrainingImage {
                name: format!("img{i}"),
                image: Image {
                    width: w,
                    height: h,
                    data,
                },
                landmarks: lm,
            }
        })
        .collect()
}

/// A model built about a named training image has that image's (aligned) shape as its base
/// and its sampled appearance as its appearance base; projecting that image gives zero
/// parameters; the model records the reference.
#[wasm_bindgen_test(unsupported = test)]
fn reference_named_training_image() {
    let images = training_set(3, 8);
    let b = |reference| {
        Builder::new(BuildOptions {
            name: "m".into(),
            reference,
            ..BuildOptions::default()
        })
    };
    let mean = b(ReferenceChoice::Mean).build(&images, None).unwrap();
    assert_eq!(*mean.reference(), Reference::Mean);
    for frame_of in [None, Some(&mean)] {
        let m = b(ReferenceChoice::Named("img5".into()))
            .build(&images, frame_of)
            .unwrap();
        assert_eq!(*m.reference(), Reference::Training("img5".into()));
        // The base is a similarity transform of img5's landmarks.
        let t = &images[5];
        let pose = Similarity::align(&m.shape().base, &t.landmarks);
        let mut placed = m.shape().base.clone();
        pose.apply_in_place(&mut placed);
        assert!(
            max_diff(&placed, &t.landmarks) < 1e-3,
            "base is not img5's shape"
        );
        // ... and differs from the mean's (the choice matters).
        let pm = Similarity::align(&mean.shape().base, &t.landmarks);
        let mut mp = mean.shape().base.clone();
        pm.apply_in_place(&mut mp);
        assert!(max_diff(&mp, &t.landmarks) > 0.05);
        // The modes are about it: img5 projects to zero parameters.
        let p = m.project(&t.image.view().unwrap(), &t.landmarks).unwrap();
        assert!(p.shape.iter().all(|v| v.abs() < 1e-3), "{:?}", p.shape);
        assert!(
            p.appearance.iter().all(|v| v.abs() < 1e-3),
            "{:?}",
            p.appearance
        );
        let q = m
            .project(&images[2].image.view().unwrap(), &images[2].landmarks)
            .unwrap();
        assert!(q.shape.iter().any(|v| v.abs() > 0.05));
    }
    assert!(matches!(
        b(ReferenceChoice::Named("nope".into())).build(&images, None),
        Err(Error::Training(_))
    ));
    assert!(matches!(
        b(ReferenceChoice::ClosestToFrame).build(&images, None),
        Err(Error::Training(_))
    ));
}

/// `closest` picks the training image whose aligned shape is nearest the frame model's base.
#[wasm_bindgen_test(unsupported = test)]
fn reference_closest_to_frame() {
    let src_images = training_set(5, 8);
    let source = Builder::new(BuildOptions {
        name: "s".into(),
        ..BuildOptions::default()
    })
    .build(&src_images, None)
    .unwrap();
    let images = training_set(6, 9);
    // Independently: align each image's landmarks onto the frame base, take the nearest.
    let dist = |lm: &[f32]| -> f32 {
        let t = Similarity::align(lm, &source.shape().base);
        let mut a = lm.to_vec();
        t.apply_in_place(&mut a);
        a.iter()
            .zip(&source.shape().base)
            .map(|(x, y)| (x - y) * (x - y))
            .sum()
    };
    let d: Vec<f32> = images.iter().map(|t| dist(&t.landmarks)).collect();
    let best = (0..d.len()).min_by(|&a, &b| d[a].total_cmp(&d[b])).unwrap();
    let m = Builder::new(BuildOptions {
        name: "t".into(),
        reference: ReferenceChoice::ClosestToFrame,
        ..BuildOptions::default()
    })
    .build(&images, Some(&source))
    .unwrap();
    assert_eq!(
        *m.reference(),
        Reference::Training(images[best].name.clone()),
        "distances {d:?}"
    );
    assert!(max_diff(m.frame().vertices(), source.frame().vertices()) == 0.0);
    let p = m
        .project(&images[best].image.view().unwrap(), &images[best].landmarks)
        .unwrap();
    assert!(p.shape.iter().all(|v| v.abs() < 1e-3));
    // And the pair works.
    let mut c = one_target(&source, &m);
    c.clone_frame(&source.base_params(), &CloneOptions::default())
        .unwrap();
}

#[wasm_bindgen_test(unsupported = test)]
fn pair_accessors() {
    let source = synthetic("src", 60, 4, 3, None);
    let target = synthetic("tgt", 61, 2, 5, Some(source.frame()));
    let pair = Pair::new(&source, &target).unwrap();
    assert_eq!(pair.shape_map().len(), 2 * 4);
    assert_eq!(pair.appearance_map().len(), 5 * 3);
    assert_eq!(pair.residual(3).unwrap().len(), source.shape().base.len());
    assert!(pair.residual(4).is_none());
    // |delta_i|^2 + sum_j R_ji^2 = 1 (Pythagoras: each source mode is a unit vector).
    for (i, n) in pair.residual_norms().iter().enumerate() {
        let r2: f32 = (0..2).map(|j| pair.shape_map()[j * 4 + i].powi(2)).sum();
        assert!((n * n + r2 - 1.0).abs() < 1e-5);
    }
}

// ---------------------------------------------------------------------------------------
// Test 7: real data (GRID), native only.

#[cfg(not(target_arch = "wasm32"))]
mod grid {
    use super::*;
    use facemimic::{io, Renderer};
    use std::path::{Path, PathBuf};

    pub const TARGETS: [&str; 4] = [
        "spk02_brbk7n",
        "spk03_lbax4n",
        "spk06_lwbsza",
        "spk10_swiz3n",
    ];

    fn data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid")
    }

    /// Builds a speaker's model from its `train20.txt`, in `frame_of`'s frame when given.
    pub fn build(folder: &str, frame_of: Option<&Model>) -> Model {
        let list = io::read_list(&data().join(folder).join("train20.txt")).unwrap();
        let images: Vec<TrainingImage> = list
            .iter()
            .map(|p| io::read_training_image(p).unwrap())
            .collect();
        let name = folder.split('_').next().unwrap().to_string();
        Builder::new(BuildOptions {
            name,
            ..BuildOptions::default()
        })
        .build(&images, frame_of)
        .unwrap()
    }

    /// The unseen spk07 clip: every frame with its landmarks.
    pub fn clip() -> Vec<TrainingImage> {
        super::common::load(&super::common::clip_frames(
            &data().join("spk07_id2_vcd_swwp2s"),
        ))
    }

    fn point(s: &[f32], idx: &[usize]) -> (f32, f32) {
        let n = idx.len() as f32;
        let x = idx.iter().map(|&i| s[2 * i]).sum::<f32>() / n;
        let y = idx.iter().map(|&i| s[2 * i + 1]).sum::<f32>() / n;
        (x, y)
    }

    /// Mouth opening of a 68-point shape (any pose): the signed gap between the inner upper
    /// lip (mean of landmarks 61-63, 0-based) and the inner lower lip (65-67), measured along
    /// the face's vertical axis (perpendicular to the line through the eye centres), divided
    /// by the inter-ocular distance (eye centres = means of 36-41 and 42-47).
    pub fn opening(s: &[f32]) -> f32 {
        let (lx, ly) = point(s, &[36, 37, 38, 39, 40, 41]);
        let (rx, ry) = point(s, &[42, 43, 44, 45, 46, 47]);
        let (ex, ey) = (rx - lx, ry - ly);
        let iod = (ex * ex + ey * ey).sqrt();
        let (ux, uy) = (-ey / iod, ex / iod); // down the face in a y-down image
        let (tx, ty) = point(s, &[61, 62, 63]);
        let (bx, by) = point(s, &[65, 66, 67]);
        ((bx - tx) * ux + (by - ty) * uy) / iod
    }

    pub fn std(v: &[f32]) -> f32 {
        let m = v.iter().sum::<f32>() / v.len() as f32;
        (v.iter().map(|x| (x - m) * (x - m)).sum::<f32>() / v.len() as f32).sqrt()
    }

    pub fn p2p(v: &[f32]) -> f32 {
        v.iter().copied().fold(f32::MIN, f32::max) - v.iter().copied().fold(f32::MAX, f32::min)
    }

    /// Share of the source's shape variance that the target's basis can express:
    /// `sum_i gamma_i |R e_i|^2 / sum_i gamma_i`.
    pub fn expressible(source: &Model, pair: &Pair) -> f32 {
        let m = source.shape().n_modes();
        let r = pair.shape_map();
        let q = r.len() / m;
        let mut num = 0.0;
        for i in 0..m {
            let c: f32 = (0..q).map(|j| r[j * m + i].powi(2)).sum();
            num += source.shape().variances[i] * c;
        }
        num / source.shape().variances.iter().sum::<f32>()
    }

    /// Renders a comparison figure: per target a row of (source frame | target reference |
    /// substitute | map | map-residual) at the clip's widest-open frame.
    pub fn figure(
        cloner: &mut Cloner,
        source_frame: &TrainingImage,
        params: &Params,
        targets: &[usize],
        out: &Path,
    ) {
        use facemimic::tiny_skia::{
            Color, FilterQuality, Paint, Pattern, Pixmap, Rect, SpreadMode, Transform,
        };
        let cell = 140u32;
        let cols = 5;
        let mut canvas = Pixmap::new(cell * cols, cell * targets.len() as u32).unwrap();
        canvas.fill(Color::from_rgba8(32, 32, 36, 255));
        // The cell's view: the face's mean-pose centre in the middle, 1.35 face widths across.
        let view_for = |m: &Model, col: u32, row: u32| -> Similarity {
            let (cx, cy) = m.mean_pose().apply_point(0.0, 4.0);
            let width = 150.0 * m.mean_pose().scale() * 1.35;
            let k = cell as f32 / width;
            Similarity {
                a: k,
                b: 0.0,
                tx: (col * cell) as f32 + cell as f32 / 2.0 - k * cx,
                ty: (row * cell) as f32 + cell as f32 / 2.0 - k * cy,
            }
        };
        let src_img = Pixmap::from_vec(
            source_frame.image.data.clone(),
            facemimic::tiny_skia::IntSize::from_wh(
                source_frame.image.width,
                source_frame.image.height,
            )
            .unwrap(),
        )
        .unwrap();
        for (row, &ti) in targets.iter().enumerate() {
            let row = row as u32;
            let v = view_for(cloner.source(), 0, row);
            let paint = Paint {
                shader: Pattern::new(
                    src_img.as_ref(),
                    SpreadMode::Pad,
                    FilterQuality::Bilinear,
                    1.0,
                    Transform::from_row(v.a, 0.0, 0.0, v.a, v.tx, v.ty),
                ),
                ..Paint::default()
            };
            let r = Rect::from_xywh(0.0, (row * cell) as f32, cell as f32, cell as f32).unwrap();
            canvas.fill_rect(r, &paint, Transform::identity(), None);
            let frame = cloner.target(ti).frame().clone();
            let mut renderer = Renderer::new(&frame).unwrap();
            let setups = [
                (Method::Map, 0.0),
                (Method::Substitute, 1.0),
                (Method::Map, 1.0),
                (Method::MapResidual, 1.0),
            ];
            for (col, (method, gain)) in setups.into_iter().enumerate() {
                let o = CloneOptions {
                    method,
                    gain,
                    ..CloneOptions::default()
                };
                cloner.clone_frame(params, &o).unwrap();
                let view = view_for(cloner.target(ti), col as u32 + 1, row);
                renderer
                    .upload(&frame, cloner.target_appearance(ti))
                    .unwrap();
                renderer
                    .warp(&frame, cloner.target_shape(ti), &view, &mut canvas.as_mut())
                    .unwrap();
            }
        }
        io::write_pixmap(out, &canvas).unwrap();
    }
}

/// Test 7 (native, real data): spk07 (source) cloned onto spk02/03/06/10 (built in spk07's
/// frame) over the 75 frames of the unseen spk07 clip. Per method, the target's mouth opening
/// (inner-lip gap / inter-ocular distance) relative to the source's: `map` under-articulates,
/// `map-residual` restores the source's articulation. Prints the table of `docs/cloning.md`
/// (`cargo test --release --test integration clone::grid -- --nocapture`). With `FACEMIMIC_CLONE_FIGURE=PATH`
/// it also renders the comparison figure.
#[cfg(not(target_arch = "wasm32"))]
#[test]
fn grid_mouth_articulation_per_method() {
    use grid::*;
    let t0 = std::time::Instant::now();
    let source = build("spk07_pwij3p", None);
    let mut cloner = Cloner::new(source.clone()).unwrap();
    for t in TARGETS {
        cloner.add_target(build(t, Some(&source))).unwrap();
    }
    let clip = clip();
    assert_eq!(clip.len(), 75);
    let params: Vec<Params> = clip
        .iter()
        .map(|f| {
            source
                .project(&f.image.view().unwrap(), &f.landmarks)
                .unwrap()
        })
        .collect();
    let built = t0.elapsed();
    let mut s = vec![0.0; source.shape().base.len()];
    let src_open: Vec<f32> = params
        .iter()
        .map(|p| {
            source.image_shape(p, &mut s).unwrap();
            opening(&s)
        })
        .collect();
    let raw_open: Vec<f32> = clip.iter().map(|f| opening(&f.landmarks)).collect();
    println!(
        "source spk07: {} shape / {} appearance modes, {} frame pixels; clip opening std {:.4} (model) / {:.4} (landmarks), peak-to-peak {:.4} / {:.4}",
        source.shape().n_modes(),
        source.appearance().n_modes(),
        source.frame().n_pixels(),
        std(&src_open),
        std(&raw_open),
        p2p(&src_open),
        p2p(&raw_open)
    );
    println!("\n| target | shape modes | expressible share | substitute | map | map-residual | map, no clamp | map-residual, no clamp |");
    println!("|---|---|---|---|---|---|---|---|");
    let setups = [
        (Method::Substitute, Some(3.0)),
        (Method::Map, Some(3.0)),
        (Method::MapResidual, Some(3.0)),
        (Method::Map, None),
        (Method::MapResidual, None),
    ];
    let mut ratios = vec![[[0f32; 2]; 5]; TARGETS.len()];
    for (mi, (method, clamp)) in setups.into_iter().enumerate() {
        let o = CloneOptions {
            method,
            clamp,
            ..CloneOptions::default()
        };
        let mut series = vec![Vec::new(); TARGETS.len()];
        for p in &params {
            cloner.clone_frame(p, &o).unwrap();
            for (ti, s) in series.iter_mut().enumerate() {
                s.push(opening(cloner.target_shape(ti)));
            }
        }
        for (ti, s) in series.iter().enumerate() {
            ratios[ti][mi] = [std(s) / std(&src_open), p2p(s) / p2p(&src_open)];
        }
    }
    for (ti, t) in TARGETS.iter().enumerate() {
        let r = &ratios[ti];
        let cells: Vec<String> = r.iter().map(|[a, b]| format!("{a:.2} / {b:.2}")).collect();
        println!(
            "| {} | {} | {:.2} | {} |",
            &t[..5],
            cloner.target(ti).shape().n_modes(),
            expressible(&source, cloner.pair(ti).unwrap()),
            cells.join(" | ")
        );
    }
    println!(
        "\n(built and projected in {built:.1?}, total {:.1?})",
        t0.elapsed()
    );
    assert_articulation(&ratios);
    if let Ok(path) = std::env::var("FACEMIMIC_CLONE_FIGURE") {
        let widest = (0..src_open.len())
            .max_by(|&a, &b| src_open[a].total_cmp(&src_open[b]))
            .unwrap();
        println!(
            "figure: frame {widest} (opening {:.3}) -> {path}",
            src_open[widest]
        );
        figure(
            &mut cloner,
            &clip[widest],
            &params[widest],
            &[0, 3],
            std::path::Path::new(&path),
        );
    }
}

/// The articulation ratios (std, peak-to-peak) per target and setup of
/// [`grid_mouth_articulation_per_method`]: `map` under-articulates, `map-residual` restores the
/// source's articulation, as substitute does, and the clamp is hardly active.
#[cfg(not(target_arch = "wasm32"))]
fn assert_articulation(ratios: &[[[f32; 2]; 5]]) {
    for (ti, t) in grid::TARGETS.iter().enumerate() {
        let [sub, map, res, _, res_free] = ratios[ti];
        for k in 0..2 {
            // map under-articulates ...
            assert!(map[k] < 0.93, "{t}: map ratio {} should be < 0.93", map[k]);
            // ... map-residual compensates: clearly more than map, close to the source and to
            // substitute (which adds the source's displacement verbatim: the geometric ceiling
            // of this measure, below 1 only because the faces' inter-ocular distances differ).
            assert!(
                res[k] > map[k] + 0.05,
                "{t}: map-residual {} vs map {}",
                res[k],
                map[k]
            );
            assert!(
                (0.9..1.1).contains(&res[k]),
                "{t}: map-residual ratio {}",
                res[k]
            );
            assert!(
                (res[k] - sub[k]).abs() < 0.05,
                "{t}: map-residual {} vs substitute {}",
                res[k],
                sub[k]
            );
            // The clamp (3 sigma*) is hardly active on this clip.
            assert!(
                (res_free[k] - res[k]).abs() < 0.02,
                "{t}: {} vs {}",
                res_free[k],
                res[k]
            );
        }
    }
}

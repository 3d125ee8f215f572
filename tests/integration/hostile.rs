//! Hostile input, one regression test per case of the "hostile input" review: finite numbers
//! that used to give NaN or infinity, memory far beyond the input, files the reader could not
//! read back, multi-line or misleading errors, and public helpers that panicked. The models are
//! the fuzz harness's small synthetic seeds (`facemimic_testkit::fuzz`).

use facemimic_testkit::fuzz as engine;

use std::sync::OnceLock;

use facemimic::clone::{constrain, CloneOptions, Cloner, Method};
use facemimic::fit::{FitOptions, Tracker};
use facemimic::format::{read_model, write_model, write_model_checked, FormatError};
use facemimic::{
    BuildOptions, Builder, DrawOptions, Error, FaceDrawer, FrameChoice, Model, ModelParts, Params,
    Similarity,
};

fn seeds() -> &'static engine::Seeds {
    static S: OnceLock<engine::Seeds> = OnceLock::new();
    S.get_or_init(engine::Seeds::new)
}

fn model() -> Model {
    seeds().models[0].clone()
}

/// [`model`] with a part changed (still a `Model`: finite numbers, dimensions that agree).
fn edited(change: impl FnOnce(&mut ModelParts)) -> Model {
    let mut parts = model().into_parts();
    change(&mut parts);
    Model::new(parts).expect("a model")
}

/// `parts` with its appearance arrays (base, modes, variances) edited by `change`.
fn edit_appearance(
    parts: &mut ModelParts,
    change: impl FnOnce(&mut [f32], &mut [f32], &mut [f32]),
) {
    let (mut b, mut m, mut v) = parts.appearance.clone().into_arrays();
    change(&mut b, &mut m, &mut v);
    parts.appearance = facemimic::AppearanceModel::new(b, m, v);
}

/// Writes `m` without checks (exact `f32` storage) and reads it back: the loader's verdict.
fn reload(m: &Model) -> Result<Model, FormatError> {
    read_model(&facemimic::format::write_model_as(
        m,
        facemimic::format::Storage::F32,
    ))
}

fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

#[test]
fn huge_mean_pose_is_rejected_on_load_naming_the_pose() {
    let m = edited(|p| {
        p.mean_pose = Similarity {
            a: 3e38,
            b: 0.0,
            tx: 0.0,
            ty: 0.0,
        }
    });
    let e = reload(&m).unwrap_err();
    assert!(
        matches!(
            e,
            FormatError::OutOfRange {
                array: "mean pose scale",
                ..
            }
        ),
        "{e}"
    );
    let m = edited(|p| p.mean_pose.tx = 1e30);
    let e = reload(&m).unwrap_err();
    assert!(e.to_string().contains("mean pose translation"), "{e}");
}

#[test]
fn huge_base_appearance_and_shape_and_variances_are_rejected_on_load() {
    let m = edited(|p| edit_appearance(p, |b, _, _| b[5] = f32::MAX));
    let e = reload(&m).unwrap_err();
    assert!(
        matches!(
            e,
            FormatError::OutOfRange {
                array: "appearance base",
                index: 5,
                ..
            }
        ),
        "{e}"
    );
    let m = edited(|p| p.shape.variances[0] = 3e38);
    let e = reload(&m).unwrap_err();
    assert!(e.to_string().contains("shape variances"), "{e}");
    let m = edited(|p| edit_appearance(p, |_, _, v| v[0] = 1e30));
    assert!(reload(&m)
        .unwrap_err()
        .to_string()
        .contains("appearance variances"));
    // A 1e30 base shape: named as such (it used to read "landmarks are degenerate").
    let m = edited(|p| p.shape.base.iter_mut().for_each(|v| *v *= 1e30));
    let e = reload(&m).unwrap_err().to_string();
    assert!(!e.contains("degenerate"), "{e}");
}

#[test]
fn valid_models_pass_the_value_bounds() {
    for m in &seeds().models {
        assert_eq!(&reload(m).unwrap(), m);
        assert!(write_model_checked(m).is_ok());
    }
}

#[test]
fn huge_parameters_give_a_typed_error_not_nan() {
    let m = model();
    let mut shape = vec![0.0; m.landmarks() * 2];
    let mut p = m.base_params();
    p.shape[0] = 1e30;
    let e = m.image_shape(&p, &mut shape).unwrap_err();
    assert!(
        matches!(e, Error::Params(_)) && e.to_string().contains("shape parameters[0]"),
        "{e}"
    );
    // The largest accepted parameters still give finite landmarks.
    p.shape
        .iter_mut()
        .for_each(|v| *v = facemimic::bounds::MAX_PARAM);
    p.pose = Similarity {
        a: facemimic::bounds::MAX_POSE_SCALE,
        b: 0.0,
        tx: facemimic::bounds::MAX_POSE_SHIFT,
        ty: -facemimic::bounds::MAX_POSE_SHIFT,
    };
    m.image_shape(&p, &mut shape).unwrap();
    assert!(finite(&shape));
    // A pose of 1e30 scale is refused.
    let mut q = m.base_params();
    q.pose.a = 1e30;
    assert!(m
        .check_params(&q)
        .unwrap_err()
        .to_string()
        .contains("scale"));
    // Landmarks of 1e30: named, not "degenerate".
    let lm = vec![1e30f32; m.landmarks() * 2];
    let e = m
        .project(&seeds().image.view().unwrap(), &lm)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("1000000000000000000000000000000") || e.contains("1e30"),
        "{e}"
    );
    assert!(!e.contains("degenerate"), "{e}");
}

#[test]
fn clone_frame_with_huge_gain_or_parameters_is_an_error_and_never_nan() {
    let s = &seeds().models;
    let mut c = Cloner::new(s[0].clone()).unwrap();
    c.add_target(s[1].clone()).unwrap();
    let mut p = s[0].base_params();
    p.shape.iter_mut().for_each(|v| *v = 1e30);
    let opts = CloneOptions {
        gain: 1e30,
        clamp: None,
        ..CloneOptions::default()
    };
    assert!(matches!(c.clone_frame(&p, &opts), Err(Error::Params(_))));
    p.shape.iter_mut().for_each(|v| *v = 1e6);
    let e = c.clone_frame(&p, &opts).unwrap_err().to_string();
    assert!(e.contains("gain"), "{e}");
    // The largest accepted gain and parameters, every method, clamp on and off: finite.
    p.appearance.iter_mut().for_each(|v| *v = -1e6);
    for method in Method::ALL {
        for clamp in [None, Some(3.0), Some(0.0), Some(1e3)] {
            let opts = CloneOptions {
                method,
                gain: facemimic::bounds::MAX_GAIN,
                shape_gains: vec![facemimic::bounds::MAX_GAIN],
                clamp,
                follow_pose: true,
                ..CloneOptions::default()
            };
            c.clone_frame(&p, &opts).unwrap();
            assert!(finite(c.target_shape(0)) && finite(c.target_appearance(0)));
            assert!(finite(&c.target_params(0).shape));
        }
    }
    for bad in [f32::NAN, -1.0, 1e30] {
        let opts = CloneOptions {
            clamp: Some(bad),
            ..CloneOptions::default()
        };
        assert!(c.clone_frame(&s[0].base_params(), &opts).is_err());
    }
}

#[test]
fn constrain_is_nan_safe_and_total() {
    let mut p = vec![f32::NAN, 5.0, -5.0, f32::INFINITY, 1.0];
    constrain(&mut p, &[1.0, 1.0, f32::NAN, 2.0, -1.0], 3.0);
    assert_eq!(p, vec![0.0, 3.0, 0.0, 6.0, 0.0]);
    for k in [f32::NAN, -1.0, f32::INFINITY] {
        let mut p = vec![1e30, f32::NAN, -2.0];
        constrain(&mut p, &[1.0, 1.0, 1.0], k);
        assert!(finite(&p), "k = {k}: {p:?}");
    }
}

#[test]
fn renderers_refuse_non_finite_appearance() {
    let m = model();
    let mut r = FaceDrawer::new(m.frame(), DrawOptions::default()).unwrap();
    let mut a = m.appearance().base().to_vec();
    a[3] = f32::NAN;
    assert!(r.upload(m.frame(), &a).is_err());
    let mut s = facemimic::Scanline::new();
    assert!(s.upload(m.frame(), &a).is_err());
    let mut p = m.base_params();
    p.appearance[0] = 1e30;
    let mut pixmap = facemimic::tiny_skia::Pixmap::new(32, 32).unwrap();
    assert!(r
        .render(&m, &p, &Similarity::IDENTITY, &mut pixmap.as_mut())
        .is_err());
}

#[test]
fn public_helpers_do_not_panic() {
    let m = model();
    // Wrong-length output.
    let mut short = vec![0.0; 3];
    assert!(m
        .shape()
        .instance(&vec![0.0; m.shape().n_modes()], &mut short)
        .is_err());
    // Mode out of range.
    assert!(m.shape().mode(m.shape().n_modes()).is_none());
    assert!(m.shape().mode(usize::MAX).is_none());
    assert!(m.appearance().mode(999).is_none());
    assert!(m.shape().mode(0).is_some());
    // PCA with ragged samples or non-finite values.
    let samples = vec![vec![1.0, 2.0, 3.0], vec![1.0, 2.0]];
    assert!(facemimic::numerics::pca(&samples, &[0.0, 0.0, 0.0], 0.9, 10).is_err());
    let samples = vec![vec![1.0, f64::NAN], vec![1.0, 2.0]];
    assert!(facemimic::numerics::pca(&samples, &[0.0, 0.0], 0.9, 10).is_err());
    // Procrustes of nothing.
    let (a, _) = facemimic::numerics::generalised_procrustes(&[], None);
    assert!(a.is_empty());
}

#[test]
fn asf_relative_coordinate_overflow_is_an_error() {
    let e = facemimic::landmarks::parse_asf("1\n0 0 1e38 0.5 0 0 0\n", 640, 480).unwrap_err();
    assert!(e.to_string().contains("relative x"), "{e}");
}

#[test]
fn writers_refuse_what_readers_reject() {
    let images = engine::training_set(12, 4, 5);
    let long = "x".repeat(300);
    let e = Builder::new(BuildOptions {
        name: long.clone(),
        face_width: 16.0,
        frame: FrameChoice::Own,
        ..BuildOptions::default()
    })
    .build(&images, None)
    .unwrap_err();
    assert!(e.to_string().contains("300 bytes"), "{e}");
    let mut m = model();
    m.set_name(long);
    assert!(read_model(&write_model(&m)).is_err());
    let e = write_model_checked(&m).unwrap_err();
    assert!(e.to_string().contains("model name length"), "{e}");
}

#[test]
fn tracker_refuses_a_model_over_its_memory_budget_before_allocating() {
    // The 0.8 MB model whose tracker precomputation took 81 MB.
    let m = engine::over_budget_model();
    let m = reload(&m).expect("a valid model file");
    let bytes = write_model(&m).len() as u64;
    let need = facemimic::bounds::tracking_bytes(&m, FitOptions::default().levels.len(), 1);
    assert!(
        need > facemimic::bounds::model_budget(bytes),
        "{need} vs {bytes}"
    );
    let e = Tracker::new(&m, FitOptions::default()).expect_err("refused");
    assert!(matches!(e, Error::Budget(_)), "{e}");
    // The small seed models track.
    assert!(Tracker::new(&seeds().models[0], FitOptions::default()).is_ok());
}

#[test]
fn files_are_read_through_a_size_cap_refusing_special_files() {
    use facemimic::bounds::read_file_capped;
    let e = read_file_capped(std::path::Path::new("/dev/zero"), 1 << 20).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let e = read_file_capped(&std::env::temp_dir(), 1 << 20).unwrap_err();
    assert!(e.to_string().contains("directory"), "{e}");
    let dir = std::env::temp_dir().join(format!("facemimic-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("big");
    std::fs::write(&f, vec![0u8; 2000]).unwrap();
    assert!(read_file_capped(&f, 1000)
        .unwrap_err()
        .to_string()
        .contains("limit"));
    assert_eq!(read_file_capped(&f, 2000).unwrap().len(), 2000);
    #[cfg(unix)]
    {
        let fifo = dir.join("fifo");
        let _ = std::process::Command::new("mkfifo").arg(&fifo).status();
        if fifo.exists() {
            // A FIFO with no writer used to hang.
            let e = read_file_capped(&fifo, 1 << 20).unwrap_err();
            assert!(e.to_string().contains("not a regular file"), "{e}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn default_render_canvas_is_bounded_not_the_declared_size() {
    let m = edited(|p| p.image_size = [8192, 8192]);
    let m = reload(&m).unwrap();
    let e = facemimic::bounds::default_canvas(&m).unwrap_err();
    assert!(matches!(e, Error::Budget(_)), "{e}");
    assert_eq!(
        facemimic::bounds::default_canvas(&model()).unwrap(),
        (64, 64)
    );
}

#[test]
fn params_json_with_huge_values_is_refused() {
    let m = model();
    let text = serde_json::to_string(&m.base_params())
        .unwrap()
        .replacen("0.0", "1e38", 1);
    let p: Params = serde_json::from_str(&text).unwrap();
    assert!(m.check_params(&p).is_err());
}

//! The canonical reference frame: the embedded asset, models built in it by default (library and
//! CLI) cloning between each other whichever was built first, and models of other frames still
//! refused with the frame error.

use std::path::Path;

use facemimic::canonical::{parse_frame, write_frame, CANONICAL_FRAME_TEXT, CANONICAL_LANDMARKS};
use facemimic::clone::{CloneOptions, Cloner};
use facemimic::{
    canonical_frame, io, BuildOptions, Builder, Error, FrameChoice, Model, CANONICAL_FINGERPRINT,
};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn images(clip: &str) -> Vec<facemimic::TrainingImage> {
    io::read_list(&root().join("data/grid").join(clip).join("train20.txt"))
        .unwrap()
        .iter()
        .map(|p| io::read_training_image(p).unwrap())
        .collect()
}

fn build(clip: &str, name: &str, frame: FrameChoice) -> Model {
    Builder::new(BuildOptions {
        name: name.into(),
        frame,
        ..BuildOptions::default()
    })
    .build(&images(clip), None)
    .unwrap()
}

/// The asset parses, its fingerprint is the recorded one, and it is (bit for bit) the frame
/// spk07's model gets in a frame of its own: the recipe in `examples/canonical_frame.rs`.
#[test]
fn asset_is_spk07_own_frame() {
    let c = canonical_frame();
    assert_eq!(c.fingerprint(), CANONICAL_FINGERPRINT);
    assert_eq!(c.landmarks(), CANONICAL_LANDMARKS);
    assert!(c.n_pixels() > 10_000, "{} pixels", c.n_pixels());
    let own = build("spk07_pwij3p", "spk07", FrameChoice::Own);
    assert!(
        *own.frame() == *c,
        "spk07's own frame is not the canonical one"
    );
    // Built in the canonical frame (the default), spk07 gets back the frame's mesh as its base.
    let canon = build("spk07_pwij3p", "spk07", FrameChoice::Canonical);
    let d = canon
        .shape()
        .base
        .iter()
        .zip(c.vertices())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(
        d < 1e-3,
        "spk07's base is {d} model units off the canonical mesh"
    );
    // Writing and parsing round-trips exactly.
    let again = parse_frame(&write_frame(c, "x")).unwrap();
    assert!(again == *c);
}

/// A damaged asset is an error, not a wrong frame: a changed vertex (fingerprint mismatch), a
/// truncated text, a bad number.
#[test]
fn damaged_frame_text_is_refused() {
    let t = CANONICAL_FRAME_TEXT;
    let changed = {
        let i = t.find("vertices").unwrap();
        let line_start = i + t[i..].find('\n').unwrap() + 1;
        let mut s = t.to_string();
        s.insert(line_start, '1'); // the first vertex's x gets a leading digit
        s
    };
    let e = parse_frame(&changed).unwrap_err().to_string();
    assert!(e.contains("fingerprint"), "{e}");
    assert!(parse_frame(&t[..t.len() / 2]).is_err());
    assert!(parse_frame(&t.replacen("\nsize ", "\nsize x", 1)).is_err());
    assert!(parse_frame("").is_err());
}

/// Two models built separately with the defaults share the canonical frame and clone between
/// each other in both directions; a model built in its own frame is refused with the frame
/// error (naming both models and both fingerprints).
#[test]
fn separately_built_models_clone_both_ways() {
    let a = build("spk07_pwij3p", "spk07", FrameChoice::Canonical);
    let b = build("spk02_brbk7n", "spk02", FrameChoice::Canonical);
    assert_eq!(a.frame().fingerprint(), CANONICAL_FINGERPRINT);
    assert_eq!(b.frame().fingerprint(), CANONICAL_FINGERPRINT);
    for (s, t) in [(&a, &b), (&b, &a)] {
        let mut c = Cloner::new(s.clone()).unwrap();
        c.add_target(t.clone()).unwrap();
        let im = images(if s.name() == "spk07" {
            "spk07_pwij3p"
        } else {
            "spk02_brbk7n"
        });
        let p = s
            .project(&im[3].image.view().unwrap(), &im[3].landmarks)
            .unwrap();
        c.clone_frame(&p, &CloneOptions::default()).unwrap();
        let q = c.target_params(0);
        assert!(q.shape.iter().all(|v| v.is_finite()));
        assert!(q.shape.iter().any(|v| v.abs() > 1e-3), "{:?}", q.shape);
    }
    let own = build("spk02_brbk7n", "spk02-own", FrameChoice::Own);
    assert_ne!(own.frame().fingerprint(), CANONICAL_FINGERPRINT);
    let mut c = Cloner::new(a.clone()).unwrap();
    match c.add_target(own) {
        Err(Error::Incompatible(m)) => {
            assert!(m.contains("different reference frames"), "{m}");
            assert!(m.contains("spk07") && m.contains("spk02-own"), "{m}");
            assert!(m.contains(&format!("{CANONICAL_FINGERPRINT:016x}")), "{m}");
        }
        other => panic!("expected the frame error, got {other:?}"),
    }
}

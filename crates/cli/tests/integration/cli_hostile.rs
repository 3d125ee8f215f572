//! The command line under hostile input (one line on stderr, no partial output) and across
//! reference frames (models built separately share the canonical frame; `--own-frame` models
//! are refused by `clone`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use facemimic::format::write_model;
use facemimic::Model;
use facemimic_testkit::fuzz as engine;

fn seeds() -> &'static engine::Seeds {
    static S: OnceLock<engine::Seeds> = OnceLock::new();
    S.get_or_init(engine::Seeds::new)
}

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

// ------------------------------------------------------------------------------------------
// The command line.

fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("facemimic-hostile-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the CLI, which must fail with exactly one line on stderr; returns that line.
fn fails_one_line(args: &[&str]) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args:?} succeeded");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "{args:?}: not one line:\n{err}"
    );
    assert!(err.starts_with("facemimic: error: "), "{err}");
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "{err}"
    );
    err
}

#[test]
fn cli_hostile_cases_fail_in_one_line() {
    let d = scratch("cli");
    let s = &seeds().models;
    let (a, b) = (d.join("a.fmm"), d.join("b.fmm"));
    std::fs::write(&a, write_model(&s[0])).unwrap();
    std::fs::write(&b, write_model(&s[1])).unwrap();
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let mut p = s[0].base_params();
    p.shape.iter_mut().for_each(|v| *v = 1e30);
    let huge = d.join("huge.json");
    std::fs::write(&huge, serde_json::to_string(&p).unwrap()).unwrap();
    let huge = huge.to_str().unwrap();
    let base = d.join("base.json");
    std::fs::write(&base, serde_json::to_string(&s[0].base_params()).unwrap()).unwrap();
    let base = base.to_str().unwrap();
    let out = d.join("o.json");
    let out = out.to_str().unwrap();
    let png = d.join("o.png");
    let png = png.to_str().unwrap();

    let e = fails_one_line(&[
        "clone",
        "--source",
        a,
        "--target",
        b,
        "--params",
        base,
        "--gain",
        "1e30",
        "--no-clamp",
        "--out-params",
        out,
    ]);
    assert!(e.contains("gain"), "{e}");
    assert!(!std::path::Path::new(out).exists());
    let e = fails_one_line(&["render", "--model", a, "--params", huge, "--out", png]);
    assert!(e.contains("shape parameters[0]"), "{e}");
    assert!(!std::path::Path::new(png).exists());
    // Usage errors: one line with the usage and a hint.
    let e = fails_one_line(&["render", "--modl", a]);
    assert!(
        e.contains("usage: facemimic render") && e.contains("facemimic render --help"),
        "{e}"
    );
    fails_one_line(&[]);
    fails_one_line(&["clone", "--gain"]);
    fails_one_line(&["bogus"]);
    // Special files and directories.
    let e = fails_one_line(&["inspect", "/dev/zero"]);
    assert!(e.contains("not a regular file"), "{e}");
    fails_one_line(&["inspect", d.to_str().unwrap()]);
    // A model declaring an 8192x8192 image: no 530 MB canvas by default.
    let mut parts = s[0].clone().into_parts();
    parts.image_size = [8192, 8192];
    let m = Model::new(parts).unwrap();
    let big = d.join("big.fmm");
    std::fs::write(&big, write_model(&m)).unwrap();
    let e = fails_one_line(&["render", "--model", big.to_str().unwrap(), "--out", png]);
    assert!(e.contains("canvas"), "{e}");
    let ok = std::process::Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args([
            "render",
            "--model",
            big.to_str().unwrap(),
            "--out",
            png,
            "--width",
            "64",
            "--height",
            "64",
        ])
        .status()
        .unwrap();
    assert!(ok.success());
    let _ = std::fs::remove_dir_all(&d);
}

fn cli(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args(args)
        .output()
        .unwrap()
}

/// The CLI: `build` without `--frame` builds in the canonical frame, so `clone` works between
/// two models built separately; `--own-frame` models are refused by `clone` with one line.
#[test]
fn cli_builds_in_the_canonical_frame() {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("facemimic-canonical-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let grid = root().join("data/grid");
    let mk = |name: &str, clip: &str, extra: &[&str]| -> PathBuf {
        let out = dir.join(format!("{name}.fmm"));
        let list = grid.join(clip).join("train20.txt");
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "build".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
            "--list".as_ref(),
            list.as_os_str(),
        ];
        args.extend(extra.iter().map(std::ffi::OsStr::new));
        let o = cli(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let me = mk("me", "spk02_brbk7n", &[]);
    let other = mk("other", "spk07_pwij3p", &[]);
    let own = mk("own", "spk03_lbax4n", &["--own-frame"]);
    let frame = grid.join("spk02_brbk7n/000002.jpg");
    let png = dir.join("out.png");
    let clone = |s: &Path, t: &Path| {
        cli(&[
            "clone".as_ref(),
            "--source".as_ref(),
            s.as_os_str(),
            "--target".as_ref(),
            t.as_os_str(),
            "--image".as_ref(),
            frame.as_os_str(),
            "--out".as_ref(),
            png.as_os_str(),
        ])
    };
    let o = clone(&me, &other);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(png.exists());
    let o = clone(&me, &own);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("different reference frames"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

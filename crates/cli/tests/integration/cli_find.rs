//! `facemimic landmark` and `facemimic build --find-faces [--select N]`, run as a process on
//! GRID frames (`data/grid`) and on images without a face.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn grid(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("data/grid")
        .join(rel)
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("facemimic-clifind-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&Path]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Copies GRID frames (without their .pts) into `dir`.
fn frames(dir: &Path, stems: &[&str]) -> Vec<PathBuf> {
    stems
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let to = dir.join(format!("f{i}.jpg"));
            std::fs::copy(grid(&format!("{s}.jpg")), &to).unwrap();
            to
        })
        .collect()
}

fn grey_png(path: &Path) {
    facemimic::io::write_png(path, 64, 48, &[128u8; 64 * 48 * 4]).unwrap();
}

#[test]
fn landmark_writes_pts_beside_or_into_a_folder_and_never_overwrites() {
    let d = scratch("landmark");
    let imgs = frames(&d, &["spk01_bbaf2n/000004", "spk05_lrwp9a/000008"]);
    let blank = d.join("blank.png");
    grey_png(&blank);
    let o = run(&[Path::new("landmark"), &imgs[0], &imgs[1], &blank]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("no face found in") && stderr(&o).contains("blank.png"));
    assert!(!d.join("blank.pts").exists());
    // The points are close to dlib's (1-based iBUG file, read back 0-based).
    let found =
        facemimic::landmarks::parse_pts(&std::fs::read_to_string(d.join("f0.pts")).unwrap())
            .unwrap();
    let truth = facemimic::landmarks::parse_pts(
        &std::fs::read_to_string(grid("spk01_bbaf2n/000004.pts")).unwrap(),
    )
    .unwrap();
    let err = facemimic::find::landmark_error(&found, &truth);
    assert!(err < 0.08, "error {err}");
    // No overwrite without --force: an error line, exit 1, the file untouched.
    std::fs::write(d.join("f1.pts"), "keep").unwrap();
    let o = run(&[Path::new("landmark"), &imgs[1]]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--force") && stderr(&o).lines().count() == 1);
    assert_eq!(std::fs::read_to_string(d.join("f1.pts")).unwrap(), "keep");
    let o = run(&[Path::new("landmark"), Path::new("--force"), &imgs[1]]);
    assert!(o.status.success());
    assert_ne!(std::fs::read_to_string(d.join("f1.pts")).unwrap(), "keep");
    // --out-dir, made when missing (as mkdir -p); a file in its place is an error.
    let out = d.join("out").join("nested");
    let o = run(&[
        Path::new("landmark"),
        Path::new("--out-dir"),
        &out,
        &imgs[0],
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("f0.pts").is_file());
    // --fast: one look instead of the mean over the image and its mirror; the same face,
    // different points.
    let fast = d.join("fast");
    let o = run(&[
        Path::new("landmark"),
        Path::new("--fast"),
        Path::new("--out-dir"),
        &fast,
        &imgs[0],
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let one_look =
        facemimic::landmarks::parse_pts(&std::fs::read_to_string(fast.join("f0.pts")).unwrap())
            .unwrap();
    let apart = facemimic::find::landmark_error(&one_look, &found);
    assert!(
        apart > 0.0 && apart < 0.05,
        "--fast points {apart} from the default's"
    );
    let file = d.join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let o = run(&[
        Path::new("landmark"),
        Path::new("--out-dir"),
        &file,
        &imgs[0],
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not a folder"), "{}", stderr(&o));
    // An unreadable image: one line, exit 1.
    let bad = d.join("bad.jpg");
    std::fs::write(&bad, b"not an image").unwrap();
    let o = run(&[Path::new("landmark"), &bad]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
}

#[test]
fn build_find_faces_selects_varied_frames_and_refuses_too_few_faces() {
    let d = scratch("build");
    let stems: Vec<String> = std::fs::read_dir(grid("spk07_pwij3p"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
        .map(|p| format!("spk07_pwij3p/{}", p.file_stem().unwrap().to_string_lossy()))
        .take(12)
        .collect();
    let stems: Vec<&str> = stems.iter().map(String::as_str).collect();
    let mut imgs = frames(&d, &stems);
    let blank = d.join("blank.png");
    grey_png(&blank);
    imgs.push(blank.clone());
    let model = d.join("m.fmm");
    let mut args: Vec<&Path> = vec![
        Path::new("build"),
        Path::new("--find-faces"),
        Path::new("--select"),
        Path::new("6"),
        Path::new("--out"),
        &model,
    ];
    args.extend(imgs.iter().map(PathBuf::as_path));
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("blank.png") && e.contains("selected 6") && e.contains("from 6 images"),
        "{e}"
    );
    assert!(facemimic::io::read_model_file(&model).is_ok());
    // Too few faces: an error, nothing written.
    let none = d.join("none.fmm");
    let o = run(&[
        Path::new("build"),
        Path::new("--find-faces"),
        Path::new("--out"),
        &none,
        &blank,
        &imgs[0],
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("at least 2"), "{}", stderr(&o));
    assert!(!none.exists());
}

/// The CLI's `build` is a thin shell over the core enrolment pipeline ([`facemimic::enrol`]):
/// from the same frames without landmark files, with `--find-faces --select 6 --reference f2`,
/// both give the same model file, byte for byte. (The wasm `buildModel`'s side of the same
/// claim is `crates/wasm/tests/integration/wasm_enrol.rs`.)
#[test]
fn build_find_faces_is_the_core_pipeline() {
    let d = scratch("pipeline");
    let stems: Vec<String> = ["02", "10", "12", "15", "18", "20", "21", "22"]
        .iter()
        .map(|n| format!("spk02_brbk7n/0000{n}"))
        .collect();
    let stems: Vec<&str> = stems.iter().map(String::as_str).collect();
    let imgs = frames(&d, &stems);
    let out = d.join("spk02-enrolled.fmm");
    let mut args: Vec<&Path> = vec![
        Path::new("build"),
        Path::new("--find-faces"),
        Path::new("--select"),
        Path::new("6"),
        Path::new("--reference"),
        Path::new("f2"),
        Path::new("--out"),
        &out,
    ];
    args.extend(imgs.iter().map(PathBuf::as_path));
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("selected 6 varied frames"),
        "{}",
        stderr(&o)
    );

    let frames: Vec<facemimic::EnrolFrame> = imgs
        .iter()
        .enumerate()
        .map(|(i, p)| facemimic::EnrolFrame {
            name: format!("f{i}"),
            image: facemimic::io::read_image(p).unwrap(),
            landmarks: None,
        })
        .collect();
    let options = facemimic::EnrolOptions {
        build: facemimic::BuildOptions {
            name: "spk02-enrolled".into(),
            reference: facemimic::ReferenceChoice::Named("f2".into()),
            ..facemimic::BuildOptions::default()
        },
        select: Some(6),
        ..facemimic::EnrolOptions::default()
    };
    let core = facemimic::enrol(frames, &options, None, None, &mut |_| true).unwrap();
    assert!(core.used.contains(&2), "the reference frame is kept");
    let bytes =
        facemimic::format::write_model_checked_as(&core.model, facemimic::format::Storage::I6)
            .unwrap();
    assert!(
        std::fs::read(&out).unwrap() == bytes,
        "facemimic build --find-faces and enrol give different models"
    );
}

/// `build --find-faces` applies the core's enrolment rules (issue 33's bad input): a frozen
/// camera (one picture 12 times) and two people alternating are errors that say so, and write
/// nothing.
#[test]
fn build_find_faces_refuses_a_frozen_camera_and_two_people() {
    let d = scratch("bad");
    let frozen = frames(&d, &["spk07_pwij3p/000010"; 12]);
    let out = d.join("frozen.fmm");
    let mut args: Vec<&Path> = vec![
        Path::new("build"),
        Path::new("--find-faces"),
        Path::new("--out"),
        &out,
    ];
    args.extend(frozen.iter().map(PathBuf::as_path));
    let o = run(&args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the camera seems frozen"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());

    let jpgs = |clip: &str| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(grid(clip))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
            .map(|p| format!("{clip}/{}", p.file_stem().unwrap().to_string_lossy()))
            .collect();
        v.sort();
        v.truncate(8);
        v
    };
    let stems: Vec<String> = jpgs("spk07_pwij3p")
        .into_iter()
        .zip(jpgs("spk02_brbk7n"))
        .flat_map(|(a, b)| [a, b])
        .collect();
    let stems: Vec<&str> = stems.iter().map(String::as_str).collect();
    let two = frames(&d, &stems);
    let out = d.join("two.fmm");
    let mut args: Vec<&Path> = vec![
        Path::new("build"),
        Path::new("--find-faces"),
        Path::new("--out"),
        &out,
    ];
    args.extend(two.iter().map(PathBuf::as_path));
    let o = run(&args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("two different people"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}

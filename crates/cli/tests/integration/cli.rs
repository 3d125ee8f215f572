//! The command-line tool, run as a process: `build`, `inspect`, `project`, `render` on GRID
//! data, and bad input (missing files, wrong formats, corrupt models, bad parameters), which
//! must end with one line on stderr, a non-zero exit and never a panic.

use facemimic_testkit as common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use serde_json::Value;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn grid(rel: &str) -> PathBuf {
    root().join("data/grid").join(rel)
}

/// A fresh scratch folder for one test.
fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("facemimic-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn ok(args: &[&dyn AsRef<std::ffi::OsStr>]) -> String {
    let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
    let out = run(&args);
    assert!(
        out.status.success(),
        "facemimic {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Runs a command that must fail cleanly; returns its one-line error message.
fn fails(args: &[&dyn AsRef<std::ffi::OsStr>]) -> String {
    let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
    let out = run(&args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "facemimic {args:?} succeeded; stderr: {err}"
    );
    assert_ne!(
        out.status.code(),
        None,
        "facemimic {args:?} was killed by a signal"
    );
    assert!(
        !err.contains("panicked") && !err.contains("internal error"),
        "facemimic {args:?} panicked: {err}"
    );
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines.len(),
        1,
        "facemimic {args:?}: expected one line on stderr, got: {err}"
    );
    assert!(
        lines[0].starts_with("facemimic: error: "),
        "facemimic {args:?}: {err}"
    );
    assert!(
        out.stdout.is_empty(),
        "facemimic {args:?} printed to stdout on failure"
    );
    println!("{}", lines[0]);
    lines[0].to_string()
}

/// The spk07 model built once by the CLI from train20 (shared by the tests of this file).
fn spk07_model() -> &'static Path {
    static MODEL: OnceLock<PathBuf> = OnceLock::new();
    MODEL.get_or_init(|| {
        let dir = scratch("model");
        let model = dir.join("spk07.fmm");
        let out = run(&[
            "build".as_ref(),
            "--out".as_ref(),
            model.as_os_str(),
            "--list".as_ref(),
            grid("spk07_pwij3p/train20.txt").as_os_str(),
        ]);
        assert!(
            out.status.success(),
            "build failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.stdout.is_empty(),
            "build prints its summary on stderr only"
        );
        model
    })
}

fn json(text: &str) -> Value {
    serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

/// Checks `inspect`'s report on the spk07 model; returns its shape and appearance mode counts.
fn assert_inspect_info(info: &Value) -> (u64, u64) {
    assert_eq!(info["landmarks"], 68);
    assert_eq!(info["channels"], 3);
    let (shape_modes, appearance_modes) = (
        info["shape_modes"].as_u64().unwrap(),
        info["appearance_modes"].as_u64().unwrap(),
    );
    assert!(
        (2..=19).contains(&shape_modes) && (2..=19).contains(&appearance_modes),
        "{info}"
    );
    assert_eq!(
        info["shape_sigma"].as_array().unwrap().len() as u64,
        shape_modes
    );
    assert_eq!(
        info["appearance_sigma"].as_array().unwrap().len() as u64,
        appearance_modes
    );
    let sig: Vec<f64> = info["shape_sigma"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        sig.windows(2).all(|w| w[0] >= w[1] && w[1] > 0.0),
        "shape sigmas descending: {sig:?}"
    );
    let (fw, fh, px) = (
        info["frame_width"].as_u64().unwrap(),
        info["frame_height"].as_u64().unwrap(),
        info["pixels"].as_u64().unwrap(),
    );
    assert!(
        fw >= 140 && fh >= 140 && px > fw * fh / 3 && px < fw * fh,
        "{info}"
    );
    assert!(info["triangles"].as_u64().unwrap() >= 90, "{info}");
    assert_eq!(
        info["frame_fingerprint"].as_str().unwrap().len(),
        16,
        "{info}"
    );

    (shape_modes, appearance_modes)
}

/// Checks a render of `frame`'s projection (`img`, its landmarks in `pts`) against the frame.
fn assert_render_matches_frame(img: &facemimic::Image, pts: &Path, frame: &Path) {
    // The rendered landmarks land where the frame's own landmarks are (0.98 of the shape
    // variance kept: the residual is a small fraction of a pixel to a pixel or so).
    let got = facemimic::io::read_landmarks(pts, 360, 288).unwrap();
    let want = facemimic::io::read_landmarks(&frame.with_extension("pts"), 360, 288).unwrap();
    let mean_dist = got
        .chunks_exact(2)
        .zip(want.chunks_exact(2))
        .map(|(a, b)| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt())
        .sum::<f32>()
        / 68.0;
    assert!(
        mean_dist < 1.5,
        "rendered landmarks {mean_dist} px from the frame's"
    );
    // The render looks like the frame over the face: compare the nose-and-mouth area.
    let original = facemimic::io::read_image(frame).unwrap();
    let (x0, x1) = (want[2 * 31] as usize, want[2 * 35] as usize);
    let (y0, y1) = (want[2 * 27 + 1] as usize, want[2 * 57 + 1] as usize);
    let (mut sq, mut n) = (0f64, 0usize);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let k = (y * 360 + x) * 4;
            for c in 0..3 {
                sq += (img.data[k + c] as f64 - original.data[k + c] as f64).powi(2);
                n += 1;
            }
        }
    }
    let rms = (sq / n as f64).sqrt();
    assert!(
        n > 300 && rms < 20.0,
        "render differs from the frame by RMS {rms} over {n} values"
    );
}

/// `build --reference rest`: the model's bases are its training frame most at rest (the core's
/// `most_at_rest` over the frames' landmarks), as `inspect` reports.
#[test]
fn build_about_the_face_at_rest() {
    let dir = scratch("rest");
    let list = grid("spk07_pwij3p/train20.txt");
    let model = dir.join("rest.fmm");
    ok(&[
        &"build",
        &"--out",
        &model,
        &"--list",
        &list,
        &"--reference",
        &"rest",
    ]);
    let images: Vec<facemimic::TrainingImage> = facemimic::io::read_list(&list)
        .unwrap()
        .iter()
        .map(|p| facemimic::io::read_training_image(p).unwrap())
        .collect();
    let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
    let rest = facemimic::most_at_rest(&shapes).unwrap();
    let info = json(&ok(&[&"inspect", &model]));
    assert_eq!(info["reference"], images[rest].name.as_str(), "{info}");
}

#[test]
fn build_inspect_project_render() {
    let model = spk07_model();
    let (shape_modes, appearance_modes) = assert_inspect_info(&json(&ok(&[&"inspect", &model])));

    // A frame of the clip that is not in train20.
    let frame = grid("spk07_pwij3p/000030.jpg");
    let params_text = ok(&[&"project", &"--model", &model, &frame]);
    let params = json(&params_text);
    assert_eq!(
        params["shape"].as_array().unwrap().len() as u64,
        shape_modes
    );
    assert_eq!(
        params["appearance"].as_array().unwrap().len() as u64,
        appearance_modes
    );
    for k in ["scale", "rotation", "tx", "ty"] {
        assert!(params["pose"][k].is_f64(), "pose.{k}: {params}");
    }
    // The face is at the middle of the 360x288 frame, about 150 model units -> ~75 px.
    let (tx, ty, scale) = (
        params["pose"]["tx"].as_f64().unwrap(),
        params["pose"]["ty"].as_f64().unwrap(),
        params["pose"]["scale"].as_f64().unwrap(),
    );
    assert!(
        (100.0..260.0).contains(&tx) && (80.0..220.0).contains(&ty) && (0.2..1.5).contains(&scale),
        "{params}"
    );

    let dir = scratch("render");
    let (p, png, pts) = (dir.join("p.json"), dir.join("out.png"), dir.join("out.pts"));
    std::fs::write(&p, &params_text).unwrap();
    ok(&[
        &"render",
        &"--model",
        &model,
        &"--params",
        &p,
        &"--out",
        &png,
        &"--out-pts",
        &pts,
    ]);
    let img = facemimic::io::read_image(&png).unwrap();
    assert_eq!(
        (img.width, img.height),
        (360, 288),
        "default canvas = training image size"
    );
    assert_render_matches_frame(&img, &pts, &frame);

    // The base face at another canvas size.
    let png2 = dir.join("mean.png");
    ok(&[
        &"render",
        &"--model",
        &model,
        &"--width",
        &"200",
        &"--height",
        &"150",
        &"--out",
        &png2,
    ]);
    let img2 = facemimic::io::read_image(&png2).unwrap();
    assert_eq!((img2.width, img2.height), (200, 150));
    std::fs::remove_dir_all(&dir).ok();
}

/// Bad input (here and in the `*_fail_cleanly` tests below) ends with one line on stderr, a
/// non-zero exit and never a panic: missing files.
#[test]
fn missing_files_fail_cleanly() {
    let model = spk07_model();
    let dir = scratch("bad-missing");
    let frame = grid("spk07_pwij3p/000030.jpg");
    let missing = dir.join("missing.fmm");
    let e = fails(&[&"inspect", &missing]);
    assert!(e.contains("missing.fmm"), "{e}");
    fails(&[&"project", &"--model", &missing, &frame]);
    fails(&[
        &"render",
        &"--model",
        &missing,
        &"--out",
        &dir.join("x.png"),
    ]);
    let e = fails(&[&"project", &"--model", &model, &dir.join("nothing.jpg")]);
    assert!(e.contains("nothing"), "{e}");
    fails(&[
        &"build",
        &"--out",
        &dir.join("m.fmm"),
        &dir.join("nothing.jpg"),
    ]);
    fails(&[
        &"build",
        &"--out",
        &dir.join("m.fmm"),
        &"--list",
        &dir.join("nothing.txt"),
    ]);
    fails(&[
        &"render",
        &"--model",
        &model,
        &"--params",
        &dir.join("nothing.json"),
        &"--out",
        &dir.join("x.png"),
    ]);

    std::fs::remove_dir_all(&dir).ok();
}

/// An image or a text file given as a model, a text file as an image, missing or wrong
/// landmarks, too few training images.
#[test]
fn wrong_formats_fail_cleanly() {
    let model = spk07_model();
    let dir = scratch("bad-formats");
    let frame = grid("spk07_pwij3p/000030.jpg");
    let e = fails(&[&"inspect", &frame]);
    assert!(e.contains("000030.jpg"), "{e}");
    fails(&[&"inspect", &grid("spk07_pwij3p/train20.txt")]);
    let text_image = dir.join("notes.jpg");
    std::fs::write(&text_image, "this is not a JPEG").unwrap();
    std::fs::copy(frame.with_extension("pts"), dir.join("notes.pts")).unwrap();
    fails(&[&"project", &"--model", &model, &text_image]);
    fails(&[
        &"build",
        &"--out",
        &dir.join("m.fmm"),
        &text_image,
        &text_image,
    ]);
    // An image without landmarks.
    std::fs::copy(&frame, dir.join("lonely.jpg")).unwrap();
    let e = fails(&[&"project", &"--model", &model, &dir.join("lonely.jpg")]);
    assert!(e.contains("landmark"), "{e}");
    // A landmark file with the wrong number of points.
    std::fs::copy(&frame, dir.join("few.jpg")).unwrap();
    std::fs::write(
        dir.join("few.pts"),
        "version: 1\nn_points: 3\n{\n1 1\n5 9\n9 1\n}\n",
    )
    .unwrap();
    fails(&[&"project", &"--model", &model, &dir.join("few.jpg")]);
    // One training image is not enough.
    fails(&[&"build", &"--out", &dir.join("m.fmm"), &frame]);

    std::fs::remove_dir_all(&dir).ok();
}

/// Corrupt models: truncated, flipped bytes, random bytes, empty.
#[test]
fn corrupt_models_fail_cleanly() {
    let model = spk07_model();
    let dir = scratch("bad-models");
    let bytes = std::fs::read(model).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty", Vec::new()),
        ("header-only", bytes[..bytes.len().min(16)].to_vec()),
        ("half", bytes[..bytes.len() / 2].to_vec()),
        ("one-short", bytes[..bytes.len() - 1].to_vec()),
        ("trailing", [bytes.as_slice(), b"junk"].concat()),
        (
            "random",
            (0..4096u32)
                .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
                .collect(),
        ),
        ("flipped", {
            let mut b = bytes.clone();
            let k = b.len() / 2;
            b[k] ^= 0x40;
            b
        }),
        ("magic", {
            let mut b = bytes.clone();
            b[0] ^= 0xff;
            b
        }),
    ];
    for (name, data) in cases {
        let p = dir.join(format!("{name}.fmm"));
        std::fs::write(&p, data).unwrap();
        let e = fails(&[&"inspect", &p]);
        assert!(e.contains(&format!("{name}.fmm")), "{name}: {e}");
        fails(&[&"render", &"--model", &p, &"--out", &dir.join("x.png")]);
        fails(&[
            &"build",
            &"--out",
            &dir.join("m.fmm"),
            &"--frame",
            &p,
            &"--list",
            &grid("spk02_brbk7n/train20.txt"),
        ]);
    }

    std::fs::remove_dir_all(&dir).ok();
}

/// Bad parameters: not JSON, NaN / infinite values, wrong lengths, zero scale.
#[test]
fn bad_parameters_fail_cleanly() {
    let model = spk07_model();
    let dir = scratch("bad-params");
    let frame = grid("spk07_pwij3p/000030.jpg");
    let params = json(&ok(&[&"project", &"--model", &model, &frame]));
    let shape_len = params["shape"].as_array().unwrap().len();
    let with = |f: &dyn Fn(&mut Value)| {
        let mut v = params.clone();
        f(&mut v);
        v.to_string()
    };
    let cases: Vec<(&str, String)> = vec![
        ("garbage", "{not json".into()),
        (
            "nan-literal",
            params
                .to_string()
                .replacen("\"shape\":[", "\"shape\":[NaN,", 1),
        ),
        ("nan-string", with(&|v| v["shape"][0] = Value::from("NaN"))),
        (
            "huge",
            params
                .to_string()
                .replacen("\"shape\":[", "\"shape\":[1e999,", 1),
        ),
        (
            "short",
            with(&|v| {
                v["shape"].as_array_mut().unwrap().pop();
            }),
        ),
        (
            "long-appearance",
            with(&|v| {
                v["appearance"]
                    .as_array_mut()
                    .unwrap()
                    .push(Value::from(0.0))
            }),
        ),
        (
            "zero-scale",
            with(&|v| v["pose"]["scale"] = Value::from(0.0)),
        ),
        (
            "no-pose",
            with(&|v| {
                v.as_object_mut().unwrap().remove("pose");
            }),
        ),
    ];
    assert!(shape_len >= 2);
    for (name, text) in cases {
        let p = dir.join(format!("{name}.json"));
        std::fs::write(&p, text).unwrap();
        let e = fails(&[
            &"render",
            &"--model",
            &model,
            &"--params",
            &p,
            &"--out",
            &dir.join("x.png"),
        ]);
        assert!(
            e.contains("param") || e.contains(&format!("{name}.json")),
            "{name}: {e}"
        );
        assert!(
            !dir.join("x.png").exists(),
            "{name}: an image was written despite the error"
        );
    }

    std::fs::remove_dir_all(&dir).ok();
}

/// Bad canvas sizes, an unwritable output, a variance fraction outside (0, 1].
#[test]
fn bad_sizes_and_outputs_fail_cleanly() {
    let model = spk07_model();
    let dir = scratch("bad-sizes");
    fails(&[
        &"render",
        &"--model",
        &model,
        &"--width",
        &"0",
        &"--height",
        &"10",
        &"--out",
        &dir.join("x.png"),
    ]);
    fails(&[
        &"render",
        &"--model",
        &model,
        &"--width",
        &"100000",
        &"--height",
        &"10",
        &"--out",
        &dir.join("x.png"),
    ]);
    fails(&[
        &"render",
        &"--model",
        &model,
        &"--out",
        &dir.join("no/such/folder/x.png"),
    ]);
    fails(&[
        &"build",
        &"--out",
        &dir.join("no/such/folder/m.fmm"),
        &"--list",
        &grid("spk07_pwij3p/train20.txt"),
    ]);
    fails(&[
        &"build",
        &"--out",
        &dir.join("m.fmm"),
        &"--shape-variance",
        &"1.5",
        &"--list",
        &grid("spk07_pwij3p/train20.txt"),
    ]);
    std::fs::remove_dir_all(&dir).ok();
}

/// `inspect` names the file's format version and storage precision; `build --precision` picks
/// the storage (default: the compact `i6`); a version-1 file still inspects.
#[test]
fn build_precision_and_inspect_version() {
    let model = spk07_model();
    let info = json(&ok(&[&"inspect", &model]));
    assert_eq!(info["format_version"], 3, "{info}");
    assert_eq!(info["backdrop"]["width"], 360, "{info}");
    assert_eq!(info["precision"], "i6", "{info}");
    let compact = std::fs::metadata(model).unwrap().len();
    let dir = scratch("precision");
    let exact = dir.join("spk07-f32.fmm");
    ok(&[
        &"build",
        &"--precision",
        &"f32",
        &"--out",
        &exact,
        &"--list",
        &grid("spk07_pwij3p/train20.txt"),
    ]);
    let info = json(&ok(&[&"inspect", &exact]));
    assert_eq!(info["precision"], "f32", "{info}");
    let exact_len = std::fs::metadata(&exact).unwrap().len();
    assert!(
        compact * 4 < exact_len,
        "i6 {compact} bytes vs f32 {exact_len} bytes"
    );
    let out = run(&[
        "build".as_ref(),
        "--precision".as_ref(),
        "f64".as_ref(),
        "--out".as_ref(),
        dir.join("x.fmm").as_os_str(),
    ]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "--precision f64 accepted");
    assert!(
        e.contains("unknown precision 'f64' (expected f32, f16, i8 or i6)"),
        "{e}"
    );
    let v1 =
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("tests/data/tiny-v1.fmm");
    let info = json(&ok(&[&"inspect", &v1]));
    assert_eq!(info["format_version"], 1, "{info}");
    assert_eq!(info["precision"], "f32", "{info}");
    assert_eq!(info["name"], "tiny-v1", "{info}");
}

/// `fit --init auto`: the face finder starts the track (GRID spk07, model built from the
/// `spk07_pwij3p` clip, tracked on the unseen `spk07_id2_vcd_swwp2s` clip); the CSV has a
/// `lost` column and the summary counts re-acquisitions and the second opinions (one every 15
/// tracked frames: one in 20 frames).
#[test]
fn fit_starts_from_the_face_finder() {
    let dir = scratch("fit-auto");
    let model = dir.join("spk07.fmm");
    ok(&[
        &"build",
        &"--list",
        &grid("spk07_pwij3p/train20.txt"),
        &"--out",
        &model,
    ]);
    let frames: Vec<PathBuf> = (0..20)
        .map(|i| grid(&format!("spk07_id2_vcd_swwp2s/{i:06}.jpg")))
        .collect();
    let csv = dir.join("track.csv");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"fit", &"--model", &model, &"--init", &"auto", &"--out", &csv,
    ];
    for f in &frames {
        args.push(f);
    }
    let out = ok(&args);
    assert!(out.contains("0 lost, 1 re-acquisitions"), "{out}");
    assert!(out.contains(", 1 second opinions ("), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("frame,lost,converged,"));
    for (l, f) in lines.zip(&frames) {
        let truth = facemimic::io::read_landmarks(&f.with_extension("pts"), 360, 288).unwrap();
        let v: Vec<&str> = l.split(',').collect();
        assert_eq!(v[1], "false", "{l}");
        let lm: Vec<f32> = v[5..5 + 136].iter().map(|s| s.parse().unwrap()).collect();
        let err = facemimic::find::landmark_error(&lm, &truth);
        assert!(err < 0.08, "{}: error {err}", v[0]);
    }
}

/// `fit --follow landmarks`: anyone followed with a model that is not theirs (spk07's model
/// on spk03's GRID clip), no `--init` needed; the CSV keeps the AAM track's columns; `--init`
/// is still needed to fit the AAM, and a bad `--fps` is refused.
#[test]
fn fit_follows_landmarks_with_another_persons_model() {
    let dir = scratch("fit-follow");
    let model = dir.join("spk07.fmm");
    ok(&[
        &"build",
        &"--list",
        &grid("spk07_pwij3p/train20.txt"),
        &"--out",
        &model,
    ]);
    let mut frames = common::clip_frames(&grid("spk03_lbax4n"));
    frames.truncate(10);
    let csv = dir.join("follow.csv");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"fit",
        &"--model",
        &model,
        &"--follow",
        &"landmarks",
        &"--out",
        &csv,
    ];
    for f in &frames {
        args.push(f);
    }
    let out = ok(&args);
    assert!(out.contains("followed by landmarks"), "{out}");
    assert!(out.contains("0 lost, 1 acquisitions"), "{out}");
    let header = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    assert!(header.starts_with("frame,lost,converged,iterations,error,x0,y0"));
    assert!(header.contains(",scale,rotation,tx,ty,p0,") && header.contains(",lambda0"));
    for (lm, f) in csv_landmarks(&csv).iter().zip(&frames) {
        let truth = facemimic::io::read_landmarks(&f.with_extension("pts"), 360, 288).unwrap();
        let e = facemimic::find::landmark_error(lm, &truth);
        assert!(e < 0.08, "{}: error {e}", f.display());
    }
    // The AAM still needs a start; a bad frame rate is refused.
    let no_init = Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args(["fit", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&csv)
        .arg(&frames[0])
        .output()
        .unwrap();
    assert!(!no_init.status.success());
    assert!(String::from_utf8_lossy(&no_init.stderr).contains("--init"));
    let bad_fps = Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .args(["fit", "--follow", "landmarks", "--fps", "NaN", "--model"])
        .arg(&model)
        .arg("--out")
        .arg(&csv)
        .arg(&frames[0])
        .output()
        .unwrap();
    assert!(!bad_fps.status.success());
    assert!(String::from_utf8_lossy(&bad_fps.stderr).contains("--fps"));
}

#[test]
fn a_reader_that_goes_away_is_not_an_error() {
    // `facemimic inspect M.fmm | head -c 1`: the reader closes the pipe before the JSON is
    // written; the command ends quietly with success instead of an "internal error".
    let mut child = Command::new(env!("CARGO_BIN_EXE_facemimic"))
        .arg("inspect")
        .arg(spk07_model())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn facemimic");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "exit {:?}: {err}", out.status);
    assert!(err.is_empty(), "stderr: {err}");
}

/// The landmarks of each data row of a track CSV (columns 5.. of 68 points).
fn csv_landmarks(csv: &Path) -> Vec<Vec<f32>> {
    let text = std::fs::read_to_string(csv).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            assert_eq!(v[1], "false", "lost: {l}");
            v[5..5 + 136].iter().map(|s| s.parse().unwrap()).collect()
        })
        .collect()
}

#[test]
fn fit_follows_a_large_face_at_the_policy_scale() {
    // spk07's unseen clip at 3x (1080x864, a face three times the model's size): the tracker's
    // policy fits it in a frame resampled to about the model's size, and the track (in the
    // large frame's pixels) matches the track of the original frames scaled by 3.
    let dir = scratch("fit-large");
    let frames: Vec<PathBuf> = (0..12)
        .map(|i| grid(&format!("spk07_id2_vcd_swwp2s/{i:06}.jpg")))
        .collect();
    let mut large = Vec::new();
    for f in &frames {
        let img = image::open(f).unwrap().to_rgb8();
        let big = image::imageops::resize(
            &img,
            img.width() * 3,
            img.height() * 3,
            image::imageops::FilterType::Triangle,
        );
        let p = dir.join(f.file_name().unwrap()).with_extension("png");
        big.save(&p).unwrap();
        large.push(p);
    }
    let init = facemimic::io::read_landmarks(&frames[0].with_extension("pts"), 360, 288).unwrap();
    let init3: Vec<f32> = init.iter().map(|v| 3.0 * (v + 0.5) - 0.5).collect();
    let init_path = dir.join("init3.pts");
    std::fs::write(&init_path, facemimic::landmarks::write_pts(&init3)).unwrap();

    let (small_csv, large_csv) = (dir.join("small.csv"), dir.join("large.csv"));
    let model = spk07_model();
    let first_pts = frames[0].with_extension("pts");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"fit", &"--model", &model, &"--init", &first_pts, &"--out", &small_csv,
    ];
    for f in &frames {
        args.push(f);
    }
    ok(&args);
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"fit", &"--model", &model, &"--init", &init_path, &"--out", &large_csv,
    ];
    for f in &large {
        args.push(f);
    }
    let out = ok(&args);
    println!("3x frames: {out}");
    assert!(out.contains("0 lost"), "{out}");
    // Fitted at about the model's scale: a third of the frame's.
    let k: f32 = out
        .split("fit scale ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no fit scale in {out}"));
    assert!((0.25..0.45).contains(&k), "fit scale {k}: {out}");
    let (small, big) = (csv_landmarks(&small_csv), csv_landmarks(&large_csv));
    assert_eq!(big.len(), frames.len());
    for (i, (s, b)) in small.iter().zip(&big).enumerate() {
        let iod = (s[90] - s[72]).hypot(s[91] - s[73]);
        let d = (0..68)
            .map(|j| {
                let (x, y) = (
                    (b[2 * j] + 0.5) / 3.0 - 0.5,
                    (b[2 * j + 1] + 0.5) / 3.0 - 0.5,
                );
                (x - s[2 * j]).hypot(y - s[2 * j + 1])
            })
            .sum::<f32>()
            / 68.0
            / iod;
        assert!(
            d < 0.03,
            "frame {i}: the large track is {d} off the small one"
        );
    }
}

/// Reads a PNG written by the CLI: (width, height, straight RGBA8).
fn png(path: &Path) -> (u32, u32, Vec<u8>) {
    let img = facemimic::io::read_image(path).unwrap();
    (img.width, img.height, img.data)
}

/// Whether the 8x8 top-left corner of an RGBA image is the face-only background (#202024).
fn corner_is_background(w: u32, data: &[u8]) -> bool {
    (0..8).all(|y| {
        (0..8).all(|x| {
            let i = 4 * (y * w as usize + x);
            data[i..i + 3] == [32, 32, 36]
        })
    })
}

/// Backdrops and compositing from the command line: `build --backdrop IMG`, `--no-backdrop`,
/// `inspect`, `render --composite` (a PNG the size of the backdrop). Photo targets below.
#[test]
fn backdrops_and_composites() {
    let dir = scratch("composite");
    let spk02 = dir.join("spk02.fmm");
    let backdrop = grid("spk02_brbk7n/000010.jpg");
    let err = ok(&[
        &"build",
        &"--out",
        &spk02,
        &"--list",
        &grid("spk02_brbk7n/train20.txt"),
        &"--backdrop",
        &backdrop,
    ]);
    assert!(err.is_empty());
    let info = json(&ok(&[&"inspect", &spk02]));
    let b = &info["backdrop"];
    assert_eq!(
        (b["width"].as_u64(), b["height"].as_u64()),
        (Some(360), Some(288)),
        "{info}"
    );
    assert!(
        b["bytes"].as_u64().unwrap() <= b["budget_bytes"].as_u64().unwrap(),
        "{info}"
    );
    assert!(b["bytes"].as_u64().unwrap() > 4000, "{info}");
    assert_eq!(info["photo_target"], false);

    // render --composite: the backdrop's size, the picture all round the face.
    let out = dir.join("composite.png");
    ok(&[
        &"render",
        &"--model",
        &spk02,
        &"--composite",
        &"--out",
        &out,
    ]);
    let (w, h, data) = png(&out);
    assert_eq!((w, h), (360, 288));
    assert!(!corner_is_background(w, &data), "the backdrop is missing");
    // Face only, as before.
    let face = dir.join("face.png");
    ok(&[&"render", &"--model", &spk02, &"--out", &face]);
    let (w, _, data) = png(&face);
    assert!(corner_is_background(w, &data));

    // Without a backdrop: compositing renders the face only, with a notice.
    let bare = dir.join("bare.fmm");
    ok(&[
        &"build",
        &"--out",
        &bare,
        &"--list",
        &grid("spk02_brbk7n/train20.txt"),
        &"--no-backdrop",
    ]);
    assert_eq!(json(&ok(&[&"inspect", &bare]))["backdrop"], Value::Null);
    let o = run(&[
        "render".as_ref(),
        "--model".as_ref(),
        bare.as_os_str(),
        "--composite".as_ref(),
        "--out".as_ref(),
        dir.join("bare.png").as_os_str(),
    ]);
    assert!(o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("no backdrop; rendering the face only"), "{e}");
    let (w, _, data) = png(&dir.join("bare.png"));
    assert!(corner_is_background(w, &data));
}

/// `build --photo`: a photo target from its .pts, and one from the face finder (the photo copied
/// alone); `clone --composite` onto it.
#[test]
fn photo_targets_and_clone_composites() {
    let dir = scratch("photo");
    let photo = dir.join("photo.fmm");
    ok(&[
        &"build",
        &"--photo",
        &grid("spk03_lbax4n/000000.jpg"),
        &"--out",
        &photo,
    ]);
    let info = json(&ok(&[&"inspect", &photo]));
    assert_eq!(info["photo_target"], true, "{info}");
    assert_eq!(info["backdrop"]["width"], 360, "{info}");
    let alone = dir.join("alone.jpg");
    std::fs::copy(grid("spk03_lbax4n/000000.jpg"), &alone).unwrap();
    let found = dir.join("found.fmm");
    ok(&[&"build", &"--photo", &alone, &"--out", &found]);
    assert_eq!(json(&ok(&[&"inspect", &found]))["photo_target"], true);

    // clone --composite onto the photo: `map` falls back to substitution with a notice.
    let params = dir.join("p.json");
    let p = ok(&[
        &"project",
        &"--model",
        &spk07_model(),
        &grid("spk07_id2_vcd_swwp2s/000024.jpg"),
    ]);
    std::fs::write(&params, p).unwrap();
    let cloned = dir.join("clone.png");
    let o = run(&[
        "clone".as_ref(),
        "--source".as_ref(),
        spk07_model().as_os_str(),
        "--target".as_ref(),
        photo.as_os_str(),
        "--params".as_ref(),
        params.as_os_str(),
        "--method".as_ref(),
        "map".as_ref(),
        "--composite".as_ref(),
        "--out".as_ref(),
        cloned.as_os_str(),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("photo target") && e.contains("substitution"),
        "{e}"
    );
    let (w, h, data) = png(&cloned);
    assert_eq!((w, h), (360, 288));
    assert!(!corner_is_background(w, &data));
    // The cloned face differs from the photo's own (the source's expression is on it).
    let own = dir.join("own.png");
    ok(&[
        &"render",
        &"--model",
        &photo,
        &"--composite",
        &"--out",
        &own,
    ]);
    assert_ne!(png(&own).2, data);
    std::fs::remove_dir_all(&dir).ok();
}

/// Bad photos fail cleanly: no face, a face under 64 px, landmarks outside, beyond the image
/// limit (also as a backdrop).
#[test]
fn bad_photos_fail_cleanly() {
    let dir = scratch("bad-photos");
    let flat = dir.join("flat.png");
    facemimic::io::write_png(&flat, 320, 240, &vec![128u8; 320 * 240 * 4]).unwrap();
    let e = fails(&[&"build", &"--photo", &flat, &"--out", &dir.join("x.fmm")]);
    assert!(e.contains("flat.png") && e.contains("face"), "{e}");
    let small = dir.join("small.png");
    let t = facemimic::io::read_training_image(&grid("spk03_lbax4n/000000.jpg")).unwrap();
    facemimic::io::write_png(&small, t.image.width, t.image.height, &t.image.data).unwrap();
    let small_face = t
        .landmarks
        .chunks_exact(2)
        .map(|p| (150.0 + p[0] * 0.2, 100.0 + p[1] * 0.2));
    std::fs::write(dir.join("small.pts"), pts_text(small_face)).unwrap();
    let e = fails(&[&"build", &"--photo", &small, &"--out", &dir.join("x.fmm")]);
    assert!(e.contains("64"), "{e}");
    let outside = dir.join("outside.png");
    std::fs::copy(&small, &outside).unwrap();
    // Point 0 outside the image.
    let shifted = t.landmarks.chunks_exact(2).enumerate();
    let shifted = shifted.map(|(i, p)| (if i == 0 { -30.0 } else { p[0] + 1.0 }, p[1] + 1.0));
    std::fs::write(dir.join("outside.pts"), pts_text(shifted)).unwrap();
    let e = fails(&[&"build", &"--photo", &outside, &"--out", &dir.join("x.fmm")]);
    assert!(e.contains("outside"), "{e}");
    let e = fails(&[
        &"build",
        &"--out",
        &dir.join("x.fmm"),
        &"--list",
        &grid("spk02_brbk7n/train20.txt"),
        &"--backdrop",
        &outside,
    ]);
    assert!(e.contains("outside"), "{e}");
    let huge = dir.join("huge.png");
    facemimic::io::write_png(&huge, 9000, 4, &vec![0u8; 9000 * 4 * 4]).unwrap();
    let e = fails(&[&"build", &"--photo", &huge, &"--out", &dir.join("x.fmm")]);
    assert!(e.contains("9000"), "{e}");
    assert!(!dir.join("x.fmm").exists(), "a failed build wrote a file");
    std::fs::remove_dir_all(&dir).ok();
}

/// An iBUG `.pts` file of 68 `points`.
fn pts_text(points: impl Iterator<Item = (f32, f32)>) -> String {
    let mut s = String::from("version: 1\nn_points: 68\n{\n");
    for (x, y) in points {
        s += &format!("{x} {y}\n");
    }
    s + "}\n"
}

/// The track the CLI and the npm package must agree on: the tiny model
/// (`tests/data/tiny-v1.fmm`) on the first six frames of spk07's unseen clip enlarged twice
/// (nearest: each pixel a 2x2 block, 720x576), so the tracker fits a copy resampled to about the
/// model's size and maps the fit back: the pixel convention is exercised, not only the fit.
const GOLDEN_TRACK: &str = "tests/data/tiny-track.csv";

/// `img` enlarged twice (each pixel a 2x2 block), as `crates/wasm/tests/integration/wasm_tracker.rs` does it.
fn doubled(img: &facemimic::Image) -> image::RgbaImage {
    image::RgbaImage::from_fn(img.width * 2, img.height * 2, |x, y| {
        let i = (((y / 2) * img.width + x / 2) * 4) as usize;
        image::Rgba([img.data[i], img.data[i + 1], img.data[i + 2], 255])
    })
}

/// `fit` gives the golden track, number for number (landmarks, pose, parameters and the
/// placement, `placed_*`), that `crates/wasm/tests/integration/wasm_tracker.rs` (`tracks_the_golden_frames_as_the_cli`)
/// checks the npm package's `Tracker` against: the CLI and the page call one core tracker
/// the same way. `FACEMIMIC_BLESS=1` rewrites the golden file (look at what changed).
#[test]
fn fit_gives_the_golden_track_the_npm_package_gives() {
    let dir = scratch("fit-golden");
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let model = root.join("tests/data/tiny-v1.fmm");
    let frames: Vec<PathBuf> = (0..6)
        .map(|i| {
            let jpeg = grid(&format!("spk07_id2_vcd_swwp2s/{i:06}.jpg"));
            let png = dir.join(format!("{i:06}.png"));
            doubled(&facemimic::io::read_image(&jpeg).unwrap())
                .save(&png)
                .unwrap();
            png
        })
        .collect();
    let lm =
        facemimic::io::read_landmarks(&grid("spk07_id2_vcd_swwp2s/000000.pts"), 360, 288).unwrap();
    let lm2: Vec<f32> = lm.iter().map(|v| 2.0 * (v + 0.5) - 0.5).collect();
    let init = dir.join("init2.pts");
    std::fs::write(&init, facemimic::landmarks::write_pts(&lm2)).unwrap();
    let csv = dir.join("track.csv");
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![
        &"fit", &"--model", &model, &"--init", &init, &"--fps", &"25", &"--out", &csv,
    ];
    for f in &frames {
        args.push(f);
    }
    let out = ok(&args);
    let k: f32 = out
        .split("fit scale ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no fit scale in {out}"));
    assert!(k < 0.9, "the frames should be fitted resampled: {out}");
    let got = std::fs::read_to_string(&csv).unwrap();
    let golden = root.join(GOLDEN_TRACK);
    if std::env::var_os("FACEMIMIC_BLESS").is_some_and(|v| v == "1") {
        std::fs::write(&golden, &got).unwrap();
    }
    let want = std::fs::read_to_string(&golden).unwrap();
    let (got, want): (Vec<&str>, Vec<&str>) = (got.lines().collect(), want.lines().collect());
    assert_eq!(got.len(), want.len());
    assert_eq!(got[0], want[0], "header");
    assert!(got[0].ends_with(",placed_scale,placed_rotation,placed_tx,placed_ty"));
    for (g, w) in got[1..].iter().zip(&want[1..]) {
        let (g, w): (Vec<&str>, Vec<&str>) = (g.split(',').collect(), w.split(',').collect());
        assert_eq!(g[..3], w[..3], "frame, lost, converged");
        for (i, (a, b)) in g[3..].iter().zip(&w[3..]).enumerate() {
            let (a, b): (f32, f32) = (a.parse().unwrap(), b.parse().unwrap());
            assert!(
                (a - b).abs() <= 1e-3 * (1.0 + b.abs()),
                "{}: column {}: {a} vs golden {b}",
                g[0],
                i + 3
            );
        }
    }
}

/// `args` as `ok` and `fails` take them.
fn dyns(v: &[std::ffi::OsString]) -> Vec<&dyn AsRef<std::ffi::OsStr>> {
    v.iter().map(|x| x as &dyn AsRef<std::ffi::OsStr>).collect()
}

/// `clone --method` takes every method of the core's one list (`Method::ALL`), with the
/// expressive method's region gains and style; a wrong name or style fails with the list.
#[test]
fn clone_takes_every_method_of_the_list() {
    let model = spk07_model();
    let dir = scratch("methods");
    let frame = grid("spk07_id2_vcd_swwp2s/000017.jpg");
    // `clone` of the frame onto spk07 itself, with `extra` arguments.
    let args = |extra: &[&str]| -> Vec<std::ffi::OsString> {
        let mut v: Vec<std::ffi::OsString> = ["clone", "--source"].map(Into::into).to_vec();
        v.extend([
            model.as_os_str().into(),
            "--target".into(),
            model.as_os_str().into(),
        ]);
        v.extend(["--image".into(), frame.as_os_str().into()]);
        v.extend(extra.iter().map(Into::into));
        v
    };
    for m in facemimic::clone::Method::ALL {
        let out = dir.join(format!("{}.png", m.name()));
        let extra = [
            "--method",
            m.name(),
            "--mouth-gain",
            "1.5",
            "--style",
            "0.8",
            "--out",
        ];
        let mut a = args(&extra);
        a.push(out.as_os_str().into());
        ok(&dyns(&a));
        assert!(facemimic::io::read_image(&out).is_ok(), "{}", m.name());
    }
    let refused = |extra: &[&str]| fails(&dyns(&args(extra)));
    let err = refused(&["--method", "laugh"]);
    for m in facemimic::clone::Method::ALL {
        assert!(err.contains(m.name()), "{err}");
    }
    let err = refused(&["--style", "2"]);
    assert!(err.contains("style"), "{err}");
}

/// The TypeScript `Method` type of the wasm package and of the npm README list exactly the
/// core's methods, in its order.
#[test]
fn the_typescript_method_type_is_the_core_list() {
    let want: Vec<String> = facemimic::clone::Method::ALL
        .iter()
        .map(|m| format!("\"{}\"", m.name()))
        .collect();
    for file in ["crates/wasm/src/lib.rs", "npm/README.md"] {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        let line = text
            .lines()
            .find(|l| l.contains("type Method = "))
            .unwrap_or_else(|| panic!("{file}: no `type Method`"));
        let names: Vec<String> = line
            .split('=')
            .nth(1)
            .unwrap()
            .trim_end_matches(';')
            .split('|')
            .map(|s| s.trim().trim_end_matches(';').to_string())
            .collect();
        assert_eq!(names, want, "{file}");
    }
}

/// Every error code the package can throw is listed once, the same, in the wasm layer
/// (`CODES`), the JS entry (`ERROR_CODES`), the TypeScript `ErrorCode` type and the npm
/// README's table; and every kind of the core's `Error` has its code among them.
#[test]
fn the_error_codes_agree_everywhere() {
    let read = |file: &str| std::fs::read_to_string(root().join(file)).unwrap();
    let quoted = |text: &str| -> Vec<String> {
        text.split('"')
            .skip(1)
            .step_by(2)
            .map(str::to_string)
            .collect()
    };
    let between = |text: &str, start: &str, end: &str| -> String {
        let i = text.find(start).unwrap_or_else(|| panic!("no {start}"));
        let rest = &text[i + start.len()..];
        rest[..rest
            .find(end)
            .unwrap_or_else(|| panic!("no {end} after {start}"))]
            .to_string()
    };
    let mut wasm = quoted(&between(
        &read("crates/wasm/src/error.rs"),
        "pub const CODES",
        "];",
    ));
    let mut js = quoted(&between(
        &read("npm/facemimic.js"),
        "ERROR_CODES = Object.freeze([",
        "]",
    ));
    let mut ts = quoted(&between(
        &read("npm/facemimic.d.ts"),
        "export type ErrorCode =",
        ";",
    ));
    let readme = read("npm/README.md");
    let table = between(&readme, "| code | when |", "\n\n");
    let mut documented: Vec<String> = table
        .lines()
        .flat_map(|l| {
            l.split('|')
                .nth(1)
                .unwrap_or("")
                .split(['`', ',', '/'])
                .map(str::trim)
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .filter(|s| {
            s.starts_with(|c: char| c.is_ascii_lowercase())
                && s.chars().all(|c| c.is_ascii_lowercase() || c == '-')
        })
        .collect();
    for list in [&mut wasm, &mut js, &mut ts, &mut documented] {
        list.sort();
        list.dedup();
    }
    assert_eq!(js, ts, "ERROR_CODES and ErrorCode differ");
    assert_eq!(js, documented, "the README's table lists other codes");
    for c in &wasm {
        assert!(
            js.contains(c),
            "the wasm layer's code {c} is not in the JS entry's list"
        );
    }
    use facemimic::{Error, FormatError};
    let kinds = [
        Error::Landmarks(String::new()),
        Error::Format(FormatError::BadMagic),
        Error::Training(String::new()),
        Error::Incompatible(String::new()),
        Error::Params(String::new()),
        Error::Image(String::new()),
        Error::Io(String::new()),
        Error::Cancelled,
        Error::Weights(String::new()),
        Error::Overflow(String::new()),
        Error::Budget(String::new()),
        Error::Cancelled.with_context("file"),
    ];
    for e in kinds {
        assert!(
            wasm.contains(&e.code().to_string()),
            "{e:?}: {} is not in CODES",
            e.code()
        );
    }
}

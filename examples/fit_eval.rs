//! Tracking accuracy of the fitter on the shared clips, for comparing fitter variants:
//! `cargo run --release --example fit_eval -- [SET...]`. Sets (models built in-process, every
//! figure measured on frames no model was built from):
//! - `grid`: spk07 from `spk07_pwij3p/train20.txt`, the unseen clip `spk07_id2_vcd_swwp2s`
//!   (75 frames) from its first frame's landmarks;
//! - `franck2`: from `franck-dev/train20.txt`, all 1000 frames of `franck-dev2` from the first
//!   frame's landmarks; `franck2-auto`: the same started (and re-acquired) by the face finder;
//! - `webcam`: from webcam-dev frames 0, 30, ..., 570, frames 600-1336 from frame 600's
//!   landmarks; `webcam-auto`: the same started (and re-acquired) by the face finder;
//! - `grid-basin`, `franck-basin`: cold fits from perturbed landmarks (as `tests/fit.rs`);
//! - `franck2-floor`: the shape model's floor (dlib landmarks projected onto it) and fits
//!   started from each frame's dlib landmarks;
//! - `dump-franck2`: writes the franck model and franck-dev2 frames 3800-4099 as raw RGBA into
//!   `$FIT_EVAL_DUMP` (default `target/fit-bench`) for `scripts/fit-bench-wasm.cjs`.
//!
//! `FIT_OPTIONS='{"refine_iters": 2}'` overrides fields of `FitOptions::default()`;
//! `FRAME=own` builds in the model's own frame instead of the canonical one;
//! `SHAPE_VARIANCE`, `APPEARANCE_VARIANCE` set the builder's kept variance fractions.
//! Error: mean landmark distance / distance of landmarks 36 and 45 (dlib points).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    native::main()
}

/// Native only: the example reads files.
#[cfg(not(target_arch = "wasm32"))]
mod native {
    use std::path::{Path, PathBuf};
    use std::time::Instant;

    use facemimic::fit::{FitOptions, Fitter, Tracker};
    use facemimic::{
        io, BuildOptions, Builder, FaceFinder, FrameChoice, Model, Similarity, TrainingImage,
    };

    fn data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
    }

    fn repo(p: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
    }

    fn options() -> FitOptions {
        let mut v = serde_json::to_value(FitOptions::default()).unwrap();
        if let Ok(s) = std::env::var("FIT_OPTIONS") {
            let o: serde_json::Value = serde_json::from_str(&s).expect("FIT_OPTIONS: JSON");
            for (k, x) in o.as_object().expect("FIT_OPTIONS: an object") {
                assert!(v.get(k).is_some(), "FIT_OPTIONS: unknown field {k}");
                v[k] = x.clone();
            }
        }
        serde_json::from_value(v).expect("FIT_OPTIONS: valid options")
    }

    fn build(paths: &[PathBuf]) -> Model {
        let images: Vec<TrainingImage> = paths
            .iter()
            .map(|p| io::read_training_image(p).unwrap())
            .collect();
        let frame = match std::env::var("FRAME").as_deref() {
            Ok("own") => FrameChoice::Own,
            _ => FrameChoice::Canonical,
        };
        let var = |k: &str| std::env::var(k).ok().map(|v| v.parse::<f64>().unwrap());
        let d = BuildOptions::default();
        Builder::new(BuildOptions {
            frame,
            shape_variance: var("SHAPE_VARIANCE").unwrap_or(d.shape_variance),
            appearance_variance: var("APPEARANCE_VARIANCE").unwrap_or(d.appearance_variance),
            ..d
        })
        .build(&images, None)
        .unwrap()
    }

    fn load(paths: &[PathBuf]) -> Vec<TrainingImage> {
        paths
            .iter()
            .map(|p| io::read_training_image(p).unwrap())
            .collect()
    }

    fn all_frames(dir: &Path) -> Vec<PathBuf> {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "jpg"))
            .collect();
        paths.sort();
        paths
    }

    fn numbered(dir: &Path, range: impl Iterator<Item = usize>) -> Vec<PathBuf> {
        range.map(|i| dir.join(format!("{i:06}.jpg"))).collect()
    }

    fn norm_error(fit: &[f32], truth: &[f32]) -> f32 {
        let iod = ((truth[90] - truth[72]).powi(2) + (truth[91] - truth[73]).powi(2)).sqrt();
        let n = truth.len() / 2;
        let sum: f32 = (0..n)
            .map(|i| {
                ((fit[2 * i] - truth[2 * i]).powi(2) + (fit[2 * i + 1] - truth[2 * i + 1]).powi(2))
                    .sqrt()
            })
            .sum();
        sum / n as f32 / iod
    }

    fn track(name: &str, model: &Model, seq: &[TrainingImage], auto: bool) {
        let mut t = Tracker::new(model, options()).unwrap();
        if auto {
            t.set_face_source(Box::new(FaceFinder::new().unwrap()));
            t.start_auto().unwrap();
        } else {
            t.start_from_landmarks(&seq[0].landmarks).unwrap();
        }
        let mut errs = Vec::new();
        let mut groups = [0f64; 5];
        let mut iters = 0u64;
        let t0 = Instant::now();
        for f in seq {
            let r = t.track(&f.image.view().unwrap()).unwrap();
            iters += r.iterations as u64;
            let tr = &f.landmarks;
            let iod = ((tr[90] - tr[72]).powi(2) + (tr[91] - tr[73]).powi(2)).sqrt();
            for (g, range) in [0..17, 17..27, 27..36, 36..48, 48..68]
                .into_iter()
                .enumerate()
            {
                let k = range.len() as f64;
                for i in range {
                    let d = ((r.landmarks[2 * i] - tr[2 * i]).powi(2)
                        + (r.landmarks[2 * i + 1] - tr[2 * i + 1]).powi(2))
                    .sqrt();
                    groups[g] += (d / iod) as f64 / k;
                }
            }
            errs.push(if r.lost {
                f32::INFINITY
            } else {
                norm_error(&r.landmarks, &f.landmarks)
            });
        }
        let secs = t0.elapsed().as_secs_f64();
        let fin: Vec<f32> = errs.iter().copied().filter(|e| e.is_finite()).collect();
        let mean = fin.iter().sum::<f32>() / fin.len().max(1) as f32;
        let (wi, max) = fin
            .iter()
            .enumerate()
            .fold((0, 0f32), |a, (i, &e)| if e > a.1 { (i, e) } else { a });
        let over = errs.iter().filter(|&&e| e > 0.1).count();
        println!(
            "{name}: {} frames, mean {mean:.4}, max {max:.4} (frame {wi}), {over} above 0.1 \
             (lost counted), lost {}, resets {}, reacquisitions {}, {:.1} iterations, {:.0} fits/s",
            errs.len(),
            t.lost_count(),
            t.resets(),
            t.reacquisitions(),
            iters as f64 / errs.len() as f64,
            errs.len() as f64 / secs
        );
        let n = errs.len() as f64;
        println!(
            "  by group: jaw {:.4}, brows {:.4}, nose {:.4}, eyes {:.4}, mouth {:.4}",
            groups[0] / n,
            groups[1] / n,
            groups[2] / n,
            groups[3] / n,
            groups[4] / n
        );
        if std::env::var_os("FIT_EVAL_FRAMES").is_some() {
            for (i, e) in errs.iter().enumerate() {
                println!("  {i} {e:.4}");
            }
        }
    }

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            ((self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) as f32
        }
    }

    fn perturb(lm: &[f32], rng: &mut Rng) -> Vec<f32> {
        let n = lm.len() / 2;
        let (mut cx, mut cy) = (0.0, 0.0);
        for p in lm.chunks_exact(2) {
            cx += p[0] / n as f32;
            cy += p[1] / n as f32;
        }
        let xs = lm.iter().step_by(2);
        let width =
            xs.clone().copied().fold(f32::MIN, f32::max) - xs.copied().fold(f32::MAX, f32::min);
        let (dx, dy) = (0.05 * width * rng.next(), 0.05 * width * rng.next());
        let rot = 5f32.to_radians() * rng.next();
        let scale = 1.0 + 0.05 * rng.next();
        let t = Similarity::from_parts(scale, rot, 0.0, 0.0);
        lm.chunks_exact(2)
            .flat_map(|p| {
                let (x, y) = t.apply_point(p[0] - cx, p[1] - cy);
                [x + cx + dx, y + cy + dy]
            })
            .collect()
    }

    fn basin(name: &str, model: &Model, frames: &[TrainingImage], per: usize, seed: u64) {
        let mut fitter = Fitter::new(model, options()).unwrap();
        let mut rng = Rng(seed);
        let (mut good, mut total, mut sum) = (0, 0, 0f32);
        for f in frames {
            let view = f.image.view().unwrap();
            for _ in 0..per {
                let init = perturb(&f.landmarks, &mut rng);
                let r = fitter.fit(&view, &init).unwrap();
                let e = norm_error(&r.landmarks, &f.landmarks);
                total += 1;
                sum += e;
                if e < 0.05 {
                    good += 1;
                }
            }
        }
        println!(
            "{name}: {total} fits, {:.1}% below 0.05, mean {:.4}",
            100.0 * good as f32 / total as f32,
            sum / total as f32
        );
    }

    fn stems(list: &Path) -> Vec<String> {
        io::read_list(list)
            .unwrap()
            .iter()
            .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
            .collect()
    }

    pub(crate) fn main() {
        let mut sets: Vec<String> = std::env::args().skip(1).collect();
        if sets.is_empty() {
            sets = ["grid", "franck2", "webcam"].map(String::from).to_vec();
        }
        let d = data();
        for set in sets {
            match set.as_str() {
                "grid" => {
                    let m =
                        build(&io::read_list(&repo("data/grid/spk07_pwij3p/train20.txt")).unwrap());
                    let seq = load(&all_frames(&repo("data/grid/spk07_id2_vcd_swwp2s")));
                    track("grid", &m, &seq, false);
                }
                "franck2" | "franck2-auto" => {
                    let m = build(&io::read_list(&d.join("franck-dev/train20.txt")).unwrap());
                    let seq = load(&all_frames(&d.join("franck-dev2")));
                    track(&set, &m, &seq, set == "franck2-auto");
                }
                "dump-franck2" => {
                    // For the wasm benchmark (scripts/fit-bench-wasm.cjs): the franck model and
                    // franck-dev2 frames 3800-4099 as raw RGBA, frame 3800's landmarks.
                    let out = PathBuf::from(
                        std::env::var("FIT_EVAL_DUMP").unwrap_or("target/fit-bench".into()),
                    );
                    std::fs::create_dir_all(&out).unwrap();
                    let m = build(&io::read_list(&d.join("franck-dev/train20.txt")).unwrap());
                    std::fs::write(out.join("model.fmm"), facemimic::format::write_model(&m))
                        .unwrap();
                    for i in 3800..4100 {
                        let f = io::read_training_image(&d.join(format!("franck-dev2/{i:06}.jpg")))
                            .unwrap();
                        let [w, h] = [f.image.width, f.image.height];
                        std::fs::write(out.join(format!("{i}.rgba")), &f.image.data).unwrap();
                        if i == 3800 {
                            let s: Vec<String> =
                                f.landmarks.iter().map(|v| v.to_string()).collect();
                            std::fs::write(out.join("init.txt"), s.join(" ")).unwrap();
                            std::fs::write(out.join("size.txt"), format!("{w} {h}")).unwrap();
                        }
                    }
                    println!("dump-franck2: model and 300 frames in {}", out.display());
                }
                "franck2-floor" => {
                    // The shape model's own floor: each frame's dlib landmarks projected onto
                    // the model (pose and p), and a fit started from them.
                    let m = build(&io::read_list(&d.join("franck-dev/train20.txt")).unwrap());
                    let seq = load(&all_frames(&d.join("franck-dev2")));
                    let mut fitter = Fitter::new(&m, options()).unwrap();
                    let (mut proj, mut fit) = (0f32, 0f32);
                    let mut p = vec![0f32; m.shape().n_modes()];
                    let mut inst = vec![0f32; m.shape().base.len()];
                    for f in &seq {
                        let pose = m.shape().project_image_shape(&f.landmarks, &mut p).unwrap();
                        m.shape().instance(&p, &mut inst).unwrap();
                        pose.apply_in_place(&mut inst);
                        proj += norm_error(&inst, &f.landmarks);
                        let r = fitter.fit(&f.image.view().unwrap(), &f.landmarks).unwrap();
                        fit += norm_error(&r.landmarks, &f.landmarks);
                    }
                    let n = seq.len() as f32;
                    println!(
                        "franck2-floor: {} shape modes, projection {:.4}, fit from the truth {:.4}",
                        p.len(),
                        proj / n,
                        fit / n
                    );
                }
                "webcam" | "webcam-auto" => {
                    let w = d.join("webcam-dev");
                    let m = build(&numbered(&w, (0..600).step_by(30)));
                    let seq = load(&numbered(&w, 600..1337));
                    track(&set, &m, &seq, set == "webcam-auto");
                }
                "grid-basin" => {
                    let list = repo("data/grid/spk07_pwij3p/train20.txt");
                    let m = build(&io::read_list(&list).unwrap());
                    let train = stems(&list);
                    let mut held: Vec<PathBuf> =
                        all_frames(&repo("data/grid/spk07_id2_vcd_swwp2s"))
                            .into_iter()
                            .step_by(3)
                            .collect();
                    held.extend(
                        all_frames(&repo("data/grid/spk07_pwij3p"))
                            .into_iter()
                            .filter(|p| {
                                !train.contains(
                                    &p.file_stem().unwrap().to_string_lossy().into_owned(),
                                )
                            })
                            .step_by(3),
                    );
                    basin("grid-basin", &m, &load(&held), 4, 0x5eed_0001);
                }
                "franck-basin" => {
                    let list = d.join("franck-dev/train20.txt");
                    let m = build(&io::read_list(&list).unwrap());
                    let train = stems(&list);
                    let held: Vec<PathBuf> = all_frames(&d.join("franck-dev"))
                        .into_iter()
                        .filter(|p| {
                            !train.contains(&p.file_stem().unwrap().to_string_lossy().into_owned())
                        })
                        .step_by(10)
                        .collect();
                    basin("franck-basin", &m, &load(&held), 2, 0x5eed_0002);
                }
                other => panic!("unknown set {other}"),
            }
        }
    }
}

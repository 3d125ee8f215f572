//! Tracking accuracy of the fitter on the shared clips, for comparing fitter variants:
//! `cargo run --release --example fit_eval -- [SET...]`. Sets (models built in-process, every
//! figure measured on frames no model was built from):
//! - `grid`: spk07 from `spk07_pwij3p/train20.txt`, the unseen clip `spk07_id2_vcd_swwp2s`
//!   (75 frames) from its first frame's landmarks;
//! - `franck2`: from `franck-dev/train20.txt`, all 1000 frames of `franck-dev2` from the first
//!   frame's landmarks; `franck2-auto`: the same started (and re-acquired) by the face finder;
//! - `webcam`: from webcam-dev frames 0, 30, ..., 570, frames 600-1336 from frame 600's
//!   landmarks; `webcam-auto`: the same started (and re-acquired) by the face finder;
//! - `webcam-fps`: the reference model of `tests/integration/enrol_webcam.rs`: the dlib landmarks of every
//!   5th frame of webcam-dev 0-599, 20 chosen by farthest-point sampling (`select_varied`),
//!   tracked over 600-1336 from the face finder's landmarks on frame 600 (the 1200-1299
//!   stretch, a hand over the chin, reported apart); `enrol`: the same with the enrolment
//!   finder's landmarks (`EnrolFinder`, as `tests/integration/enrol_webcam.rs`);
//! - `control`: the control row of `examples/enrol_eval.rs`: the dlib landmarks of the frames
//!   of webcam-dev 0-599 (every 5th) the face finder scores >= 0.5, 20 chosen by
//!   farthest-point sampling, tracked over 600-1336 from the finder's frame-600 landmarks
//!   (1190-1289, the hand, reported apart); prints the left-out frames' shapes in the model's
//!   standard deviations; `CONTROL_KEEP=490,495,...` keeps those frames whatever their score;
//! - `grid-basin`, `franck-basin`: cold fits from perturbed landmarks (as `tests/integration/fit.rs`);
//! - `franck2-floor`: the shape model's floor (dlib landmarks projected onto it) and fits
//!   started from each frame's dlib landmarks;
//! - `dump-franck2`: writes the franck model and franck-dev2 frames 3800-4099 as raw RGBA into
//!   `$FIT_EVAL_DUMP` (default `target/fit-bench`) for `scripts/fit-bench-wasm.cjs`.
//!
//! `FIT_OPTIONS='{"refine_iters": 2}'` overrides fields of `FitOptions::default()`;
//! `FRAME=own` builds in the model's own frame instead of the canonical one;
//! `SHAPE_VARIANCE`, `APPEARANCE_VARIANCE` set the builder's kept variance fractions,
//! `MAX_SHAPE_MODES` its most shape modes, `SYMMETRIC_SHAPES=0` turns off its mirrored
//! deviations. For `webcam-fps`, `enrol` and `control`:
//! `FIT_EVAL_FRAMES=1` prints every frame (error, residual, iterations, a cold fit from the
//! frame's dlib landmarks, the shape model's floor, the fit's and the truth's shape parameters
//! in standard deviations); `FIT_EVAL_PROBE='592:{"levels":...};{...}'` fits that frame from
//! the previous tracked result with each set of options (fields over the current options).
//! Error: mean landmark distance / distance of landmarks 36 and 45 (dlib points).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

#[cfg(not(any(target_arch = "wasm32", test)))]
use facemimic_testkit as common;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::fit::FaceTracker;
    use std::path::{Path, PathBuf};
    use std::time::Instant;

    use super::common::{clip_frames, first_face, load, perturb, Rng};
    use facemimic::find::landmark_error;
    use facemimic::fit::{FitOptions, Fitter, Tracker};
    use facemimic::{
        io, select_varied, BuildOptions, Builder, EnrolFinder, FaceFinder, FrameChoice, Model,
        TrainingImage,
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
        build_images(&images)
    }

    /// `images` and each one mirrored (image flipped left-right, landmarks flipped and
    /// renumbered by `MIRROR_68`): an experiment on symmetric augmentation.
    fn mirrored(images: &[TrainingImage]) -> Vec<TrainingImage> {
        let mut out = images.to_vec();
        for t in images {
            let (w, h) = (t.image.width as usize, t.image.height as usize);
            let mut data = t.image.data.clone();
            for y in 0..h {
                for x in 0..w {
                    let (a, b) = ((y * w + x) * 4, (y * w + w - 1 - x) * 4);
                    data[a..a + 4].copy_from_slice(&t.image.data[b..b + 4]);
                }
            }
            let mut lm = t.landmarks.clone();
            for (i, &j) in facemimic::MIRROR_68.iter().enumerate() {
                lm[2 * i] = (w - 1) as f32 - t.landmarks[2 * j];
                lm[2 * i + 1] = t.landmarks[2 * j + 1];
            }
            out.push(TrainingImage {
                name: format!("{}-mirror", t.name),
                image: facemimic::Image {
                    width: t.image.width,
                    height: t.image.height,
                    data,
                },
                landmarks: lm,
            });
        }
        out
    }

    /// The model of `images`; `MIRROR=1` builds it of `images` and their mirror images,
    /// `MIRROR=shape` takes only the shape model from those (the appearance from `images`;
    /// canonical frame only: the appearance lives on the frame's mesh).
    fn build_images(images: &[TrainingImage]) -> Model {
        match std::env::var("MIRROR").as_deref() {
            Ok("1") => build_plain(&mirrored(images)),
            Ok("shape") => {
                let mut parts = build_plain(images).into_parts();
                parts.shape = build_plain(&mirrored(images)).into_parts().shape;
                Model::new(parts).unwrap()
            }
            _ => build_plain(images),
        }
    }

    fn build_plain(images: &[TrainingImage]) -> Model {
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
            max_shape_modes: var("MAX_SHAPE_MODES").map_or(d.max_shape_modes, |v| v as usize),
            symmetric_shapes: var("SYMMETRIC_SHAPES").map_or(d.symmetric_shapes, |v| v != 0.0),
            ..d
        })
        .build(images, None)
        .unwrap()
    }

    /// 20 of `images` chosen by farthest-point sampling, in the order `tests/integration/enrol_webcam.rs`
    /// builds them, and the model built from them.
    fn build_varied(mut images: Vec<TrainingImage>) -> Model {
        let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
        let mut keep = select_varied(&shapes, 20).unwrap();
        keep.sort_unstable();
        let chosen: Vec<TrainingImage> =
            keep.iter().rev().map(|&i| images.swap_remove(i)).collect();
        build_images(&chosen)
    }

    /// Tracks `seq` from `init`; prints the mean error, the mean over `stretch` (indices into
    /// `seq`), frames above 0.1 and resets.
    fn track_from(
        name: &str,
        model: &Model,
        seq: &[TrainingImage],
        init: &[f32],
        stretch: std::ops::Range<usize>,
    ) {
        let mut t = Tracker::new(model, options()).unwrap();
        let mut cold = Fitter::new(model, options()).unwrap();
        t.start_from_landmarks(init).unwrap();
        let errs: Vec<f32> = seq
            .iter()
            .enumerate()
            .map(|(i, f)| {
                if let Ok(probe) = std::env::var("FIT_EVAL_PROBE") {
                    // Fits this frame from the previous tracked result with other options.
                    let (at, variants) = probe.split_once(':').unwrap();
                    if i == at.parse::<usize>().unwrap() {
                        let prev = t.last().unwrap().landmarks.clone();
                        probe_variants(model, f, i, &prev, variants);
                    }
                }
                let r = t
                    .track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                    .unwrap();
                let e = landmark_error(&r.landmarks, &f.landmarks);
                if std::env::var_os("FIT_EVAL_FRAMES").is_some() {
                    print_frame(model, &mut cold, f, i, r);
                }
                e
            })
            .collect();
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
        let rest: Vec<f32> = errs
            .iter()
            .enumerate()
            .filter(|(i, _)| !stretch.contains(i))
            .map(|(_, &e)| e)
            .collect();
        println!(
            "{name}: {} shape modes, {} frames, mean {:.4}, max {:.4}, stretch {stretch:?} {:.4}, \
             elsewhere {:.4}, {} above 0.1, resets {}, lost {}",
            model.shape().n_modes(),
            errs.len(),
            mean(&errs),
            errs.iter().copied().fold(0f32, f32::max),
            mean(&errs[stretch.clone()]),
            mean(&rest),
            errs.iter().filter(|&&e| e > 0.1).count(),
            t.resets(),
            t.sequence().lost_count()
        );
        let v = &model.shape().variances;
        let rel: Vec<String> = v.iter().map(|x| format!("{:.3}", x / v[0])).collect();
        println!("  shape variances / the first: {}", rel.join(" "));
    }

    /// `FIT_EVAL_PROBE`: fits frame `f` (number `i`) from `prev` with each of `variants`
    /// (`;`-separated JSON objects of `FitOptions` fields over [`options`]) and prints the
    /// error, the residual and the iterations.
    fn probe_variants(model: &Model, f: &TrainingImage, i: usize, prev: &[f32], variants: &str) {
        for v in variants.split(';') {
            let mut o = serde_json::to_value(options()).unwrap();
            let x: serde_json::Value = serde_json::from_str(v).unwrap();
            for (k, x) in x.as_object().unwrap() {
                o[k] = x.clone();
            }
            let o: FitOptions = serde_json::from_value(o).unwrap();
            let mut pf = Fitter::new(model, o).unwrap();
            let r = pf.fit(&f.image.view().unwrap(), prev).unwrap();
            println!(
                "  probe {i} {v}: {:.4} residual {:.4} iterations {}",
                landmark_error(&r.landmarks, &f.landmarks),
                r.error,
                r.iterations
            );
        }
    }

    /// `FIT_EVAL_FRAMES`: prints frame `f` (number `i`) tracked as `r`: its error, residual and
    /// iterations, a cold fit's (`cold`) from the truth, the truth's projection's own error,
    /// and the fit's and the truth's shape parameters in standard deviations.
    fn print_frame(
        model: &Model,
        cold: &mut Fitter,
        f: &TrainingImage,
        i: usize,
        r: &facemimic::fit::FitResult,
    ) {
        let e = landmark_error(&r.landmarks, &f.landmarks);
        // The fit's shape parameters and the truth's (its projection onto the
        // model), in standard deviations, and the projection's own error.
        let v = &model.shape().variances;
        let sig = |p: &[f32]| {
            p.iter()
                .zip(v)
                .map(|(x, s)| format!("{:+.1}", x / s.sqrt()))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let mut p = vec![0f32; v.len()];
        let mut inst = vec![0f32; model.shape().base.len()];
        let pose = model
            .shape()
            .project_image_shape(&f.landmarks, &mut p)
            .unwrap();
        model.shape().instance(&p, &mut inst).unwrap();
        pose.apply_in_place(&mut inst);
        // A cold fit started from the truth: is the tracked fit in the cost's
        // minimum near the truth, or in another one?
        let c = cold.fit(&f.image.view().unwrap(), &f.landmarks).unwrap();
        println!(
            "  {i} {e:.4} residual {:.4} iterations {} from truth {:.4} residual {:.4} \
             floor {:.4} fit [{}] truth [{}]",
            r.error,
            r.iterations,
            landmark_error(&c.landmarks, &f.landmarks),
            c.error,
            landmark_error(&inst, &f.landmarks),
            sig(&r.params.shape),
            sig(&p)
        );
    }

    fn numbered(dir: &Path, range: impl Iterator<Item = usize>) -> Vec<PathBuf> {
        range.map(|i| dir.join(format!("{i:06}.jpg"))).collect()
    }

    fn track(name: &str, model: &Model, seq: &[TrainingImage], auto: bool) {
        let v = &model.shape().variances;
        let rel: Vec<String> = v.iter().map(|x| format!("{:.3}", x / v[0])).collect();
        println!("{name}: shape variances / the first: {}", rel.join(" "));
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
        let c0 = cpu_seconds();
        for f in seq {
            let r = t
                .track(&f.image.view().unwrap(), facemimic::fit::DEFAULT_TIME_STEP)
                .unwrap();
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
                landmark_error(&r.landmarks, &f.landmarks)
            });
        }
        let secs = t0.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - c0;
        let fin: Vec<f32> = errs.iter().copied().filter(|e| e.is_finite()).collect();
        let mean = fin.iter().sum::<f32>() / fin.len().max(1) as f32;
        let (wi, max) = fin
            .iter()
            .enumerate()
            .fold((0, 0f32), |a, (i, &e)| if e > a.1 { (i, e) } else { a });
        let over = errs.iter().filter(|&&e| e > 0.1).count();
        println!(
            "{name}: {} frames, mean {mean:.4}, max {max:.4} (frame {wi}), {over} above 0.1 \
             (lost counted), lost {}, resets {}, reacquisitions {}, {:.1} iterations, {:.0} fits/s \
             ({:.0} fits/s of CPU time)",
            errs.len(),
            t.sequence().lost_count(),
            t.resets(),
            t.sequence().reacquisitions(),
            iters as f64 / errs.len() as f64,
            errs.len() as f64 / secs,
            errs.len() as f64 / cpu.max(1e-9)
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

    /// CPU time of this process in seconds (Linux `/proc/self/stat`; 0 elsewhere), so speed
    /// comparisons on a shared machine do not count other processes' time.
    fn cpu_seconds() -> f64 {
        let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
            return 0.0;
        };
        let after = stat.rsplit(')').next().unwrap_or("");
        let f: Vec<&str> = after.split_whitespace().collect();
        let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
        (ticks(11) + ticks(12)) / 100.0
    }

    fn basin(name: &str, model: &Model, frames: &[TrainingImage], per: usize, seed: u64) {
        let mut fitter = Fitter::new(model, options()).unwrap();
        let mut rng = Rng::new(seed);
        let (mut good, mut total, mut sum) = (0, 0, 0f32);
        for f in frames {
            let view = f.image.view().unwrap();
            for _ in 0..per {
                let init = perturb(&f.landmarks, &mut rng);
                let r = fitter.fit(&view, &init).unwrap();
                let e = landmark_error(&r.landmarks, &f.landmarks);
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

    /// `dump-franck2`: the franck model and franck-dev2 frames 3800-4099 as raw RGBA.
    fn dump_franck2(d: &Path) {
        // For the wasm benchmark (scripts/fit-bench-wasm.cjs): the franck model and
        // franck-dev2 frames 3800-4099 as raw RGBA, frame 3800's landmarks.
        let out =
            PathBuf::from(std::env::var("FIT_EVAL_DUMP").unwrap_or("target/fit-bench".into()));
        std::fs::create_dir_all(&out).unwrap();
        let m = build(&io::read_list(&d.join("franck-dev/train20.txt")).unwrap());
        std::fs::write(out.join("model.fmm"), facemimic::format::write_model(&m)).unwrap();
        for i in 3800..4100 {
            let f = io::read_training_image(&d.join(format!("franck-dev2/{i:06}.jpg"))).unwrap();
            let [w, h] = [f.image.width, f.image.height];
            std::fs::write(out.join(format!("{i}.rgba")), &f.image.data).unwrap();
            if i == 3800 {
                let s: Vec<String> = f.landmarks.iter().map(|v| v.to_string()).collect();
                std::fs::write(out.join("init.txt"), s.join(" ")).unwrap();
                std::fs::write(out.join("size.txt"), format!("{w} {h}")).unwrap();
            }
        }
        println!("dump-franck2: model and 300 frames in {}", out.display());
    }

    /// `franck2-floor`: the shape model's own floor on franck-dev2.
    fn franck2_floor(d: &Path) {
        // The shape model's own floor: each frame's dlib landmarks projected onto
        // the model (pose and p), and a fit started from them.
        let m = build(&io::read_list(&d.join("franck-dev/train20.txt")).unwrap());
        let seq = load(&clip_frames(&d.join("franck-dev2")));
        let mut fitter = Fitter::new(&m, options()).unwrap();
        let (mut proj, mut fit) = (0f32, 0f32);
        let mut p = vec![0f32; m.shape().n_modes()];
        let mut inst = vec![0f32; m.shape().base.len()];
        for f in &seq {
            let pose = m.shape().project_image_shape(&f.landmarks, &mut p).unwrap();
            m.shape().instance(&p, &mut inst).unwrap();
            pose.apply_in_place(&mut inst);
            proj += landmark_error(&inst, &f.landmarks);
            let r = fitter.fit(&f.image.view().unwrap(), &f.landmarks).unwrap();
            fit += landmark_error(&r.landmarks, &f.landmarks);
        }
        let n = seq.len() as f32;
        println!(
            "franck2-floor: {} shape modes, projection {:.4}, fit from the truth {:.4}",
            p.len(),
            proj / n,
            fit / n
        );
    }

    /// `webcam-fps` and `enrol`: a model of webcam-dev 0-599 (every 5th frame; `enrol`: the finder's landmarks), tracked from the finder's landmarks on frame 600.
    fn webcam_enrol(set: &str, d: &Path) {
        let w = d.join("webcam-dev");
        let mut finder = EnrolFinder::new(1).unwrap();
        let mut train = load(&numbered(&w, (0..600).step_by(5)));
        if set == "enrol" {
            train.retain_mut(
                |f| match finder.find(&f.image.view().unwrap(), 0.0).unwrap() {
                    Some(face) => {
                        f.landmarks = face.landmarks;
                        true
                    }
                    None => false,
                },
            );
        }
        let m = build_varied(train);
        let seq = load(&numbered(&w, 600..1337));
        let init = first_face(finder.finder(), &seq[0].image).expect("a face in frame 600");
        track_from(set, &m, &seq, &init, 600..700);
    }

    /// `control`: the control row of `examples/enrol_eval.rs`.
    fn control(set: &str, d: &Path) {
        // The control row of `examples/enrol_eval.rs`: the dlib landmarks of the
        // frames of webcam-dev 0-599 (every 5th) the finder scores >= 0.5, 20 chosen
        // by farthest-point sampling, built in that order; tracked over 600-1336 from
        // the finder's landmarks on frame 600 (1190-1289, the hand, reported apart).
        let w = d.join("webcam-dev");
        let mut enrol = EnrolFinder::new(1).unwrap();
        // `CONTROL_KEEP=490,495` keeps those frames whatever their score.
        let extra: Vec<String> = std::env::var("CONTROL_KEEP")
            .unwrap_or_default()
            .split(',')
            .filter(|k| !k.is_empty())
            .map(|k| format!("{:06}", k.parse::<usize>().expect("CONTROL_KEEP")))
            .collect();
        let (mut train, mut dropped) = (Vec::new(), Vec::new());
        for f in load(&numbered(&w, (0..600).step_by(5))) {
            let view = f.image.view().unwrap();
            let faces = enrol.finder().find(&view);
            let Some(face) = faces.first() else { continue };
            if enrol.average(&view, face).unwrap().is_some() {
                if face.score >= 0.5 || extra.contains(&f.name) {
                    train.push(f);
                } else {
                    dropped.push(f);
                }
            }
        }
        let shapes: Vec<&[f32]> = train.iter().map(|t| t.landmarks.as_slice()).collect();
        let mut keep = select_varied(&shapes, 20).unwrap();
        keep.sort_unstable();
        let chosen: Vec<TrainingImage> = keep.iter().map(|&i| train[i].clone()).collect();
        println!(
            "control: {} frames (score >= 0.5 or kept), chose {:?}",
            train.len(),
            keep.iter()
                .map(|&i| train[i].name.clone())
                .collect::<Vec<_>>()
        );
        let m = build_images(&chosen);
        // The frames left out (score < 0.5) in the model's standard deviations.
        let v = &m.shape().variances;
        let mut p = vec![0f32; v.len()];
        for f in &dropped {
            m.shape().project_image_shape(&f.landmarks, &mut p).unwrap();
            let z: Vec<String> = p
                .iter()
                .zip(v)
                .map(|(x, s)| format!("{:+.1}", x / s.sqrt()))
                .collect();
            println!("  left out {}: [{}]", f.name, z.join(" "));
        }
        let seq = load(&numbered(&w, 600..1337));
        let init = first_face(enrol.finder(), &seq[0].image).expect("a face in frame 600");
        track_from(set, &m, &seq, &init, 590..690);
    }

    /// Every `every`-th frame of `frames` whose stem is not in the training list `list`.
    fn held_out(frames: Vec<PathBuf>, list: &Path, every: usize) -> Vec<PathBuf> {
        let train = stems(list);
        frames
            .into_iter()
            .filter(|p| !train.contains(&p.file_stem().unwrap().to_string_lossy().into_owned()))
            .step_by(every)
            .collect()
    }

    /// `grid-basin`: spk07's unseen clip (every 3rd frame) and its training clip's frames
    /// left out of the model (every 3rd), 4 perturbed starts each.
    fn grid_basin() {
        let list = repo("data/grid/spk07_pwij3p/train20.txt");
        let m = build(&io::read_list(&list).unwrap());
        let mut held: Vec<PathBuf> = clip_frames(&repo("data/grid/spk07_id2_vcd_swwp2s"))
            .into_iter()
            .step_by(3)
            .collect();
        held.extend(held_out(
            clip_frames(&repo("data/grid/spk07_pwij3p")),
            &list,
            3,
        ));
        basin("grid-basin", &m, &load(&held), 4, 0x5eed_0001);
    }

    /// `franck-basin`: franck-dev's frames left out of the model (every 10th), 2 perturbed
    /// starts each.
    fn franck_basin(d: &Path) {
        let list = d.join("franck-dev/train20.txt");
        let m = build(&io::read_list(&list).unwrap());
        let held = held_out(clip_frames(&d.join("franck-dev")), &list, 10);
        basin("franck-basin", &m, &load(&held), 2, 0x5eed_0002);
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
                    let seq = load(&clip_frames(&repo("data/grid/spk07_id2_vcd_swwp2s")));
                    track("grid", &m, &seq, false);
                }
                "franck2" | "franck2-auto" => {
                    let m = build(&io::read_list(&d.join("franck-dev/train20.txt")).unwrap());
                    let seq = load(&clip_frames(&d.join("franck-dev2")));
                    track(&set, &m, &seq, set == "franck2-auto");
                }
                "dump-franck2" => dump_franck2(&d),
                "franck2-floor" => franck2_floor(&d),
                "webcam" | "webcam-auto" => {
                    let w = d.join("webcam-dev");
                    let m = build(&numbered(&w, (0..600).step_by(30)));
                    let seq = load(&numbered(&w, 600..1337));
                    track(&set, &m, &seq, set == "webcam-auto");
                }
                "webcam-fps" | "enrol" => webcam_enrol(&set, &d),
                "control" => control(&set, &d),
                "grid-basin" => grid_basin(),
                "franck-basin" => franck_basin(&d),
                other => panic!("unknown set {other}"),
            }
        }
    }
}

//! Does a *learned* correction move the face finder's landmarks onto dlib's convention on faces
//! it was not learned from? The finder's calibration (src/find/calibration.rs) adds the mean
//! offset of ten GRID speakers; what is left differs from person to person. Two richer
//! corrections are learned here from GRID (the 825 frames in ../shared/data/grid, 10 speakers)
//! and measured on speakers and clips they never saw:
//!
//! - a local one: supervised descent (Xiong & De la Torre, CVPR 2013), per landmark a ridge
//!   regression from a HOG-like descriptor of the patch around the point (4x4 cells x 8
//!   orientations, in the face's own frame) to its offset from dlib's point, in `stages` cascaded
//!   stages, trained from the finder's points and `perturb` perturbed copies of them;
//! - a shape-conditioned one (`stages` 0): ridge regression from the finder's normalised shape
//!   to the offsets, for several ridge weights;
//! - a generic AAM (`generic`): a model of every 4th training frame with the dlib landmarks (at
//!   most 4, 8 or 12 shape modes), fitted to each test frame from the finder's points.
//!
//! Printed: the finder's error against dlib (mean point distance over the outer-eye-corner
//! distance) per group (jaw, brows, nose, eyes, lips, all) before and after, on speakers 6-10
//! with the correction learned on 1-5 and the reverse, and on franck-dev (every 5th frame),
//! franck-dev2 (every 5th), webcam-dev 0-599 and 600-1336 (every 5th) with it learned on all of
//! GRID. Research data in ../shared, never committed. Results: docs/finding.md, "A learned
//! correction does not transfer".
//!
//!   cargo run --release --example convention_transfer -- [STAGES [PERTURB [RIDGE [SCALES]]]]
//!   cargo run --release --example convention_transfer -- generic
//!
//! (defaults 2 4 0.01 0.03,0.02; the finder's landmarks are cached in target/convention-cache).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::path::{Path, PathBuf};

    use facemimic::find::{add_face_offsets, face_frame, face_offsets, landmark_error};
    use facemimic::{io, EnrolFinder, Image};
    use nalgebra::{DMatrix, DVector};

    pub const GROUPS: [(&str, std::ops::Range<usize>); 6] = [
        ("jaw", 0..17),
        ("brows", 17..27),
        ("nose", 27..36),
        ("eyes", 36..48),
        ("lips", 48..68),
        ("all", 0..68),
    ];

    pub struct Sample {
        pub set: String,
        pub image: Image,
        pub truth: Vec<f32>,
        pub found: Vec<f32>,
    }

    fn load(finder: &mut EnrolFinder, set: &str, paths: &[PathBuf], cache: &Path) -> Vec<Sample> {
        let mut look = facemimic::FaceFinder::new().unwrap();
        let cached: Option<Vec<Vec<f32>>> = std::fs::read_to_string(cache).ok().map(|s| {
            s.lines()
                .map(|l| l.split(' ').map(|x| x.parse().unwrap()).collect())
                .collect()
        });
        let mut out = Vec::new();
        let mut lines = Vec::new();
        for (k, p) in paths.iter().enumerate() {
            let t = io::read_training_image(p).unwrap();
            let found = match &cached {
                Some(c) => c[k].clone(),
                None if std::env::var_os("CT_LOOK").is_some() => look
                    .find(&t.image.view().unwrap())
                    .into_iter()
                    .next()
                    .map(|f| f.landmarks)
                    .unwrap_or_default(),
                None => finder
                    .find(&t.image.view().unwrap(), 0.0)
                    .unwrap()
                    .map(|f| f.landmarks)
                    .unwrap_or_default(),
            };
            lines.push(
                found
                    .iter()
                    .map(|x| x.to_string())
                    .collect::<Vec<_>>()
                    .join(" "),
            );
            if found.len() == 136 {
                out.push(Sample {
                    set: set.into(),
                    image: t.image,
                    truth: t.landmarks,
                    found,
                });
            }
        }
        if cached.is_none() {
            std::fs::write(cache, lines.join("\n")).unwrap();
        }
        out
    }

    /// The face frame of `p` (centroid, RMS radius, eye line's cosine and sine).
    fn frame(p: &[f32]) -> ([f32; 2], f32, f32, f32) {
        face_frame(p).expect("a face frame")
    }

    pub const CELLS: usize = 4;
    pub const PER: usize = 4; // samples per cell side
    pub const BINS: usize = 8;
    pub const DIM: usize = CELLS * CELLS * BINS;

    /// HOG-like descriptor of the patch around each point, in the face's frame.
    pub fn features(s: &Sample, pts: &[f32], scale: f32, out: &mut Vec<f32>) {
        let view = s.image.view().unwrap();
        // Grey (luma) of the crate's bilinear RGB sample.
        let grey = |x: f32, y: f32| {
            let [r, g, b] = view.sample_rgb(x, y);
            0.299 * r + 0.587 * g + 0.114 * b
        };
        let (_, r, c, sn) = frame(pts);
        let step = r * scale;
        let n = CELLS * PER + 2;
        let mut patch = vec![0f32; n * n];
        out.clear();
        for i in 0..68 {
            let (px, py) = (pts[2 * i], pts[2 * i + 1]);
            for v in 0..n {
                for u in 0..n {
                    let a = (u as f32 - (n as f32 - 1.0) / 2.0) * step;
                    let b = (v as f32 - (n as f32 - 1.0) / 2.0) * step;
                    patch[v * n + u] = grey(px + c * a - sn * b, py + sn * a + c * b);
                }
            }
            let mut d = [0f32; DIM];
            for v in 1..n - 1 {
                for u in 1..n - 1 {
                    let gx = patch[v * n + u + 1] - patch[v * n + u - 1];
                    let gy = patch[(v + 1) * n + u] - patch[(v - 1) * n + u];
                    let m = (gx * gx + gy * gy).sqrt();
                    let ang = gy.atan2(gx) + std::f32::consts::PI; // 0..2pi
                    let fb = ang / (2.0 * std::f32::consts::PI) * BINS as f32;
                    let b0 = (fb.floor() as usize) % BINS;
                    let b1 = (b0 + 1) % BINS;
                    let t = fb - fb.floor();
                    let cell = ((v - 1) / PER) * CELLS + (u - 1) / PER;
                    d[cell * BINS + b0] += m * (1.0 - t);
                    d[cell * BINS + b1] += m * t;
                }
            }
            let norm = d.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-6);
            for x in d.iter_mut() {
                *x = (*x / norm).min(0.2);
            }
            let norm = d.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-6);
            out.extend(d.iter().map(|x| x / norm));
        }
    }

    /// `truth - pts` in the face frame of `pts`.
    fn target(pts: &[f32], truth: &[f32]) -> Vec<f32> {
        face_offsets(pts, truth).unwrap_or_else(|| vec![0.0; 136])
    }

    fn apply(pts: &mut [f32], delta: &[f32]) {
        add_face_offsets(pts, delta);
    }

    /// One stage: per landmark ridge regression, features of point i (and optionally neighbours) -> delta_i
    pub struct Stage {
        scale: f32,
        w: Vec<DMatrix<f32>>, // per landmark (DIM+1) x 2
    }

    impl Stage {
        fn predict(&self, s: &Sample, pts: &[f32], f: &mut Vec<f32>) -> Vec<f32> {
            features(s, pts, self.scale, f);
            let mut out = vec![0f32; 136];
            let first = if std::env::var_os("CT_NOJAW").is_some() {
                17
            } else {
                0
            };
            for i in first..68 {
                let x = &f[i * DIM..(i + 1) * DIM];
                let w = &self.w[i];
                for k in 0..2 {
                    let mut acc = w[(DIM, k)];
                    for j in 0..DIM {
                        acc += x[j] * w[(j, k)];
                    }
                    out[2 * i + k] = acc;
                }
            }
            out
        }
    }

    fn train_stage(
        starts: &[(usize, Vec<f32>)],
        samples: &[Sample],
        scale: f32,
        lambda: f64,
    ) -> Stage {
        let d = DIM + 1;
        let mut xtx = vec![DMatrix::<f64>::zeros(d, d); 68];
        let mut xty = vec![DMatrix::<f64>::zeros(d, 2); 68];
        let mut f = Vec::new();
        for (k, pts) in starts {
            let s = &samples[*k];
            features(s, pts, scale, &mut f);
            let t = target(pts, &s.truth);
            for i in 0..68 {
                let mut x = DVector::<f64>::zeros(d);
                for j in 0..DIM {
                    x[j] = f[i * DIM + j] as f64;
                }
                x[DIM] = 1.0;
                xtx[i] += &x * x.transpose();
                for c in 0..2 {
                    let y = t[2 * i + c] as f64;
                    for j in 0..d {
                        xty[i][(j, c)] += x[j] * y;
                    }
                }
            }
        }
        let n = starts.len() as f64;
        let w = (0..68)
            .map(|i| {
                let mut a = xtx[i].clone();
                for j in 0..DIM {
                    a[(j, j)] += lambda * n;
                }
                let sol = a.cholesky().unwrap().solve(&xty[i]);
                sol.map(|x| x as f32)
            })
            .collect();
        Stage { scale, w }
    }

    fn rng(seed: &mut u64) -> f32 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }
    fn gauss(seed: &mut u64) -> f32 {
        let (a, b) = (rng(seed).max(1e-7), rng(seed));
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f32::consts::PI * b).cos()
    }

    pub fn train(
        samples: &[Sample],
        idx: &[usize],
        stages: usize,
        perturb: usize,
        lambda: f64,
        scales: &[f32],
    ) -> Vec<Stage> {
        let mut seed = 0x9e3779b97f4a7c15u64;
        // starts: the finder's points, plus perturbed copies (shift / scale / rotation of the
        // whole shape + per point noise in face units)
        let mut starts: Vec<(usize, Vec<f32>)> = Vec::new();
        for &k in idx {
            let s = &samples[k];
            starts.push((k, s.found.clone()));
            for _ in 0..perturb {
                let mut p = s.found.clone();
                let (cc, r, _, _) = frame(&p);
                let (tx, ty) = (gauss(&mut seed) * 0.03 * r, gauss(&mut seed) * 0.03 * r);
                let sc = 1.0 + gauss(&mut seed) * 0.03;
                let th = gauss(&mut seed) * 0.03;
                let (co, si) = (th.cos(), th.sin());
                for i in 0..68 {
                    let (x, y) = (p[2 * i] - cc[0], p[2 * i + 1] - cc[1]);
                    p[2 * i] = cc[0] + sc * (co * x - si * y) + tx + gauss(&mut seed) * 0.02 * r;
                    p[2 * i + 1] =
                        cc[1] + sc * (si * x + co * y) + ty + gauss(&mut seed) * 0.02 * r;
                }
                starts.push((k, p));
            }
        }
        let mut out = Vec::new();
        let mut f = Vec::new();
        for st in 0..stages {
            let stage = train_stage(&starts, samples, scales[st.min(scales.len() - 1)], lambda);
            for (k, p) in starts.iter_mut() {
                let d = stage.predict(&samples[*k], p, &mut f);
                apply(p, &d);
            }
            out.push(stage);
        }
        out
    }

    pub fn run(stages: &[Stage], s: &Sample) -> Vec<f32> {
        let mut p = s.found.clone();
        let mut f = Vec::new();
        for st in stages {
            let d = st.predict(s, &p, &mut f);
            apply(&mut p, &d);
        }
        p
    }

    fn group_err(a: &[f32], b: &[f32], g: &std::ops::Range<usize>) -> f32 {
        let iod = ((b[90] - b[72]).powi(2) + (b[91] - b[73]).powi(2)).sqrt();
        g.clone()
            .map(|i| ((a[2 * i] - b[2 * i]).powi(2) + (a[2 * i + 1] - b[2 * i + 1]).powi(2)).sqrt())
            .sum::<f32>()
            / g.len() as f32
            / iod
    }

    pub fn report(name: &str, samples: &[Sample], idx: &[usize], stages: &[Stage]) {
        let mut before = [0f32; 6];
        let mut after = [0f32; 6];
        // also: per-person mean correction (average of the per-frame corrections in face frame)
        let mut mean_delta = vec![0f32; 136];
        let mut outs = Vec::new();
        for &k in idx {
            let s = &samples[k];
            let p = run(stages, s);
            for (g, (_, r)) in GROUPS.iter().enumerate() {
                before[g] += group_err(&s.found, &s.truth, r);
                after[g] += group_err(&p, &s.truth, r);
            }
            let t = target(&s.found, &p);
            for j in 0..136 {
                mean_delta[j] += t[j] / idx.len() as f32;
            }
            outs.push(p);
        }
        let mut avg = 0f32;
        for &k in idx {
            let s = &samples[k];
            let mut p = s.found.clone();
            apply(&mut p, &mean_delta);
            avg += landmark_error(&p, &s.truth);
        }
        let n = idx.len() as f32;
        let cf = |pts: &[Vec<f32>]| {
            let pairs: Vec<(&[f32], &[f32])> = pts
                .iter()
                .zip(idx)
                .map(|(p, &k)| (p.as_slice(), samples[k].truth.as_slice()))
                .collect();
            let e = facemimic::find::convention_free_errors(&pairs);
            e.iter().sum::<f32>() / e.len() as f32
        };
        let founds: Vec<Vec<f32>> = idx.iter().map(|&k| samples[k].found.clone()).collect();
        println!(
            "{name:28} convention-free before {:.4} after {:.4}",
            cf(&founds),
            cf(&outs)
        );
        println!(
            "{name:28} n={:4} before {} | after {} | mean-corr {:.4}",
            idx.len(),
            before
                .iter()
                .map(|x| format!("{:.4}", x / n))
                .collect::<Vec<_>>()
                .join(" "),
            after
                .iter()
                .map(|x| format!("{:.4}", x / n))
                .collect::<Vec<_>>()
                .join(" "),
            avg / n
        );
    }

    fn list(dir: &Path, step: usize, range: std::ops::Range<usize>) -> Vec<PathBuf> {
        let mut v = io::annotated_images(dir).unwrap();
        v.sort();
        v.into_iter()
            .filter(|p| {
                let i: usize = p
                    .file_stem()
                    .unwrap()
                    .to_str()
                    .unwrap()
                    .parse()
                    .unwrap_or(0);
                range.contains(&i) && i % step == 0
            })
            .collect()
    }

    fn shape_feat(p: &[f32]) -> Vec<f64> {
        let (c, r, co, si) = frame(p);
        let mut v: Vec<f64> = (0..68)
            .flat_map(|i| {
                let (x, y) = (p[2 * i] - c[0], p[2 * i + 1] - c[1]);
                [
                    ((co * x + si * y) / r) as f64,
                    ((-si * x + co * y) / r) as f64,
                ]
            })
            .collect();
        v.push(1.0);
        v
    }

    /// shape-conditioned calibration: ridge from the normalised shape to the offset
    fn shape_reg(samples: &[Sample], tr: &[usize], te: &[usize], lambda: f64) -> (f32, f32) {
        let d = 137;
        let mut xtx = DMatrix::<f64>::zeros(d, d);
        let mut xty = DMatrix::<f64>::zeros(d, 136);
        for &k in tr {
            let x = DVector::from_vec(shape_feat(&samples[k].found));
            let t = target(&samples[k].found, &samples[k].truth);
            xtx += &x * x.transpose();
            for j in 0..d {
                for c in 0..136 {
                    xty[(j, c)] += x[j] * t[c] as f64;
                }
            }
        }
        for j in 0..136 {
            xtx[(j, j)] += lambda * tr.len() as f64;
        }
        let w = xtx.cholesky().unwrap().solve(&xty);
        let (mut b, mut a) = (0f32, 0f32);
        for &k in te {
            let s = &samples[k];
            let x = DVector::from_vec(shape_feat(&s.found));
            let dlt: Vec<f32> = (w.transpose() * x).iter().map(|v| *v as f32).collect();
            let mut p = s.found.clone();
            apply(&mut p, &dlt);
            b += landmark_error(&s.found, &s.truth);
            a += landmark_error(&p, &s.truth);
        }
        (b / te.len() as f32, a / te.len() as f32)
    }

    /// A generic AAM of the training frames (every 4th, dlib landmarks), fitted to each test
    /// frame from the finder's points: does a model whose shapes follow dlib's convention move
    /// the points onto it on a face it never saw?
    fn generic_aam(samples: &[Sample], tr: &[usize], te: &[usize], max_modes: usize) -> (f32, f32) {
        use facemimic::fit::{FitOptions, Fitter};
        use facemimic::{BuildOptions, Builder, TrainingImage};
        let images: Vec<TrainingImage> = tr
            .iter()
            .step_by(4)
            .map(|&k| TrainingImage {
                name: format!("f{k}"),
                image: samples[k].image.clone(),
                landmarks: samples[k].truth.clone(),
            })
            .collect();
        let model = Builder::new(BuildOptions {
            max_shape_modes: max_modes,
            ..BuildOptions::default()
        })
        .build(&images, None)
        .unwrap();
        let mut fitter = Fitter::new(&model, FitOptions::default()).unwrap();
        let (mut b, mut a) = (0f32, 0f32);
        for &k in te {
            let s = &samples[k];
            let r = fitter.fit(&s.image.view().unwrap(), &s.found).unwrap();
            b += landmark_error(&s.found, &s.truth);
            a += landmark_error(&r.landmarks, &s.truth);
        }
        (b / te.len() as f32, a / te.len() as f32)
    }

    pub fn main() {
        let args: Vec<String> = std::env::args().collect();
        let generic = args.get(1).is_some_and(|a| a == "generic");
        let stages_n: usize = match args.get(1) {
            Some(a) if a != "generic" => a.parse().unwrap(),
            _ => 2,
        };
        let perturb: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(4);
        let lambda: f64 = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(0.01);
        let scales: Vec<f32> = args
            .get(4)
            .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
            .unwrap_or(vec![0.03, 0.02]);
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let shared = root.join("../shared/data");
        let cache = root.join(if std::env::var_os("CT_LOOK").is_some() {
            "target/convention-cache-look"
        } else {
            "target/convention-cache"
        });
        std::fs::create_dir_all(&cache).unwrap();
        let (samples, speakers) = load_samples(&shared, &cache);
        let ngrid = speakers.len();
        let idx_of = |f: &dyn Fn(usize) -> bool| -> Vec<usize> {
            (0..samples.len()).filter(|&k| f(k)).collect()
        };
        let a = idx_of(&|k| k < ngrid && speakers[k] <= 5);
        let b = idx_of(&|k| k < ngrid && speakers[k] > 5);
        let all = idx_of(&|k| k < ngrid);
        if generic {
            generic_table(&samples, &a, &b, &all);
            return;
        }
        if stages_n == 0 {
            shape_reg_table(&samples, &a, &b, &all);
            return;
        }
        println!("stages {stages_n} perturb {perturb} lambda {lambda} scales {scales:?}");
        let sa = train(&samples, &a, stages_n, perturb, lambda, &scales);
        report("train A, test B", &samples, &b, &sa);
        report("train A, on A", &samples, &a, &sa);
        let sb = train(&samples, &b, stages_n, perturb, lambda, &scales);
        report("train B, test A", &samples, &a, &sb);
        let s = train(&samples, &all, stages_n, perturb, lambda, &scales);
        for set in ["franck-dev", "franck-dev2", "webcam-dev", "webcam-dev-test"] {
            let idx = set_indices(&samples, set);
            report(set, &samples, &idx, &s);
        }
    }

    /// The samples: GRID's speakers (each a speaker's number in the second vector, in the
    /// same order), then the dev and test sets.
    fn load_samples(shared: &Path, cache: &Path) -> (Vec<Sample>, Vec<usize>) {
        let mut finder = EnrolFinder::new(1).unwrap();
        let mut samples = Vec::new();
        let mut speakers = Vec::new();
        let mut gdirs: Vec<_> = std::fs::read_dir(shared.join("grid"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_dir())
            .collect();
        gdirs.sort();
        for d in &gdirs {
            let name = d.file_name().unwrap().to_str().unwrap().to_string();
            let spk: usize = name[3..5].parse().unwrap();
            let v = load(
                &mut finder,
                &name,
                &list(d, 1, 0..100000),
                &cache.join(&name),
            );
            for _ in 0..v.len() {
                speakers.push(spk);
            }
            samples.extend(v);
        }
        for (set, step, range) in [
            ("franck-dev", 5, 0..1000),
            ("franck-dev2", 5, 0..100000),
            ("webcam-dev", 5, 0..600),
            ("webcam-dev-test", 5, 600..1400),
        ] {
            let dir = if set == "webcam-dev-test" {
                "webcam-dev"
            } else {
                set
            };
            let v = load(
                &mut finder,
                set,
                &list(&shared.join(dir), step, range),
                &cache.join(set),
            );
            samples.extend(v);
        }
        (samples, speakers)
    }

    /// The indices of the samples of `set`.
    fn set_indices(samples: &[Sample], set: &str) -> Vec<usize> {
        (0..samples.len())
            .filter(|&k| samples[k].set == set)
            .collect()
    }

    /// `generic`: the generic AAM's errors (before and after) with 4, 8 and 12 modes, across
    /// the GRID halves `a` and `b` and from all of GRID onto each dev set.
    fn generic_table(samples: &[Sample], a: &[usize], b: &[usize], all: &[usize]) {
        for modes in [4, 8, 12] {
            let (b0, a0) = generic_aam(samples, a, b, modes);
            let (b1, a1) = generic_aam(samples, b, a, modes);
            let mut line = format!(
                "generic AAM, <= {modes} modes: A->B {b0:.4}->{a0:.4}  B->A {b1:.4}->{a1:.4}"
            );
            for set in ["franck-dev", "webcam-dev", "webcam-dev-test"] {
                let idx = set_indices(samples, set);
                let (bb, aa) = generic_aam(samples, all, &idx, modes);
                line += &format!("  {set} {bb:.4}->{aa:.4}");
            }
            println!("{line}");
        }
    }

    /// Stages 0: the shape regression's errors (before and after) for a range of lambdas,
    /// across the GRID halves `a` and `b` and from all of GRID onto each dev set.
    fn shape_reg_table(samples: &[Sample], a: &[usize], b: &[usize], all: &[usize]) {
        for lam in [0.0001, 0.001, 0.01, 0.1] {
            let (b0, a0) = shape_reg(samples, a, b, lam);
            let (b1, a1) = shape_reg(samples, b, a, lam);
            let mut line = format!("lambda {lam}: A->B {b0:.4}->{a0:.4}  B->A {b1:.4}->{a1:.4}");
            for set in ["franck-dev", "franck-dev2", "webcam-dev", "webcam-dev-test"] {
                let idx = set_indices(samples, set);
                let (bb, aa) = shape_reg(samples, all, &idx, lam);
                line += &format!("  {set} {bb:.4}->{aa:.4}");
            }
            println!("{line}");
        }
    }
}

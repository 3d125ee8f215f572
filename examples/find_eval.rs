//! The face finder's detection rate and landmark error on the shared data, against the dlib
//! landmarks: `cargo run --release --example find_eval -- [STEP] [SET...]` (default step 1, the
//! sets grid franck-dev franck-dev2 webcam-dev under ../shared/data). Each frame is found on
//! its own (`FIND_THRESHOLD`: the detector's threshold; `FIND_MIRROR` set: `FindOptions::mirror`,
//! the mean over the image and its mirror). A frame counts as found when the most
//! confident face's landmarks lie within 0.25 of
//! the inter-ocular (36-45) distance of the dlib points on average; the error is that mean over
//! the found frames. Also printed: the convention-free error (each point's mean offset from
//! dlib's over the set removed, in the face frame: `find::convention_free_errors`), and how much
//! of the mouth's motion the points keep (the spread, p95 - p5, of the mouth's width,
//! lip-corner lift and inner lips' opening over dlib's, and their correlation with dlib's, each person's mean removed:
//! a GRID speaker is the clip folder's name before `_`).
//!
//! To compare two builds frame by frame (e.g. MediaPipe's nets with float16 and with int8
//! weights): `FIND_EVAL_DUMP=FILE` writes each frame's most confident face's 68 points to FILE;
//! a later run with `FIND_EVAL_AGAINST=FILE` also prints, per set, the mean and p95 of the
//! landmark error of its points against FILE's (same normalisation: FILE's inter-ocular
//! distance) over the frames where both found a face, and how many frames only one found.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::io::{read_image, read_landmarks};
    use facemimic::FaceFinder;
    use facemimic_testkit::following::{pearson, spread};
    use std::collections::HashMap;
    use std::io::Write;
    use std::path::{Path, PathBuf};
    use std::time::Instant;

    fn frames(dir: &Path) -> Vec<PathBuf> {
        facemimic::io::annotated_images(dir).unwrap()
    }

    /// A `FIND_EVAL_DUMP` file: per frame, `set/name` and the points (none when no face).
    fn read_dump(path: &str) -> HashMap<String, Vec<f32>> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|l| {
                let mut it = l.split(' ');
                let key = it.next().unwrap().to_string();
                (key, it.map(|v| v.parse().unwrap()).collect())
            })
            .collect()
    }

    /// The p95 of sorted `errors` (NaN when empty).
    fn p95(errors: &[f32]) -> f32 {
        errors
            .get((errors.len() * 95 / 100).min(errors.len().saturating_sub(1)))
            .copied()
            .unwrap_or(f32::NAN)
    }

    pub(crate) fn main() {
        let mut args = std::env::args().skip(1);
        let step: usize = args.next().map(|s| s.parse().unwrap()).unwrap_or(1);
        let mut sets: Vec<String> = args.collect();
        if sets.is_empty() {
            sets = ["grid", "franck-dev", "franck-dev2", "webcam-dev"]
                .map(String::from)
                .to_vec();
        }
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        let mut finder = finder_from_env();
        let mut dump = std::env::var_os("FIND_EVAL_DUMP")
            .map(|p| std::io::BufWriter::new(std::fs::File::create(p).unwrap()));
        let against = std::env::var("FIND_EVAL_AGAINST")
            .ok()
            .map(|p| read_dump(&p));
        for set in sets {
            let mut tally = Tally::default();
            for p in frames(&root.join(&set)).iter().step_by(step) {
                let key = p.strip_prefix(&root).unwrap().to_string_lossy().to_string();
                tally.frame(&mut finder, p, &key, dump.as_mut(), against.as_ref());
            }
            tally.report(&set, against.is_some());
        }
    }

    /// The face finder with the options the environment asks for (`FIND_THRESHOLD`,
    /// `FIND_MIRROR`, `FIND_NO_LOCAL`).
    fn finder_from_env() -> FaceFinder {
        let mut finder = FaceFinder::new().unwrap();
        let mut opts = finder.options();
        if let Ok(t) = std::env::var("FIND_THRESHOLD") {
            opts.score_threshold = t.parse().unwrap();
        }
        opts.mirror = std::env::var_os("FIND_MIRROR").is_some();
        // `FIND_NO_LOCAL` set: the finder without its local correction (to measure it).
        finder.set_local_correction(std::env::var_os("FIND_NO_LOCAL").is_none());
        finder.set_options(opts);
        finder
    }

    /// What one set's evaluation gathers, frame by frame.
    #[derive(Default)]
    struct Tally {
        n: usize,
        found: usize,
        err_sum: f32,
        worst: f32,
        secs: f64,
        extra: usize,
        missed: Vec<String>,
        errors: Vec<f32>,
        /// The found frames' points and dlib's, for the convention-free figure.
        pairs: Vec<(Vec<f32>, Vec<f32>)>,
        /// Whose face each of `pairs` is (a GRID speaker: the folder's name before `_`).
        people: Vec<String>,
        /// The errors against `FIND_EVAL_AGAINST`'s points.
        versus: Vec<f32>,
        /// Frames where only this run or only `FIND_EVAL_AGAINST` found a face.
        only_one: usize,
    }

    impl Tally {
        /// Finds the faces of the frame at `p` (`key` in the dumps), writes them to `dump`,
        /// compares them with `against`'s and with the dlib points, and counts the result.
        fn frame(
            &mut self,
            finder: &mut FaceFinder,
            p: &Path,
            key: &str,
            dump: Option<&mut std::io::BufWriter<std::fs::File>>,
            against: Option<&HashMap<String, Vec<f32>>>,
        ) {
            let img = read_image(p).unwrap();
            let truth = read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            let view = img.view().unwrap();
            let t = Instant::now();
            let faces = finder.find(&view);
            self.secs += t.elapsed().as_secs_f64();
            self.n += 1;
            let points = faces.first().map_or(&[][..], |f| &f.landmarks[..]);
            if let Some(d) = dump {
                let values: Vec<String> = points.iter().map(|v| v.to_string()).collect();
                writeln!(d, "{key} {}", values.join(" ")).unwrap();
            }
            if let Some(other) = against.and_then(|a| a.get(key)) {
                match (points.is_empty(), other.is_empty()) {
                    (false, false) => self
                        .versus
                        .push(facemimic::find::landmark_error(points, other)),
                    (true, true) => {}
                    _ => self.only_one += 1,
                }
            }
            self.extra += faces.len().saturating_sub(1);
            match faces
                .first()
                .map(|f| facemimic::find::landmark_error(&f.landmarks, &truth))
            {
                Some(e) if e < 0.25 => {
                    if std::env::var_os("FIND_EVAL_BOXES").is_some() {
                        print_box(&faces[0], &truth);
                    }
                    self.found += 1;
                    self.pairs.push((faces[0].landmarks.clone(), truth.clone()));
                    let folder =
                        p.parent()
                            .and_then(|d| d.file_name())
                            .map_or(String::new(), |n| {
                                n.to_string_lossy()
                                    .split('_')
                                    .next()
                                    .unwrap_or("")
                                    .to_string()
                            });
                    self.people.push(folder);
                    self.errors.push(e);
                    self.err_sum += e;
                    self.worst = self.worst.max(e);
                }
                _ => self
                    .missed
                    .push(p.file_name().unwrap().to_string_lossy().to_string()),
            }
        }

        /// Prints the set's figures: the detection rate and errors, the convention-free error
        /// and, with `against`, the errors against `FIND_EVAL_AGAINST`'s points.
        fn report(mut self, set: &str, against: bool) {
            let (n, found) = (self.n, self.found);
            self.errors.sort_by(f32::total_cmp);
            let p95_error = p95(&self.errors);
            println!(
                "{set}: {found}/{n} found ({:.2}%), mean error {:.5}, p95 {p95_error:.4}, worst {:.4}, extra faces {}, {:.1} ms/frame; missed {:?}",
                100.0 * found as f64 / n as f64,
                self.err_sum / found.max(1) as f32,
                self.worst,
                self.extra,
                1000.0 * self.secs / n as f64,
                &self.missed[..self.missed.len().min(8)]
            );
            // Each point's mean offset from dlib's over the set removed (one person a set but
            // GRID's ten: a per-person convention counted there).
            let refs: Vec<(&[f32], &[f32])> = self
                .pairs
                .iter()
                .map(|(a, b)| (a.as_slice(), b.as_slice()))
                .collect();
            let cf = facemimic::find::convention_free_errors(&refs);
            println!(
                "{set}: convention-free mean error {:.5}",
                cf.iter().sum::<f32>() / cf.len().max(1) as f32
            );
            // How much of the mouth's motion the points keep: the spread (p95 - p5) of the
            // mouth's width and lip-corner lift (`fit::mouth_shape`) and of the inner lips'
            // opening (`fit::mouth_opening`) over dlib's, and their
            // correlation with dlib's, over the found frames.
            // Each person's mean removed first (GRID's clips are ten people: their spread
            // would be their faces', not their motion).
            let mut shapes: Vec<[[f32; 3]; 2]> = Vec::new();
            let mut people = self.people.clone();
            people.sort();
            people.dedup();
            for who in people {
                let mine: Vec<[[f32; 3]; 2]> = self
                    .pairs
                    .iter()
                    .zip(&self.people)
                    .filter(|(_, w)| **w == who)
                    .filter_map(|((a, b), _)| {
                        let with_opening = |p: &[f32]| {
                            let [w, l] = facemimic::fit::mouth_shape(p)?;
                            Some([w, l, facemimic::fit::mouth_opening(p)])
                        };
                        Some([with_opening(a)?, with_opening(b)?])
                    })
                    .collect();
                let n = mine.len().max(1) as f32;
                let mut mean = [[0f32; 3]; 2];
                for s in &mine {
                    for (m, v) in mean.iter_mut().flatten().zip(s.iter().flatten()) {
                        *m += v / n;
                    }
                }
                shapes.extend(mine.iter().map(|s| {
                    let mut d = *s;
                    for (x, m) in d.iter_mut().flatten().zip(mean.iter().flatten()) {
                        *x -= m;
                    }
                    d
                }));
            }
            if !shapes.is_empty() {
                let motion: Vec<String> = ["width", "lift", "opening"]
                    .iter()
                    .enumerate()
                    .map(|(k, name)| {
                        let ours: Vec<f32> = shapes.iter().map(|s| s[0][k]).collect();
                        let dlib: Vec<f32> = shapes.iter().map(|s| s[1][k]).collect();
                        format!(
                            "{name} spread {:.2} of dlib's, r {:.3}",
                            spread(ours.clone()) / spread(dlib.clone()),
                            pearson(&ours, &dlib)
                        )
                    })
                    .collect();
                println!("{set}: mouth {}", motion.join("; "));
            }
            if against {
                let versus = &mut self.versus;
                versus.sort_by(f32::total_cmp);
                println!(
                    "{set} against FIND_EVAL_AGAINST: {} frames, mean error {:.5}, p95 {:.5}, worst {:.5}; found by only one {}",
                    versus.len(),
                    versus.iter().sum::<f32>() / versus.len().max(1) as f32,
                    p95(versus),
                    versus.last().copied().unwrap_or(f32::NAN),
                    self.only_one
                );
            }
        }
    }

    /// Prints where the finder's box lies against the dlib points' box (`FIND_EVAL_BOXES`):
    /// the centre's offset and the size, in units of the points' box, and the score.
    fn print_box(f: &facemimic::Face, truth: &[f32]) {
        let lb = facemimic::BBox::of_points(truth);
        println!(
            "box {:.3} {:.3} {:.3} {:.3} score {:.3}",
            (f.bbox.x + 0.5 * f.bbox.width - lb.x - 0.5 * lb.width) / lb.width,
            (f.bbox.y + 0.5 * f.bbox.height - lb.y - 0.5 * lb.height) / lb.height,
            f.bbox.width / lb.width,
            f.bbox.height / lb.height,
            f.score
        );
    }
}

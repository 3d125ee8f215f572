//! Do the strong expressions of an expressive source (franck: speech, smiles, laughs, blinks)
//! arrive on speech-only targets (the page's default GRID models)? Per cloning method, the
//! spread of five geometric features of every target's cloned shape against the source's.
//!
//! ```sh
//! cargo run --profile eval --example expression_eval -- \
//!     [--methods substitute,map,map-residual] [--gains 1,2] [--targets spk02,spk03,spk06,spk10] \
//!     [--sheet scratch/expression-sheet.png] [--sheet-rows laugh,smile,jaw-drop,blink,brows]
//!     [--no-source] [--dump-dir scratch/expression-dump] [--seed 1]
//! ```
//!
//! **Split.** The source model `franck` is built from `franck-dev/train20.txt` (its 20 frames are
//! the only franck frames any model sees); the measured frames are franck-dev's other 980 frames
//! and all 1000 frames of franck-dev2 (3800-4799). The targets are built as
//! `scripts/build-models.sh` builds the page's defaults (`facemimic build --name spkNN --list
//! data/grid/spkNN_*/train20.txt`: canonical frame, default variances, the training frame
//! closest to the mean as backdrop, stored with the default `i6` appearance), from GRID frames
//! only. Research data is read from `../shared/data` (never copied into the repository); the
//! `--dump-dir` and `--sheet` outputs hold derived franck pictures and belong in the untracked
//! `scratch/`.
//!
//! **Measure.** Each measured frame's `.pts` landmarks are projected into franck
//! (`Model::project`), cloned onto every target with each method (default `CloneOptions`: gain 1,
//! clamp 3 sigma, target at rest), and the features are taken in a face frame (a similarity
//! putting the eye centres, means of points 36-41 and 42-47 0-based, horizontal, 1 apart, y
//! down) on the source model's instance and on each target's `Cloner::target_shape`: mouth width
//! `|p48 - p54|`; lip-corner lift (outer-lip midpoint y minus the corners' mean y, positive =
//! corners up); jaw drop (chin p8 below the eye line); brow height (eye line above the brows'
//! mean y, 17-26); eye opening (the mean vertical lid gap, both eyes and each eye). Printed per
//! method, on all measured frames and on each clip: the target / source ratio of each feature's
//! p95 - p5 range, and the Pearson correlation of eye opening with the source's over all frames
//! and over the frames within 10 of a blink (a run of source eye openings below 60% of the
//! clip's median, gaps of one frame bridged). `--gains` checks that a higher gain never gives a
//! narrower range. `--sheet` draws the strongest expressions cloned and composited into each
//! target's picture (PNG, or JPEG at quality 90 when the name ends in `.jpg`); `--no-source`
//! leaves franck's frames out of it (each row labelled with its frame number instead), which is
//! the only kind of sheet that may be published; `--dump-dir` writes the laughing frames (top 10% of source mouth width +
//! lift) and as many random others, with their clones, for an external expression classifier.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
fn main() -> std::process::ExitCode {
    match native::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("expression_eval: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::collections::HashSet;
    use std::path::{Path, PathBuf};
    use std::time::Instant;

    use clap::Parser;
    use facemimic::clone::{CloneOptions, Cloner, Method};
    use facemimic::format::{read_model, write_model_checked_as, Storage};
    use facemimic::glam::Vec2;
    use facemimic::tiny_skia::{FilterQuality, IntSize, Pixmap, PixmapPaint, Transform};
    use facemimic::{
        enrol, io, picture_view, BuildOptions, Compositor, DrawOptions, EnrolFrame, EnrolOptions,
        Error, Model, Params, Result, Similarity,
    };
    use facemimic_testkit::sheet::{canvas, put, save};

    /// The page's default targets (`www/models/manifest.json`).
    const DEFAULT_TARGETS: &str = "spk02,spk03,spk06,spk10";
    /// Frames either side of a blink in its correlation window.
    const BLINK_WINDOW: u32 = 10;
    /// A blink: the source's eye opening below this share of the clip's median.
    const BLINK_FRACTION: f32 = 0.6;
    /// Frames from a blink's first to its last from which it is long (eyes narrow for 0.4 s or
    /// more at 24 fps; on franck: looking down, or laughing with the eyes shut): counted apart,
    /// and not drawn as the contact sheet's blink.
    const LONG_BLINK: u32 = 10;
    /// A contact-sheet cell (width, height) in pixels.
    const CELL: (u32, u32) = (128, 160);
    /// Gap between the contact sheet's groups of columns, in pixels.
    const GAP: u32 = 6;
    /// Frames two contact-sheet rows of one clip are at least apart.
    const SHEET_SPACING: u32 = 24;

    /// Expression transfer per cloning method, measured on franck's unseen frames.
    #[derive(Parser, Debug)]
    #[command(name = "expression_eval")]
    struct Args {
        /// The shared data folder holding franck-dev/ and franck-dev2/
        /// (default: ../shared/data beside the repository).
        #[arg(long, value_name = "DIR")]
        data: Option<PathBuf>,
        /// Cloning methods, by name, comma-separated.
        #[arg(
            long,
            default_value = "substitute,map,map-residual",
            value_name = "M,..."
        )]
        methods: String,
        /// Gains whose feature ranges must not shrink as the gain grows, comma-separated.
        #[arg(long, default_value = "1,2", value_name = "G,...")]
        gains: String,
        /// GRID speakers to clone onto, comma-separated (each data/grid/<speaker>_*/).
        #[arg(long, default_value = DEFAULT_TARGETS, value_name = "SPK,...")]
        targets: String,
        /// Write a contact sheet of the strongest expressions (PNG; JPEG at quality 90 when
        /// the name ends in .jpg or .jpeg).
        #[arg(long, value_name = "PATH")]
        sheet: Option<PathBuf>,
        /// The sheet's rows, in order, each the strongest frame of its kind at least 24 frames
        /// from the rows before it: laugh (source mouth width + lift), smile (the same among
        /// frames whose jaw drop is at most its median), jaw-drop, blink (the deepest short
        /// blink), brows (the highest brows among frames whose eye opening is at least its
        /// median: brows measured from the eye centres also "rise" as the lids close).
        #[arg(
            long,
            default_value = "laugh,laugh,laugh,laugh,blink,jaw-drop",
            value_name = "KIND,..."
        )]
        sheet_rows: String,
        /// Leave the source frames out of the sheet (franck's pictures may never be published)
        /// and label each row with its frame number instead.
        #[arg(long)]
        no_source: bool,
        /// Write laughing and random frames with their clones and a manifest here.
        #[arg(long, value_name = "DIR")]
        dump_dir: Option<PathBuf>,
        /// Clone without the constraint (default: `CloneOptions::default()`'s, 3 sigma).
        #[arg(long)]
        no_clamp: bool,
        /// Seed of the random frames of --dump-dir.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// In the contact sheet and the dump, give the expressive method each frame's pixels
        /// sampled at its landmarks against the model's mean appearance
        /// (`Cloner::set_observed`, as a follower's face is given), instead of the model's
        /// synthesis of the projected appearance parameters.
        #[arg(long)]
        observed: bool,
        /// Measure every K-th frame only (quick runs; the split is unchanged).
        #[arg(long, default_value_t = 1, value_name = "K")]
        every: usize,
    }

    /// The repository's root.
    fn root() -> &'static Path {
        Path::new(env!("CARGO_MANIFEST_DIR"))
    }

    /// Runs the evaluation: builds, projects, clones, prints, and draws what was asked.
    pub fn run() -> Result<()> {
        let args = Args::parse();
        let t0 = Instant::now();
        let setups: Vec<CloneOptions> = parse_methods(&args.methods)?
            .into_iter()
            .map(|method| CloneOptions {
                method,
                clamp: if args.no_clamp {
                    None
                } else {
                    CloneOptions::default().clamp
                },
                ..CloneOptions::default()
            })
            .collect();
        let gains = parse_gains(&args.gains)?;
        let sheet_rows = parse_sheet_rows(&args.sheet_rows)?;
        if args.every == 0 {
            return Err(Error::Params("--every must be at least 1".into()));
        }
        let data = args
            .data
            .clone()
            .unwrap_or_else(|| root().join("../shared/data"));
        let source = build_model("franck", &data.join("franck-dev/train20.txt"))?;
        let mut cloner = Cloner::new(source)?;
        for speaker in split_list(&args.targets) {
            let list = grid_list(speaker)?;
            cloner.add_target(build_model(speaker, &list)?)?;
        }
        if cloner.n_targets() == 0 {
            return Err(Error::Params("--targets names no speaker".into()));
        }
        let built = t0.elapsed();
        let frames = load_frames(&data, cloner.source(), args.every)?;
        let projected = t0.elapsed() - built;
        print_split(&cloner, &frames, &setups[0]);
        let source = Source::new(cloner.source(), &frames)?;
        let runs = clone_runs(&mut cloner, &frames, &setups, &gains)?;
        let cloned = t0.elapsed() - built - projected;
        report(&cloner, &frames, &source, &runs);
        gain_check(&cloner, &source.series, &runs, &setups, &gains);
        if let Some(path) = &args.sheet {
            let picks = pick_sheet_frames(&frames, &source.series, &source.blinks, &sheet_rows);
            write_sheet(
                &mut cloner,
                &frames,
                &setups,
                &picks,
                (path, args.no_source, args.observed),
            )?;
        }
        if let Some(dir) = &args.dump_dir {
            dump(
                &mut cloner,
                &frames,
                &source.series,
                &setups,
                args.seed,
                (dir, args.observed),
            )?;
        }
        println!(
            "\ntime: models built {built:.1?}, {} frames read and projected {projected:.1?}, \
             cloned {cloned:.1?}, total {:.1?}",
            frames.len(),
            t0.elapsed()
        );
        Ok(())
    }

    // -----------------------------------------------------------------------------------
    // Arguments and models.

    /// The non-empty, trimmed items of a comma-separated list.
    fn split_list(s: &str) -> impl Iterator<Item = &str> {
        s.split(',').map(str::trim).filter(|x| !x.is_empty())
    }

    /// The methods named in `s`, by the library's own parser (so a method added to the library
    /// works by name), without repeats.
    fn parse_methods(s: &str) -> Result<Vec<Method>> {
        let mut out: Vec<Method> = Vec::new();
        for name in split_list(s) {
            let m: Method = name
                .parse()
                .map_err(|e: Error| e.with_context("--methods"))?;
            if !out.contains(&m) {
                out.push(m);
            }
        }
        if out.is_empty() {
            return Err(Error::Params("--methods names no method".into()));
        }
        Ok(out)
    }

    /// The gains in `s`, finite and non-negative, ascending, without repeats, with 1 (the
    /// main tables' gain) added when missing.
    fn parse_gains(s: &str) -> Result<Vec<f32>> {
        let mut out = vec![1.0f32];
        for g in split_list(s) {
            let v: f32 = g
                .parse()
                .map_err(|_| Error::Params(format!("--gains: '{g}' is not a number")))?;
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Params(format!(
                    "--gains: {g} must be a finite gain >= 0"
                )));
            }
            out.push(v);
        }
        out.sort_by(f32::total_cmp);
        out.dedup();
        Ok(out)
    }

    /// A kind of contact-sheet row: which strongest source frame it shows.
    #[derive(Clone, Copy, Debug)]
    enum SheetRow {
        /// The largest mouth width + lip-corner lift.
        Laugh,
        /// The largest mouth width + lift among the frames whose jaw drop is at most its median.
        Smile,
        /// The largest jaw drop.
        JawDrop,
        /// The deepest short blink.
        Blink,
        /// The highest brows among the frames whose eye opening is at least its median (the
        /// brows are measured from the eye centres, which drop as the lids close).
        Brows,
    }

    impl SheetRow {
        /// Every kind with its name on the command line.
        const NAMES: [(SheetRow, &'static str); 5] = [
            (SheetRow::Laugh, "laugh"),
            (SheetRow::Smile, "smile"),
            (SheetRow::JawDrop, "jaw-drop"),
            (SheetRow::Blink, "blink"),
            (SheetRow::Brows, "brows"),
        ];

        /// The kind's name.
        fn name(self) -> &'static str {
            Self::NAMES
                .iter()
                .find(|(k, _)| std::mem::discriminant(k) == std::mem::discriminant(&self))
                .map_or("?", |(_, n)| n)
        }
    }

    /// The sheet's row kinds named in `s`, in order (repeats allowed: each takes the next
    /// strongest frame).
    fn parse_sheet_rows(s: &str) -> Result<Vec<SheetRow>> {
        let rows = split_list(s)
            .map(|name| {
                SheetRow::NAMES
                    .iter()
                    .find(|(_, n)| *n == name)
                    .map(|(k, _)| *k)
                    .ok_or_else(|| {
                        let names: Vec<&str> = SheetRow::NAMES.iter().map(|(_, n)| *n).collect();
                        Error::Params(format!(
                            "--sheet-rows: '{name}' is not one of {}",
                            names.join(", ")
                        ))
                    })
            })
            .collect::<Result<Vec<_>>>()?;
        if rows.is_empty() {
            return Err(Error::Params("--sheet-rows names no row".into()));
        }
        Ok(rows)
    }

    /// `data/grid/<speaker>_*/train20.txt`; with several clips of the speaker, the last by name
    /// (`scripts/build-models.sh` builds each in turn into the same file, so the last stays).
    fn grid_list(speaker: &str) -> Result<PathBuf> {
        let grid = root().join("data/grid");
        let entries =
            std::fs::read_dir(&grid).map_err(|e| Error::Io(format!("{}: {e}", grid.display())))?;
        let prefix = format!("{speaker}_");
        let mut dirs: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_dir())
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with(&prefix))
            })
            .collect();
        dirs.sort();
        let dir = dirs.pop().ok_or_else(|| {
            Error::Io(format!(
                "no clip of '{speaker}' in {} ({prefix}*)",
                grid.display()
            ))
        })?;
        Ok(dir.join("train20.txt"))
    }

    /// The model `facemimic build --name NAME --list LIST` makes (the enrolment pipeline with the
    /// CLI's defaults: canonical frame, mean reference, the default backdrop), passed through
    /// the file format with the CLI's default `i6` appearance storage, as the page loads it.
    fn build_model(name: &str, list: &Path) -> Result<Model> {
        let frames = io::read_list(list)?
            .iter()
            .map(|p| {
                let t = io::read_training_image(p)?;
                Ok(EnrolFrame {
                    name: t.name,
                    image: t.image,
                    landmarks: Some(t.landmarks),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let options = EnrolOptions {
            build: BuildOptions {
                name: name.to_string(),
                ..BuildOptions::default()
            },
            ..EnrolOptions::default()
        };
        let made = enrol(frames, &options, None, None, &mut |_| true)
            .map_err(|e| e.with_context(&list.display().to_string()))?;
        let bytes = write_model_checked_as(&made.model, Storage::I6)?;
        let model = read_model(&bytes)?;
        println!(
            "model {name}: {} frames of {}, {} shape / {} appearance modes, backdrop {}",
            made.images.len(),
            list.strip_prefix(root()).unwrap_or(list).display(),
            model.shape().n_modes(),
            model.appearance().n_modes(),
            model.backdrop().map_or("none".to_string(), |b| format!(
                "{}x{}",
                b.width(),
                b.height()
            ))
        );
        Ok(model)
    }

    // -----------------------------------------------------------------------------------
    // Frames.

    /// One measured frame: where it is, its landmarks and its projection into the source.
    struct Frame {
        /// The clip folder's name (`franck-dev` or `franck-dev2`).
        clip: &'static str,
        /// The frame number (its file stem).
        number: u32,
        /// The image file.
        path: PathBuf,
        /// Its `.pts` landmarks (0-based image pixels).
        landmarks: Vec<f32>,
        /// The landmarks (and the image at them) projected into the source model.
        params: Params,
    }

    /// The measured frames, every `every`-th: franck-dev less its training list, then all of
    /// franck-dev2 (which no list names), each projected into `source`.
    fn load_frames(data: &Path, source: &Model, every: usize) -> Result<Vec<Frame>> {
        let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned());
        let train: HashSet<String> = io::read_list(&data.join("franck-dev/train20.txt"))?
            .iter()
            .filter_map(|p| stem(p))
            .collect();
        let mut frames = Vec::new();
        for clip in ["franck-dev", "franck-dev2"] {
            let paths = io::annotated_images(&data.join(clip))?;
            let measured = paths
                .iter()
                .filter(|p| !(clip == "franck-dev" && stem(p).is_some_and(|s| train.contains(&s))));
            for path in measured.step_by(every) {
                frames.push(load_frame(clip, path, source)?);
            }
        }
        if frames.is_empty() {
            return Err(Error::Io(format!(
                "no measured frames under {}",
                data.display()
            )));
        }
        Ok(frames)
    }

    /// One frame read and projected into `source`.
    fn load_frame(clip: &'static str, path: &Path, source: &Model) -> Result<Frame> {
        let name = path.display().to_string();
        let number = path
            .file_stem()
            .and_then(|s| s.to_str())
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| Error::Io(format!("{name}: the file stem is not a frame number")))?;
        let t = io::read_training_image(path)?;
        let params = source
            .project(&t.image.view()?, &t.landmarks)
            .map_err(|e| e.with_context(&name))?;
        Ok(Frame {
            clip,
            number,
            path: path.to_path_buf(),
            landmarks: t.landmarks,
            params,
        })
    }

    /// Prints the split, the models and the cloning options (`setup`, less its method).
    fn print_split(cloner: &Cloner, frames: &[Frame], setup: &CloneOptions) {
        let count = |c: &str| frames.iter().filter(|f| f.clip == c).count();
        let targets: Vec<&str> = (0..cloner.n_targets())
            .map(|i| cloner.target(i).name())
            .collect();
        println!(
            "\nsplit: source model franck built from franck-dev/train20.txt (20 frames: the only \
             franck frames any model sees); measured: {} frames = franck-dev's other frames ({}) \
             + franck-dev2 3800-4799 ({}); targets {} built from data/grid/<speaker>_*/train20.txt \
             (GRID only), all in the canonical frame {:016x}",
            frames.len(),
            count("franck-dev"),
            count("franck-dev2"),
            targets.join(", "),
            cloner.source().frame().fingerprint()
        );
        println!(
            "cloning: gain {}, clamp {}, follow_pose {} (CloneOptions::default() unless --no-clamp)",
            setup.gain,
            setup
                .clamp
                .map_or("none".to_string(), |k| format!("{k} sigma")),
            setup.follow_pose
        );
    }

    // -----------------------------------------------------------------------------------
    // Features.

    /// The features of one shape, in the face frame (eye centres at (-0.5, 0) and (0.5, 0),
    /// y down; one unit = the distance between the eye centres).
    #[derive(Clone, Copy, Debug, Default)]
    struct Features {
        /// `|p48 - p54|`.
        mouth_width: f32,
        /// `y((p51 + p57) / 2) - mean(y48, y54)`: positive = corners up.
        lift: f32,
        /// `y8` (the eye line is at y = 0).
        jaw_drop: f32,
        /// `-mean(y17..=y26)`.
        brow: f32,
        /// Lid gap of the eye of points 36-41: `(|p37 - p41| + |p38 - p40|) / 2`.
        eye_a: f32,
        /// Lid gap of the eye of points 42-47: `(|p43 - p47| + |p44 - p46|) / 2`.
        eye_b: f32,
    }

    /// A feature of [`Features`], for tables and loops.
    #[derive(Clone, Copy, Debug)]
    enum Feature {
        /// [`Features::mouth_width`].
        MouthWidth,
        /// [`Features::lift`].
        Lift,
        /// [`Features::jaw_drop`].
        JawDrop,
        /// [`Features::brow`].
        Brow,
        /// The mean of both eyes' lid gaps.
        Eyes,
        /// [`Features::eye_a`].
        EyeA,
        /// [`Features::eye_b`].
        EyeB,
    }

    /// The features whose ranges are compared, with their column names.
    const RANGED: [(Feature, &str); 5] = [
        (Feature::MouthWidth, "mouth width"),
        (Feature::Lift, "lip-corner lift"),
        (Feature::JawDrop, "jaw drop"),
        (Feature::Brow, "brow height"),
        (Feature::Eyes, "eye opening"),
    ];

    impl Features {
        /// The value of feature `f`.
        fn get(&self, f: Feature) -> f32 {
            match f {
                Feature::MouthWidth => self.mouth_width,
                Feature::Lift => self.lift,
                Feature::JawDrop => self.jaw_drop,
                Feature::Brow => self.brow,
                Feature::Eyes => 0.5 * (self.eye_a + self.eye_b),
                Feature::EyeA => self.eye_a,
                Feature::EyeB => self.eye_b,
            }
        }

        /// The features of a 68-point shape (any similarity pose).
        fn of(shape: &[f32]) -> Features {
            let p = |i: usize| Vec2::new(shape[2 * i], shape[2 * i + 1]);
            let mean = |r: std::ops::Range<usize>| {
                let n = r.len() as f32;
                r.map(p).sum::<Vec2>() / n
            };
            let (left, right) = (mean(36..42), mean(42..48));
            let d = right - left;
            let scale = d.length();
            let u = d / scale;
            let v = Vec2::new(-u.y, u.x); // down the face in a y-down image
            let origin = 0.5 * (left + right);
            let q = |i: usize| {
                let w = p(i) - origin;
                Vec2::new(w.dot(u), w.dot(v)) / scale
            };
            let gap = |a: usize, b: usize| q(a).distance(q(b));
            Features {
                mouth_width: gap(48, 54),
                lift: 0.5 * (q(51).y + q(57).y) - 0.5 * (q(48).y + q(54).y),
                jaw_drop: q(8).y,
                brow: -(17..27).map(|i| q(i).y).sum::<f32>() / 10.0,
                eye_a: 0.5 * (gap(37, 41) + gap(38, 40)),
                eye_b: 0.5 * (gap(43, 47) + gap(44, 46)),
            }
        }
    }

    /// One feature vector per measured frame.
    type Series = Vec<Features>;

    /// The source's side of the measure.
    struct Source {
        /// The features of the source model's instance (the projected parameters) per frame:
        /// what the targets are compared with.
        series: Series,
        /// The features of the frames' `.pts` landmarks (what the source model reconstructs).
        landmarks: Series,
        /// The blinks of `series`.
        blinks: Vec<Blink>,
        /// The blinks of `landmarks`.
        landmark_blinks: Vec<Blink>,
    }

    impl Source {
        /// The source's features and blinks over `frames`, projected into `model`.
        fn new(model: &Model, frames: &[Frame]) -> Result<Source> {
            let mut shape = vec![0.0; model.shape().base.len()];
            let series = frames
                .iter()
                .map(|f| {
                    model.image_shape(&f.params, &mut shape)?;
                    Ok(Features::of(&shape))
                })
                .collect::<Result<Series>>()?;
            let landmarks: Series = frames.iter().map(|f| Features::of(&f.landmarks)).collect();
            Ok(Source {
                blinks: find_blinks(frames, &series),
                landmark_blinks: find_blinks(frames, &landmarks),
                series,
                landmarks,
            })
        }
    }

    /// The p95 - p5 range of `values` (linear interpolation between order statistics).
    fn range(values: impl Iterator<Item = f32>) -> f64 {
        let mut v: Vec<f32> = values.collect();
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f32::total_cmp);
        let at = |q: f64| {
            let x = q * (v.len() - 1) as f64;
            let (i, t) = (x.floor() as usize, x.fract());
            let next = v[(i + 1).min(v.len() - 1)] as f64;
            v[i] as f64 * (1.0 - t) + next * t
        };
        at(0.95) - at(0.05)
    }

    /// Pearson's correlation of two equally long series (NaN for fewer than 3 values or a
    /// constant series).
    fn pearson(a: &[f32], b: &[f32]) -> f64 {
        let n = a.len().min(b.len());
        if n < 3 {
            return f64::NAN;
        }
        let ma = a[..n].iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        let mb = b[..n].iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
        for (&x, &y) in a[..n].iter().zip(&b[..n]) {
            let (dx, dy) = (x as f64 - ma, y as f64 - mb);
            sab += dx * dy;
            saa += dx * dx;
            sbb += dy * dy;
        }
        sab / (saa * sbb).sqrt()
    }

    // -----------------------------------------------------------------------------------
    // Cloning.

    /// The target features of one method at one gain: `targets[t][frame]`.
    struct Run {
        method: Method,
        gain: f32,
        targets: Vec<Series>,
    }

    /// Every frame cloned with every setup (a method's options) at every gain.
    fn clone_runs(
        cloner: &mut Cloner,
        frames: &[Frame],
        setups: &[CloneOptions],
        gains: &[f32],
    ) -> Result<Vec<Run>> {
        let mut runs = Vec::new();
        for setup in setups {
            let method = setup.method;
            for &gain in gains {
                let options = CloneOptions {
                    gain,
                    ..setup.clone()
                };
                let mut targets = vec![Series::with_capacity(frames.len()); cloner.n_targets()];
                for f in frames {
                    cloner.clone_frame(&f.params, &options).map_err(|e| {
                        e.with_context(&format!("{} ({method}, gain {gain})", f.path.display()))
                    })?;
                    for (i, s) in targets.iter_mut().enumerate() {
                        s.push(Features::of(cloner.target_shape(i)));
                    }
                }
                runs.push(Run {
                    method,
                    gain,
                    targets,
                });
            }
        }
        Ok(runs)
    }

    /// The run of `method` at `gain`.
    fn run_of(runs: &[Run], method: Method, gain: f32) -> Option<&Run> {
        runs.iter().find(|r| r.method == method && r.gain == gain)
    }

    // -----------------------------------------------------------------------------------
    // Blinks.

    /// A blink: a run of measured frames of one clip whose source eye opening is below
    /// [`BLINK_FRACTION`] of the clip's median (a gap of one frame bridged).
    struct Blink {
        clip: &'static str,
        first: u32,
        last: u32,
        /// Index (into the frames) of the frame with the smallest opening.
        deepest: usize,
    }

    /// The blinks of every clip, each clip against its own median eye opening.
    fn find_blinks(frames: &[Frame], source: &Series) -> Vec<Blink> {
        let mut blinks: Vec<Blink> = Vec::new();
        for clip in ["franck-dev", "franck-dev2"] {
            let idx: Vec<usize> = (0..frames.len())
                .filter(|&i| frames[i].clip == clip)
                .collect();
            let mut eyes: Vec<f32> = idx.iter().map(|&i| source[i].get(Feature::Eyes)).collect();
            if eyes.is_empty() {
                continue;
            }
            eyes.sort_by(f32::total_cmp);
            let threshold = BLINK_FRACTION * eyes[eyes.len() / 2];
            let eye = |i: usize| source[i].get(Feature::Eyes);
            for &i in idx.iter().filter(|&&i| eye(i) < threshold) {
                let n = frames[i].number;
                match blinks.last_mut() {
                    Some(b) if b.clip == clip && n <= b.last + 2 => {
                        b.last = n;
                        if eye(i) < eye(b.deepest) {
                            b.deepest = i;
                        }
                    }
                    _ => blinks.push(Blink {
                        clip,
                        first: n,
                        last: n,
                        deepest: i,
                    }),
                }
            }
        }
        blinks
    }

    /// Per frame, whether it lies within [`BLINK_WINDOW`] frames of a blink of its clip.
    fn blink_mask(frames: &[Frame], blinks: &[Blink]) -> Vec<bool> {
        frames
            .iter()
            .map(|f| {
                blinks.iter().any(|b| {
                    b.clip == f.clip
                        && f.number + BLINK_WINDOW >= b.first
                        && f.number <= b.last + BLINK_WINDOW
                })
            })
            .collect()
    }

    // -----------------------------------------------------------------------------------
    // Tables.

    /// Frames measured together: all, or one clip.
    struct Subset {
        name: String,
        members: Vec<usize>,
    }

    /// All measured frames, then each clip's.
    fn subsets(frames: &[Frame]) -> Vec<Subset> {
        let mut out = vec![Subset {
            name: "all measured frames".into(),
            members: (0..frames.len()).collect(),
        }];
        for clip in ["franck-dev", "franck-dev2"] {
            out.push(Subset {
                name: format!("{clip} only"),
                members: (0..frames.len())
                    .filter(|&i| frames[i].clip == clip)
                    .collect(),
            });
        }
        out
    }

    /// The values of feature `f` of `series` at `members` (and where `keep` holds).
    fn pick(
        series: &Series,
        members: &[usize],
        keep: &dyn Fn(usize) -> bool,
        f: Feature,
    ) -> Vec<f32> {
        members
            .iter()
            .filter(|&&i| keep(i))
            .map(|&i| series[i].get(f))
            .collect()
    }

    /// The blinks of `blinks` in `subset`.
    fn blinks_in<'a>(blinks: &'a [Blink], subset: &Subset) -> Vec<&'a Blink> {
        let members: HashSet<usize> = subset.members.iter().copied().collect();
        blinks
            .iter()
            .filter(|b| members.contains(&b.deepest))
            .collect()
    }

    /// Prints the source's side of one subset: its ranges, how much of its landmarks' ranges
    /// the source model reconstructs, and its blinks.
    fn source_lines(subset: &Subset, source: &Source, mask: &[bool]) {
        let all = |_: usize| true;
        let cells: Vec<String> = RANGED
            .iter()
            .map(|&(f, name)| {
                let r = |s: &Series| range(pick(s, &subset.members, &all, f).into_iter());
                let (model, pts) = (r(&source.series), r(&source.landmarks));
                format!("{name} {model:.3} ({:.2} of the .pts')", model / pts)
            })
            .collect();
        println!("source model p95-p5, eye distances: {}", cells.join(", "));
        let found = blinks_in(&source.blinks, subset);
        let spans: Vec<String> = found
            .iter()
            .map(|b| format!("{}-{}", b.first, b.last))
            .collect();
        let long = found
            .iter()
            .filter(|b| b.last - b.first >= LONG_BLINK)
            .count();
        let windowed = subset.members.iter().filter(|&&i| mask[i]).count();
        println!(
            "blinks (source model's eye opening < {:.0}% of the clip's median, gaps of one frame \
             bridged): {} [{}], {long} of them spanning {LONG_BLINK} frames or more; {windowed} \
             frames within +-{BLINK_WINDOW} of one; on the .pts landmarks: {}",
            100.0 * BLINK_FRACTION,
            found.len(),
            spans.join(", "),
            blinks_in(&source.landmark_blinks, subset).len()
        );
    }

    /// Prints the tables of every subset and method at gain 1.
    fn report(cloner: &Cloner, frames: &[Frame], source: &Source, runs: &[Run]) {
        let mask = blink_mask(frames, &source.blinks);
        for subset in subsets(frames) {
            println!("\n## {} ({} frames)\n", subset.name, subset.members.len());
            source_lines(&subset, source, &mask);
            for run in runs.iter().filter(|r| r.gain == 1.0) {
                method_table(cloner, &subset, &source.series, run, &mask);
            }
        }
    }

    /// One method's table on one subset: per target the range ratios and the eye-opening
    /// correlations (all frames, and the blink windows).
    fn method_table(cloner: &Cloner, subset: &Subset, source: &Series, run: &Run, mask: &[bool]) {
        println!("\n### {} (gain 1)\n", run.method);
        println!(
            "| target | mouth width | lip-corner lift | jaw drop | brow height | eye opening \
             | r eyes | r eye 36-41 / 42-47 | r eyes, blinks +-{BLINK_WINDOW} | r 36-41 / 42-47, blinks |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|");
        let all = |_: usize| true;
        let blink = |i: usize| mask[i];
        for (t, series) in run.targets.iter().enumerate() {
            let mut cells = vec![cloner.target(t).name().to_string()];
            for &(f, _) in &RANGED {
                let r = |s: &Series| range(pick(s, &subset.members, &all, f).into_iter());
                cells.push(format!("{:.2}", r(series) / r(source)));
            }
            for keep in [&all as &dyn Fn(usize) -> bool, &blink] {
                let r = |f: Feature| {
                    pearson(
                        &pick(series, &subset.members, keep, f),
                        &pick(source, &subset.members, keep, f),
                    )
                };
                cells.push(format!("{:.2}", r(Feature::Eyes)));
                cells.push(format!("{:.2} / {:.2}", r(Feature::EyeA), r(Feature::EyeB)));
            }
            println!("| {} |", cells.join(" | "));
        }
    }

    /// Prints, per method, each feature's range ratio at every gain, and whether a higher gain
    /// ever gives a narrower range (over all measured frames).
    fn gain_check(
        cloner: &Cloner,
        source: &Series,
        runs: &[Run],
        setups: &[CloneOptions],
        gains: &[f32],
    ) {
        if gains.len() < 2 {
            return;
        }
        let all: Vec<usize> = (0..source.len()).collect();
        let src: Vec<f64> = RANGED
            .iter()
            .map(|&(f, _)| range(pick(source, &all, &|_| true, f).into_iter()))
            .collect();
        let names: Vec<String> = gains.iter().map(|g| g.to_string()).collect();
        println!(
            "\n## Gain check: range ratio at gains {} (all measured frames; WEAKER = a higher gain \
             gave a narrower range)",
            names.join(" -> ")
        );
        let mut monotonic = true;
        for method in setups.iter().map(|s| s.method) {
            println!("\n### {method}\n");
            let header: Vec<&str> = RANGED.iter().map(|&(_, n)| n).collect();
            println!("| target | {} |", header.join(" | "));
            println!("|---|{}", "---|".repeat(RANGED.len()));
            for t in 0..cloner.n_targets() {
                let mut cells = vec![cloner.target(t).name().to_string()];
                for (k, &(f, _)) in RANGED.iter().enumerate() {
                    let ratios: Vec<f64> = gains
                        .iter()
                        .filter_map(|&g| run_of(runs, method, g))
                        .map(|r| {
                            range(pick(&r.targets[t], &all, &|_| true, f).into_iter()) / src[k]
                        })
                        .collect();
                    let ok = ratios.windows(2).all(|w| w[1] >= w[0]);
                    monotonic &= ok;
                    let text: Vec<String> = ratios.iter().map(|r| format!("{r:.2}")).collect();
                    cells.push(format!(
                        "{}{}",
                        text.join(" -> "),
                        if ok { "" } else { " WEAKER" }
                    ));
                }
                println!("| {} |", cells.join(" | "));
            }
        }
        println!(
            "\ngain check: {}",
            if monotonic {
                "every feature's range grows (or stays) with the gain, for every method and target"
            } else {
                "FAILED: a higher gain gave a narrower range (marked WEAKER)"
            }
        );
    }

    // -----------------------------------------------------------------------------------
    // Pictures.

    /// The face box of landmarks: their bounding box widened by 15% each side and raised by
    /// 25% of its height, `[x, y, w, h]` in the landmarks' pixels.
    fn face_box(points: &[f32]) -> [f32; 4] {
        let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for p in points.chunks_exact(2) {
            (x0, x1) = (x0.min(p[0]), x1.max(p[0]));
            (y0, y1) = (y0.min(p[1]), y1.max(p[1]));
        }
        let (w, h) = (x1 - x0, y1 - y0);
        [x0 - 0.15 * w, y0 - 0.25 * h, 1.3 * w, 1.25 * h]
    }

    /// `b` clipped to a `width x height` picture, in whole pixels.
    fn clip_box(b: [f32; 4], width: u32, height: u32) -> [u32; 4] {
        let x0 = b[0].floor().clamp(0.0, width as f32) as u32;
        let y0 = b[1].floor().clamp(0.0, height as f32) as u32;
        let x1 = (b[0] + b[2]).ceil().clamp(0.0, width as f32) as u32;
        let y1 = (b[1] + b[3]).ceil().clamp(0.0, height as f32) as u32;
        [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
    }

    /// The view (picture pixels -> cell pixels) showing box `b` centred in a [`CELL`], the
    /// box grown to the cell's aspect.
    fn cell_view(b: [f32; 4]) -> Similarity {
        let (cw, ch) = (CELL.0 as f32, CELL.1 as f32);
        let h = b[3].max(b[2] * ch / cw);
        let k = ch / h;
        let (cx, cy) = (b[0] + 0.5 * b[2], b[1] + 0.5 * b[3]);
        Similarity {
            a: k,
            b: 0.0,
            tx: 0.5 * cw - k * cx,
            ty: 0.5 * ch - k * cy,
        }
    }

    /// A picture (RGBA, opaque) as a pixmap.
    fn pixmap_of(image: &facemimic::Image) -> Result<Pixmap> {
        IntSize::from_wh(image.width, image.height)
            .and_then(|size| Pixmap::from_vec(image.data.clone(), size))
            .ok_or_else(|| Error::Image(format!("{}x{} picture", image.width, image.height)))
    }

    /// Creates the folder `dir` (and its parents).
    fn make_dir(dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io(format!("{}: {e}", dir.display())))
    }

    /// One compositor per target (as `facemimic clone --composite`: tiny-skia, no mesh).
    fn compositors(cloner: &Cloner) -> Result<Vec<Compositor>> {
        (0..cloner.n_targets())
            .map(|i| Compositor::new(cloner.target(i), DrawOptions::default()))
            .collect()
    }

    /// Whether frame `i` is at least [`SHEET_SPACING`] frames from every frame of `chosen`.
    fn apart(frames: &[Frame], chosen: &[(usize, String)], i: usize) -> bool {
        chosen.iter().all(|&(j, _)| {
            frames[i].clip != frames[j].clip
                || frames[i].number.abs_diff(frames[j].number) >= SHEET_SPACING
        })
    }

    /// The contact sheet's frames: per kind of `rows`, in order, the strongest frame of that
    /// kind at least [`SHEET_SPACING`] frames from the ones chosen before (a kind with no such
    /// frame is left out, with a note).
    fn pick_sheet_frames(
        frames: &[Frame],
        source: &Series,
        blinks: &[Blink],
        rows: &[SheetRow],
    ) -> Vec<(usize, String)> {
        let by = |key: &dyn Fn(&Features) -> f32| {
            let mut idx: Vec<usize> = (0..frames.len()).collect();
            idx.sort_by(|&a, &b| key(&source[b]).total_cmp(&key(&source[a])));
            idx
        };
        let smile = |f: &Features| f.mouth_width + f.lift;
        let median = |key: &dyn Fn(&Features) -> f32| {
            let mut v: Vec<f32> = source.iter().map(key).collect();
            v.sort_by(f32::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        };
        let median_jaw = median(&|f| f.jaw_drop);
        let median_eyes = median(&|f| f.get(Feature::Eyes));
        // The deepest blinks first: short runs only (on franck the long ones are eyes lowered
        // while looking down, or shut while laughing).
        let mut short: Vec<usize> = blinks
            .iter()
            .filter(|b| b.last - b.first < LONG_BLINK)
            .map(|b| b.deepest)
            .collect();
        short.sort_by(|&a, &b| {
            source[a]
                .get(Feature::Eyes)
                .total_cmp(&source[b].get(Feature::Eyes))
        });
        let mut chosen: Vec<(usize, String)> = Vec::new();
        for &kind in rows {
            let candidates: Vec<usize> = match kind {
                SheetRow::Laugh => by(&smile),
                SheetRow::Smile => by(&smile)
                    .into_iter()
                    .filter(|&i| source[i].jaw_drop <= median_jaw)
                    .collect(),
                SheetRow::JawDrop => by(&|f| f.jaw_drop),
                SheetRow::Blink => short.clone(),
                SheetRow::Brows => by(&|f| f.brow)
                    .into_iter()
                    .filter(|&i| source[i].get(Feature::Eyes) >= median_eyes)
                    .collect(),
            };
            match candidates.into_iter().find(|&i| apart(frames, &chosen, i)) {
                Some(i) => chosen.push((i, kind.name().into())),
                None => eprintln!(
                    "expression_eval: no frame for the sheet row '{}'",
                    kind.name()
                ),
            }
        }
        chosen
    }

    /// The contact sheet: a row per picked frame, the source frame cropped to the face (unless
    /// `no_source`: then the row's first cell carries its frame number), then per target and
    /// method the clone composited into the target's picture, cropped to the face (a fixed box
    /// per target: its face at rest, with room below for the jaw).
    fn write_sheet(
        cloner: &mut Cloner,
        frames: &[Frame],
        setups: &[CloneOptions],
        picks: &[(usize, String)],
        (path, no_source, observed): (&Path, bool, bool),
    ) -> Result<()> {
        let (nt, nm) = (cloner.n_targets() as u32, setups.len() as u32);
        let first = u32::from(!no_source);
        let width = CELL.0 * (first + nt * nm) + GAP * (nt - 1 + first);
        let mut sheet = canvas(width, CELL.1 * picks.len() as u32)?;
        let mut comps = compositors(cloner)?;
        let views: Vec<Similarity> = (0..cloner.n_targets())
            .map(|t| {
                let b = facemimic::base_box(cloner.target(t));
                let (w, h) = (b[2] - b[0], b[3] - b[1]);
                cell_view([b[0] - 0.15 * w, b[1] - 0.25 * h, 1.3 * w, 1.35 * h])
            })
            .collect();
        for (row, (i, why)) in picks.iter().enumerate() {
            let f = &frames[*i];
            let y = row as u32 * CELL.1;
            if !no_source {
                let picture = pixmap_of(&io::read_image(&f.path)?)?;
                let mut cell = canvas(CELL.0, CELL.1)?;
                let v = cell_view(face_box(&f.landmarks));
                let paint = PixmapPaint {
                    quality: FilterQuality::Bilinear,
                    ..PixmapPaint::default()
                };
                let to_cell = Transform::from_row(v.a, 0.0, 0.0, v.a, v.tx, v.ty);
                cell.draw_pixmap(0, 0, picture.as_ref(), &paint, to_cell, None);
                put(&mut sheet, (0, y), &cell);
            }
            observe(cloner, f, observed)?;
            for (m, options) in setups.iter().enumerate() {
                cloner.clone_frame(&f.params, options)?;
                for t in 0..cloner.n_targets() {
                    let mut cell = canvas(CELL.0, CELL.1)?;
                    let (model, app, shape) = (
                        cloner.target(t),
                        cloner.target_appearance(t),
                        cloner.target_shape(t),
                    );
                    comps[t].draw(model, app, shape, &views[t], &mut cell.as_mut())?;
                    let t = t as u32;
                    let x = (first + t * nm + m as u32) * CELL.0 + GAP * (first + t);
                    put(&mut sheet, (x, y), &cell);
                }
            }
            if no_source {
                draw_number(&mut sheet, (3, y + 3), f.number);
            }
            println!("sheet row {row}: {} {:06} ({why})", f.clip, f.number);
        }
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            make_dir(dir)?;
        }
        save(path, &sheet)?;
        let methods: Vec<String> = setups.iter().map(|s| s.method.to_string()).collect();
        println!(
            "sheet: {} ({} rows; columns: {}per target in order, the methods {})",
            path.display(),
            picks.len(),
            if no_source {
                "no source frame (each row labelled with its frame number), "
            } else {
                "the source frame, then "
            },
            methods.join(", ")
        );
        Ok(())
    }

    /// 3x5 pixel digits: five lines of three bits, top line first, the left pixel the high bit.
    const DIGITS: [[u8; 5]; 10] = [
        [7, 5, 5, 5, 7],
        [2, 6, 2, 2, 7],
        [7, 1, 7, 4, 7],
        [7, 1, 7, 1, 7],
        [5, 5, 7, 1, 1],
        [7, 4, 7, 1, 7],
        [7, 4, 7, 5, 7],
        [7, 1, 1, 1, 1],
        [7, 5, 7, 5, 7],
        [7, 5, 7, 1, 7],
    ];
    /// Side of a digit's pixel on the sheet, in sheet pixels.
    const DIGIT_PIXEL: u32 = 3;

    /// Writes `number` in white on a dark box whose top-left corner is `(x, y)`.
    fn draw_number(sheet: &mut Pixmap, (x, y): (u32, u32), number: u32) {
        let text = number.to_string();
        let k = DIGIT_PIXEL as f32;
        let mut fill = |x: f32, y: f32, w: f32, h: f32, grey: u8| {
            if let Some(r) = facemimic::tiny_skia::Rect::from_xywh(x, y, w, h) {
                let mut paint = facemimic::tiny_skia::Paint::default();
                paint.set_color_rgba8(grey, grey, grey, 255);
                sheet.fill_rect(r, &paint, Transform::identity(), None);
            }
        };
        let n = text.len() as f32;
        fill(x as f32, y as f32, k * (4.0 * n + 1.0), 7.0 * k, 16);
        for (d, c) in text.bytes().enumerate() {
            let glyph = DIGITS[usize::from(c - b'0')];
            for (line, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        let gx = x as f32 + k * (1.0 + 4.0 * d as f32 + col as f32);
                        let gy = y as f32 + k * (1.0 + line as f32);
                        fill(gx, gy, k, k, 255);
                    }
                }
            }
        }
    }

    // -----------------------------------------------------------------------------------
    // The dump for an external classifier.

    /// A small deterministic generator (SplitMix64) for the random frames.
    struct SplitMix(u64);

    impl SplitMix {
        /// The next 64 random bits.
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }

        /// A number in `0..n` (`n > 0`).
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    /// The laughing frames (top 10% of source mouth width + lift) and as many random other
    /// frames (seeded), each as `(index, group)`.
    fn dump_frames(source: &Series, seed: u64) -> Vec<(usize, &'static str)> {
        let score = |i: usize| source[i].mouth_width + source[i].lift;
        let mut idx: Vec<usize> = (0..source.len()).collect();
        idx.sort_by(|&a, &b| score(b).total_cmp(&score(a)));
        let n = source.len().div_ceil(10);
        let (laughing, rest) = idx.split_at_mut(n);
        let mut rng = SplitMix(seed);
        for k in 0..n.min(rest.len()) {
            let j = k + rng.below(rest.len() - k);
            rest.swap(k, j);
        }
        let mut out: Vec<(usize, &'static str)> =
            laughing.iter().map(|&i| (i, "laughing")).collect();
        out.extend(rest.iter().take(n).map(|&i| (i, "random")));
        out
    }

    /// With `on`, gives `cloner` frame `f`'s pixels sampled at its landmarks against the source
    /// model's mean appearance as the observed face; else none.
    fn observe(cloner: &mut Cloner, f: &Frame, on: bool) -> Result<()> {
        if !on {
            return cloner.set_observed(None);
        }
        let image = io::read_image(&f.path)?;
        let source = cloner.source();
        let mut app = vec![0.0; source.appearance().len()];
        facemimic::sample_rgb(source.frame(), &image.view()?, &f.landmarks, &mut app)?;
        let neutral = source.appearance().base().to_vec();
        cloner.set_observed(Some(facemimic::fit::Observed {
            appearance: &app,
            neutral: &neutral,
            displacement: None,
            turn: None,
        }))
    }

    /// Writes one frame's source picture and every target's composited clone per method into
    /// `dir`; returns the manifest rows.
    fn dump_frame(
        cloner: &mut Cloner,
        comps: &mut [Compositor],
        f: &Frame,
        setups: &[CloneOptions],
        (dir, observed): (&Path, bool),
    ) -> Result<Vec<String>> {
        let image = io::read_image(&f.path)?;
        observe(cloner, f, observed)?;
        let source_png = format!("{}-{:06}.png", f.clip, f.number);
        save(&dir.join(&source_png), &pixmap_of(&image)?)?;
        let s = clip_box(face_box(&f.landmarks), image.width, image.height);
        let mut rows = Vec::new();
        for options in setups {
            let method = options.method;
            cloner.clone_frame(&f.params, options)?;
            for (t, comp) in comps.iter_mut().enumerate() {
                let model = cloner.target(t);
                let (w, h) = comp.size();
                let mut picture = canvas(w, h)?;
                let view = picture_view(w, h, w, h);
                comp.draw(
                    model,
                    cloner.target_appearance(t),
                    cloner.target_shape(t),
                    &view,
                    &mut picture.as_mut(),
                )?;
                let id = format!("{}-{:06}-{}-{method}", f.clip, f.number, model.name());
                save(&dir.join(format!("{id}.png")), &picture)?;
                let b = clip_box(face_box(cloner.target_shape(t)), w, h);
                rows.push(format!(
                    "{id},{source_png},{id}.png,{},{},{},{},{},{},{},{}",
                    s[0], s[1], s[2], s[3], b[0], b[1], b[2], b[3]
                ));
            }
        }
        Ok(rows)
    }

    /// Writes the laughing and random frames, their clones, `manifest.csv` (`id,source,target`
    /// and the two face boxes) and `frames.csv` (which frame is in which group, kept apart so
    /// the classifier is not told).
    fn dump(
        cloner: &mut Cloner,
        frames: &[Frame],
        source: &Series,
        setups: &[CloneOptions],
        seed: u64,
        (dir, observed): (&Path, bool),
    ) -> Result<()> {
        make_dir(dir)?;
        let chosen = dump_frames(source, seed);
        let mut comps = compositors(cloner)?;
        let mut manifest = String::from("id,source,target,sx,sy,sw,sh,tx,ty,tw,th\n");
        let mut groups = String::from("clip,frame,group,mouth_width,lift,source\n");
        for &(i, group) in &chosen {
            let f = &frames[i];
            for row in dump_frame(cloner, &mut comps, f, setups, (dir, observed))? {
                manifest.push_str(&row);
                manifest.push('\n');
            }
            groups.push_str(&format!(
                "{},{:06},{group},{:.4},{:.4},{}-{:06}.png\n",
                f.clip, f.number, source[i].mouth_width, source[i].lift, f.clip, f.number
            ));
        }
        for (name, text) in [("manifest.csv", &manifest), ("frames.csv", &groups)] {
            let p = dir.join(name);
            std::fs::write(&p, text).map_err(|e| Error::Io(format!("{}: {e}", p.display())))?;
        }
        println!(
            "dump: {} frames ({} laughing, {} random, seed {seed}) and {} clones in {}",
            chosen.len(),
            chosen.iter().filter(|c| c.1 == "laughing").count(),
            chosen.iter().filter(|c| c.1 == "random").count(),
            manifest.lines().count() - 1,
            dir.display()
        );
        Ok(())
    }
}

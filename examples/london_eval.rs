//! Cloning a smile onto one-photo targets, measured against the real smile: the London set
//! (`../shared/data/london`, 60 people photographed neutral and smiling, research data never
//! committed), leave-people-out.
//!
//! For every ordered pair of different people (X, Y):
//! - **source**: X's model built from X's two photos, the neutral as its reference
//!   (`BuildOptions::reference`, as `facemimic build --reference`), in the canonical frame; X's
//!   smiling photo projected into it gives the source parameters;
//! - **target**: a photo target of Y's neutral photo (`photo_model`), cloned onto with each
//!   method named by `--methods` (default options: the target at its own pose) and composited
//!   into Y's picture at its size, as `facemimic clone --composite` does;
//! - **truth**: Y's smiling photo, aligned onto the result by the least-squares similarity of
//!   its nose (27-35) and eye corners (36, 39, 42, 45) onto the clone's landmarks, resampled
//!   bilinearly into the result's pixel grid.
//!
//! Baselines: `neutral`, Y's own neutral photo (the truth aligned onto its landmarks), and
//! `neutral-render`, Y's photo target rendered by the library unchanged (gain 0 at its home
//! pose, composited), which shows what the rendering alone costs.
//!
//! Measures per pair: RGB PSNR over the mouth (the aligned true smile's outer lips, 48-59,
//! dilated by 0.1 of the eye-centre distance) and over the face (the convex hull of its 68
//! points); the mouth's mean CIE76 colour difference (sRGB to Lab, D65); in the face frame
//! (eye centres horizontal, 1 apart, y down) the mouth width `|p48 - p54|` and the lip-corner
//! lift `y_mid(51, 57) - mean y(48, 54)` (positive when the corners are raised relative to the
//! lips' centre), each as the ratio `(clone - Y neutral) / (Y smile - Y neutral)` (no ratio when
//! the real change is under 0.01).
//!
//! Prints two markdown tables; writes the per-pair CSV (`--csv`, default
//! `scratch/london_pairs.csv`), a contact sheet (`--sheet PNG`, or a `.jpg`: JPEG at quality
//! 90) and files for an external expression classifier (`--dump-dir DIR`).
//!
//!   cargo run --profile eval --example london_eval -- [--limit N] [--stride S]
//!       [--methods substitute,map,map-residual] [--csv PATH] [--sheet PNG] [--dump-dir DIR]
#![cfg_attr(target_arch = "wasm32", no_main)]

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
fn main() -> std::process::ExitCode {
    match native::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("london_eval: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::fmt::Write as _;
    use std::ops::RangeInclusive;
    use std::path::{Path, PathBuf};
    use std::time::Instant;

    use clap::Parser;
    use facemimic::clone::{effective_method, CloneOptions, Cloner, Method};
    use facemimic::tiny_skia::Pixmap;
    use facemimic::{
        canonical_frame, demultiply_into, io, photo_model, picture_view, BuildOptions, Builder,
        Compositor, DrawOptions, Error, ImageRef, Model, Params, ReferenceChoice, Result,
        Similarity, TrainingImage,
    };

    /// The outer lips, in order around the mouth.
    const OUTER_LIPS: RangeInclusive<usize> = 48..=59;
    /// The mouth region's dilation, in eye-centre distances.
    const MOUTH_DILATION: f32 = 0.1;
    /// Smallest real change (face-frame units) an amplitude ratio is taken over.
    const MIN_REAL_CHANGE: f32 = 0.01;
    /// Y's smile counts as one that moves the mouth when it widens it by at least this (the
    /// face frame's eye-centre distances; a third of the real smiles' mean): the worst tenth of
    /// pairs is also printed over those Y alone, since a Y whose "smile" hardly moves the mouth
    /// makes any clone of X's smile a loss against the neutral photo.
    const SMILED_WIDTH: f32 = 0.04;
    /// The contact sheet's tile side and the gap between tiles, pixels.
    const TILE: u32 = 160;
    const GAP: u32 = 4;
    /// A sheet tile shows the landmarks' bounding box grown by this factor (squared up).
    const SHEET_CROP: f32 = 1.3;
    /// The baseline rows besides the methods.
    const NEUTRAL: &str = "neutral";
    const RENDERED: &str = "neutral-render";

    /// Cloning methods against the London set's real smiles (one-photo targets,
    /// leave-people-out).
    #[derive(Parser)]
    struct Args {
        /// The London set: `neutral/NNN.jpg` and `smiling/NNN.jpg`, each with its `.pts`
        /// (default: ../shared/data/london beside the crate).
        #[arg(long, value_name = "DIR")]
        data: Option<PathBuf>,
        /// Only the first N people (by number).
        #[arg(long, value_name = "N")]
        limit: Option<usize>,
        /// Measure every S-th ordered pair (source-major order).
        #[arg(long, default_value_t = 1, value_name = "S")]
        stride: usize,
        /// Cloning methods by their library names, comma-separated.
        #[arg(
            long,
            default_value = "substitute,map,map-residual",
            value_name = "LIST"
        )]
        methods: String,
        /// The per-pair CSV (default: scratch/london_pairs.csv in the crate).
        #[arg(long, value_name = "PATH")]
        csv: Option<PathBuf>,
        /// Write a contact sheet: X smiling, Y neutral, the clone per method, Y smiling (PNG;
        /// JPEG at quality 90 when the name ends in .jpg or .jpeg).
        #[arg(long, value_name = "PNG")]
        sheet: Option<PathBuf>,
        /// Rows of the contact sheet.
        #[arg(long, default_value_t = 8, value_name = "N")]
        sheet_rows: usize,
        /// Write clones, sources and a manifest for an external expression classifier here.
        #[arg(long, value_name = "DIR")]
        dump_dir: Option<PathBuf>,
        /// Instead of pairs of different people, each person's own smile cloned onto their
        /// own neutral photo (X = Y; the expression prior still learned without them): the
        /// ceiling of the pipeline when the source's smile is the target's own, which
        /// separates what cloning costs from another person's smile not being Y's.
        #[arg(long)]
        own_smiles: bool,
        /// An oracle of how much Y smiles: each pair's expressive clone takes the global gain
        /// (0, 0.25, ..., 1.5) whose mouth (points 48-67, the true smile aligned on the nose
        /// and eye corners) lies nearest Y's own smile. Chosen on landmarks, never on pixels;
        /// for measuring what the smile's amount alone costs the pixel measures.
        #[arg(long)]
        oracle_gain: bool,
        /// Pairs written to --dump-dir.
        #[arg(long, default_value_t = 24, value_name = "N")]
        dump_pairs: usize,
    }

    /// One person: the neutral and the smiling photo, each with its landmarks.
    struct Person {
        id: String,
        neutral: TrainingImage,
        smile: TrainingImage,
    }

    /// X as a source: its two-photo model and its smile's parameters in it.
    struct Source {
        model: Model,
        smile: Params,
    }

    /// Y as a target: its photo target and the compositor into its picture.
    struct Target {
        model: Model,
        compositor: Compositor,
    }

    /// Mouth width and lip-corner lift in the face frame (eye centres 1 apart, y down).
    #[derive(Clone, Copy, Debug)]
    struct Amplitudes {
        width: f32,
        lift: f32,
    }

    /// What one picture scores against the aligned true smile.
    #[derive(Clone, Copy, Debug)]
    struct Outcome {
        mouth_psnr: f64,
        face_psnr: f64,
        mouth_de: f64,
        shape: Amplitudes,
    }

    /// Per target person: the two baselines and the real smile's amplitudes.
    struct Baseline {
        neutral: Outcome,
        rendered: Outcome,
        smile: Amplitudes,
    }

    /// One measured picture of a pair: a method's clone or a baseline.
    struct Row {
        x: usize,
        y: usize,
        label: String,
        effective: String,
        outcome: Outcome,
    }

    /// Buffers reused from picture to picture.
    struct Scratch {
        pixmap: Option<Pixmap>,
        /// The picture measured (RGBA, straight alpha).
        rgba: Vec<u8>,
        /// The aligned true smile, RGB 0..255 per pixel of the picture (only the measured
        /// regions are written).
        truth: Vec<f32>,
    }

    /// The pixel regions measured (indices `y * width + x` of the result's grid).
    struct Regions {
        mouth: Vec<u32>,
        face: Vec<u32>,
    }

    /// Parses the arguments, builds every source and target, measures, prints and writes.
    pub fn run() -> Result<()> {
        let args = Args::parse();
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let methods = parse_methods(&args.methods)?;
        if args.stride == 0 || args.sheet_rows == 0 {
            return Err(Error::Params(
                "--stride and --sheet-rows must be at least 1".into(),
            ));
        }
        let data = args
            .data
            .clone()
            .unwrap_or_else(|| root.join("../shared/data/london"));
        let start = Instant::now();
        let people = load_people(&data, args.limit)?;
        let sources = people
            .iter()
            .map(build_source)
            .collect::<Result<Vec<_>>>()?;
        let mut targets = people
            .iter()
            .map(build_target)
            .collect::<Result<Vec<_>>>()?;
        let built = start.elapsed().as_secs_f64();
        print_setup(&people, &sources, &targets, &methods);
        let pairs = if args.own_smiles {
            (0..people.len())
                .step_by(args.stride)
                .map(|y| (y, y))
                .collect()
        } else {
            pair_list(people.len(), args.stride)
        };
        let mut scratch = Scratch {
            pixmap: None,
            rgba: Vec::new(),
            truth: Vec::new(),
        };
        let baselines = measure_baselines(&people, &mut targets, &mut scratch)?;
        let rows = measure_pairs(
            (&people, &sources, &mut targets),
            &pairs,
            &methods,
            &baselines,
            &mut scratch,
            args.oracle_gain,
        )?;
        let measured = start.elapsed().as_secs_f64() - built;
        let mut labels: Vec<String> = methods.iter().map(|m| m.to_string()).collect();
        labels.push(RENDERED.into());
        println!(
            "\n{} ordered pairs of {} people (stride {}); every mean is over pairs.\n",
            pairs.len(),
            people.len(),
            args.stride
        );
        println!("{}", image_table(&rows, &baselines, &labels));
        println!("{}", shape_table(&rows, &baselines, &labels));
        let csv = args
            .csv
            .clone()
            .unwrap_or_else(|| root.join("scratch/london_pairs.csv"));
        write_csv(&csv, &rows, &people, &baselines)?;
        println!("wrote {}", csv.display());
        if let Some(path) = &args.sheet {
            write_sheet(
                path,
                args.sheet_rows,
                &people,
                &sources,
                &mut targets,
                &methods,
            )?;
        }
        if let Some(dir) = &args.dump_dir {
            write_dump(
                dir,
                args.dump_pairs,
                &people,
                &sources,
                &mut targets,
                &methods,
            )?;
        }
        println!(
            "time: {built:.1} s loading and building, {measured:.1} s measuring, {:.1} s in all",
            start.elapsed().as_secs_f64()
        );
        Ok(())
    }

    /// The methods named in `list` (comma-separated library names), each once, in order.
    fn parse_methods(list: &str) -> Result<Vec<Method>> {
        let mut methods: Vec<Method> = Vec::new();
        for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let m = name.parse::<Method>()?;
            if !methods.contains(&m) {
                methods.push(m);
            }
        }
        if methods.is_empty() {
            return Err(Error::Params("--methods names no method".into()));
        }
        Ok(methods)
    }

    /// Every ordered pair (source, target) of different people, source-major, every
    /// `stride`-th kept.
    fn pair_list(n: usize, stride: usize) -> Vec<(usize, usize)> {
        (0..n)
            .flat_map(|x| (0..n).filter(move |&y| y != x).map(move |y| (x, y)))
            .step_by(stride)
            .collect()
    }

    // -----------------------------------------------------------------------------------
    // Loading and building.

    /// The people of `dir` with both photos, by number (the first `limit` of them).
    fn load_people(dir: &Path, limit: Option<usize>) -> Result<Vec<Person>> {
        let neutral_dir = dir.join("neutral");
        let entries = std::fs::read_dir(&neutral_dir)
            .map_err(|e| Error::Io(format!("{}: {e}", neutral_dir.display())))?;
        let mut ids: Vec<String> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("jpg")))
            .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .collect();
        ids.sort();
        let (mut ids, alone): (Vec<String>, Vec<String>) = ids
            .into_iter()
            .partition(|id| dir.join("smiling").join(format!("{id}.jpg")).is_file());
        if !alone.is_empty() {
            eprintln!(
                "london_eval: no smiling photo for {}; left out",
                alone.join(", ")
            );
        }
        if let Some(n) = limit {
            ids.truncate(n);
        }
        if ids.len() < 2 {
            return Err(Error::Params(format!(
                "{}: {} people with both photos; at least 2 are needed",
                dir.display(),
                ids.len()
            )));
        }
        ids.into_iter()
            .map(|id| {
                let photo = |kind: &str, name: &str| {
                    read_photo(&dir.join(kind).join(format!("{id}.jpg")), name)
                };
                Ok(Person {
                    neutral: photo("neutral", "neutral")?,
                    smile: photo("smiling", "smiling")?,
                    id,
                })
            })
            .collect()
    }

    /// A photo and its landmarks, named `name` (both of a person's photos have the same file
    /// stem, so the stem cannot name the reference).
    fn read_photo(path: &Path, name: &str) -> Result<TrainingImage> {
        let mut t = io::read_training_image(path)?;
        if t.landmarks.len() != 136 {
            return Err(Error::Landmarks(format!(
                "{}: {} points, 68 expected",
                path.display(),
                t.landmarks.len() / 2
            )));
        }
        t.name = name.to_string();
        Ok(t)
    }

    /// X's model from its two photos, the neutral as its reference, in the canonical frame
    /// (the builder's minimum is two images), and its smile projected into it.
    fn build_source(p: &Person) -> Result<Source> {
        let options = BuildOptions {
            name: format!("london-{}", p.id),
            reference: ReferenceChoice::Named(p.neutral.name.clone()),
            ..BuildOptions::default()
        };
        let context = format!("source {}", p.id);
        let model = Builder::new(options)
            .build(&[p.neutral.clone(), p.smile.clone()], None)
            .map_err(|e| e.with_context(&context))?;
        let smile = model
            .project(&p.smile.image.view()?, &p.smile.landmarks)
            .map_err(|e| e.with_context(&context))?;
        Ok(Source { model, smile })
    }

    /// Y's photo target (its neutral photo, in the canonical frame every source is built in)
    /// and the compositor into its picture.
    fn build_target(p: &Person) -> Result<Target> {
        let model = photo_model(
            &format!("london-{}-photo", p.id),
            &p.neutral.image.view()?,
            &p.neutral.landmarks,
            canonical_frame(),
        )
        .map_err(|e| e.with_context(&format!("target {}", p.id)))?;
        let compositor = Compositor::new(&model, DrawOptions::default())?;
        Ok(Target { model, compositor })
    }

    /// Prints the models' sizes and what each method does on a photo target.
    fn print_setup(people: &[Person], sources: &[Source], targets: &[Target], methods: &[Method]) {
        let mut sizes: Vec<(usize, usize)> = sources
            .iter()
            .map(|s| (s.model.shape().n_modes(), s.model.appearance().n_modes()))
            .collect();
        sizes.sort_unstable();
        sizes.dedup();
        let sizes: Vec<String> = sizes.iter().map(|(s, a)| format!("{s}/{a}")).collect();
        println!(
            "{} people; source models (neutral reference, canonical frame) with shape/appearance \
             modes {}",
            people.len(),
            sizes.join(", ")
        );
        for m in methods {
            let e = effective_method(*m, &targets[0].model);
            if e != *m {
                println!(
                    "note: on a photo target '{m}' is cloned as '{e}' (clone::effective_method)"
                );
            }
        }
    }

    // -----------------------------------------------------------------------------------
    // Measuring.

    /// Y's two baselines (its neutral photo; its photo target rendered unchanged) and the
    /// amplitudes of its real smile.
    fn measure_baselines(
        people: &[Person],
        targets: &mut [Target],
        scratch: &mut Scratch,
    ) -> Result<Vec<Baseline>> {
        people
            .iter()
            .zip(targets.iter_mut())
            .map(|(p, t)| {
                let n = &p.neutral;
                scratch.rgba.clear();
                scratch.rgba.extend_from_slice(&n.image.data);
                let neutral = evaluate(
                    scratch,
                    n.image.width,
                    n.image.height,
                    &n.landmarks,
                    &p.smile,
                )?;
                let params = Params {
                    pose: t.model.home_pose(),
                    ..t.model.base_params()
                };
                let mut shape = vec![0.0; 2 * t.model.landmarks()];
                t.model.image_shape(&params, &mut shape)?;
                let mut appearance = vec![0.0; t.model.appearance().len()];
                t.model
                    .appearance()
                    .instance(&params.appearance, &mut appearance)?;
                let (w, h) = composite(t, &appearance, &shape, scratch)?;
                let rendered = evaluate(scratch, w, h, &shape, &p.smile)?;
                Ok(Baseline {
                    neutral,
                    rendered,
                    smile: amplitudes(&p.smile.landmarks)?,
                })
            })
            .collect()
    }

    /// Every pair with every method, one cloner per source holding all its targets; plus a
    /// `neutral-render` row per pair (the target's own rendering, the same for every source).
    fn measure_pairs(
        (people, sources, targets): (&[Person], &[Source], &mut [Target]),
        pairs: &[(usize, usize)],
        methods: &[Method],
        baselines: &[Baseline],
        scratch: &mut Scratch,
        oracle_gain: bool,
    ) -> Result<Vec<Row>> {
        let mut gains_chosen = vec![0usize; ORACLE_GAINS.len()];
        let mut rows = Vec::with_capacity(pairs.len() * (methods.len() + 1));
        let start = Instant::now();
        for (x, source) in sources.iter().enumerate() {
            let ys: Vec<usize> = pairs.iter().filter(|p| p.0 == x).map(|p| p.1).collect();
            if ys.is_empty() {
                continue;
            }
            let mut cloner = Cloner::new(source.model.clone())?;
            for &y in &ys {
                cloner.add_target(targets[y].model.clone())?;
            }
            for &method in methods {
                let options = CloneOptions {
                    method,
                    ..CloneOptions::default()
                };
                cloner.clone_frame(&source.smile, &options)?;
                for (k, &y) in ys.iter().enumerate() {
                    if method == Method::Expressive {
                        // Anything learned from the London set is learned without X and Y.
                        cloner.set_prior(prior_without(&[&people[x].id, &people[y].id])?);
                        let mut out = cloner
                            .target_frame(k)
                            .ok_or_else(|| Error::Params("internal: no target frame".into()))?;
                        if oracle_gain {
                            let mut best = (f32::INFINITY, 1.0, 0);
                            for (j, &g) in ORACLE_GAINS.iter().enumerate() {
                                let o = CloneOptions {
                                    gain: g,
                                    ..options.clone()
                                };
                                cloner.clone_target(k, &source.smile, &o, &mut out)?;
                                let d = mouth_distance(out.shape(), &people[y].smile.landmarks)?;
                                if d < best.0 {
                                    best = (d, g, j);
                                }
                            }
                            gains_chosen[best.2] += 1;
                            let o = CloneOptions {
                                gain: best.1,
                                ..options.clone()
                            };
                            cloner.clone_target(k, &source.smile, &o, &mut out)?;
                        } else {
                            cloner.clone_target(k, &source.smile, &options, &mut out)?;
                        }
                        let (w, h) =
                            composite(&mut targets[y], out.appearance(), out.shape(), scratch)?;
                        let outcome = evaluate(scratch, w, h, out.shape(), &people[y].smile)?;
                        rows.push(Row {
                            x,
                            y,
                            label: method.to_string(),
                            effective: method.to_string(),
                            outcome,
                        });
                        continue;
                    }
                    let (w, h) = composite(
                        &mut targets[y],
                        cloner.target_appearance(k),
                        cloner.target_shape(k),
                        scratch,
                    )?;
                    let outcome = evaluate(scratch, w, h, cloner.target_shape(k), &people[y].smile)
                        .map_err(|e| {
                            e.with_context(&format!("{} -> {}", people[x].id, people[y].id))
                        })?;
                    let effective = effective_method(method, cloner.target(k)).to_string();
                    rows.push(Row {
                        x,
                        y,
                        label: method.to_string(),
                        effective,
                        outcome,
                    });
                }
            }
            for &y in &ys {
                let outcome = baselines[y].rendered;
                rows.push(Row {
                    x,
                    y,
                    label: RENDERED.into(),
                    effective: String::new(),
                    outcome,
                });
            }
            eprintln!(
                "london_eval: source {} ({}/{}) done, {:.0} s",
                people[x].id,
                x + 1,
                sources.len(),
                start.elapsed().as_secs_f64()
            );
        }
        if oracle_gain {
            eprintln!("oracle gains {ORACLE_GAINS:?} chosen {gains_chosen:?} times");
        }
        Ok(rows)
    }

    /// Composites a face of `target` (appearance on the frame, landmarks in its picture's
    /// pixels) into its own picture at the picture's size, as `facemimic clone --composite`;
    /// the result is in `scratch.rgba`. Returns the picture's size.
    fn composite(
        target: &mut Target,
        appearance: &[f32],
        shape: &[f32],
        scratch: &mut Scratch,
    ) -> Result<(u32, u32)> {
        let (w, h) = target.compositor.size();
        let fits = scratch
            .pixmap
            .as_ref()
            .is_some_and(|p| p.width() == w && p.height() == h);
        if !fits {
            scratch.pixmap = Some(
                Pixmap::new(w, h)
                    .ok_or_else(|| Error::Image(format!("cannot make a {w}x{h} canvas")))?,
            );
        }
        let pixmap = scratch
            .pixmap
            .as_mut()
            .ok_or_else(|| Error::Image("no canvas".into()))?;
        let view = picture_view(w, h, w, h);
        target.compositor.draw(
            &target.model,
            appearance,
            shape,
            &view,
            &mut pixmap.as_mut(),
        )?;
        demultiply_into(pixmap.as_ref(), &mut scratch.rgba);
        Ok((w, h))
    }

    /// Scores the picture in `scratch.rgba` (`w x h`), whose face has `landmarks`, against
    /// `smile` aligned onto those landmarks.
    fn evaluate(
        scratch: &mut Scratch,
        w: u32,
        h: u32,
        landmarks: &[f32],
        smile: &TrainingImage,
    ) -> Result<Outcome> {
        let to_result = alignment(&smile.landmarks, landmarks)?;
        let mut aligned = smile.landmarks.clone();
        to_result.apply_in_place(&mut aligned);
        let regions = regions(&aligned, w, h)?;
        resample(
            &smile.image.view()?,
            &to_result,
            &regions,
            (w, h),
            &mut scratch.truth,
        )?;
        let (result, truth) = (&scratch.rgba, &scratch.truth);
        Ok(Outcome {
            mouth_psnr: psnr(result, truth, &regions.mouth),
            face_psnr: psnr(result, truth, &regions.face),
            mouth_de: mean_delta_e(result, truth, &regions.mouth),
            shape: amplitudes(landmarks)?,
        })
    }

    // -----------------------------------------------------------------------------------
    // Geometry.

    /// Point `i` of interleaved landmarks.
    fn point(lm: &[f32], i: usize) -> (f32, f32) {
        (lm[2 * i], lm[2 * i + 1])
    }

    /// The mean of points `range`.
    fn mean_point(lm: &[f32], range: RangeInclusive<usize>) -> (f32, f32) {
        let n = range.clone().count() as f32;
        let (x, y) = range.fold((0.0, 0.0), |(x, y), i| (x + lm[2 * i], y + lm[2 * i + 1]));
        (x / n, y / n)
    }

    /// The eye centres (means of 36-41 and 42-47) of interleaved landmarks.
    struct Eyes {
        left: (f32, f32),
        right: (f32, f32),
        /// Their distance (the inter-ocular distance, IOD).
        distance: f32,
    }

    /// The eye centres of `lm`; an error when they coincide.
    fn eyes(lm: &[f32]) -> Result<Eyes> {
        let (left, right) = (mean_point(lm, 36..=41), mean_point(lm, 42..=47));
        let distance = (right.0 - left.0).hypot(right.1 - left.1);
        if distance.is_nan() || distance <= 1e-3 {
            return Err(Error::Landmarks("the eye centres coincide".into()));
        }
        Ok(Eyes {
            left,
            right,
            distance,
        })
    }

    /// Mouth width `|p48 - p54|` and lip-corner lift `y_mid(51, 57) - mean y(48, 54)` in the
    /// face frame: the eye centres at (0, 0) and (1, 0), y down.
    fn amplitudes(lm: &[f32]) -> Result<Amplitudes> {
        let Eyes {
            left: l, right: r, ..
        } = eyes(lm)?;
        let frame = Similarity::align(&[l.0, l.1, r.0, r.1], &[0.0, 0.0, 1.0, 0.0]);
        let p = |i: usize| frame.apply_point(lm[2 * i], lm[2 * i + 1]);
        let (a, b) = (p(48), p(54));
        Ok(Amplitudes {
            width: (b.0 - a.0).hypot(b.1 - a.1),
            lift: 0.5 * (p(51).1 + p(57).1) - 0.5 * (a.1 + b.1),
        })
    }

    /// The least-squares similarity taking `from`'s nose and eye corners onto `onto`'s
    /// (`landmarks::STABLE_POINTS`, which a smile barely moves).
    /// The global gains `--oracle-gain` chooses from.
    const ORACLE_GAINS: [f32; 7] = [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5];

    /// The mean distance of the mouth's points (48-67) of `clone` from those of `smile`
    /// aligned onto it ([`alignment`]), over the clone's outer eye corners' distance.
    fn mouth_distance(clone: &[f32], smile: &[f32]) -> Result<f32> {
        let to = alignment(smile, clone)?;
        let mut aligned = smile.to_vec();
        to.apply_in_place(&mut aligned);
        let (a, b) = (point(clone, 36), point(clone, 45));
        let iod = (a.0 - b.0).hypot(a.1 - b.1).max(1e-6);
        let d: f32 = (48..68)
            .map(|i| {
                let (p, q) = (point(clone, i), point(&aligned, i));
                (p.0 - q.0).hypot(p.1 - q.1)
            })
            .sum();
        Ok(d / 20.0 / iod)
    }

    fn alignment(from: &[f32], onto: &[f32]) -> Result<Similarity> {
        let s = Similarity::align_points(from, onto, &facemimic::landmarks::STABLE_POINTS);
        if s.is_valid() {
            Ok(s)
        } else {
            Err(Error::Landmarks(
                "the smile's alignment is degenerate".into(),
            ))
        }
    }

    /// The measured regions of a `w x h` grid from the aligned true smile's landmarks: the
    /// outer lips dilated by 0.1 of the eye-centre distance, and the convex hull.
    fn regions(aligned: &[f32], w: u32, h: u32) -> Result<Regions> {
        let iod = eyes(aligned)?.distance;
        let lips: Vec<(f32, f32)> = OUTER_LIPS.map(|i| point(aligned, i)).collect();
        let all: Vec<(f32, f32)> = (0..aligned.len() / 2).map(|i| point(aligned, i)).collect();
        Ok(Regions {
            mouth: polygon_pixels(&lips, MOUTH_DILATION * iod, w, h),
            face: polygon_pixels(&convex_hull(&all), 0.0, w, h),
        })
    }

    /// The pixels of a `w x h` grid (centres on integers) inside `poly` or within `dilate` of
    /// its outline.
    fn polygon_pixels(poly: &[(f32, f32)], dilate: f32, w: u32, h: u32) -> Vec<u32> {
        let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for &(x, y) in poly {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
        let lo = |v: f32| (v - dilate).floor().max(0.0) as u32;
        let hi = |v: f32, n: u32| ((v + dilate).ceil().max(0.0) as u32).min(n - 1);
        let mut out = Vec::new();
        for y in lo(y0)..=hi(y1, h) {
            for x in lo(x0)..=hi(x1, w) {
                let p = (x as f32, y as f32);
                if inside(poly, p) || (dilate > 0.0 && outline_distance(poly, p) <= dilate) {
                    out.push(y * w + x);
                }
            }
        }
        out
    }

    /// Whether `p` is inside the closed polygon (even-odd rule).
    fn inside(poly: &[(f32, f32)], p: (f32, f32)) -> bool {
        let mut odd = false;
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            if (a.1 > p.1) != (b.1 > p.1) && p.0 < a.0 + (p.1 - a.1) * (b.0 - a.0) / (b.1 - a.1) {
                odd = !odd;
            }
        }
        odd
    }

    /// The distance from `p` to the closed polygon's outline.
    fn outline_distance(poly: &[(f32, f32)], p: (f32, f32)) -> f32 {
        let mut best = f32::MAX;
        for (i, &a) in poly.iter().enumerate() {
            let b = poly[(i + 1) % poly.len()];
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let len2 = dx * dx + dy * dy;
            let t = if len2 > 0.0 {
                (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            best = best.min((a.0 + t * dx - p.0).hypot(a.1 + t * dy - p.1));
        }
        best
    }

    /// The convex hull (Andrew's monotone chain), its points in order around it.
    fn convex_hull(points: &[(f32, f32)]) -> Vec<(f32, f32)> {
        let mut p = points.to_vec();
        p.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        p.dedup();
        if p.len() < 3 {
            return p;
        }
        let mut hull = half_hull(p.iter().copied());
        hull.extend(half_hull(p.iter().rev().copied()));
        hull
    }

    /// One half of the monotone chain over sorted points, without its last point.
    fn half_hull(points: impl Iterator<Item = (f32, f32)>) -> Vec<(f32, f32)> {
        let cross = |o: (f32, f32), a: (f32, f32), b: (f32, f32)| {
            (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
        };
        let mut h: Vec<(f32, f32)> = Vec::new();
        for q in points {
            while h.len() >= 2 && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
                h.pop();
            }
            h.push(q);
        }
        h.pop();
        h
    }

    // -----------------------------------------------------------------------------------
    // Pixels.

    /// `photo` resampled (bilinear) by `to_result` into the result's `size` grid at the pixels
    /// of `regions`, as RGB 0..255 into `out`.
    fn resample(
        photo: &ImageRef<'_>,
        to_result: &Similarity,
        regions: &Regions,
        (w, h): (u32, u32),
        out: &mut Vec<f32>,
    ) -> Result<()> {
        let back = to_result
            .inverse()
            .ok_or_else(|| Error::Landmarks("the smile's alignment has no inverse".into()))?;
        out.resize(3 * w as usize * h as usize, 0.0);
        for &k in regions.mouth.iter().chain(&regions.face) {
            let (x, y) = ((k % w) as f32, (k / w) as f32);
            let (sx, sy) = back.apply_point(x, y);
            let c = photo.sample_rgb(sx, sy);
            let k = 3 * k as usize;
            for (o, v) in out[k..k + 3].iter_mut().zip(c) {
                *o = 255.0 * v;
            }
        }
        Ok(())
    }

    /// RGB PSNR (8-bit peak) of `result` (RGBA) against `truth` (RGB floats) over `pixels`;
    /// NaN for no pixels.
    fn psnr(result: &[u8], truth: &[f32], pixels: &[u32]) -> f64 {
        let mut sum = 0f64;
        for &k in pixels {
            let k = k as usize;
            for c in 0..3 {
                let d = result[4 * k + c] as f64 - truth[3 * k + c] as f64;
                sum += d * d;
            }
        }
        let mse = sum / (3 * pixels.len()) as f64;
        10.0 * (255.0f64 * 255.0 / mse.max(1e-10)).log10()
    }

    /// Mean CIE76 colour difference of `result` (RGBA) against `truth` over `pixels`.
    fn mean_delta_e(result: &[u8], truth: &[f32], pixels: &[u32]) -> f64 {
        let mut sum = 0f64;
        for &k in pixels {
            let k = k as usize;
            let a = lab([result[4 * k], result[4 * k + 1], result[4 * k + 2]].map(f32::from));
            let b = lab([truth[3 * k], truth[3 * k + 1], truth[3 * k + 2]]);
            sum += ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
                as f64;
        }
        sum / pixels.len() as f64
    }

    /// CIE Lab (D65 white) of an sRGB colour given as 0..255.
    fn lab(rgb: [f32; 3]) -> [f32; 3] {
        let lin = rgb.map(|v| {
            let c = (v / 255.0).clamp(0.0, 1.0);
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        });
        let [r, g, b] = lin;
        let x = (0.4124564 * r + 0.3575761 * g + 0.1804375 * b) / 0.95047;
        let y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
        let z = (0.0193339 * r + 0.119_192 * g + 0.9503041 * b) / 1.08883;
        let f = |t: f32| {
            if t > 216.0 / 24389.0 {
                t.cbrt()
            } else {
                (24389.0 / 27.0 * t + 16.0) / 116.0
            }
        };
        let (fx, fy, fz) = (f(x), f(y), f(z));
        [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
    }

    // -----------------------------------------------------------------------------------
    // Summaries.

    /// The finite values' mean (NaN when none).
    fn mean(v: &[f64]) -> f64 {
        let f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        f.iter().sum::<f64>() / f.len() as f64
    }

    /// The `q` quantile (0..=1) of the finite values, linearly interpolated (NaN when none).
    fn quantile(v: &[f64], q: f64) -> f64 {
        let mut f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        if f.is_empty() {
            return f64::NAN;
        }
        f.sort_by(f64::total_cmp);
        let t = q * (f.len() - 1) as f64;
        let (i, u) = (t.floor() as usize, t - t.floor());
        f[i] + u * (f[(i + 1).min(f.len() - 1)] - f[i])
    }

    /// The share of `diff` above 0 (the pairs whose clone beats the neutral photo).
    fn share_above(diff: &[f64]) -> f64 {
        diff.iter().filter(|d| **d > 0.0).count() as f64 / diff.len().max(1) as f64
    }

    /// The rows of `label`.
    fn rows_of<'a>(rows: &'a [Row], label: &'a str) -> impl Iterator<Item = &'a Row> + 'a {
        rows.iter().filter(move |r| r.label == label)
    }

    /// The image measures per method against the neutral photo, as a markdown table.
    fn image_table(rows: &[Row], baselines: &[Baseline], labels: &[String]) -> String {
        let mut s = String::from(
            "| method | pairs | mouth PSNR | neutral's | > neutral | p10 of Δ mouth | face PSNR | \
             Δ face vs neutral | mouth ΔE | neutral's ΔE |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for label in labels {
            let r: Vec<&Row> = rows_of(rows, label).collect();
            let get = |f: &dyn Fn(&Row) -> f64| r.iter().map(|r| f(r)).collect::<Vec<f64>>();
            let mouth = get(&|r| r.outcome.mouth_psnr);
            let n_mouth = get(&|r| baselines[r.y].neutral.mouth_psnr);
            let diff: Vec<f64> = mouth.iter().zip(&n_mouth).map(|(a, b)| a - b).collect();
            let above = share_above(&diff);
            let face = mean(&get(&|r| r.outcome.face_psnr));
            let n_face = mean(&get(&|r| baselines[r.y].neutral.face_psnr));
            let _ = writeln!(
                s,
                "| {label} | {} | {:.2} | {:.2} | {:.1}% | {:+.2} | {:.2} | {:+.2} | {:.2} | {:.2} |",
                r.len(),
                mean(&mouth),
                mean(&n_mouth),
                100.0 * above,
                quantile(&diff, 0.1),
                face,
                face - n_face,
                mean(&get(&|r| r.outcome.mouth_de)),
                mean(&get(&|r| baselines[r.y].neutral.mouth_de)),
            );
        }
        let smiled = |b: &Baseline| b.smile.width - b.neutral.shape.width >= SMILED_WIDTH;
        let people = baselines.iter().filter(|b| smiled(b)).count();
        for label in labels {
            let diff: Vec<f64> = rows_of(rows, label)
                .filter(|r| smiled(&baselines[r.y]))
                .map(|r| r.outcome.mouth_psnr - baselines[r.y].neutral.mouth_psnr)
                .collect();
            let above = share_above(&diff);
            let _ = writeln!(
                s,
                "\n{label}, the {} pairs whose Y's smile widens the mouth by at least {SMILED_WIDTH} \
                 ({people} of {} people): p10 of Δ mouth {:+.2}, > neutral {:.1}%",
                diff.len(),
                baselines.len(),
                quantile(&diff, 0.1),
                100.0 * above,
            );
        }
        s
    }

    /// A clone's amplitude ratio `(clone - neutral) / (smile - neutral)`, or `None` when the
    /// real change is under [`MIN_REAL_CHANGE`].
    fn ratio(clone: f32, neutral: f32, smile: f32) -> Option<f64> {
        let real = smile - neutral;
        (real.abs() >= MIN_REAL_CHANGE).then(|| ((clone - neutral) / real) as f64)
    }

    /// The shape amplitudes per method, as a markdown table.
    fn shape_table(rows: &[Row], baselines: &[Baseline], labels: &[String]) -> String {
        let mut s = String::from(
            "| method | median width ratio | median lift ratio | width: mean clone / mean real | \
             lift: mean clone / mean real | ratios kept (width, lift) |\n|---|---:|---:|---:|---:|---:|\n",
        );
        for label in labels {
            let (mut wr, mut lr) = (Vec::new(), Vec::new());
            let (mut wc, mut wreal, mut lc, mut lreal) = (0f64, 0f64, 0f64, 0f64);
            let mut n = 0usize;
            for r in rows_of(rows, label) {
                let (b, c) = (&baselines[r.y], r.outcome.shape);
                let (yn, ys) = (b.neutral.shape, b.smile);
                wr.extend(ratio(c.width, yn.width, ys.width));
                lr.extend(ratio(c.lift, yn.lift, ys.lift));
                wc += (c.width - yn.width) as f64;
                wreal += (ys.width - yn.width) as f64;
                lc += (c.lift - yn.lift) as f64;
                lreal += (ys.lift - yn.lift) as f64;
                n += 1;
            }
            let _ = writeln!(
                s,
                "| {label} | {:.3} | {:.3} | {:.3} | {:.3} | {}, {} of {n} |",
                quantile(&wr, 0.5),
                quantile(&lr, 0.5),
                wc / wreal,
                lc / lreal,
                wr.len(),
                lr.len(),
            );
        }
        let real_w: Vec<f64> = baselines
            .iter()
            .map(|b| (b.smile.width - b.neutral.shape.width) as f64)
            .collect();
        let real_l: Vec<f64> = baselines
            .iter()
            .map(|b| (b.smile.lift - b.neutral.shape.lift) as f64)
            .collect();
        let _ = writeln!(
            s,
            "\nReal smiles (Y smile - Y neutral, face frame), mean over people: width {:+.4}, lift \
             {:+.4}; under {MIN_REAL_CHANGE} (no ratio): width {}, lift {} of {} people.",
            mean(&real_w),
            mean(&real_l),
            real_w.iter().filter(|v| v.abs() < MIN_REAL_CHANGE as f64).count(),
            real_l.iter().filter(|v| v.abs() < MIN_REAL_CHANGE as f64).count(),
            baselines.len()
        );
        s
    }

    /// Writes one line per pair and method (and `neutral-render`), with the pair's neutral
    /// baseline and real amplitudes beside it.
    fn write_csv(
        path: &Path,
        rows: &[Row],
        people: &[Person],
        baselines: &[Baseline],
    ) -> Result<()> {
        let mut s = String::from(
            "source,target,method,effective,mouth_psnr,face_psnr,mouth_de,neutral_mouth_psnr,\
             neutral_face_psnr,neutral_mouth_de,width,lift,neutral_width,neutral_lift,smile_width,\
             smile_lift,width_ratio,lift_ratio\n",
        );
        let opt = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_default();
        for r in rows {
            let (b, o) = (&baselines[r.y], &r.outcome);
            let (n, c, sm) = (b.neutral.shape, o.shape, b.smile);
            let _ = writeln!(
                s,
                "{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{},{}",
                people[r.x].id, people[r.y].id, r.label, r.effective,
                o.mouth_psnr, o.face_psnr, o.mouth_de,
                b.neutral.mouth_psnr, b.neutral.face_psnr, b.neutral.mouth_de,
                c.width, c.lift, n.width, n.lift, sm.width, sm.lift,
                opt(ratio(c.width, n.width, sm.width)),
                opt(ratio(c.lift, n.lift, sm.lift)),
            );
        }
        write_text(path, &s)
    }

    /// Writes a text file, making its folder.
    fn write_text(path: &Path, text: &str) -> Result<()> {
        make_parent(path)?;
        std::fs::write(path, text).map_err(|e| Error::Io(format!("{}: {e}", path.display())))
    }

    /// Makes the folder a file goes in.
    fn make_parent(path: &Path) -> Result<()> {
        match path.parent().filter(|p| !p.as_os_str().is_empty()) {
            Some(dir) => std::fs::create_dir_all(dir)
                .map_err(|e| Error::Io(format!("{}: {e}", dir.display()))),
            None => Ok(()),
        }
    }

    // -----------------------------------------------------------------------------------
    // Pictures: the contact sheet and the classifier's files.

    /// The expression prior learned as the shipped one is (`facemimic::clone::learn_prior`
    /// over the crate's `data/`), without the London people numbered `ids`.
    fn prior_without(ids: &[&str]) -> Result<facemimic::clone::ExpressionPrior> {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
        let exclude: Vec<u32> = ids.iter().filter_map(|s| s.parse().ok()).collect();
        let (london, speakers) = io::expression_sets(&data, &exclude)?;
        facemimic::clone::learn_prior(&london, &speakers, facemimic::canonical_frame().vertices())
    }

    /// One pair cloned with `method` alone and composited; returns the picture (RGBA) and the
    /// clone's landmarks.
    fn render_pair(
        ids: [&str; 2],
        source: &Source,
        target: &mut Target,
        method: Method,
        scratch: &mut Scratch,
    ) -> Result<(Vec<u8>, Vec<f32>)> {
        let mut cloner = Cloner::new(source.model.clone())?;
        cloner.add_target(target.model.clone())?;
        cloner.set_prior(prior_without(&ids)?);
        let options = CloneOptions {
            method,
            ..CloneOptions::default()
        };
        cloner.clone_frame(&source.smile, &options)?;
        composite(
            target,
            cloner.target_appearance(0),
            cloner.target_shape(0),
            scratch,
        )?;
        Ok((scratch.rgba.clone(), cloner.target_shape(0).to_vec()))
    }

    /// The sheet's pairs: sources spread over the people ordered by the lightness of their
    /// neutral face (mean L* over the landmarks' hull), each with the target about half the
    /// order away, so light and dark faces meet; at most `rows` (at least 1), no repeats.
    fn sheet_pairs(people: &[Person], rows: usize) -> Vec<(usize, usize)> {
        let mut lightness = Vec::with_capacity(people.len());
        for p in people {
            let n = &p.neutral;
            let all: Vec<(f32, f32)> = (0..68).map(|i| point(&n.landmarks, i)).collect();
            let px = polygon_pixels(&convex_hull(&all), 0.0, n.image.width, n.image.height);
            let l: Vec<f64> = px
                .iter()
                .map(|&k| {
                    let k = 4 * k as usize;
                    lab([n.image.data[k], n.image.data[k + 1], n.image.data[k + 2]].map(f32::from))
                        [0] as f64
                })
                .collect();
            lightness.push(mean(&l));
        }
        let mut order: Vec<usize> = (0..people.len()).collect();
        order.sort_by(|&a, &b| lightness[a].total_cmp(&lightness[b]));
        let (n, rows) = (people.len(), rows.min(people.len()));
        // Half the order plus half a row's step away: no pair comes back reversed.
        let shift = n / 2 + (n / (2 * rows)).max(1);
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        for k in 0..rows {
            let i = k * n / rows;
            let pair = (order[i], order[(i + shift) % n]);
            if pair.0 != pair.1 && !pairs.contains(&pair) {
                pairs.push(pair);
            }
        }
        pairs
    }

    /// A square crop (centre x, centre y, side) around landmarks: their box grown by `grow`.
    fn crop_box(lm: &[f32], grow: f32) -> (f32, f32, f32) {
        let b = facemimic::BBox::of_points(lm);
        (
            b.x + 0.5 * b.width,
            b.y + 0.5 * b.height,
            grow * b.width.max(b.height),
        )
    }

    /// Draws `sample` (RGB 0..1 at picture coordinates) over the square `crop` into the
    /// sheet's tile (`col`, `row`), 2x2 samples a pixel.
    fn draw_tile(
        sheet: &mut [u8],
        sheet_w: u32,
        (col, row): (u32, u32),
        (cx, cy, side): (f32, f32, f32),
        sample: &dyn Fn(f32, f32) -> [f32; 3],
    ) {
        let k = side / TILE as f32;
        let (ox, oy) = (GAP + col * (TILE + GAP), GAP + row * (TILE + GAP));
        for j in 0..TILE {
            for i in 0..TILE {
                let mut acc = [0f32; 3];
                for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let x = cx - 0.5 * side + (i as f32 + dx) * k - 0.5;
                    let y = cy - 0.5 * side + (j as f32 + dy) * k - 0.5;
                    let c = sample(x, y);
                    acc.iter_mut().zip(c).for_each(|(a, v)| *a += 0.25 * v);
                }
                let o = 3 * ((oy + j) * sheet_w + ox + i) as usize;
                for (d, v) in sheet[o..o + 3].iter_mut().zip(acc) {
                    *d = (255.0 * v).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }

    /// The contact sheet: a row per pair of [`sheet_pairs`]: X smiling, Y neutral, the clone
    /// per method, Y smiling aligned onto the first method's clone. Y's tiles share one crop
    /// (its neutral landmarks), X's is its smile's.
    fn write_sheet(
        path: &Path,
        rows: usize,
        people: &[Person],
        sources: &[Source],
        targets: &mut [Target],
        methods: &[Method],
    ) -> Result<()> {
        let pairs = sheet_pairs(people, rows);
        let cols = 3 + methods.len() as u32;
        let (sw, sh) = (
            GAP + cols * (TILE + GAP),
            GAP + pairs.len() as u32 * (TILE + GAP),
        );
        let mut sheet = vec![32u8; 3 * (sw * sh) as usize];
        let mut scratch = Scratch {
            pixmap: None,
            rgba: Vec::new(),
            truth: Vec::new(),
        };
        for (row, &(x, y)) in pairs.iter().enumerate() {
            let row = row as u32;
            let (xs, yn, ys) = (&people[x].smile, &people[y].neutral, &people[y].smile);
            let crop = crop_box(&yn.landmarks, SHEET_CROP);
            let view = xs.image.view()?;
            draw_tile(
                &mut sheet,
                sw,
                (0, row),
                crop_box(&xs.landmarks, SHEET_CROP),
                &|a, b| view.sample_rgb(a, b),
            );
            let view = yn.image.view()?;
            draw_tile(&mut sheet, sw, (1, row), crop, &|a, b| {
                view.sample_rgb(a, b)
            });
            let mut first: Option<Vec<f32>> = None;
            for (c, &m) in methods.iter().enumerate() {
                let (rgba, lm) = render_pair(
                    [&people[x].id, &people[y].id],
                    &sources[x],
                    &mut targets[y],
                    m,
                    &mut scratch,
                )?;
                let (w, h) = targets[y].compositor.size();
                let view = ImageRef::new(w, h, &rgba)?;
                draw_tile(&mut sheet, sw, (2 + c as u32, row), crop, &|a, b| {
                    view.sample_rgb(a, b)
                });
                first.get_or_insert(lm);
            }
            let onto = first.ok_or_else(|| Error::Params("no method".into()))?;
            let back = alignment(&ys.landmarks, &onto)?
                .inverse()
                .ok_or_else(|| Error::Landmarks("the smile's alignment has no inverse".into()))?;
            let view = ys.image.view()?;
            let sample = |a: f32, b: f32| {
                let (u, v) = back.apply_point(a, b);
                view.sample_rgb(u, v)
            };
            draw_tile(&mut sheet, sw, (cols - 1, row), crop, &sample);
            println!(
                "sheet row {}: {} -> {}",
                row + 1,
                people[x].id,
                people[y].id
            );
        }
        facemimic_testkit::sheet::save_rgb(path, &sheet, (sw, sh))?;
        let names: Vec<String> = methods.iter().map(|m| m.to_string()).collect();
        println!(
            "wrote {} (columns: X smiling | Y neutral | {} | Y smiling, aligned)",
            path.display(),
            names.join(" | ")
        );
        Ok(())
    }

    /// A face box `[x, y, w, h]` (whole pixels, inside a `w x h` picture): the landmarks' box
    /// grown by 15% of its width left and right, 15% of its height down and 25% up.
    fn face_box(lm: &[f32], (w, h): (u32, u32)) -> [u32; 4] {
        let b = facemimic::BBox::of_points(lm);
        let x0 = (b.x - 0.15 * b.width).floor().clamp(0.0, w as f32 - 1.0);
        let y0 = (b.y - 0.25 * b.height).floor().clamp(0.0, h as f32 - 1.0);
        let x1 = (b.right() + 0.15 * b.width)
            .ceil()
            .clamp(x0 + 1.0, w as f32);
        let y1 = (b.bottom() + 0.15 * b.height)
            .ceil()
            .clamp(y0 + 1.0, h as f32);
        [x0 as u32, y0 as u32, (x1 - x0) as u32, (y1 - y0) as u32]
    }

    /// Writes a picture as PNG.
    fn write_png(path: &Path, (w, h): (u32, u32), rgba: &[u8]) -> Result<()> {
        image::save_buffer(path, rgba, w, h, image::ExtendedColorType::Rgba8)
            .map_err(|e| Error::Io(format!("{}: {e}", path.display())))
    }

    /// For `n` ordered pairs spread over all of them (golden-ratio steps): the source photo
    /// (X smiling), each method's clone, Y's neutral and smiling photos, and `manifest.csv`
    /// (`id,source,target,sx,sy,sw,sh,tx,ty,tw,th`, face boxes from the landmarks).
    fn write_dump(
        dir: &Path,
        n: usize,
        people: &[Person],
        sources: &[Source],
        targets: &mut [Target],
        methods: &[Method],
    ) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io(format!("{}: {e}", dir.display())))?;
        let all = pair_list(people.len(), 1);
        let mut picks: Vec<usize> = (0..n.min(all.len()))
            .map(|i| ((i as f64 * 0.618_033_988_75).fract() * all.len() as f64) as usize)
            .collect();
        picks.sort_unstable();
        picks.dedup();
        let mut manifest = String::from("id,source,target,sx,sy,sw,sh,tx,ty,tw,th\n");
        let mut scratch = Scratch {
            pixmap: None,
            rgba: Vec::new(),
            truth: Vec::new(),
        };
        let size = |t: &TrainingImage| (t.image.width, t.image.height);
        for &(x, y) in picks.iter().map(|&i| &all[i]) {
            let (px, py) = (&people[x], &people[y]);
            let src = format!("source_{}.png", px.id);
            write_png(&dir.join(&src), size(&px.smile), &px.smile.image.data)?;
            let sb = face_box(&px.smile.landmarks, size(&px.smile));
            let mut line = |id: String, file: &str, tb: [u32; 4]| {
                let _ = writeln!(
                    manifest,
                    "{id},{src},{file},{},{},{},{},{},{},{},{}",
                    sb[0], sb[1], sb[2], sb[3], tb[0], tb[1], tb[2], tb[3]
                );
            };
            for (kind, photo) in [(NEUTRAL, &py.neutral), ("smiling", &py.smile)] {
                let file = format!("target_{}_{kind}.png", py.id);
                write_png(&dir.join(&file), size(photo), &photo.image.data)?;
                line(
                    format!("{}_{}_{kind}", px.id, py.id),
                    &file,
                    face_box(&photo.landmarks, size(photo)),
                );
            }
            for &m in methods {
                let (rgba, lm) = render_pair(
                    [&people[x].id, &people[y].id],
                    &sources[x],
                    &mut targets[y],
                    m,
                    &mut scratch,
                )?;
                let wh = targets[y].compositor.size();
                let file = format!("{}_{}_{m}.png", px.id, py.id);
                write_png(&dir.join(&file), wh, &rgba)?;
                line(format!("{}_{}_{m}", px.id, py.id), &file, face_box(&lm, wh));
            }
        }
        write_text(&dir.join("manifest.csv"), &manifest)?;
        println!(
            "wrote {} pairs to {} (manifest.csv)",
            picks.len(),
            dir.display()
        );
        Ok(())
    }
}

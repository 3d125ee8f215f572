//! Anyone without a model of their own: a person followed by the landmark follower (the page's
//! default source, spk07's model, as the page uses it), cloned by the expressive method onto
//! the page's default GRID targets, with the appearance observed in the frame's pixels against
//! the person's running neutral (`Cloner::set_observed`, on) and without it (the source
//! model's mean appearance, off: what the follower drove before).
//!
//! - **Clip**: franck-dev2 (frames 3800-4799, in no training list) by default, or franck-dev
//!   (`--clip`); every frame is followed in order at 25 fps, every `--every`-th measured.
//!   Nothing here is built from franck: spk07 and the targets are GRID models, and the
//!   follower's neutral thresholds were chosen on franck-dev (measure on franck-dev2).
//! - **Teeth**: on frames whose real mouth is open (dlib's inner lips at least 0.08 of the eye
//!   corners' distance apart), the real frame sampled into the frame at dlib's points: the
//!   inner mouth's mean luminance over the skin's (its teeth showing or not); the same ratio of
//!   each target's cloned appearance. Printed: their correlation per target, on and off.
//! - **Motion**: the spread (p95 - p5) of the mouth's width and lip-corner lift over the real
//!   frames', of the tracked source's landmarks (what the tracker read) and of each target's
//!   clone (what arrived); and the clones' correlation with the real frames' (Pearson r).
//! - **Laughs**: the tenth of measured frames with the widest, most lifted real mouths:
//!   `--dump-dir` writes the source frames and the targets' composited clones (on and off) with
//!   a manifest for `scripts/eval/fer_judge.py`; `--sheet` draws four of them (targets only:
//!   franck's frames are research data and are never published).
//!
//! - **Where the follower loses a laugh** (`--displacement`, with `--dump-dir`): the dumped
//!   clones keep the follower's observed look but take their shape displacement from other
//!   points, each against that convention's own face at rest (the per-coordinate median of
//!   the clip's closed-mouth frontal frames, by dlib's points: the inner lips under 0.03 of
//!   the eye corners' distance apart, the nose tip within 0.03 of it from their midpoint;
//!   the rest aligned onto the follower's neutral by a similarity of all 68 points, each frame
//!   onto the rest by one of the nose and the eye corners, `STABLE_POINTS`, as the follower
//!   poses a frame):
//!   `dlib` (the clip's own landmarks: what a perfect landmarker would give), `finder` (the
//!   face finder's points on each frame, unsmoothed). An oracle (the rest is taken from the
//!   whole clip, future frames included), for measuring only. With `--own`, `dlib` replaces the
//!   AAM tracker's shape parameters with dlib's points projected into franck's model
//!   (`Model::project`), the tracker's pose, appearance and observed look kept: what the
//!   tracker's reading of the shape costs.
//! - **The own model's reference** (`--own --reference rest|mean`): franck's model built about
//!   his training frame most at rest (`ReferenceChoice::Rest`, the default, as the page's
//!   enrolment builds) or about the mean of his 20 frames (the paper's default).
//! - **A tracker setting's effect** (`--own --fit-options JSON`): franck's AAM tracker with the
//!   given `FitOptions` fields over the defaults, e.g. `'{"shape_prior": 0}'`.
//!
//! ```text
//! cargo run --release --example follow_expressions -- [--clip franck-dev2] [--every 2]
//!     [--sheet docs/img/follow-expressive.jpg] [--dump-dir /tmp/follow-fer]
//!     [--displacement follower|dlib|finder] [--own [--reference rest|mean] [--fit-options JSON]]
//! ```
#![cfg_attr(target_arch = "wasm32", no_main)]
#![allow(clippy::needless_range_loop)]

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
fn main() -> std::process::ExitCode {
    match native::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("follow_expressions: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::path::{Path, PathBuf};

    use clap::Parser;
    use facemimic::clone::{CloneOptions, Cloner};
    use facemimic::fit::{FaceTracker, FitOptions, FollowOptions, Follower, Tracker};
    use facemimic::{io, picture_view, Compositor, DrawOptions, Error, Model, Result};
    use facemimic_testkit as common;
    use facemimic_testkit::following::{track_expressions, OPEN_MOUTH};
    use facemimic_testkit::sheet;

    /// The page's default targets (`www/models/manifest.json`).
    const TARGETS: &str = "spk02,spk03,spk06,spk10";
    /// A contact-sheet cell (width, height).
    const CELL: (u32, u32) = (128, 160);

    /// Followed expressions with and without the observed appearance.
    #[derive(Parser, Debug)]
    #[command(name = "follow_expressions")]
    struct Args {
        /// The shared data folder (default: ../shared/data beside the repository).
        #[arg(long, value_name = "DIR")]
        data: Option<PathBuf>,
        /// The clip: franck-dev2 or franck-dev.
        #[arg(long, default_value = "franck-dev2")]
        clip: String,
        /// Measure every K-th frame (all are followed).
        #[arg(long, default_value_t = 2, value_name = "K")]
        every: usize,
        /// Write a contact sheet of four laughs (targets only: off, on).
        #[arg(long, value_name = "PATH")]
        sheet: Option<PathBuf>,
        /// Write the laughing frames, their clones and a manifest for fer_judge.py here.
        #[arg(long, value_name = "DIR")]
        dump_dir: Option<PathBuf>,
        /// Clone without the constraint (the expression prior's bound and the modes' limit).
        #[arg(long)]
        no_clamp: bool,
        /// Track with the person's own model instead of following with spk07's: franck's AAM
        /// from `franck-dev/train20.txt` (the build part; measure on franck-dev2), the AAM
        /// tracker started from the clip's first frame's landmarks. "off" is then the model's
        /// synthesis, "on" the frame observed against the person's neutral look.
        #[arg(long)]
        own: bool,
        /// With `--own`: the face franck's model is built about, `rest` (his training frame
        /// most at rest, as the page's enrolment builds a person's model) or `mean` (the
        /// paper's default).
        #[arg(long, default_value = "rest", value_name = "REF")]
        reference: String,
        /// With `--own`: the tracker's options, a JSON object of `FitOptions` fields over the
        /// defaults (e.g. `{"shape_prior": 0}`), to measure a tracker setting's effect on the
        /// clones.
        #[arg(long, value_name = "JSON", requires = "own")]
        fit_options: Option<String>,
        /// The dumped clones' shape displacement: the follower's own, or (an oracle, for
        /// measuring where a laugh is lost) dlib's points or the finder's, each against its
        /// convention's face at rest over the clip. With `--own`, `dlib` only: the tracker's
        /// shape parameters replaced by dlib's points projected into the model.
        #[arg(long, value_enum, default_value_t = Displacement::Follower)]
        displacement: Displacement,
    }

    /// Whose points give the dumped clones their shape displacement.
    #[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
    enum Displacement {
        /// The follower's (the product's path).
        Follower,
        /// The clip's dlib landmarks against their rest.
        Dlib,
        /// The face finder's points on each frame against theirs at rest.
        Finder,
    }

    /// Shapes whose inner lips are less than this far apart (eye corners' distances, dlib's
    /// points) are the clip's face at rest for `--displacement`.
    const REST_OPENING: f32 = 0.03;
    /// ... and whose nose tip lies within this fraction of the outer eye corners' distance of
    /// their midpoint, along the eye line ([`frontal`]).
    const REST_TURN: f32 = 0.03;

    /// The tracker of the run: the follower with `source` (spk07), or with `--own` (`Some`
    /// options) the AAM tracker of franck's own model, started on the clip's first frame's
    /// landmarks.
    fn start_tracker(
        source: &Model,
        own: Option<&FitOptions>,
        paths: &[PathBuf],
    ) -> Result<Box<dyn FaceTracker>> {
        let Some(options) = own else {
            return Ok(Box::new(Follower::new(source, FollowOptions::default())?));
        };
        let first = io::read_training_image(&paths[0])?;
        let mut tracker = Tracker::new(source, options.clone())?;
        tracker.start_from_landmarks(&first.landmarks)?;
        Ok(Box::new(tracker))
    }

    /// `FitOptions::default()` with the fields of the JSON object `json` put over it.
    fn fit_options(json: &str) -> Result<FitOptions> {
        let bad = |e: serde_json::Error| Error::Params(format!("--fit-options: {e}"));
        let patch: serde_json::Value = serde_json::from_str(json).map_err(bad)?;
        let mut options = serde_json::to_value(FitOptions::default()).map_err(bad)?;
        match (options.as_object_mut(), patch.as_object()) {
            (Some(o), Some(p)) => o.extend(p.clone()),
            _ => {
                return Err(Error::Params(
                    "--fit-options: a JSON object expected".into(),
                ))
            }
        }
        serde_json::from_value(options).map_err(bad)
    }

    pub fn run() -> Result<()> {
        let args = Args::parse();
        if args.every == 0 {
            return Err(Error::Params("--every must be at least 1".into()));
        }
        if args.own && args.displacement == Displacement::Finder {
            return Err(Error::Params(
                "--displacement finder is for the follower, not --own".into(),
            ));
        }
        let data = args
            .data
            .clone()
            .unwrap_or_else(|| common::repo("../shared/data"));
        let dir = data.join(&args.clip);
        let paths = common::clip_frames(&dir);
        if paths.is_empty() {
            return Err(Error::Io(format!("{}: no frames", dir.display())));
        }
        let source = if args.own {
            let list = data.join("franck-dev/train20.txt");
            let train: Vec<facemimic::TrainingImage> = io::read_list(&list)?
                .iter()
                .map(|p| io::read_training_image(p))
                .collect::<Result<_>>()?;
            let reference = match args.reference.as_str() {
                "mean" => facemimic::ReferenceChoice::Mean,
                "rest" => facemimic::ReferenceChoice::Rest,
                r => return Err(Error::Params(format!("--reference: mean or rest, not {r}"))),
            };
            let m = facemimic::Builder::new(facemimic::BuildOptions {
                name: "franck".into(),
                reference,
                ..facemimic::BuildOptions::default()
            })
            .build(&train, None)?;
            println!(
                "franck's model from {} about {:?}",
                list.display(),
                m.reference()
            );
            m
        } else {
            common::following::spk07()
        };
        let mut cloner = Cloner::new(source.clone())?;
        for name in TARGETS.split(',') {
            let list = grid_list(name)?;
            cloner.add_target(common::path_list_model(&list, name, true).clone())?;
        }
        let options = CloneOptions {
            clamp: if args.no_clamp {
                None
            } else {
                CloneOptions::default().clamp
            },
            ..CloneOptions::default()
        };
        let fit = match &args.fit_options {
            Some(json) => Some(fit_options(json)?),
            None => args.own.then(FitOptions::default),
        };
        let own = fit.as_ref();
        let mut tracker = start_tracker(&source, own, &paths)?;
        let m = track_expressions(
            &paths,
            args.every,
            &mut *tracker,
            &source,
            &mut cloner,
            &options,
        );
        let open = m.frames.iter().filter(|f| f.teeth.is_some()).count();
        println!(
            "{}: {} frames measured, {open} with the real mouth open (inner lips >= {OPEN_MOUTH} apart)",
            args.clip,
            m.frames.len()
        );
        println!(
            "the tracked source's spread over the real frames' (p95 - p5): width {:.2}, lift {:.2}",
            m.tracked_spread_ratio(0),
            m.tracked_spread_ratio(1)
        );
        println!("per target, observed off -> on:");
        for t in 0..cloner.n_targets() {
            let r = m.teeth_r(t);
            let (w, l) = (m.spread_ratio(t, 0), m.spread_ratio(t, 1));
            let c = m.change(t);
            let (rw, rl) = (m.mouth_r(t, 0), m.mouth_r(t, 1));
            println!(
                "  {}: inner mouth vs the real one r {:.2} -> {:.2}; spread over the real frames' (p95 - p5): width {:.2} -> {:.2}, lift {:.2} -> {:.2}; against the real ones r: width {:.2} -> {:.2}, lift {:.2} -> {:.2}; appearance change between measured frames {:.4} -> {:.4}",
                cloner.target(t).name(),
                r[0], r[1], w[0], w[1], l[0], l[1], rw[0], rw[1], rl[0], rl[1], c[0], c[1]
            );
        }
        let laughs = m.laughing();
        if let Some(out) = &args.sheet {
            write_sheet(out, &paths, &laughs, &source, own, None, &mut cloner)?;
        }
        if let Some(out) = &args.dump_dir {
            let oracle = match args.displacement {
                Displacement::Follower => None,
                Displacement::Dlib if args.own => Some(Oracle::Projected),
                d => Some(Oracle::Rest(RestOracle::new(
                    &paths,
                    &laughs,
                    d,
                    &source.shape().base,
                )?)),
            };
            dump(
                out,
                &paths,
                &laughs,
                &source,
                own,
                oracle.as_ref(),
                &mut cloner,
            )?;
        }
        Ok(())
    }

    /// Whether a face (68 points) looks at the camera: its nose tip (30) lies within
    /// [`REST_TURN`] of the eye corners' distance from their midpoint, along the eye line
    /// (a turned head's rest is foreshortened: its mouth would read narrow).
    fn frontal(p: &[f32]) -> bool {
        let (ax, ay, bx, by) = (p[72], p[73], p[90], p[91]);
        let (ex, ey) = (bx - ax, by - ay);
        let d2 = ex * ex + ey * ey;
        if d2.is_nan() || d2 <= 0.0 {
            return false;
        }
        let (nx, ny) = (p[60] - 0.5 * (ax + bx), p[61] - 0.5 * (ay + by));
        ((nx * ex + ny * ey) / d2).abs() <= REST_TURN
    }

    /// Where the dumped clones' shape comes from instead of the tracker's.
    enum Oracle {
        /// Another convention's points against their face at rest (the follower's path).
        Rest(RestOracle),
        /// dlib's points projected into the person's own model (`--own`): the tracker's shape
        /// parameters replaced.
        Projected,
    }

    /// Shapes of the clip in one convention (dlib's or the finder's): each laughing frame's,
    /// and the face at rest (the median of the closed-mouth frontal frames').
    struct RestOracle {
        /// The laughing frames' points (image coordinates), by frame index.
        frames: Vec<(usize, Vec<f32>)>,
        /// The face at rest, aligned onto the source model's base.
        rest: Vec<f32>,
    }

    impl RestOracle {
        /// Reads (or, for [`Displacement::Finder`], finds) the points of `laughs` and of every
        /// closed-mouth frontal frame of the clip; `base` is the source model's base shape.
        fn new(
            paths: &[PathBuf],
            laughs: &[usize],
            whose: Displacement,
            base: &[f32],
        ) -> Result<RestOracle> {
            let finder = whose == Displacement::Finder;
            let mut find = if finder {
                Some(facemimic::FaceFinder::new()?)
            } else {
                None
            };
            let mut points = |t: &facemimic::TrainingImage| -> Result<Option<Vec<f32>>> {
                Ok(match &mut find {
                    None => Some(t.landmarks.clone()),
                    Some(f) => f
                        .find(&t.image.view()?)
                        .into_iter()
                        .next()
                        .map(|face| face.landmarks),
                })
            };
            let (mut frames, mut rest) = (Vec::new(), Vec::new());
            for (i, path) in paths.iter().enumerate() {
                let t = io::read_training_image(path)?;
                let closed = facemimic::fit::mouth_opening(&t.landmarks) < REST_OPENING
                    && frontal(&t.landmarks);
                if !closed && !laughs.contains(&i) {
                    continue;
                }
                let Some(p) = points(&t)? else { continue };
                if laughs.contains(&i) {
                    frames.push((i, p.clone()));
                }
                if closed {
                    rest.push(p);
                }
            }
            let first = rest
                .first()
                .cloned()
                .ok_or_else(|| Error::Params("no closed-mouth frame in the clip".into()))?;
            // Each rest shape aligned onto the first, then the per-coordinate median.
            let aligned: Vec<Vec<f32>> = rest
                .iter()
                .map(|r| {
                    let mut o = vec![0f32; r.len()];
                    facemimic::Similarity::align(r, &first).apply(r, &mut o);
                    o
                })
                .collect();
            let mut column = vec![0f32; aligned.len()];
            let median: Vec<f32> = (0..first.len())
                .map(|k| {
                    column.iter_mut().zip(&aligned).for_each(|(c, a)| *c = a[k]);
                    let mid = column.len() / 2;
                    *column.select_nth_unstable_by(mid, f32::total_cmp).1
                })
                .collect();
            // Aligned once onto the source model's base, as every frame will be.
            let mut rest = vec![0f32; median.len()];
            facemimic::Similarity::align(&median, base).apply(&median, &mut rest);
            println!(
                "oracle ({}): {} closed-mouth frames at rest, {} laughing frames",
                if finder { "finder" } else { "dlib" },
                aligned.len(),
                frames.len()
            );
            Ok(RestOracle { frames, rest })
        }

        /// Frame `i`'s displacement from the rest, in the source model's coordinates (the rest
        /// aligned onto its base, as the follower's neutral is): the frame aligned onto the rest
        /// by a similarity of the points an expression hardly moves (`STABLE_POINTS`, as the
        /// follower poses a frame); `None` when the frame has none.
        fn displacement(&self, i: usize) -> Option<Vec<f32>> {
            let (_, p) = self.frames.iter().find(|(j, _)| *j == i)?;
            let mut x = vec![0f32; p.len()];
            let stable = &facemimic::landmarks::STABLE_POINTS;
            facemimic::Similarity::align_points(p, &self.rest, stable).apply(p, &mut x);
            Some(x.iter().zip(&self.rest).map(|(a, b)| a - b).collect())
        }
    }

    /// The `train20.txt` of the last clip folder of `speaker` under data/grid.
    fn grid_list(speaker: &str) -> Result<PathBuf> {
        let grid = common::repo("data/grid");
        let mut clips: Vec<PathBuf> = std::fs::read_dir(&grid)
            .map_err(|e| Error::Io(format!("{}: {e}", grid.display())))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with(&format!("{speaker}_")))
                    && p.join("train20.txt").exists()
            })
            .collect();
        clips.sort();
        clips
            .pop()
            .map(|c| c.join("train20.txt"))
            .ok_or_else(|| Error::Io(format!("no GRID clip of {speaker}")))
    }

    /// Follows the clip again up to each frame of `picks` (in order) and yields, per pick,
    /// the targets' (off, on) clones as (appearance, shape) pairs.
    fn replay(
        paths: &[PathBuf],
        picks: &[usize],
        source: &facemimic::Model,
        own: Option<&FitOptions>,
        oracle: Option<&Oracle>,
        cloner: &mut Cloner,
        mut each: impl FnMut(usize, &mut Cloner, bool) -> Result<()>,
    ) -> Result<()> {
        let mut follower = start_tracker(source, own, paths)?;
        let last = picks.iter().copied().max().unwrap_or(0);
        let options = CloneOptions::default();
        for (i, path) in paths.iter().enumerate().take(last + 1) {
            let t = io::read_training_image(path)?;
            let mut fit = follower.track(&t.image.view()?, 1.0 / 25.0)?.clone();
            if !picks.contains(&i) {
                continue;
            }
            // With an oracle, the follower's look and the oracle's displacement, in the source
            // model's coordinates (aligned onto its base, as the follower's neutral is); or the
            // tracker's shape parameters from dlib's points, and its displacement against the
            // person's neutral moved by what they change (`S (p_dlib - p_fit)`).
            let replaced = match oracle {
                Some(Oracle::Rest(o)) => o.displacement(i),
                Some(Oracle::Projected) => {
                    let p = source.project(&t.image.view()?, &t.landmarks)?.shape;
                    let base = &source.shape().base;
                    let mut d = match follower.observed().and_then(|o| o.displacement) {
                        Some(d) => d.to_vec(),
                        None => vec![0.0; base.len()],
                    };
                    for ((pd, pf), mode) in p
                        .iter()
                        .zip(&fit.params.shape)
                        .zip(source.shape().modes.chunks_exact(base.len()))
                    {
                        d.iter_mut()
                            .zip(mode)
                            .for_each(|(o, m)| *o += (pd - pf) * m);
                    }
                    fit.params.shape = p;
                    Some(d)
                }
                None => None,
            };
            for on in [false, true] {
                let seen = follower.observed().map(|seen| match &replaced {
                    Some(d) => facemimic::fit::Observed {
                        displacement: Some(d),
                        ..seen
                    },
                    None => seen,
                });
                cloner.set_observed(if on { seen } else { None })?;
                cloner.clone_frame(&fit.params, &options)?;
                each(i, cloner, on)?;
            }
        }
        Ok(())
    }

    /// A compositor per target.
    fn compositors(cloner: &Cloner) -> Result<Vec<Compositor>> {
        (0..cloner.n_targets())
            .map(|t| Compositor::new(cloner.target(t), DrawOptions::default()))
            .collect()
    }

    /// Four laughs at least a second apart: a row each, per target off then on.
    fn write_sheet(
        out: &Path,
        paths: &[PathBuf],
        laughs: &[usize],
        source: &facemimic::Model,
        own: Option<&FitOptions>,
        oracle: Option<&Oracle>,
        cloner: &mut Cloner,
    ) -> Result<()> {
        let mut rows: Vec<usize> = Vec::new();
        for &i in laughs {
            if rows.len() < 4 && rows.iter().all(|&r| r.abs_diff(i) >= 25) {
                rows.push(i);
            }
        }
        rows.sort_unstable();
        let nt = cloner.n_targets() as u32;
        let mut page = sheet::canvas(CELL.0 * 2 * nt + 6 * nt, CELL.1 * rows.len() as u32)?;
        let mut comps = compositors(cloner)?;
        replay(paths, &rows, source, own, oracle, cloner, |i, c, on| {
            let row = rows.iter().position(|&r| r == i).unwrap_or(0) as u32;
            for t in 0..c.n_targets() {
                let b = facemimic::BBox::of_points(c.target_shape(t));
                let view = sheet::cell_view([b.x, b.y, b.right(), b.bottom()], CELL);
                let cell = sheet::target_cell(
                    &mut comps[t],
                    c.target(t),
                    (c.target_appearance(t), c.target_shape(t)),
                    &view,
                    CELL,
                )?;
                let x = t as u32 * (2 * CELL.0 + 6) + on as u32 * CELL.0;
                sheet::put(&mut page, (x, row * CELL.1), &cell);
            }
            Ok(())
        })?;
        sheet::save(out, &page)?;
        println!("sheet: frames {rows:?} -> {}", out.display());
        Ok(())
    }

    /// The laughing frames, each target's composited clone off and on, and `manifest.csv` for
    /// `fer_judge.py` (the face boxes left empty: the judge finds them).
    fn dump(
        out: &Path,
        paths: &[PathBuf],
        laughs: &[usize],
        source: &facemimic::Model,
        own: Option<&FitOptions>,
        oracle: Option<&Oracle>,
        cloner: &mut Cloner,
    ) -> Result<()> {
        std::fs::create_dir_all(out).map_err(|e| Error::Io(format!("{}: {e}", out.display())))?;
        let mut comps = compositors(cloner)?;
        let mut manifest = String::from("id,source,target\n");
        replay(paths, laughs, source, own, oracle, cloner, |i, c, on| {
            let src = format!("src-{i:06}.png");
            if !on {
                let t = io::read_training_image(&paths[i])?;
                image::save_buffer(
                    out.join(&src),
                    &t.image.data,
                    t.image.width,
                    t.image.height,
                    image::ExtendedColorType::Rgba8,
                )
                .map_err(|e| Error::Io(e.to_string()))?;
            }
            for t in 0..c.n_targets() {
                let (w, h) = comps[t].size();
                let mut picture = sheet::canvas(w, h)?;
                comps[t].draw(
                    c.target(t),
                    c.target_appearance(t),
                    c.target_shape(t),
                    &picture_view(w, h, w, h),
                    &mut picture.as_mut(),
                )?;
                let id = format!(
                    "{i:06}-{}-{}",
                    c.target(t).name(),
                    if on { "on" } else { "off" }
                );
                sheet::save(&out.join(format!("{id}.png")), &picture)?;
                manifest.push_str(&format!("{id},{src},{id}.png\n"));
            }
            Ok(())
        })?;
        std::fs::write(out.join("manifest.csv"), manifest).map_err(|e| Error::Io(e.to_string()))?;
        println!(
            "dump: {} laughing frames -> {}",
            laughs.len(),
            out.display()
        );
        Ok(())
    }
}

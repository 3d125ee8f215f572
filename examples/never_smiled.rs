//! A target that never made the expression: GRID speakers, whose training frames are speech
//! only (they never smile), driven by London smiles with teeth, one contact sheet per run.
//!
//! - **Sources**: London people (`--sources`, default 096, 026, 010, 002: broad smiles with
//!   teeth), each a model of their neutral and smiling photos with the neutral as its reference
//!   (as `examples/london_eval.rs` and the goldens build them), the smile projected into it.
//! - **Targets**: GRID speakers (`--targets`, default spk03), each built as the tests'
//!   `list_model` builds it: default options from `data/grid/<speaker>_*/train20.txt` (the last
//!   such clip by name), with its default backdrop (`with_default_backdrop`).
//! - **Cloning**: each method of `--methods` with `CloneOptions::default()` otherwise (the
//!   target at its own pose), composited into the target's backdrop. The expression prior is
//!   learned as the shipped one is, without the source person's own London landmarks (as
//!   `london_eval` does), so no source smiles onto a target through its own example.
//!
//! The sheet: a row per source: X smiling, then per target its face at rest and the clone per
//! method. PNG, or JPEG at quality 90 when the name ends in `.jpg` or `.jpeg`. The London set
//! (DeBruine & Jones 2017) and GRID (Cooke et al. 2006) are both CC BY 4.0, so the sheet may
//! be published with their attribution.
//!
//!   cargo run --profile eval --example never_smiled -- [--sources 096,026,010,002]
//!       [--targets spk03] [--methods map-residual,expressive]
//!       [--out docs/img/expressive-never-smiled.jpg] [--data ../shared/data/london]
#![cfg_attr(target_arch = "wasm32", no_main)]

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
fn main() -> std::process::ExitCode {
    match native::run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("never_smiled: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use std::path::{Path, PathBuf};

    use clap::Parser;
    use facemimic::clone::{CloneOptions, Cloner, ExpressionPrior, Method};
    use facemimic::tiny_skia::{FilterQuality, IntSize, Pixmap, PixmapPaint, Transform};
    use facemimic::{
        io, with_default_backdrop, BuildOptions, Builder, Compositor, DrawOptions, Error, Model,
        Params, ReferenceChoice, Result, Similarity, TrainingImage,
    };
    use facemimic_testkit::sheet::{canvas, cell_view, put, save, target_cell};

    /// A cell (width, height) in pixels.
    const CELL: (u32, u32) = (160, 200);
    /// Gap between the sheet's groups of columns (the source, each target), in pixels.
    const GAP: u32 = 6;

    /// GRID targets driven by London smiles: a contact sheet per cloning method.
    #[derive(Parser)]
    struct Args {
        /// The London set: `neutral/NNN.jpg` and `smiling/NNN.jpg`, each with its `.pts`
        /// (default: ../shared/data/london beside the crate).
        #[arg(long, value_name = "DIR")]
        data: Option<PathBuf>,
        /// London people whose smiles are the sources, one row each, comma-separated.
        #[arg(long, default_value = "096,026,010,002", value_name = "NNN,...")]
        sources: String,
        /// GRID speakers to clone onto, comma-separated (each data/grid/<speaker>_*/).
        #[arg(long, default_value = "spk03", value_name = "SPK,...")]
        targets: String,
        /// Cloning methods by their library names, comma-separated.
        #[arg(long, default_value = "map-residual,expressive", value_name = "LIST")]
        methods: String,
        /// The sheet (PNG, or JPEG when the name ends in .jpg or .jpeg).
        #[arg(long, default_value = "scratch/never-smiled.png", value_name = "PATH")]
        out: PathBuf,
    }

    /// The repository's root.
    fn root() -> &'static Path {
        Path::new(env!("CARGO_MANIFEST_DIR"))
    }

    /// A London person as a source: the smiling photo, the two-photo model and the smile's
    /// parameters in it.
    struct Source {
        id: String,
        smile: TrainingImage,
        model: Model,
        params: Params,
    }

    /// Builds the sources and targets, clones, and writes the sheet.
    pub fn run() -> Result<()> {
        let args = Args::parse();
        let data = args
            .data
            .clone()
            .unwrap_or_else(|| root().join("../shared/data/london"));
        let methods = parse_methods(&args.methods)?;
        let sources = split_list(&args.sources)
            .map(|id| build_source(&data, id))
            .collect::<Result<Vec<_>>>()?;
        let targets = split_list(&args.targets)
            .map(grid_model)
            .collect::<Result<Vec<_>>>()?;
        if sources.is_empty() || targets.is_empty() {
            return Err(Error::Params(
                "--sources and --targets must each name one at least".into(),
            ));
        }
        let out = if args.out.is_absolute() {
            args.out.clone()
        } else {
            root().join(&args.out)
        };
        write_sheet(&out, &sources, &targets, &methods)
    }

    /// The non-empty, trimmed items of a comma-separated list.
    fn split_list(s: &str) -> impl Iterator<Item = &str> {
        s.split(',').map(str::trim).filter(|x| !x.is_empty())
    }

    /// The methods named in `list`, each once, in order.
    fn parse_methods(list: &str) -> Result<Vec<Method>> {
        let mut methods: Vec<Method> = Vec::new();
        for name in split_list(list) {
            let m = name
                .parse::<Method>()
                .map_err(|e| e.with_context("--methods"))?;
            if !methods.contains(&m) {
                methods.push(m);
            }
        }
        if methods.is_empty() {
            return Err(Error::Params("--methods names no method".into()));
        }
        Ok(methods)
    }

    /// London person `id`'s model of their two photos (the neutral as its reference) and their
    /// smile projected into it.
    fn build_source(data: &Path, id: &str) -> Result<Source> {
        let photo = |kind: &str| -> Result<TrainingImage> {
            let mut t = io::read_training_image(&data.join(kind).join(format!("{id}.jpg")))?;
            t.name = kind.to_string();
            Ok(t)
        };
        let (neutral, smile) = (photo("neutral")?, photo("smiling")?);
        let context = format!("source {id}");
        let model = Builder::new(BuildOptions {
            name: format!("london-{id}"),
            reference: ReferenceChoice::Named(neutral.name.clone()),
            ..BuildOptions::default()
        })
        .build(&[neutral, smile.clone()], None)
        .map_err(|e| e.with_context(&context))?;
        let params = model
            .project(&smile.image.view()?, &smile.landmarks)
            .map_err(|e| e.with_context(&context))?;
        Ok(Source {
            id: id.to_string(),
            smile,
            model,
            params,
        })
    }

    /// GRID speaker `speaker`'s model: default options from the last of its clips' 20
    /// training frames, with its default backdrop.
    fn grid_model(speaker: &str) -> Result<Model> {
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
        let list = dirs
            .pop()
            .ok_or_else(|| Error::Io(format!("no clip of '{speaker}' in {}", grid.display())))?
            .join("train20.txt");
        let train = io::read_list(&list)?
            .iter()
            .map(|p| io::read_training_image(p))
            .collect::<Result<Vec<_>>>()?;
        let model = Builder::new(BuildOptions {
            name: speaker.to_string(),
            ..BuildOptions::default()
        })
        .build(&train, None)
        .map_err(|e| e.with_context(&list.display().to_string()))?;
        with_default_backdrop(model, &train, None)
    }

    /// The expression prior learned as the shipped one is, without London person `id`.
    fn prior_without(id: &str) -> Result<ExpressionPrior> {
        let exclude: Vec<u32> = id.parse().into_iter().collect();
        let (london, speakers) = io::expression_sets(&root().join("data"), &exclude)?;
        facemimic::clone::learn_prior(&london, &speakers, facemimic::canonical_frame().vertices())
    }

    /// The cell of a source: its smiling photo around its landmarks.
    fn source_cell(s: &Source) -> Result<Pixmap> {
        let image = &s.smile.image;
        let picture = IntSize::from_wh(image.width, image.height)
            .and_then(|size| Pixmap::from_vec(image.data.clone(), size))
            .ok_or_else(|| Error::Image(format!("{}x{} photo", image.width, image.height)))?;
        let b = facemimic::BBox::of_points(&s.smile.landmarks);
        let v = cell_view([b.x, b.y, b.right(), b.bottom()], CELL);
        let mut cell = canvas(CELL.0, CELL.1)?;
        let paint = PixmapPaint {
            quality: FilterQuality::Bilinear,
            ..PixmapPaint::default()
        };
        let to_cell = Transform::from_row(v.a, 0.0, 0.0, v.a, v.tx, v.ty);
        cell.draw_pixmap(0, 0, picture.as_ref(), &paint, to_cell, None);
        Ok(cell)
    }

    /// A target's face at rest: its base parameters at its home pose, as (appearance, shape).
    fn rest(model: &Model) -> Result<(Vec<f32>, Vec<f32>)> {
        let params = Params {
            pose: model.home_pose(),
            ..model.base_params()
        };
        let mut shape = vec![0.0; 2 * model.landmarks()];
        model.image_shape(&params, &mut shape)?;
        let mut appearance = vec![0.0; model.appearance().len()];
        model
            .appearance()
            .instance(&params.appearance, &mut appearance)?;
        Ok((appearance, shape))
    }

    /// The sheet: a row per source (its smile, then per target its face at rest and the clone
    /// per method).
    fn write_sheet(
        path: &Path,
        sources: &[Source],
        targets: &[Model],
        methods: &[Method],
    ) -> Result<()> {
        let (nt, nm) = (targets.len() as u32, methods.len() as u32);
        let width = CELL.0 * (1 + nt * (1 + nm)) + GAP * nt;
        let mut sheet = canvas(width, CELL.1 * sources.len() as u32)?;
        let mut compositors = targets
            .iter()
            .map(|t| Compositor::new(t, DrawOptions::default()))
            .collect::<Result<Vec<_>>>()?;
        let views: Vec<Similarity> = targets
            .iter()
            .map(|t| cell_view(facemimic::base_box(t), CELL))
            .collect();
        let x_of = |t: u32, col: u32| CELL.0 * (1 + t * (1 + nm) + col) + GAP * (t + 1);
        for (row, s) in sources.iter().enumerate() {
            let y = row as u32 * CELL.1;
            put(&mut sheet, (0, y), &source_cell(s)?);
            let mut cloner = Cloner::new(s.model.clone())?;
            for t in targets {
                cloner.add_target(t.clone())?;
            }
            cloner.set_prior(prior_without(&s.id)?);
            for (t, target) in targets.iter().enumerate() {
                let (appearance, shape) = rest(target)?;
                let cell = target_cell(
                    &mut compositors[t],
                    target,
                    (&appearance, &shape),
                    &views[t],
                    CELL,
                )?;
                put(&mut sheet, (x_of(t as u32, 0), y), &cell);
            }
            for (m, &method) in methods.iter().enumerate() {
                let options = CloneOptions {
                    method,
                    ..CloneOptions::default()
                };
                cloner.clone_frame(&s.params, &options)?;
                for (t, target) in targets.iter().enumerate() {
                    let face = (cloner.target_appearance(t), cloner.target_shape(t));
                    let cell = target_cell(&mut compositors[t], target, face, &views[t], CELL)?;
                    put(&mut sheet, (x_of(t as u32, 1 + m as u32), y), &cell);
                }
            }
            println!("row {}: London {}", row + 1, s.id);
        }
        save(path, &sheet)?;
        let names: Vec<String> = methods.iter().map(|m| m.to_string()).collect();
        let speakers: Vec<&str> = targets.iter().map(|t| t.name()).collect();
        println!(
            "wrote {} (columns: London smiling, then per target ({}): at rest | {})",
            path.display(),
            speakers.join(", "),
            names.join(" | ")
        );
        Ok(())
    }
}

//! `facemimic clone`: one source frame cloned onto one target model.

use std::path::{Path, PathBuf};

use facemimic::clone::{CloneOptions, Method};
use facemimic::{io, Error, Result, Stage};

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["params", "image"])))]
pub struct Args {
    /// The source model (the face whose expression is cloned).
    #[arg(long, value_name = "S.fmm")]
    source: PathBuf,
    /// The target model, in the source's reference frame (the canonical frame by default).
    #[arg(long, value_name = "T.fmm")]
    target: PathBuf,
    /// Source parameters as printed by `facemimic project --model S.fmm`.
    #[arg(long, value_name = "P.json")]
    params: Option<PathBuf>,
    /// A source image with its landmark file (.pts/.asf beside it), projected into the source.
    #[arg(long, value_name = "IMAGE")]
    image: Option<PathBuf>,
    /// The cloning method.
    #[arg(long, default_value = Method::default().name(), value_name = "METHOD",
          value_parser = method_parser())]
    method: String,
    /// expressive: gain on the mouth's motion and shading (with --gain).
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "G",
        allow_negative_numbers = true
    )]
    mouth_gain: f32,
    /// expressive: gain on the eyes' motion and shading (with --gain).
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "G",
        allow_negative_numbers = true
    )]
    eyes_gain: f32,
    /// expressive: gain on the brows' motion (with --gain).
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "G",
        allow_negative_numbers = true
    )]
    brows_gain: f32,
    /// expressive: 0 = the target's own range (its modes, limited), 1 = the source's full
    /// motion.
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    style: f32,
    /// Gain on the source parameters: 0 = the target's reference face, 1 = faithful,
    /// >1 = exaggerated.
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "G",
        allow_negative_numbers = true
    )]
    gain: f32,
    /// Limit the mapped target parameters to +-K standard deviations of the target.
    #[arg(
        long,
        default_value_t = 3.0,
        value_name = "K",
        conflicts_with = "no_clamp"
    )]
    clamp: f32,
    /// No limit on the mapped target parameters.
    #[arg(long)]
    no_clamp: bool,
    /// The target follows the source's head motion, its turns included (default: it stays at
    /// its mean pose and, with the expressive method, keeps its own view and light).
    #[arg(long)]
    follow_pose: bool,
    /// Canvas width (default: the target's training image width).
    #[arg(long, value_name = "W")]
    width: Option<u32>,
    /// Canvas height (default: the target's training image height).
    #[arg(long, value_name = "H")]
    height: Option<u32>,
    /// Write the rendered target face (PNG).
    #[arg(long, value_name = "OUT.png")]
    out: Option<PathBuf>,
    /// Write the cloned target shape's landmarks (image coordinates, .pts).
    #[arg(long, value_name = "OUT.pts")]
    out_pts: Option<PathBuf>,
    /// Write the target parameters (JSON like `project`'s); without any --out* option they
    /// are printed on stdout.
    #[arg(long, value_name = "OUT.json")]
    out_params: Option<PathBuf>,
    #[command(flatten)]
    draw: super::render::DrawArgs,
}

/// The methods' names and descriptions, from the core's one list.
pub fn method_parser() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(
        Method::ALL.map(|m| clap::builder::PossibleValue::new(m.name()).help(m.description())),
    )
}

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|e| Error::Io(format!("{}: {e}", path.display())))
}

pub fn run(a: Args) -> Result<()> {
    let method: Method = a.method.parse()?;
    let source = io::read_model_file(&a.source)?;
    let target = io::read_model_file(&a.target)?;
    let params = match (&a.params, &a.image) {
        (Some(p), _) => super::render::read_params(p)?,
        (None, Some(img)) => {
            let t = io::read_training_image(img)?;
            source
                .project(&t.image.view()?, &t.landmarks)
                .map_err(|e| e.with_context(&img.display().to_string()))?
        }
        (None, None) => return Err(Error::Params("give --params or --image".into())),
    };
    // A size the model declares is only a default, bounded; a larger canvas must be asked for.
    let composite = super::render::composite_wanted(a.draw.composite, &target);
    if facemimic::clone::effective_method(method, &target) != method {
        eprintln!(
            "facemimic: notice: '{}' is a photo target (no modes of its own); cloned by substitution instead of {method}",
            target.name()
        );
    }
    let (width, height) = super::render::canvas_size(&target, a.width, a.height, composite)?;
    super::render::check_canvas(width, height)?;
    let options = CloneOptions {
        method,
        gain: a.gain,
        clamp: if a.no_clamp { None } else { Some(a.clamp) },
        follow_pose: a.follow_pose,
        regions: facemimic::clone::RegionGains {
            mouth: a.mouth_gain,
            eyes: a.eyes_gain,
            brows: a.brows_gain,
        },
        style: a.style,
        ..CloneOptions::default()
    };
    let mut stage = Stage::new(source)?;
    stage.add_target(target)?;
    stage.set_source_params(&params)?;
    stage.set_options(options)?;
    stage.update()?;
    if let Some(out) = &a.out {
        let picture = stage.target_picture_mut(0)?;
        picture.set_size(width, height)?;
        picture.set_options(super::render::picture_options(a.draw.options(), composite));
        stage.draw_target(0)?;
        super::render::write_picture(out, stage.target_picture_mut(0)?)?;
    }
    let cloner = stage.cloner();
    if let Some(p) = &a.out_pts {
        write(p, &facemimic::landmarks::write_pts(cloner.target_shape(0)))?;
    }
    let json =
        serde_json::to_string(cloner.target_params(0)).map_err(|e| Error::Io(e.to_string()))?;
    match &a.out_params {
        Some(p) => write(p, &format!("{json}\n"))?,
        None if a.out.is_none() && a.out_pts.is_none() => crate::print_line(&json)?,
        None => {}
    }
    Ok(())
}

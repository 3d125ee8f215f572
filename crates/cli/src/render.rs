//! `facemimic render`.

use std::path::{Path, PathBuf};

use facemimic::{
    io, DrawOptions, Error, Framing, Params, Picture, PictureOptions, Rasterizer, Result, Stage,
};

/// How faces are drawn (shared by `render` and `clone`).
#[derive(clap::Args)]
pub struct DrawArgs {
    /// Stroke the triangle mesh over the face.
    #[arg(long)]
    mesh: bool,
    /// The triangle rasteriser: tiny-skia (pattern fills, the default) or scanline (faster,
    /// within ~1.5 levels of tiny-skia).
    #[arg(long, default_value = "tiny-skia", value_name = "RASTER",
          value_parser = clap::builder::PossibleValuesParser::new(["tiny-skia", "scanline"]))]
    raster: String,
    /// Composite the face into the model's backdrop (its own picture): the PNG is the size of
    /// the backdrop (unless --width/--height are given), the head at the given pose. A model
    /// without a backdrop renders face only, with a notice.
    #[arg(long)]
    pub composite: bool,
}

impl DrawArgs {
    /// The core's drawing options.
    pub fn options(&self) -> DrawOptions {
        DrawOptions {
            rasterizer: if self.raster == "scanline" {
                Rasterizer::Scanline
            } else {
                Rasterizer::TinySkia
            },
            mesh: self.mesh,
        }
    }
}

/// An error naming an unsupported canvas size.
pub fn check_canvas(width: u32, height: u32) -> Result<()> {
    if width == 0
        || height == 0
        || width > facemimic::MAX_IMAGE_SIDE
        || height > facemimic::MAX_IMAGE_SIDE
    {
        return Err(Error::Image(format!(
            "canvas size {width}x{height} not supported"
        )));
    }
    Ok(())
}

/// The options of a picture the CLI writes: the dark grey background, the face alone at the
/// identity view (the canvas is in the image's pixels) or composited into the backdrop.
pub fn picture_options(draw: DrawOptions, composite: bool) -> PictureOptions {
    PictureOptions {
        draw,
        composite,
        framing: Framing::Image,
        ..PictureOptions::default()
    }
}

/// Writes a drawn picture as PNG.
pub fn write_picture(path: &Path, picture: &Picture) -> Result<()> {
    let pixmap = picture
        .pixmap()
        .ok_or_else(|| Error::Image("internal error: the picture was not drawn".into()))?;
    io::write_pixmap(path, pixmap)
}

#[derive(clap::Args)]
pub struct Args {
    /// The model to render.
    #[arg(long, value_name = "MODEL.fmm")]
    model: PathBuf,
    /// Parameters as printed by `facemimic project` (default: the base face at its mean pose).
    #[arg(long, value_name = "P.json")]
    params: Option<PathBuf>,
    /// Canvas width (default: the training images' width).
    #[arg(long, value_name = "W")]
    width: Option<u32>,
    /// Canvas height (default: the training images' height).
    #[arg(long, value_name = "H")]
    height: Option<u32>,
    /// The PNG to write.
    #[arg(long, value_name = "OUT.png")]
    out: PathBuf,
    /// Also write the instance's landmarks (canvas pixel coordinates) as .pts.
    #[arg(long, value_name = "OUT.pts")]
    out_pts: Option<PathBuf>,
    #[command(flatten)]
    draw: DrawArgs,
}

/// Reads a parameters JSON file.
pub fn read_params(path: &Path) -> Result<Params> {
    let text = facemimic::bounds::read_text_capped(path, facemimic::bounds::MAX_TEXT_FILE_BYTES)?;
    serde_json::from_str(&text).map_err(|e| Error::Params(format!("{}: {e}", path.display())))
}

/// Whether to composite `model`'s faces: asked for and possible. A model without a backdrop
/// renders face only, with a notice on stderr.
pub fn composite_wanted(asked: bool, model: &facemimic::Model) -> bool {
    if asked && model.backdrop().is_none() {
        eprintln!(
            "facemimic: notice: model '{}' has no backdrop; rendering the face only",
            model.name()
        );
    }
    asked && model.backdrop().is_some()
}

/// The canvas size: `--width`/`--height` when given, else the backdrop's size when compositing,
/// else the model's default canvas.
pub fn canvas_size(
    model: &facemimic::Model,
    width: Option<u32>,
    height: Option<u32>,
    composite: bool,
) -> Result<(u32, u32)> {
    Ok(match (width, height) {
        (Some(w), Some(h)) => (w, h),
        (w, h) => {
            let (dw, dh) = match (composite, model.backdrop()) {
                (true, Some(b)) => (b.width(), b.height()),
                _ => facemimic::bounds::default_canvas(model)?,
            };
            (w.unwrap_or(dw), h.unwrap_or(dh))
        }
    })
}

/// Renders `params` of `model` on a `width x height` canvas (dark grey background, or the
/// backdrop when compositing) with a [`Stage`] driven by the model, and writes the PNG and
/// optionally the landmarks (`(png, pts)`).
pub fn render_to_files(
    model: facemimic::Model,
    params: &Params,
    (width, height): (u32, u32),
    (draw, composite): (DrawOptions, bool),
    (out, out_pts): (&Path, Option<&Path>),
) -> Result<()> {
    check_canvas(width, height)?;
    let mut stage = Stage::new(model)?;
    stage.set_source_params(params)?;
    let picture = stage.source_picture_mut();
    picture.set_size(width, height)?;
    picture.set_options(picture_options(draw, composite));
    stage.draw_source()?;
    write_picture(out, stage.source_picture())?;
    if let Some(p) = out_pts {
        let shape = stage.source_landmarks()?;
        std::fs::write(p, facemimic::landmarks::write_pts(shape))
            .map_err(|e| Error::Io(format!("{}: {e}", p.display())))?;
    }
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    let model = io::read_model_file(&a.model)?;
    let composite = composite_wanted(a.draw.composite, &model);
    let params = match &a.params {
        Some(p) => read_params(p)?,
        None if composite => facemimic::Params {
            pose: model.home_pose(),
            ..model.base_params()
        },
        None => model.base_params(),
    };
    model.check_params(&params)?;
    // A size the model declares is only a default, bounded; a larger canvas must be asked for.
    let size = canvas_size(&model, a.width, a.height, composite)?;
    let files = (a.out.as_path(), a.out_pts.as_deref());
    render_to_files(model, &params, size, (a.draw.options(), composite), files)
}

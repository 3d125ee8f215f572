//! `facemimic render`.

use std::path::{Path, PathBuf};

use facemimic::tiny_skia::{Color, Pixmap};
use facemimic::{io, DrawOptions, Error, FaceDrawer, Params, Rasterizer, Result, Similarity};

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

/// A `width x height` canvas filled with the dark grey background.
pub fn canvas(width: u32, height: u32) -> Result<Pixmap> {
    check_canvas(width, height)?;
    let mut pixmap = Pixmap::new(width, height)
        .ok_or_else(|| Error::Image(format!("cannot make a {width}x{height} canvas")))?;
    pixmap.fill(Color::from_rgba8(32, 32, 36, 255));
    Ok(pixmap)
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

/// Renders `params` of `model` on a `width x height` canvas (dark grey background) and writes
/// the PNG and optionally the landmarks (`(png, pts)`).
pub fn render_to_files(
    model: &facemimic::Model,
    params: &Params,
    width: u32,
    height: u32,
    draw: DrawOptions,
    (out, out_pts): (&Path, Option<&Path>),
) -> Result<()> {
    let mut pixmap = canvas(width, height)?;
    let mut drawer = FaceDrawer::new(model.frame(), draw)?;
    drawer.render(model, params, &Similarity::IDENTITY, &mut pixmap.as_mut())?;
    io::write_pixmap(out, &pixmap)?;
    if let Some(p) = out_pts {
        let mut shape = vec![0.0; model.landmarks() * 2];
        model.image_shape(params, &mut shape)?;
        std::fs::write(p, facemimic::landmarks::write_pts(&shape))
            .map_err(|e| Error::Io(format!("{}: {e}", p.display())))?;
    }
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    let model = io::read_model_file(&a.model)?;
    let params = match &a.params {
        Some(p) => read_params(p)?,
        None => model.base_params(),
    };
    model.check_params(&params)?;
    // A size the model declares is only a default, bounded; a larger canvas must be asked for.
    let (width, height) = match (a.width, a.height) {
        (Some(w), Some(h)) => (w, h),
        (w, h) => {
            let (dw, dh) = facemimic::bounds::default_canvas(&model)?;
            (w.unwrap_or(dw), h.unwrap_or(dh))
        }
    };
    let files = (a.out.as_path(), a.out_pts.as_deref());
    render_to_files(&model, &params, width, height, a.draw.options(), files)
}

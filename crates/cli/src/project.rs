//! `facemimic project`.

use std::path::PathBuf;

use facemimic::{io, Result};

#[derive(clap::Args)]
pub struct Args {
    /// The model to project into.
    #[arg(long, value_name = "MODEL.fmm")]
    model: PathBuf,
    /// The image (with a sibling .pts or .asf landmark file).
    #[arg(value_name = "IMAGE")]
    image: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let model = io::read_model_file(&a.model)?;
    let t = io::read_training_image(&a.image)?;
    let params = model
        .project(&t.image.view()?, &t.landmarks)
        .map_err(|e| e.with_context(&a.image.display().to_string()))?;
    crate::print_line(
        &serde_json::to_string(&params).map_err(|e| facemimic::Error::Io(e.to_string()))?,
    )
}

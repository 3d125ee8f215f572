//! `facemimic inspect`.

use std::path::PathBuf;

use facemimic::{io, Reference, Result};

#[derive(clap::Args)]
pub struct Args {
    /// The model file.
    #[arg(value_name = "MODEL.fmm")]
    model: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let (m, info) = io::read_model_file_info(&a.model)?;
    let json = serde_json::json!({
        "name": m.name(),
        "format_version": info.version,
        "precision": info.storage.name(),
        "landmarks": m.landmarks(),
        "scheme": format!("{:?}", m.scheme()),
        "triangles": m.frame().triangles().len(),
        "frame_width": m.frame().width(),
        "frame_height": m.frame().height(),
        "pixels": m.frame().n_pixels(),
        "channels": 3,
        "shape_modes": m.shape().n_modes(),
        "appearance_modes": m.appearance().n_modes(),
        "shape_sigma": m.shape().sigmas(),
        "appearance_sigma": m.appearance().sigmas(),
        "shape_variance_share": m.shape().variance_shares(),
        "appearance_variance_share": m.appearance().variance_shares(),
        "frame_fingerprint": format!("{:016x}", m.frame().fingerprint()),
        "reference": match &m.reference() { Reference::Mean => "mean".to_string(), Reference::Training(n) => n.clone() },
        "image_width": m.image_size()[0],
        "image_height": m.image_size()[1],
        "mean_pose": m.mean_pose(),
        "photo_target": m.is_photo(),
        "backdrop": m.backdrop().map(|b| serde_json::json!({
            "width": b.width(),
            "height": b.height(),
            "bytes": b.jpeg().len(),
            "budget_bytes": facemimic::backdrop_budget(b.width(), b.height()),
        })),
        "backdrop_notice": info.backdrop_notice,
    });
    crate::print_line(&json.to_string())
}

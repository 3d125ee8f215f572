//! `facemimic build`.

use std::path::PathBuf;

use facemimic::{
    io, BuildOptions, Builder, EnrolFinder, FrameChoice, ReferenceChoice, Result, TrainingImage,
};

#[derive(clap::Args)]
pub struct Args {
    /// Where to write the model (.fmm).
    #[arg(long, value_name = "MODEL.fmm")]
    out: PathBuf,
    /// Build in the reference frame of this model instead of the canonical frame.
    #[arg(long, value_name = "REF.fmm", conflicts_with = "own_frame")]
    frame: Option<PathBuf>,
    /// Build in a reference frame of the model's own instead of the canonical frame (such a
    /// model clones only with models built in its frame).
    #[arg(long)]
    own_frame: bool,
    /// Fraction of shape variance to keep (at most 12 shape modes are kept).
    #[arg(long, default_value_t = 0.99, value_name = "F")]
    shape_variance: f64,
    /// Fraction of appearance variance to keep.
    #[arg(long, default_value_t = 0.98, value_name = "F")]
    appearance_variance: f64,
    /// Face width in reference-frame pixels (--own-frame, or landmarks other than 68, only).
    #[arg(long, default_value_t = 150.0, value_name = "PX")]
    face_width: f32,
    /// The reference face: `mean` (default), `closest` (the training image closest to the
    /// --frame model's reference) or the name (file stem) of a training image.
    #[arg(long, default_value = "mean", value_name = "REF")]
    reference: String,
    /// How the file stores the appearance: `i6` (compact, about a fifth of `f32`), `i8`, `f16`
    /// or `f32` (exact).
    #[arg(long, default_value = "i6", value_name = "P")]
    precision: facemimic::format::Storage,
    /// Model name stored in the file (default: the output's file stem).
    #[arg(long)]
    name: Option<String>,
    /// A list of image stems, one a line, relative to the list's folder.
    #[arg(long, value_name = "FILE")]
    list: Option<PathBuf>,
    /// Place the landmarks with the face finder (the most confident face of each image),
    /// ignoring any landmark files; images without a face are skipped with a note.
    #[arg(long)]
    find_faces: bool,
    /// Keep this many varied frames (farthest-point sampling of the aligned shapes).
    #[arg(long, value_name = "N")]
    select: Option<usize>,
    /// Images (PNG or JPEG), each with a sibling .pts or .asf landmark file (unless
    /// --find-faces).
    #[arg(value_name = "IMAGE")]
    images: Vec<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let mut paths = a.images.clone();
    if let Some(list) = &a.list {
        paths.extend(io::read_list(list)?);
    }
    if paths.is_empty() {
        return Err(facemimic::Error::Training(
            "no training images given (IMAGE... or --list)".into(),
        ));
    }
    let mut images = if a.find_faces {
        find_faces(&paths)?
    } else {
        paths
            .iter()
            .map(|p| io::read_training_image(p))
            .collect::<Result<Vec<_>>>()?
    };
    if let Some(n) = a.select {
        if n < 2 {
            return Err(facemimic::Error::Training(format!(
                "--select {n}: at least 2 frames are needed"
            )));
        }
        if n < images.len() {
            let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
            let mut keep = facemimic::select_varied(&shapes, n)?;
            keep.sort_unstable();
            let mut all: Vec<Option<TrainingImage>> = images.into_iter().map(Some).collect();
            images = keep.iter().filter_map(|&i| all[i].take()).collect();
            eprintln!("facemimic: selected {} varied frames", images.len());
        }
    }
    let frame_model = a.frame.as_deref().map(io::read_model_file).transpose()?;
    let reference = match a.reference.as_str() {
        "mean" => ReferenceChoice::Mean,
        "closest" => ReferenceChoice::ClosestToFrame,
        name => ReferenceChoice::Named(name.to_string()),
    };
    let name = a.name.clone().unwrap_or_else(|| {
        a.out
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "model".into())
    });
    let builder = Builder::new(BuildOptions {
        name,
        shape_variance: a.shape_variance,
        appearance_variance: a.appearance_variance,
        face_width: a.face_width,
        reference,
        frame: if a.own_frame {
            FrameChoice::Own
        } else {
            FrameChoice::Canonical
        },
        ..BuildOptions::default()
    });
    let model = builder.build(&images, frame_model.as_ref())?;
    io::write_model_file_as(&a.out, &model, a.precision)?;
    eprintln!(
        "facemimic: built '{}' from {} images: {} shape modes, {} appearance modes, {} frame pixels -> {}",
        model.name(),
        images.len(),
        model.shape().n_modes(),
        model.appearance().n_modes(),
        model.frame().n_pixels(),
        a.out.display()
    );
    Ok(())
}

/// The training images with the finder's landmarks; images without a face are skipped with a
/// note. Fewer than two faces is an error (nothing is written).
fn find_faces(paths: &[PathBuf]) -> Result<Vec<TrainingImage>> {
    // The finder's points averaged with a pass on the mirrored image, as the page's enrolment.
    let mut finder = EnrolFinder::new(1)?;
    let mut out = Vec::new();
    for p in paths {
        let image = io::read_image(p)?;
        let Some(face) = finder.find(&image.view()?, 0.0)? else {
            eprintln!("facemimic: no face found in {}, skipped", p.display());
            continue;
        };
        out.push(TrainingImage {
            name: p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            image,
            landmarks: face.landmarks,
        });
    }
    if out.len() < 2 {
        return Err(facemimic::Error::Training(format!(
            "faces found in {} of {} images: at least 2 are needed",
            out.len(),
            paths.len()
        )));
    }
    Ok(out)
}

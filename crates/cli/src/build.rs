//! `facemimic build`.

use std::path::PathBuf;

use facemimic::{
    io, BuildOptions, EnrolFinder, EnrolFrame, EnrolOptions, FrameChoice, ReferenceChoice, Result,
    TrainingImage,
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
    /// The reference face: `mean` (default), `rest` (the training image most at rest: mouth
    /// closed, no smile, eyes open, facing the camera; a person's own model to track them
    /// with), `closest` (the training image closest to the --frame model's reference) or the
    /// name (file stem) of a training image.
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
    /// ignoring any landmark files; images without a face are skipped with a note, and images
    /// whose face is occluded, blurred, dark, turned too far or partly outside the picture are
    /// rejected, a line each naming the reason.
    #[arg(long)]
    find_faces: bool,
    /// Keep this many varied frames (farthest-point sampling of the aligned shapes).
    #[arg(long, value_name = "N")]
    select: Option<usize>,
    /// The picture the model's face is composited into (its .pts beside it, or the face
    /// finder's landmarks). Default: the training image closest to the model's mean.
    #[arg(long, value_name = "IMG", conflicts_with = "no_backdrop")]
    backdrop: Option<PathBuf>,
    /// Build the model without a backdrop (it renders face only).
    #[arg(long)]
    no_backdrop: bool,
    /// Make a target from this one photo (its .pts beside it, or the face finder's landmarks):
    /// the photo's face is the base, the photo its backdrop; cloning onto it substitutes the
    /// source's modes. No training images are used.
    #[arg(long, value_name = "IMG", conflicts_with_all = ["list", "images", "backdrop", "no_backdrop", "select"])]
    photo: Option<PathBuf>,
    /// Images (PNG or JPEG), each with a sibling .pts or .asf landmark file (unless
    /// --find-faces).
    #[arg(value_name = "IMAGE")]
    images: Vec<PathBuf>,
}

/// The model's name: `--name`, or the output's file stem.
fn model_name(a: &Args) -> String {
    a.name.clone().unwrap_or_else(|| {
        a.out
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "model".into())
    })
}

/// An image and its landmarks: from the landmark file beside it when there is one, otherwise
/// the face finder's (the most confident face).
fn picture_with_landmarks(path: &std::path::Path) -> Result<TrainingImage> {
    if io::landmark_path(path).is_ok() {
        return io::read_training_image(path);
    }
    let image = io::read_image(path)?;
    let mut finder = EnrolFinder::new(1)?;
    let face = finder.find(&image.view()?, 0.0)?.ok_or_else(|| {
        facemimic::Error::Landmarks(format!(
            "{}: no landmark file beside it and no face found in it",
            path.display()
        ))
    })?;
    Ok(TrainingImage {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        image,
        landmarks: face.landmarks,
    })
}

/// `build --photo`: a target model of one photo.
fn build_photo(a: &Args, path: &std::path::Path) -> Result<()> {
    // The errors of the picture's own reading name it already.
    let t = picture_with_landmarks(path)?;
    let frame_model = a.frame.as_deref().map(io::read_model_file).transpose()?;
    let frame = match &frame_model {
        Some(m) => m.frame(),
        None => facemimic::canonical_frame(),
    };
    let model = facemimic::photo_model(&model_name(a), &t.image.view()?, &t.landmarks, frame)
        .map_err(|e| e.with_context(&path.display().to_string()))?;
    io::write_model_file_as(&a.out, &model, a.precision)?;
    let b = model.backdrop().map(|b| b.jpeg().len()).unwrap_or(0);
    eprintln!(
        "facemimic: made the photo target '{}' from {} ({}x{}, backdrop {b} bytes) -> {}",
        model.name(),
        path.display(),
        t.image.width,
        t.image.height,
        a.out.display()
    );
    Ok(())
}

pub fn run(a: Args) -> Result<()> {
    if let Some(photo) = &a.photo {
        return build_photo(&a, photo);
    }
    let paths = training_paths(&a)?;
    // Every frame read first (a missing or unreadable file fails before any work), with its
    // landmark file unless the finder is to place them.
    let frames = paths
        .iter()
        .map(|p| read_frame(p, a.find_faces))
        .collect::<Result<Vec<_>>>()?;
    let options = enrol_options(&a)?;
    let frame_model = a.frame.as_deref().map(io::read_model_file).transpose()?;
    let mut noted = 0;
    let made = facemimic::enrol(frames, &options, frame_model.as_ref(), None, &mut |p| {
        for &i in &p.skipped[noted..] {
            eprintln!(
                "facemimic: no face found in {}, skipped",
                paths[i].display()
            );
        }
        noted = p.skipped.len();
        true
    })?;
    // The quality checks' verdicts (the comparison of the faces with each other comes after
    // the search), a line each, in frame order.
    for &(i, why) in &made.rejected {
        eprintln!("facemimic: rejected {} ({why})", paths[i].display());
    }
    // The expressions the usable frames show (the page's guide shows the same checklist).
    if a.find_faces {
        eprintln!("facemimic: expressions: {}", made.coverage);
    }
    if made.images.len() < paths.len() - made.skipped.len() - made.rejected.len() {
        eprintln!("facemimic: selected {} varied frames", made.images.len());
    }
    let images = made.images;
    let model = match &a.backdrop {
        Some(path) => {
            let chosen = picture_with_landmarks(path)?;
            let view = chosen.image.view()?;
            facemimic::with_default_backdrop(made.model, &images, Some((&view, &chosen.landmarks)))
                .map_err(|e| e.with_context(&format!("backdrop {}", path.display())))?
        }
        None => made.model,
    };
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

/// The training images: `IMAGE...` then the `--list`'s; fails when there are none.
fn training_paths(a: &Args) -> Result<Vec<PathBuf>> {
    let mut paths = a.images.clone();
    if let Some(list) = &a.list {
        paths.extend(io::read_list(list)?);
    }
    if paths.is_empty() {
        return Err(facemimic::Error::Training(
            "no training images given (IMAGE... or --list)".into(),
        ));
    }
    Ok(paths)
}

/// One training frame read from `p`: with its landmark file, or without landmarks (for the
/// finder to place) when `find_faces`.
fn read_frame(p: &std::path::Path, find_faces: bool) -> Result<EnrolFrame> {
    let name = p
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    if find_faces {
        let image = io::read_image(p)?;
        Ok(EnrolFrame {
            name,
            image,
            landmarks: None,
        })
    } else {
        let t = io::read_training_image(p)?;
        Ok(EnrolFrame {
            name: t.name,
            image: t.image,
            landmarks: Some(t.landmarks),
        })
    }
}

/// The enrolment's options from the arguments; fails on a `--select` below 2.
fn enrol_options(a: &Args) -> Result<EnrolOptions> {
    if let Some(n) = a.select {
        if n < 2 {
            return Err(facemimic::Error::Training(format!(
                "--select {n}: at least 2 frames are needed"
            )));
        }
    }
    let reference = match a.reference.as_str() {
        "mean" => ReferenceChoice::Mean,
        "closest" => ReferenceChoice::ClosestToFrame,
        "rest" => ReferenceChoice::Rest,
        name => ReferenceChoice::Named(name.to_string()),
    };
    Ok(EnrolOptions {
        build: BuildOptions {
            name: model_name(a),
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
        },
        select: a.select,
        // The default backdrop is the core's; a chosen one is put in below.
        backdrop: !a.no_backdrop && a.backdrop.is_none(),
        ..EnrolOptions::default()
    })
}

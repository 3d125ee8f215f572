//! `facemimic landmark`: find the most confident face of each image and write its 68 landmarks.

use std::path::{Path, PathBuf};

use facemimic::{io, landmarks, Error, FaceFinder, Result};

#[derive(clap::Args)]
pub struct Args {
    /// Write the .pts files into this folder (made if missing) instead of beside the images.
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    /// Overwrite existing .pts files.
    #[arg(long)]
    force: bool,
    /// One look per image instead of the mean over the image and its mirror (about 40% faster,
    /// a little further from dlib's points: docs/finding.md, "Precise").
    #[arg(long)]
    fast: bool,
    /// Images (PNG or JPEG).
    #[arg(value_name = "IMAGE", required = true)]
    images: Vec<PathBuf>,
}

fn out_path(image: &Path, dir: Option<&Path>) -> PathBuf {
    let name = image.with_extension("pts");
    match dir {
        Some(d) => d.join(name.file_name().unwrap_or_default()),
        None => name,
    }
}

pub fn run(a: Args) -> Result<()> {
    if let Some(d) = &a.out_dir {
        if d.exists() && !d.is_dir() {
            return Err(Error::Io(format!("{}: not a folder", d.display())));
        }
        // A folder that does not exist yet is made (as `mkdir -p`).
        std::fs::create_dir_all(d)
            .map_err(|e| Error::Io(format!("{}: cannot make the folder: {e}", d.display())))?;
    }
    // Refuse before any work if a file would be overwritten.
    if !a.force {
        for img in &a.images {
            let out = out_path(img, a.out_dir.as_deref());
            if out.exists() {
                return Err(Error::Io(format!(
                    "{} exists (use --force to overwrite)",
                    out.display()
                )));
            }
        }
    }
    let mut finder = FaceFinder::new()?;
    let mut options = finder.options();
    options.mirror = !a.fast;
    finder.set_options(options);
    let (mut written, mut faceless) = (0, 0);
    for img in &a.images {
        let image = io::read_image(img)?;
        let faces = finder.find(&image.view()?);
        let Some(face) = faces.first() else {
            eprintln!("facemimic: no face found in {}", img.display());
            faceless += 1;
            continue;
        };
        let out = out_path(img, a.out_dir.as_deref());
        std::fs::write(&out, landmarks::write_pts(&face.landmarks))
            .map_err(|e| Error::Io(format!("{}: {e}", out.display())))?;
        written += 1;
    }
    eprintln!(
        "facemimic: wrote landmarks for {written} of {} images ({faceless} without a face)",
        a.images.len()
    );
    Ok(())
}

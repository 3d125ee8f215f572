//! Native file input: decoding images and finding their landmark files (not in the wasm build).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::image::{Image, TrainingImage, MAX_IMAGE_SIDE};
use crate::landmarks::{parse_asf, parse_pts};

/// Decodes a PNG or JPEG file into RGBA8.
pub fn read_image(path: &Path) -> Result<Image> {
    // Through the size cap: a device, FIFO or directory is refused before it is opened.
    let bytes =
        crate::model::bounds::read_file_capped(path, crate::model::bounds::MAX_IMAGE_FILE_BYTES)?;
    let mut reader = ::image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::Io(format!("{}: {e}", path.display())))?;
    // The decoder checks the size against these limits before it allocates the pixels.
    let mut limits = ::image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    reader.limits(limits);
    let img = reader
        .decode()
        .map_err(|e| match e {
            ::image::ImageError::Limits(_) => Error::Image(format!(
                "{}: {} is beyond the image limit of {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE} pixels",
                path.display(),
                image_size(path).unwrap_or_else(|| "the image".into())
            )),
            e => Error::Image(format!("{}: {e}", path.display())),
        })?
        .to_rgba8();
    if img.width() == 0 || img.height() == 0 {
        return Err(Error::Image(format!(
            "{}: the image is empty",
            path.display()
        )));
    }
    Ok(Image {
        width: img.width(),
        height: img.height(),
        data: img.into_raw(),
    })
}

/// `WxH` of an image file, read from its header alone (for messages).
fn image_size(path: &Path) -> Option<String> {
    let (w, h) = ::image::ImageReader::open(path)
        .ok()?
        .with_guessed_format()
        .ok()?
        .into_dimensions()
        .ok()?;
    Some(format!("{w}x{h}"))
}

/// Writes RGBA8 pixels as a PNG file.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    ::image::save_buffer(path, rgba, width, height, ::image::ExtendedColorType::Rgba8)
        .map_err(|e| Error::Io(format!("{}: {e}", path.display())))
}

/// The landmark file beside an image: same stem, `.pts` preferred, else `.asf`.
pub fn landmark_path(image: &Path) -> Result<PathBuf> {
    for ext in ["pts", "asf"] {
        let p = image.with_extension(ext);
        if p.is_file() {
            return Ok(p);
        }
    }
    Err(Error::Landmarks(format!(
        "{}: no landmark file ({} or .asf) beside the image",
        image.display(),
        image.with_extension("pts").display()
    )))
}

/// Reads the landmarks of an image of the given size from a `.pts` or `.asf` file.
pub fn read_landmarks(path: &Path, width: u32, height: u32) -> Result<Vec<f32>> {
    let text =
        crate::model::bounds::read_text_capped(path, crate::model::bounds::MAX_TEXT_FILE_BYTES)?;
    let r = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("asf"))
    {
        parse_asf(&text, width, height)
    } else {
        parse_pts(&text)
    };
    r.map_err(|e| {
        Error::Landmarks(format!(
            "{}: {}",
            path.display(),
            e.to_string().trim_start_matches("landmarks: ")
        ))
    })
}

/// Loads an image and its sibling landmark file.
pub fn read_training_image(path: &Path) -> Result<TrainingImage> {
    let lm = landmark_path(path)?;
    let image = read_image(path)?;
    let landmarks = read_landmarks(&lm, image.width, image.height)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(TrainingImage {
        name,
        image,
        landmarks,
    })
}

/// Reads a list file (one image stem a line, relative to the list's folder; `#` comments) and
/// resolves each stem to an existing `.jpg`, `.jpeg` or `.png` file.
pub fn read_list(list: &Path) -> Result<Vec<PathBuf>> {
    let text =
        crate::model::bounds::read_text_capped(list, crate::model::bounds::MAX_TEXT_FILE_BYTES)?;
    let dir = list.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for line in text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
    {
        let base = dir.join(line);
        let found = if base.extension().is_some() && base.is_file() {
            Some(base.clone())
        } else {
            ["jpg", "jpeg", "png"]
                .iter()
                .map(|e| base.with_extension(e))
                .find(|p| p.is_file())
        };
        out.push(found.ok_or_else(|| {
            Error::Io(format!(
                "{}: no image for '{line}' (looked for .jpg, .jpeg, .png)",
                list.display()
            ))
        })?);
    }
    if out.is_empty() {
        return Err(Error::Io(format!(
            "{}: the list names no image",
            list.display()
        )));
    }
    Ok(out)
}

/// Every annotated image under `dir` (searched recursively): the `.jpg`, `.jpeg` and `.png`
/// files with a `.pts` file of the same stem beside them, sorted by path. The shared data sets
/// and `data/grid` are laid out this way.
pub fn annotated_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries =
            std::fs::read_dir(&d).map_err(|e| Error::Io(format!("{}: {e}", d.display())))?;
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .is_some_and(|x| x == "jpg" || x == "jpeg" || x == "png")
                && p.with_extension("pts").is_file()
            {
                out.push(p);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// Writes a tiny-skia pixmap (premultiplied) as a PNG file (straight alpha).
pub fn write_pixmap(path: &Path, pixmap: &tiny_skia::Pixmap) -> Result<()> {
    let rgba = crate::render::demultiply(pixmap);
    write_png(path, pixmap.width(), pixmap.height(), &rgba)
}

/// Reads and validates a `.fmm` model file.
pub fn read_model_file(path: &Path) -> Result<crate::model::Model> {
    read_model_file_info(path).map(|(model, _)| model)
}

/// Writes a model as a `.fmm` file (the default, compact storage).
pub fn write_model_file(path: &Path, model: &crate::model::Model) -> Result<()> {
    write_model_file_as(path, model, crate::model::format::Storage::default())
}

/// Writes a model as a `.fmm` file with the given appearance storage; refuses (writing
/// nothing) a model that [`crate::model::format::read_model`] would reject.
pub fn write_model_file_as(
    path: &Path,
    model: &crate::model::Model,
    storage: crate::model::format::Storage,
) -> Result<()> {
    let bytes = crate::model::format::write_model_checked_as(model, storage)
        .map_err(|e| Error::Format(e).with_context(&path.display().to_string()))?;
    std::fs::write(path, bytes).map_err(|e| Error::Io(format!("{}: {e}", path.display())))
}

/// Reads and validates a `.fmm` model file, also returning its version and storage.
pub fn read_model_file_info(
    path: &Path,
) -> Result<(crate::model::Model, crate::model::format::FileInfo)> {
    let bytes =
        crate::model::bounds::read_file_capped(path, crate::model::bounds::MAX_MODEL_FILE_BYTES)?;
    crate::model::format::read_model_info(&bytes)
        .map_err(|e| Error::Format(e).with_context(&path.display().to_string()))
}

/// The landmarks the shipped expression prior is learned from, under `data` (the crate's
/// `data/` folder): the London set's `london/neutral/NNN.pts` with `london/smiling/NNN.pts`
/// (people whose number is in `exclude` left out), and every GRID speaker's `.pts` under
/// `grid/spkNN_*/`, grouped by speaker. Sorted by name, so the order is the same everywhere.
/// The iBUG files' 1-based coordinates are read as 0-based.
pub fn expression_sets(
    data: &Path,
    exclude: &[u32],
) -> Result<(crate::clone::ShapePairs, crate::clone::SpeakerShapes)> {
    let read = |p: &Path| -> Result<Vec<f32>> {
        let text =
            std::fs::read_to_string(p).map_err(|e| Error::Io(format!("{}: {e}", p.display())))?;
        crate::landmarks::parse_pts(&text)
    };
    let sorted = |dir: &Path| -> Result<Vec<PathBuf>> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| Error::Io(format!("{}: {e}", dir.display())))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        v.sort();
        Ok(v)
    };
    let mut london = Vec::new();
    for p in sorted(&data.join("london/neutral"))? {
        let (Some(stem), Some("pts")) = (
            p.file_stem().and_then(|s| s.to_str()),
            p.extension().and_then(|s| s.to_str()),
        ) else {
            continue;
        };
        if stem.parse::<u32>().is_ok_and(|n| exclude.contains(&n)) {
            continue;
        }
        let smile = data.join("london/smiling").join(format!("{stem}.pts"));
        london.push((read(&p)?, read(&smile)?));
    }
    let mut speakers: Vec<(String, Vec<Vec<f32>>)> = Vec::new();
    for clip in sorted(&data.join("grid"))? {
        let Some(name) = clip.file_name().and_then(|s| s.to_str()) else {
            continue;
        };
        let Some(speaker) = name.split('_').next().filter(|s| s.starts_with("spk")) else {
            continue;
        };
        let mut frames = Vec::new();
        for p in sorted(&clip)? {
            if p.extension().and_then(|s| s.to_str()) == Some("pts") {
                frames.push(read(&p)?);
            }
        }
        match speakers.iter_mut().find(|(s, _)| s == speaker) {
            Some((_, f)) => f.extend(frames),
            None => speakers.push((speaker.to_string(), frames)),
        }
    }
    Ok((london, speakers.into_iter().map(|(_, f)| f).collect()))
}

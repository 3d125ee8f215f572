//! Contact sheets of rendered faces: a grey canvas, cells put on it, saved as JPEG or PNG.

use std::path::Path;

use facemimic::tiny_skia::{Color, Pixmap, PixmapPaint, Transform};
use facemimic::{Compositor, Error, Model, Result, Similarity};

/// JPEG quality of the sheets written as `.jpg`.
pub const JPEG_QUALITY: u8 = 90;

/// A `width x height` pixmap filled with dark grey.
pub fn canvas(width: u32, height: u32) -> Result<Pixmap> {
    let mut p = Pixmap::new(width, height)
        .ok_or_else(|| Error::Image(format!("cannot make a {width}x{height} canvas")))?;
    p.fill(Color::from_rgba8(32, 32, 36, 255));
    Ok(p)
}

/// Draws `cell` onto `sheet` with its top-left corner at `(x, y)`.
pub fn put(sheet: &mut Pixmap, (x, y): (u32, u32), cell: &Pixmap) {
    sheet.draw_pixmap(
        x as i32,
        y as i32,
        cell.as_ref(),
        &PixmapPaint::default(),
        Transform::identity(),
        None,
    );
}

/// The view showing the box `[x0, y0, x1, y1]` (a face's landmarks' extent), grown by a margin,
/// centred in a `cell` (width, height).
pub fn cell_view(b: [f32; 4], cell: (u32, u32)) -> Similarity {
    let (w, h) = (b[2] - b[0], b[3] - b[1]);
    let (x, y, w, h) = (b[0] - 0.15 * w, b[1] - 0.25 * h, 1.3 * w, 1.35 * h);
    let (cw, ch) = (cell.0 as f32, cell.1 as f32);
    let k = ch / h.max(w * ch / cw);
    Similarity {
        a: k,
        b: 0.0,
        tx: 0.5 * cw - k * (x + 0.5 * w),
        ty: 0.5 * ch - k * (y + 0.5 * h),
    }
}

/// A `cell`-sized picture of a target face (`appearance` on its frame, `shape` in its
/// picture's pixels) composited into its backdrop, seen through `view`.
pub fn target_cell(
    compositor: &mut Compositor,
    model: &Model,
    (appearance, shape): (&[f32], &[f32]),
    view: &Similarity,
    cell: (u32, u32),
) -> Result<Pixmap> {
    let mut p = canvas(cell.0, cell.1)?;
    compositor.draw(model, appearance, shape, view, &mut p.as_mut())?;
    Ok(p)
}

/// Writes `sheet` (opaque) as JPEG at [`JPEG_QUALITY`] when `path` ends in `.jpg` or `.jpeg`,
/// else as PNG, making its folder.
pub fn save(path: &Path, sheet: &Pixmap) -> Result<()> {
    let rgb: Vec<u8> = facemimic::demultiply(sheet)
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    save_rgb(path, &rgb, (sheet.width(), sheet.height()))
}

/// Writes a `w x h` RGB picture as [`save`] does.
pub fn save_rgb(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io(format!("{}: {e}", dir.display())))?;
    }
    let io_error = |e: &dyn std::fmt::Display| Error::Io(format!("{}: {e}", path.display()));
    let jpeg = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("jpg") || e.eq_ignore_ascii_case("jpeg"));
    if jpeg {
        let file = std::fs::File::create(path).map_err(|e| io_error(&e))?;
        image::codecs::jpeg::JpegEncoder::new_with_quality(
            std::io::BufWriter::new(file),
            JPEG_QUALITY,
        )
        .encode(rgb, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| io_error(&e))
    } else {
        image::save_buffer(path, rgb, w, h, image::ExtendedColorType::Rgb8)
            .map_err(|e| io_error(&e))
    }
}

//! One picture of the stage: a pixmap the stage owns, sized by the caller, the options it is
//! drawn with, and its pixels as straight RGBA.

use tiny_skia::{Color, Pixmap};

use crate::error::{Error, Result};
use crate::image::MAX_IMAGE_SIDE;
use crate::render::DrawOptions;

/// Most pixels one picture may have (64 MB of RGBA): a larger pixmap could exhaust wasm
/// memory, which aborts instead of failing.
pub const MAX_PICTURE_PIXELS: u64 = 1 << 24;

/// The default background of a picture, `#202024` (opaque dark grey), as the page, the npm
/// package and the CLI draw faces on.
pub const DEFAULT_BACKGROUND: [u8; 4] = [0x20, 0x20, 0x24, 0xff];

/// Where a face goes in its picture when it is not composited.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Framing {
    /// Centred and scaled: the model's mean placement ([`crate::base_box`]) fitted to the
    /// picture by [`crate::fit_view`] (the page and the npm package).
    #[default]
    Fitted,
    /// At the identity view: picture pixels are image pixels (the CLI, whose canvas is the
    /// size of the training images).
    Image,
}

/// How one picture is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PictureOptions {
    /// The colour under the face (premultiplied by tiny-skia; default [`DEFAULT_BACKGROUND`]).
    pub background: Color,
    /// The rasteriser and the mesh overlay.
    pub draw: DrawOptions,
    /// Composite the face into its model's backdrop (the whole picture, letterboxed by
    /// [`crate::picture_view`]); a model without a backdrop is drawn face only.
    pub composite: bool,
    /// Where a face drawn alone goes ([`Framing`]).
    pub framing: Framing,
    /// Keep the composited picture whole (default true): follow-pose is damped where the
    /// backdrop's warp would fold or stretch past 2x ([`crate::Compositor::set_keep_whole`]); false
    /// applies the head's whole motion.
    pub keep_whole: bool,
}

impl Default for PictureOptions {
    fn default() -> Self {
        let [r, g, b, a] = DEFAULT_BACKGROUND;
        PictureOptions {
            background: Color::from_rgba8(r, g, b, a),
            draw: DrawOptions::default(),
            composite: false,
            framing: Framing::Fitted,
            keep_whole: true,
        }
    }
}

/// Checks a picture size: each side in `1..=MAX_IMAGE_SIDE`, at most [`MAX_PICTURE_PIXELS`].
pub fn check_picture_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(Error::Image(format!(
            "picture size {width}x{height} outside 1..={MAX_IMAGE_SIDE}"
        )));
    }
    if width as u64 * height as u64 > MAX_PICTURE_PIXELS {
        return Err(Error::Image(format!(
            "{width}x{height} is more than {MAX_PICTURE_PIXELS} pixels: draw a smaller picture"
        )));
    }
    Ok(())
}

/// One picture of a [`super::Stage`]: the source's, a target's or a compare view's.
///
/// Represents: a pixmap of the size the caller set (none until then), the
/// [`PictureOptions`] it is drawn with, whether the stage draws it ([`Picture::set_shown`])
/// and, after a draw, its pixels as straight RGBA.
///
/// Ensures: the pixmap is made only when the size changes; drawing into it allocates nothing
/// (a non-opaque background's straight copy grows once).
#[derive(Debug, Default)]
pub struct Picture {
    pixmap: Option<Pixmap>,
    straight: Vec<u8>,
    options: PictureOptions,
    shown: bool,
    drawn: bool,
    /// The last drawing's straight copy is in `straight` (its background was not opaque).
    demultiplied: bool,
}

impl Picture {
    /// An unsized picture, shown, drawn with `options`.
    pub(super) fn new(options: PictureOptions) -> Picture {
        Picture {
            pixmap: None,
            straight: Vec::new(),
            options,
            shown: true,
            drawn: false,
            demultiplied: false,
        }
    }

    /// Sets the picture's size in pixels; `(0, 0)` drops the pixmap (the stage then skips the
    /// picture). Requires a size [`check_picture_size`] accepts; on error nothing changes.
    pub fn set_size(&mut self, width: u32, height: u32) -> Result<()> {
        if width == 0 && height == 0 {
            self.pixmap = None;
            self.drawn = false;
            self.demultiplied = false;
            return Ok(());
        }
        check_picture_size(width, height)?;
        if self.size() != (width, height) {
            let pixmap = Pixmap::new(width, height).ok_or_else(|| {
                Error::Image(format!("cannot allocate a {width}x{height} picture"))
            })?;
            self.pixmap = Some(pixmap);
            self.drawn = false;
            self.demultiplied = false;
        }
        Ok(())
    }

    /// The size, `(0, 0)` when unsized.
    pub fn size(&self) -> (u32, u32) {
        self.pixmap
            .as_ref()
            .map_or((0, 0), |p| (p.width(), p.height()))
    }

    /// The drawing options.
    pub fn options(&self) -> &PictureOptions {
        &self.options
    }

    /// Replaces the drawing options (used from the next draw).
    pub fn set_options(&mut self, options: PictureOptions) {
        self.options = options;
    }

    /// Whether the stage draws this picture (default true; a sized picture only).
    pub fn shown(&self) -> bool {
        self.shown
    }

    /// Shows or hides the picture: a hidden one keeps its last pixels and costs nothing.
    pub fn set_shown(&mut self, shown: bool) {
        self.shown = shown;
    }

    /// Whether the picture holds a drawing (it was drawn since it was last sized).
    pub fn drawn(&self) -> bool {
        self.drawn
    }

    /// The pixmap (premultiplied), `None` when unsized.
    pub fn pixmap(&self) -> Option<&Pixmap> {
        self.pixmap.as_ref()
    }

    /// The last drawing as straight (non-premultiplied) RGBA8, `4 * width * height` bytes, as
    /// PNG files and `ImageData` take; empty when unsized.
    pub fn rgba(&self) -> &[u8] {
        match &self.pixmap {
            None => &[],
            Some(_) if self.demultiplied => &self.straight,
            // Already straight (crate::render::straight_rgba).
            Some(p) => p.data(),
        }
    }

    /// The pixmap to draw into when the picture is sized and shown.
    pub(super) fn target(&mut self) -> Option<&mut Pixmap> {
        if self.shown {
            self.pixmap.as_mut()
        } else {
            None
        }
    }

    /// Records a finished drawing: the straight copy for a non-opaque background.
    pub(super) fn finish(&mut self) {
        if let Some(p) = &self.pixmap {
            self.demultiplied = !self.options.background.is_opaque();
            crate::render::straight_rgba(p.as_ref(), !self.demultiplied, &mut self.straight);
            self.drawn = true;
        }
    }
}

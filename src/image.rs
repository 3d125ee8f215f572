//! Borrowed and owned RGBA8 images.

use crate::error::{Error, Result};

/// Largest image side accepted anywhere (guards allocations from hostile sizes).
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// A borrowed, tightly packed RGBA8 image (the layout of a browser `ImageData`).
#[derive(Clone, Copy, Debug)]
pub struct ImageRef<'a> {
    width: u32,
    height: u32,
    data: &'a [u8],
}

impl<'a> ImageRef<'a> {
    /// Wraps `data` (`width * height * 4` bytes, RGBA, row-major).
    pub fn new(width: u32, height: u32, data: &'a [u8]) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(Error::Image(format!(
                "size {width}x{height} outside 1..={MAX_IMAGE_SIDE}"
            )));
        }
        if data.len() != width as usize * height as usize * 4 {
            return Err(Error::Image(format!(
                "{} bytes for a {width}x{height} RGBA image (expected {})",
                data.len(),
                width as usize * height as usize * 4
            )));
        }
        Ok(ImageRef {
            width,
            height,
            data,
        })
    }
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// The RGBA bytes.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// Bilinear RGB sample at `(x, y)` (pixel centres on integers), clamped at the borders,
    /// scaled to `0..=1`.
    #[inline]
    pub fn sample_rgb(&self, x: f32, y: f32) -> [f32; 3] {
        let maxx = (self.width - 1) as f32;
        let maxy = (self.height - 1) as f32;
        let x = if x.is_finite() {
            x.clamp(0.0, maxx)
        } else {
            0.0
        };
        let y = if y.is_finite() {
            y.clamp(0.0, maxy)
        } else {
            0.0
        };
        let x0 = x as u32;
        let y0 = y as u32;
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let fx = x - x0 as f32;
        let fy = y - y0 as f32;
        let w = self.width as usize;
        let at = |xx: u32, yy: u32| (yy as usize * w + xx as usize) * 4;
        let (i00, i10, i01, i11) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        let d = self.data;
        let mut out = [0f32; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let top = d[i00 + c] as f32 * (1.0 - fx) + d[i10 + c] as f32 * fx;
            let bot = d[i01 + c] as f32 * (1.0 - fx) + d[i11 + c] as f32 * fx;
            *o = (top * (1.0 - fy) + bot * fy) * (1.0 / 255.0);
        }
        out
    }
}

/// An owned RGBA8 image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA bytes, row-major, `width * height * 4`.
    pub data: Vec<u8>,
}

impl Image {
    /// Borrows the image (validating its size).
    pub fn view(&self) -> Result<ImageRef<'_>> {
        ImageRef::new(self.width, self.height, &self.data)
    }
}

//! Borrowed and owned RGBA8 images.

use crate::error::{Error, Result};

/// Largest image side accepted anywhere (guards allocations from hostile sizes).
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// Luminance weights (Rec. 601) of R, G and B: the fitter's grey levels and the expressive
/// method's ratio images.
pub(crate) const LUMA: [f32; 3] = [0.299, 0.587, 0.114];

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
        let b = crate::filter::bilinear(
            x,
            y,
            0.0,
            0.0,
            (self.width - 1) as f32,
            (self.height - 1) as f32,
        );
        let (fx, fy) = (b.fx, b.fy);
        let w = self.width as usize;
        let i00 = (b.y * w + b.x) * 4;
        let (i10, i01) = (i00 + 4 * b.dx, i00 + 4 * w * b.dy);
        let i11 = i01 + 4 * b.dx;
        let d = self.data;
        let mut out = [0f32; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let top = d[i00 + c] as f32 * (1.0 - fx) + d[i10 + c] as f32 * fx;
            let bot = d[i01 + c] as f32 * (1.0 - fx) + d[i11 + c] as f32 * fx;
            *o = (top * (1.0 - fy) + bot * fy) * (1.0 / 255.0);
        }
        out
    }

    /// The image mirrored left to right, into `out` (RGBA, resized to fit; keeps its
    /// allocation from call to call).
    pub fn mirror_into(&self, out: &mut Vec<u8>) {
        let w = self.width as usize;
        out.resize(self.data.len(), 0);
        for (o, row) in out
            .chunks_exact_mut(w * 4)
            .zip(self.data.chunks_exact(w * 4))
        {
            for (op, ip) in o.chunks_exact_mut(4).zip(row.chunks_exact(4).rev()) {
                op.copy_from_slice(ip);
            }
        }
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

/// One training example: an image and its landmarks (0-based image coordinates).
#[derive(Clone, Debug)]
pub struct TrainingImage {
    /// A name for it (the file stem), used to name a reference image.
    pub name: String,
    /// The RGBA image.
    pub image: Image,
    /// Its landmarks, interleaved.
    pub landmarks: Vec<f32>,
}

//! The backdrop: the picture a model's face is composited into (issue "near-videorealistic
//! faces"). One image of the person with its landmarks, kept JPEG-compressed in the model file
//! and decoded once on load.

use crate::summary::summary;
use std::io::Cursor;

use crate::error::{Error, Result};
use crate::image::ImageRef;

/// Largest backdrop side (pixels) a model may carry; also a limit of the file format.
pub const MAX_BACKDROP_SIDE: u32 = 4096;

/// Largest compressed backdrop (bytes) a model file may carry.
pub const MAX_BACKDROP_BYTES: usize = 4 << 20;

/// Pixels a backdrop may have per compressed byte (beyond 1 Mi pixels, which any JPEG may
/// have): a photograph at the budget's qualities has 5-20; only a nearly flat picture has more.
pub const MAX_PIXELS_PER_BYTE: u64 = 64;

/// The compressed size a backdrop aims at: 60 KB for 640x480, in proportion to the area for
/// other sizes (never under 12 KB). The encoder lowers the JPEG quality until it fits.
pub fn backdrop_budget(width: u32, height: u32) -> usize {
    let area = width as f64 * height as f64;
    ((60_000.0 * area / (640.0 * 480.0)) as usize).max(12_000)
}

/// The JPEG qualities tried, best first, until the file fits [`backdrop_budget`].
const QUALITIES: [u8; 7] = [88, 82, 76, 70, 62, 54, 45];

/// A picture of the person and their landmarks in it.
///
/// Represents: a `width x height` RGBA8 image (opaque), the landmarks of the face in it
/// (image pixels, centres on integers, as the model's landmark scheme), and the compressed
/// bytes (baseline JPEG) it was decoded from, which are what the model file stores.
/// Ensures: the size is within `1..=MAX_BACKDROP_SIDE`, the landmarks are finite and inside
/// the image, and `rgba` is the decoding of `jpeg` (so writing and reading a model keeps the
/// picture byte for byte).
#[derive(Clone, PartialEq)]
pub struct Backdrop {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
    landmarks: Vec<f32>,
    jpeg: Vec<u8>,
}

impl std::fmt::Debug for Backdrop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (size, n, jpeg) = (
            (self.width, self.height),
            self.landmarks.len() / 2,
            self.jpeg.len(),
        );
        summary(
            f,
            "Backdrop",
            &[("size", &size), ("landmarks", &n), ("jpeg_bytes", &jpeg)],
        )
    }
}

fn check_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_BACKDROP_SIDE || height > MAX_BACKDROP_SIDE {
        return Err(Error::Image(format!(
            "backdrop size {width}x{height} outside 1..={MAX_BACKDROP_SIDE}"
        )));
    }
    Ok(())
}

/// Fails unless `landmarks` holds finite points inside a `width x height` image.
pub(crate) fn check_landmarks_inside(landmarks: &[f32], width: u32, height: u32) -> Result<()> {
    if landmarks.len() < 6 || landmarks.len() % 2 != 0 {
        return Err(Error::Landmarks(format!(
            "a backdrop needs at least 3 landmarks, got {} values",
            landmarks.len()
        )));
    }
    for (i, p) in landmarks.chunks_exact(2).enumerate() {
        let inside = p[0] >= -0.5
            && p[1] >= -0.5
            && p[0] <= width as f32 - 0.5
            && p[1] <= height as f32 - 0.5;
        if !inside {
            return Err(Error::Landmarks(format!(
                "landmark {} at ({}, {}) falls outside the {width}x{height} backdrop",
                i + 1,
                p[0],
                p[1]
            )));
        }
    }
    Ok(())
}

impl Backdrop {
    /// Compresses an image (RGBA8; alpha is ignored) and its landmarks into a backdrop, at the
    /// best JPEG quality that fits [`backdrop_budget`].
    pub fn encode(image: &ImageRef<'_>, landmarks: &[f32]) -> Result<Backdrop> {
        let (w, h) = (image.width(), image.height());
        check_size(w, h)?;
        check_landmarks_inside(landmarks, w, h)?;
        let rgb: Vec<u8> = image
            .data()
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        let budget = backdrop_budget(w, h);
        let mut best = Vec::new();
        for q in QUALITIES {
            best.clear();
            let encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut best, q);
            image::ImageEncoder::write_image(encoder, &rgb, w, h, image::ExtendedColorType::Rgb8)
                .map_err(|e| Error::Image(format!("backdrop: JPEG encoding failed: {e}")))?;
            if best.len() <= budget {
                break;
            }
        }
        Backdrop::decode(w, h, landmarks.to_vec(), best)
    }

    /// Decodes stored backdrop bytes. Fails with a message naming the problem when the bytes
    /// are not a JPEG of the stated size or the landmarks are outside it.
    pub fn decode(width: u32, height: u32, landmarks: Vec<f32>, jpeg: Vec<u8>) -> Result<Backdrop> {
        check_size(width, height)?;
        check_landmarks_inside(&landmarks, width, height)?;
        if jpeg.len() > MAX_BACKDROP_BYTES {
            return Err(Error::Image(format!(
                "backdrop: {} compressed bytes (limit {MAX_BACKDROP_BYTES})",
                jpeg.len()
            )));
        }
        // A picture compresses at most so much: a small file stating a huge flat picture would
        // otherwise cost far more memory than its bytes (the reader's budget, model-format.md).
        let pixels = width as u64 * height as u64;
        if pixels > MAX_PIXELS_PER_BYTE * jpeg.len() as u64 + (1 << 20) {
            return Err(Error::Image(format!(
                "backdrop: {width}x{height} pixels from {} compressed bytes is implausible \
                 (at most {MAX_PIXELS_PER_BYTE} pixels a byte)",
                jpeg.len()
            )));
        }
        let mut reader =
            image::ImageReader::with_format(Cursor::new(&jpeg), image::ImageFormat::Jpeg);
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(width);
        limits.max_image_height = Some(height);
        limits.max_alloc = Some(width as u64 * height as u64 * 8 + (1 << 20));
        reader.limits(limits);
        let decoded = reader
            .decode()
            .map_err(|e| Error::Image(format!("backdrop: not a readable JPEG ({e})")))?;
        if decoded.width() != width || decoded.height() != height {
            return Err(Error::Image(format!(
                "backdrop: the JPEG is {}x{}, the model says {width}x{height}",
                decoded.width(),
                decoded.height()
            )));
        }
        let rgba = decoded.to_rgba8().into_raw();
        Ok(Backdrop {
            width,
            height,
            rgba,
            landmarks,
            jpeg,
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

    /// The decoded picture, RGBA8 (opaque), row-major.
    pub fn rgba(&self) -> &[u8] {
        &self.rgba
    }

    /// The picture as an [`ImageRef`].
    pub fn image(&self) -> ImageRef<'_> {
        // The size was checked when the backdrop was made, and `rgba` is its decoding.
        ImageRef::new(self.width, self.height, &self.rgba)
            .expect("a backdrop's size and pixels agree by construction")
    }

    /// The face's landmarks in the picture (image pixels, interleaved `x, y`).
    pub fn landmarks(&self) -> &[f32] {
        &self.landmarks
    }

    /// The compressed bytes (baseline JPEG) the model file stores.
    pub fn jpeg(&self) -> &[u8] {
        &self.jpeg
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wasm_bindgen_test::wasm_bindgen_test;

    fn gradient(w: u32, h: u32) -> Vec<u8> {
        let mut v = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h {
            for x in 0..w {
                v.extend_from_slice(&[(x * 255 / w) as u8, (y * 255 / h) as u8, 128, 255]);
            }
        }
        v
    }

    #[wasm_bindgen_test(unsupported = test)]
    fn encode_decode_round_trip() {
        let px = gradient(64, 48);
        let img = ImageRef::new(64, 48, &px).unwrap();
        let lm = vec![10.0, 10.0, 50.0, 10.0, 30.0, 40.0];
        let b = Backdrop::encode(&img, &lm).unwrap();
        assert!(b.jpeg().len() <= backdrop_budget(64, 48));
        let again = Backdrop::decode(64, 48, lm.clone(), b.jpeg().to_vec()).unwrap();
        assert_eq!(again, b);
        // A smooth gradient survives JPEG within a few levels.
        let worst = px
            .iter()
            .zip(b.rgba())
            .map(|(a, b)| (*a as i32 - *b as i32).abs())
            .max()
            .unwrap();
        assert!(worst <= 8, "worst {worst}");
    }

    #[wasm_bindgen_test(unsupported = test)]
    fn bad_backdrops_are_errors() {
        let px = gradient(64, 48);
        let img = ImageRef::new(64, 48, &px).unwrap();
        let outside = vec![10.0, 10.0, 70.0, 10.0, 30.0, 40.0];
        let e = Backdrop::encode(&img, &outside).unwrap_err().to_string();
        assert!(e.contains("outside"), "{e}");
        let nan = vec![10.0, f32::NAN, 50.0, 10.0, 30.0, 40.0];
        assert!(Backdrop::encode(&img, &nan).is_err());
        let lm = vec![10.0, 10.0, 50.0, 10.0, 30.0, 40.0];
        let e = Backdrop::decode(64, 48, lm.clone(), b"not a jpeg".to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("JPEG"), "{e}");
        let good = Backdrop::encode(&img, &lm).unwrap();
        // A picture of another size than the model states (larger: the decoder's limits refuse
        // it; smaller: the size check does).
        let e = Backdrop::decode(64, 44, lm.clone(), good.jpeg().to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("backdrop"), "{e}");
        let e = Backdrop::decode(64, 60, lm.clone(), good.jpeg().to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("64x48"), "{e}");
        // A small file stating a huge picture is refused before decoding.
        let e = Backdrop::decode(4096, 4096, lm.clone(), good.jpeg().to_vec())
            .unwrap_err()
            .to_string();
        assert!(e.contains("implausible"), "{e}");
        let mut cut = good.jpeg().to_vec();
        cut.truncate(cut.len() / 2);
        // A truncated JPEG either fails or decodes to the stated size; never panics.
        let _ = Backdrop::decode(64, 48, lm, cut);
    }
}

//! The grey image a fit samples: a grey-level (or grey + chroma) copy of the frame, reused
//! between fits, a smoothed copy of the region around the face for the coarse levels, and the
//! sampling of either through the current mesh at a level's pixels.

use crate::filter::{bilinear, gaussian_kernel};
use crate::image::ImageRef;

use super::linalg::{axpy, dot};
use super::precompute::{channel_weights, Level};

/// Grey-level copy of the frame being fitted (reused between fits) and a smoothed copy of
/// the region around the face for coarse levels.
pub(super) struct Grey {
    width: usize,
    height: usize,
    /// Channel planes, each `width * height`.
    channels: usize,
    data: Vec<f32>,
    blur: Vec<f32>,
    tmp: Vec<f32>,
}

/// A grey image to sample: the full frame, or the smoothed region `[x0, x1] x [y0, y1]`.
#[derive(Clone, Copy)]
pub(super) struct GreyView<'a> {
    data: &'a [f32],
    stride: usize,
    plane: usize,
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
}

impl Grey {
    /// An empty grey image of `channels` planes (sized by the first [`Grey::load`]).
    pub(super) fn new(channels: usize) -> Grey {
        Grey {
            width: 0,
            height: 0,
            channels,
            data: Vec::new(),
            blur: Vec::new(),
            tmp: Vec::new(),
        }
    }

    /// Loads `image` as grey (and chroma) planes in `0..=1`.
    pub(super) fn load(&mut self, image: &ImageRef<'_>) {
        self.width = image.width() as usize;
        self.height = image.height() as usize;
        let len = self.width * self.height;
        if self.data.len() != len * self.channels {
            self.data.resize(len * self.channels, 0.0);
            self.blur.resize(len * self.channels, 0.0);
            self.tmp.resize(len, 0.0);
        }
        for (c, wc) in channel_weights(self.channels).iter().enumerate() {
            let k = [wc[0] / 255.0, wc[1] / 255.0, wc[2] / 255.0];
            let plane = &mut self.data[c * len..(c + 1) * len];
            for (o, px) in plane.iter_mut().zip(image.data().chunks_exact(4)) {
                *o = k[0] * px[0] as f32 + k[1] * px[1] as f32 + k[2] * px[2] as f32;
            }
        }
    }

    /// The full frame.
    pub(super) fn full(&self) -> GreyView<'_> {
        GreyView {
            data: &self.data,
            stride: self.width,
            plane: self.width * self.height,
            x0: 0.0,
            y0: 0.0,
            x1: (self.width - 1) as f32,
            y1: (self.height - 1) as f32,
        }
    }

    /// Smooths the region around `shape` (its bounding box grown by half its size) with a
    /// Gaussian of `sigma` image pixels (separable, at most radius 24) into `blur`.
    pub(super) fn smooth(&mut self, shape: &[f32], sigma: f32) -> GreyView<'_> {
        let b = crate::geometry::BBox::of_points(shape);
        let (minx, miny, maxx, maxy) = (b.x, b.y, b.right(), b.bottom());
        let (mw, mh) = (
            0.2 * (maxx - minx) + 3.0 * sigma + 2.0,
            0.2 * (maxy - miny) + 3.0 * sigma + 2.0,
        );
        let clampx = |v: f32| {
            if v.is_finite() {
                v.clamp(0.0, (self.width - 1) as f32) as usize
            } else {
                0
            }
        };
        let clampy = |v: f32| {
            if v.is_finite() {
                v.clamp(0.0, (self.height - 1) as f32) as usize
            } else {
                0
            }
        };
        let (x0, x1) = (clampx((minx - mw).floor()), clampx((maxx + mw).ceil()));
        let (y0, y1) = (clampy((miny - mh).floor()), clampy((maxy + mh).ceil()));
        let mut kernel = [0f32; 49];
        let r = gaussian_kernel(sigma, 2.5, 24, &mut kernel);
        let w = self.width;
        let len = w * self.height;
        for c in 0..self.channels {
            let data = &self.data[c * len..(c + 1) * len];
            let blur = &mut self.blur[c * len..(c + 1) * len];
            let k = &kernel[..=2 * r];
            // Horizontal pass (clamped at the region's edges): a window dot product inside.
            for y in y0..=y1 {
                let row = &data[y * w..(y + 1) * w];
                let out = &mut self.tmp[y * w..(y + 1) * w];
                for x in x0..=x1 {
                    out[x] = if x >= x0 + r && x + r <= x1 {
                        dot(k, &row[x - r..=x + r])
                    } else {
                        let mut acc = 0.0;
                        for (i, kv) in k.iter().enumerate() {
                            acc += kv * row[(x + i).saturating_sub(r).clamp(x0, x1)];
                        }
                        acc
                    };
                }
            }
            // Vertical pass: each output row is a weighted sum of (clamped) input rows.
            for y in y0..=y1 {
                let out = &mut blur[y * w + x0..=y * w + x1];
                out.iter_mut().for_each(|v| *v = 0.0);
                for (i, kv) in k.iter().enumerate() {
                    let yy = (y + i).saturating_sub(r).clamp(y0, y1);
                    axpy(*kv, &self.tmp[yy * w + x0..=yy * w + x1], out);
                }
            }
        }
        GreyView {
            data: &self.blur,
            stride: w,
            plane: len,
            x0: x0 as f32,
            y0: y0 as f32,
            x1: x1 as f32,
            y1: y1 as f32,
        }
    }
}

impl GreyView<'_> {
    /// Bilinear sample, clamped to the view's region (the crate's one bilinear rule,
    /// [`bilinear`]).
    #[inline]
    fn sample(&self, x: f32, y: f32, channel: usize) -> f32 {
        let b = bilinear(x, y, self.x0, self.y0, self.x1, self.y1);
        let i = channel * self.plane + b.y * self.stride + b.x;
        let (dx, dy) = (b.dx, b.dy * self.stride);
        let d = self.data;
        let top = d[i] + b.fx * (d[i + dx] - d[i]);
        let bot = d[i + dy] + b.fx * (d[i + dy + dx] - d[i + dy]);
        top + b.fy * (bot - top)
    }
}

/// Samples the grey image at the level pixels through the current mesh.
pub(super) fn sample(level: &Level, img: GreyView<'_>, shape: &[f32], out: &mut [f32]) {
    let np = level.np.max(1);
    for (c, block) in out[..level.n].chunks_exact_mut(np).enumerate() {
        for ((t, b), o) in level.verts.iter().zip(&level.bary).zip(block.iter_mut()) {
            let (a0, a1, a2) = (t[0] as usize, t[1] as usize, t[2] as usize);
            let x = b[0] * shape[2 * a0] + b[1] * shape[2 * a1] + b[2] * shape[2 * a2];
            let y = b[0] * shape[2 * a0 + 1] + b[1] * shape[2 * a1 + 1] + b[2] * shape[2 * a2 + 1];
            *o = img.sample(x, y, c);
        }
    }
}

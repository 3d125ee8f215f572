//! Resampling a frame by the fit scale, the same on every target (the CLI, the npm package):
//! a separable triangle filter, widened when shrinking so a large face is not aliased.
//!
//! The pixel convention is the crate's: pixel centres on integers, the resampled pixels covering
//! the same picture, so a point `v` of the frame is `(v + 0.5) * k - 0.5` in a copy resampled by
//! `k` ([`to_scaled`]) and back ([`from_scaled`]).

use crate::error::{Error, Result};
use crate::image::ImageRef;
use crate::similarity::Similarity;

/// `points` (frame pixels) in a copy of the frame resampled by `k`, written to `out`.
pub(crate) fn to_scaled(points: &[f32], k: f32, out: &mut [f32]) {
    for (o, v) in out.iter_mut().zip(points) {
        *o = (v + 0.5) * k - 0.5;
    }
}

/// Points of a copy resampled by `k` back in frame pixels, in place.
pub(crate) fn from_scaled(points: &mut [f32], k: f32) {
    for v in points {
        *v = (*v + 0.5) / k - 0.5;
    }
}

/// A pose placing a shape in a copy resampled by `k`, as it places it in the frame.
pub(crate) fn pose_from_scaled(p: &Similarity, k: f32) -> Similarity {
    let c = 0.5 / k - 0.5;
    Similarity {
        a: p.a / k,
        b: p.b / k,
        tx: p.tx / k + c,
        ty: p.ty / k + c,
    }
}

/// The size of a `width x height` frame resampled by `k` (at least 1 x 1).
pub(crate) fn scaled_size(width: u32, height: u32, k: f32) -> (u32, u32) {
    let side = |v: u32| ((v as f32 * k).round() as u32).max(1);
    (side(width), side(height))
}

/// The filter taps of one axis: for each output sample, `(first source index, weights)`.
#[derive(Debug, Default)]
struct Taps {
    /// For output `i`: its taps are `weights[off[i]..off[i + 1]]` on source samples
    /// `first[i]..`.
    first: Vec<u32>,
    off: Vec<u32>,
    weights: Vec<f32>,
    /// The source length, output length and scale the taps were made for.
    made_for: (u32, u32, u32),
}

impl Taps {
    /// Makes the taps for resampling `src` samples to `dst` by `k` (kept when already made).
    fn make(&mut self, src: u32, dst: u32, k: f32) {
        let key = (src, dst, k.to_bits());
        if self.made_for == key && !self.off.is_empty() {
            return;
        }
        self.made_for = key;
        self.first.clear();
        self.off.clear();
        self.weights.clear();
        self.off.push(0);
        // The triangle's half-width in source samples: 1 when enlarging, 1/k when shrinking.
        let r = (1.0 / k).max(1.0);
        let last = src as i64 - 1;
        for i in 0..dst {
            let c = (i as f32 + 0.5) / k - 0.5;
            let lo = ((c - r).floor() as i64 + 1).clamp(0, last);
            let hi = ((c + r).ceil() as i64 - 1).clamp(0, last);
            let start = self.weights.len();
            let mut sum = 0.0f32;
            for j in lo..=hi {
                let w = (1.0 - (j as f32 - c).abs() / r).max(0.0);
                self.weights.push(w);
                sum += w;
            }
            if sum <= 0.0 {
                // A sample beyond the edge: the nearest source sample.
                self.weights.truncate(start);
                let j = (c.round() as i64).clamp(0, last);
                self.first.push(j as u32);
                self.weights.push(1.0);
            } else {
                self.first.push(lo as u32);
                self.weights[start..].iter_mut().for_each(|w| *w /= sum);
            }
            self.off.push(self.weights.len() as u32);
        }
    }

    fn of(&self, i: usize) -> (usize, &[f32]) {
        let (a, b) = (self.off[i] as usize, self.off[i + 1] as usize);
        (self.first[i] as usize, &self.weights[a..b])
    }
}

/// Resamples frames by a scale into buffers kept between frames: resampling every frame of a
/// clip at the same size allocates nothing.
#[derive(Debug, Default)]
pub(crate) struct Resampler {
    x: Taps,
    y: Taps,
    /// One output row's source rows blended (`src_w` RGBA).
    acc: Vec<f32>,
    out: Vec<u8>,
    /// The stamp, scale and size of the image in `out`.
    made: Option<(u32, u32, u32, u32)>,
}

impl Resampler {
    /// `frame` resampled by `k` (`k > 0`), borrowed from the kept buffer. `stamp` names the
    /// frame: asked again for the same stamp and scale, the kept copy is returned as it is.
    pub(crate) fn resample(
        &mut self,
        frame: &ImageRef<'_>,
        k: f32,
        stamp: u32,
    ) -> Result<ImageRef<'_>> {
        if !(k.is_finite() && k > 0.0) {
            return Err(Error::Params(format!("resampling scale {k}")));
        }
        let (sw, sh) = (frame.width(), frame.height());
        let (dw, dh) = scaled_size(sw, sh, k);
        if self.made == Some((stamp, k.to_bits(), sw, sh)) {
            return ImageRef::new(dw, dh, &self.out);
        }
        self.made = None;
        self.x.make(sw, dw, k);
        self.y.make(sh, dh, k);
        let (sw, dw) = (sw as usize, dw as usize);
        let src = frame.data();
        self.out.resize(dw * dh as usize * 4, 255);
        let stride = sw * 4;
        self.acc.resize(stride, 0.0);
        for (y, line) in self.out.chunks_exact_mut(dw * 4).enumerate() {
            // The output row's source rows blended, whole rows at a time (contiguous: the loop
            // vectorises)...
            let (first, wy) = self.y.of(y);
            self.acc.fill(0.0);
            for (j, w) in wy.iter().enumerate() {
                let row = &src[(first + j) * stride..(first + j + 1) * stride];
                self.acc
                    .iter_mut()
                    .zip(row)
                    .for_each(|(a, v)| *a += w * *v as f32);
            }
            // ...then along the row, a pixel's four channels at a time.
            for (x, o) in line.chunks_exact_mut(4).enumerate() {
                let (first, wx) = self.x.of(x);
                let mut p = [0.0f32; 4];
                for (q, w) in self.acc[first * 4..].chunks_exact(4).zip(wx) {
                    for (p, q) in p.iter_mut().zip(q) {
                        *p += w * q;
                    }
                }
                o[0] = (p[0] + 0.5).clamp(0.0, 255.0) as u8;
                o[1] = (p[1] + 0.5).clamp(0.0, 255.0) as u8;
                o[2] = (p[2] + 0.5).clamp(0.0, 255.0) as u8;
                o[3] = 255;
            }
        }
        self.made = Some((stamp, k.to_bits(), frame.width(), frame.height()));
        ImageRef::new(dw as u32, dh, &self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_keeps_its_values_at_the_mapped_points() {
        // A horizontal ramp v = 4x: resampled by k, output pixel i samples x = (i + 0.5)/k - 0.5.
        let (w, h) = (40u32, 8u32);
        let mut data = vec![0u8; (w * h * 4) as usize];
        for y in 0..h {
            for x in 0..w {
                let i = ((y * w + x) * 4) as usize;
                data[i..i + 4].copy_from_slice(&[(4 * x) as u8, 100, 50, 255]);
            }
        }
        let frame = ImageRef::new(w, h, &data).unwrap();
        let mut r = Resampler::default();
        for (stamp, k) in [0.5f32, 0.25, 1.5].into_iter().enumerate() {
            let img = r.resample(&frame, k, stamp as u32).unwrap();
            assert_eq!((img.width(), img.height()), scaled_size(w, h, k));
            let dw = img.width() as usize;
            // Away from the edges the ramp is linear, so the filter keeps it exactly.
            for i in 3..dw - 3 {
                let x = (i as f32 + 0.5) / k - 0.5;
                let got = img.data()[i * 4] as f32;
                assert!(
                    (got - 4.0 * x).abs() <= 1.0,
                    "k {k}, i {i}: {got} vs {}",
                    4.0 * x
                );
                assert_eq!(img.data()[i * 4 + 1], 100);
            }
        }
        assert!(r.resample(&frame, f32::NAN, 9).is_err());
        assert!(r.resample(&frame, 0.0, 9).is_err());
    }

    #[test]
    fn points_and_poses_map_back_exactly() {
        let k = 0.4;
        let p = [10.0f32, 20.0, 33.5, 7.25];
        let mut s = [0.0f32; 4];
        to_scaled(&p, k, &mut s);
        let mut back = s;
        from_scaled(&mut back, k);
        for (a, b) in p.iter().zip(back) {
            assert!((a - b).abs() < 1e-4);
        }
        // A pose placing a shape at `s` places it at `p` once mapped back.
        let pose = Similarity::from_parts(2.0, 0.3, 5.0, -4.0);
        let shape = [1.0f32, 2.0, -3.0, 0.5];
        let (mut a, mut b) = ([0.0f32; 4], [0.0f32; 4]);
        pose.apply(&shape, &mut a);
        from_scaled(&mut a, k);
        pose_from_scaled(&pose, k).apply(&shape, &mut b);
        for (a, b) in a.iter().zip(b) {
            assert!((a - b).abs() < 1e-4);
        }
    }
}

//! The crate's one bilinear sampling rule and one Gaussian kernel, shared by the image
//! sampler ([`crate::ImageRef::sample_rgb`]), the fitter's grey image and the fitter's
//! template smoothing; and its one temporal filter, the One-Euro filter of the person-
//! independent follower (`fit::follow`).

/// Where a bilinear sample reads: the top-left pixel `(x, y)`, the fractions `fx`, `fy`
/// towards the next column and row, and the steps `dx`, `dy` (0 or 1) to them (0 on the
/// region's last column or row, so nothing outside is read).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bilinear {
    pub x: usize,
    pub y: usize,
    pub fx: f32,
    pub fy: f32,
    pub dx: usize,
    pub dy: usize,
}

/// The bilinear footprint of `(x, y)` (pixel centres on integers) clamped to the region
/// `[x0, x1] x [y0, y1]` (integral bounds, `x0 <= x1`, `y0 <= y1`); a non-finite coordinate
/// reads the region's first column or row.
#[inline]
pub(crate) fn bilinear(x: f32, y: f32, x0: f32, y0: f32, x1: f32, y1: f32) -> Bilinear {
    let x = if x.is_finite() { x.clamp(x0, x1) } else { x0 };
    let y = if y.is_finite() { y.clamp(y0, y1) } else { y0 };
    let (xi, yi) = (x as usize, y as usize);
    Bilinear {
        x: xi,
        y: yi,
        fx: x - xi as f32,
        fy: y - yi as f32,
        dx: usize::from((xi as f32) < x1),
        dy: usize::from((yi as f32) < y1),
    }
}

/// Fills `kernel[..=2r]` with a normalised Gaussian of standard deviation `sigma` and radius
/// `r = ceil(extent * sigma)` (at least 1, at most `max_radius` and what `kernel` holds);
/// returns `r`.
pub(crate) fn gaussian_kernel(
    sigma: f32,
    extent: f32,
    max_radius: usize,
    kernel: &mut [f32],
) -> usize {
    let cap = max_radius.min(kernel.len().saturating_sub(1) / 2).max(1);
    let r = ((extent * sigma).ceil() as usize).clamp(1, cap);
    let denom = (2.0 * sigma * sigma).max(1e-6);
    let mut sum = 0.0;
    for (i, k) in kernel[..=2 * r].iter_mut().enumerate() {
        let d = i as f32 - r as f32;
        *k = (-(d * d) / denom).exp();
        sum += *k;
    }
    kernel[..=2 * r].iter_mut().for_each(|k| *k /= sum);
    r
}

/// The One-Euro filter (Casiez, Roussel & Vogel, CHI 2012) of a vector of values: each value
/// is low-passed with a cutoff that rises with its speed, `fc = min_cutoff + beta |dx/dt|`, so
/// a still signal is smoothed hard (jitter removed) and a fast one followed with little lag.
/// The speed is itself low-passed at `d_cutoff`. `scale` divides the speeds (the face's size,
/// so one `beta` suits faces near and far).
///
/// Holds its state in buffers sized by [`OneEuro::reset`]; [`OneEuro::filter`] allocates
/// nothing.
#[derive(Clone, Debug, Default)]
pub(crate) struct OneEuro {
    prev: Vec<f32>,
    speed: Vec<f32>,
    primed: bool,
}

/// The exponential smoothing factor of a first-order low-pass at `cutoff` Hz for a step of
/// `dt` seconds (Casiez et al.'s `alpha`).
#[inline]
fn smoothing(cutoff: f32, dt: f32) -> f32 {
    let tau = 1.0 / (2.0 * std::f32::consts::PI * cutoff.max(1e-6));
    1.0 / (1.0 + tau / dt)
}

impl OneEuro {
    /// Forgets the signal: the next [`OneEuro::filter`] passes its values through.
    pub fn reset(&mut self, len: usize) {
        self.prev.clear();
        self.prev.resize(len, 0.0);
        self.speed.clear();
        self.speed.resize(len, 0.0);
        self.primed = false;
    }

    /// Filters `x` in place, `dt` seconds after the previous call (`dt` must be positive and
    /// finite; `x.len()` the length given to [`OneEuro::reset`], else `x` is left as is and
    /// the filter restarts from it).
    pub fn filter(
        &mut self,
        x: &mut [f32],
        dt: f32,
        min_cutoff: f32,
        beta: f32,
        d_cutoff: f32,
        scale: f32,
    ) {
        if !self.primed || x.len() != self.prev.len() || !(dt > 0.0 && dt.is_finite()) {
            if x.len() != self.prev.len() {
                self.reset(x.len());
            }
            self.prev.copy_from_slice(x);
            self.speed.iter_mut().for_each(|v| *v = 0.0);
            self.primed = true;
            return;
        }
        let ad = smoothing(d_cutoff, dt);
        let inv = 1.0 / scale.max(1e-6);
        for ((v, p), s) in x.iter_mut().zip(&mut self.prev).zip(&mut self.speed) {
            *s += ad * ((*v - *p) / dt - *s);
            let a = smoothing(min_cutoff + beta * s.abs() * inv, dt);
            *p += a * (*v - *p);
            *v = *p;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_normalised_and_symmetric() {
        let mut k = [0f32; 49];
        let r = gaussian_kernel(2.0, 2.5, 24, &mut k);
        assert_eq!(r, 5);
        let s: f32 = k[..=2 * r].iter().sum();
        assert!((s - 1.0).abs() < 1e-5);
        for i in 0..r {
            assert_eq!(k[i], k[2 * r - i]);
        }
        assert_eq!(gaussian_kernel(100.0, 3.0, 24, &mut k), 24);
    }

    #[test]
    fn bilinear_stays_inside() {
        let b = bilinear(9.7, -3.0, 0.0, 0.0, 9.0, 4.0);
        assert_eq!((b.x, b.y, b.dx, b.dy), (9, 0, 0, 1));
        let b = bilinear(f32::NAN, 2.5, 1.0, 0.0, 9.0, 4.0);
        assert_eq!((b.x, b.y), (1, 2));
        assert!((b.fy - 0.5).abs() < 1e-6);
    }

    #[test]
    fn one_euro_smooths_jitter_and_follows_a_step() {
        let mut f = OneEuro::default();
        f.reset(1);
        let mut x = [0.0f32];
        f.filter(&mut x, 0.04, 1.0, 0.5, 1.0, 1.0);
        assert_eq!(x[0], 0.0);
        // Jitter of +-1 is damped to well under 1.
        let mut worst = 0.0f32;
        for i in 0..50 {
            let mut v = [if i % 2 == 0 { 1.0 } else { -1.0 }];
            f.filter(&mut v, 0.04, 1.0, 0.0, 1.0, 1.0);
            worst = worst.max(v[0].abs());
        }
        assert!(worst < 0.5, "{worst}");
        // A large step is followed within a few frames when beta is large.
        let mut v = [0.0f32];
        for _ in 0..5 {
            v = [100.0];
            f.filter(&mut v, 0.04, 1.0, 1.0, 1.0, 1.0);
        }
        assert!(v[0] > 90.0, "{}", v[0]);
        // A bad step restarts from the values.
        let mut w = [7.0f32];
        f.filter(&mut w, f32::NAN, 1.0, 1.0, 1.0, 1.0);
        assert_eq!(w[0], 7.0);
    }
}

//! The crate's one bilinear sampling rule and one Gaussian kernel, shared by the image
//! sampler ([`crate::ImageRef::sample_rgb`]), the fitter's grey image and the fitter's
//! template smoothing.

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
}

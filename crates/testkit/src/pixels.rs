//! Comparing rendered images: the golden images, the two rasterisers, the canvas paths.

/// How two images of interleaved 8-bit values differ.
pub struct PixelDiff {
    /// Pixels compared.
    pub pixels: usize,
    /// Pixels with a value that differs by more than the tolerance.
    pub differing: usize,
    /// The largest difference of one value, in levels.
    pub worst: i32,
}

impl PixelDiff {
    /// The share of the pixels that differ.
    pub fn share(&self) -> f64 {
        self.differing as f64 / self.pixels.max(1) as f64
    }
}

/// Compares `a` and `b` (`channels` values a pixel, equal lengths) pixel by pixel: a pixel differs
/// when one of its values differs by more than `tolerance` levels.
pub fn pixel_diff(a: &[u8], b: &[u8], channels: usize, tolerance: i32) -> PixelDiff {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    let (mut differing, mut worst) = (0, 0);
    for (p, q) in a.chunks_exact(channels).zip(b.chunks_exact(channels)) {
        let d = p
            .iter()
            .zip(q)
            .map(|(x, y)| (*x as i32 - *y as i32).abs())
            .max()
            .unwrap_or(0);
        worst = worst.max(d);
        differing += usize::from(d > tolerance);
    }
    PixelDiff {
        pixels: a.len() / channels,
        differing,
        worst,
    }
}

/// The mean absolute difference of the values of `a` and `b`, in levels.
pub fn mean_abs_diff(a: &[u8], b: &[u8]) -> f32 {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x as f32 - *y as f32).abs())
        .sum::<f32>()
        / a.len().max(1) as f32
}

/// Whether the pixel centre `(x, y)` lies in triangle `(a, b, c)`; `margin` (in barycentric
/// units) widens (> 0) or narrows (< 0) it.
pub fn in_triangle(
    p: (f32, f32),
    a: (f32, f32),
    b: (f32, f32),
    c: (f32, f32),
    margin: f32,
) -> bool {
    let det = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
    if det.abs() < 1e-9 {
        return false;
    }
    let l1 = ((p.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (p.1 - a.1)) / det;
    let l2 = ((b.0 - a.0) * (p.1 - a.1) - (p.0 - a.0) * (b.1 - a.1)) / det;
    let l0 = 1.0 - l1 - l2;
    l0 >= -margin && l1 >= -margin && l2 >= -margin
}

/// The largest absolute difference of two appearances (or any values) of equal length.
pub fn worst_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "values of different lengths");
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// How many values of `a` differ from `b`'s by more than `tolerance`.
pub fn count_changed(a: &[f32], b: &[f32], tolerance: f32) -> usize {
    assert_eq!(a.len(), b.len(), "values of different lengths");
    a.iter()
        .zip(b)
        .filter(|(x, y)| (*x - *y).abs() > tolerance)
        .count()
}

/// Asserts that two clones `out` of one expression, from a person and from the same person
/// tinted (a colour offset of zero luminance), are the same (the tint never reaches the target,
/// within 1e-4), and that the expression changed the target's `base` appearance (more than 500
/// values by more than 0.02).
pub fn assert_tint_left_out(out: &[Vec<f32>], base: &[f32], who: &str) {
    let worst = worst_diff(&out[0], &out[1]);
    assert!(worst < 1e-4, "{who}'s tint reached the target: {worst}");
    let changed = count_changed(&out[0], base, 0.02);
    assert!(changed > 500, "{changed} values changed");
}

/// The mean absolute difference of two appearances (or any values) of equal length.
pub fn mean_abs_diff_f32(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len(), "values of different lengths");
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len().max(1) as f32
}

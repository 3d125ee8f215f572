//! The local correction: the 68 points moved towards dlib's placement by what the image shows
//! around each of them, after the constant convention offsets of `calibration.rs`.
//!
//! Supervised descent (X. Xiong and F. De la Torre, "Supervised descent method and its
//! applications to face alignment", CVPR 2013): per point, a ridge regression maps a HOG-like
//! descriptor of the patch about the point ([`local_descriptor`], in the face's own frame) to the
//! point's offset from dlib's point (in the face frame of [`super::face_frame`], as
//! [`super::face_offsets`] gives it), in cascaded stages, each from the points the stage before
//! left. Learned by `cargo run --release --example finder_data -- local` on the committed GRID
//! frames (`data/grid`, CC BY 4.0), from the finder's calibrated points and perturbed copies of
//! them; the jaw is left out (its correction made GRID's held-out halves worse). Measured in
//! docs/finding.md ("The local correction").
//!
//! The weights are a small binary file (`data/weights/local_correction.fmlc`), parsed and
//! checked by [`LocalCorrection::from_bytes`]:
//!
//! | bytes | what |
//! |---|---|
//! | 4 | magic `FMLC` |
//! | 4 | version, `u32` little-endian: 1 |
//! | 4 | stages `S`, 1..=[`MAX_STAGES`] |
//! | 4 | descriptor length, must be [`DIM`] |
//! | per stage: 4 | the patch's sample step as a fraction of the face's RMS radius (`f32`, in (0, 1]) |
//! | 4 | points `P`, 1..=68 |
//! | `P` | their indices (`u8`, strictly increasing, < 68) |
//! | `P * (DIM + 1) * 2 * 2` | per point the weights, `float16` little-endian: for each of the `DIM` features and then the constant, the x and the y offset's weight |
//!
//! Nothing may follow the last stage.

use super::calibration::{add_face_offsets, face_frame};
use crate::error::{Error, Result};
use crate::image::ImageRef;

/// Cells of the descriptor along each side of the patch.
const CELLS: usize = 4;
/// Samples along each side of a cell.
const PER: usize = 2;
/// Orientation bins of each cell (over the full circle).
const BINS: usize = 8;
/// Length of one point's descriptor ([`local_descriptor`]).
pub const DIM: usize = CELLS * CELLS * BINS;
/// Samples along each side of the patch: the cells plus a one-sample border for the gradient.
const SIDE: usize = CELLS * PER + 2;
/// At most this many stages in a weight file.
pub const MAX_STAGES: usize = 8;
/// The largest value a descriptor entry keeps before the second normalisation (Lowe's clip).
const CLIP: f32 = 0.2;

/// The shipped weights (`examples/finder_data.rs local`).
pub(crate) const SHIPPED: &[u8] = include_bytes!("../../data/weights/local_correction.fmlc");

/// One stage: which points it moves, the sample step and per point `(DIM + 1) x 2` weights.
#[derive(Clone, Debug)]
pub(super) struct Stage {
    scale: f32,
    points: Vec<u8>,
    /// Per point `(DIM + 1) * 2` values: the `DIM` features' weights for x, then for y, then
    /// the two constants (the file interleaves x and y; see [`rows`] and [`interleaved`]).
    rows: Vec<f32>,
}

/// A stage's step in (0, 1] and its 1 to 68 points, increasing and under 68; the error says
/// which is not.
pub(super) fn check_stage(scale: f32, points: &[u8]) -> std::result::Result<(), String> {
    if !(scale.is_finite() && scale > 0.0 && scale <= 1.0) {
        return Err(format!("sample step {scale} outside (0, 1]"));
    }
    if !(1..=68).contains(&points.len()) {
        return Err(format!("{} points (1..=68 allowed)", points.len()));
    }
    if points.iter().any(|&p| p >= 68) || points.windows(2).any(|w| w[0] >= w[1]) {
        return Err("point indices must be increasing and under 68".into());
    }
    Ok(())
}

impl Stage {
    /// A stage from its step, its points and their weights in the file's order (x and y
    /// interleaved per feature, the constants last), kept as the file stores them: rounded to
    /// float16. Checked as a file's stage is ([`check_stage`], `(DIM + 1) * 2` weights a
    /// point, finite as float16); the error says what is wrong.
    pub(super) fn stored(
        scale: f32,
        points: Vec<u8>,
        interleaved: &[f32],
    ) -> std::result::Result<Stage, String> {
        check_stage(scale, &points)?;
        if interleaved.len() != points.len() * (DIM + 1) * 2 {
            return Err(format!(
                "{} weights for {} points",
                interleaved.len(),
                points.len()
            ));
        }
        let weights: Vec<f32> = interleaved
            .iter()
            .map(|&w| half::f16::from_f32(w).to_f32())
            .collect();
        if weights.iter().any(|w| !w.is_finite()) {
            return Err("non-finite weights".into());
        }
        Ok(Stage {
            scale,
            points,
            rows: rows(&weights),
        })
    }

    /// Moves `points` by this stage's prediction (see [`LocalCorrection::apply`]); `false`,
    /// leaving them as they are, for a degenerate shape.
    pub(super) fn step(&self, image: &ImageRef, points: &mut [f32], sc: &mut LocalScratch) -> bool {
        if !stage_offsets(self, image, points, sc) {
            return false;
        }
        add_face_offsets(points, &sc.offsets)
    }
}

/// The learned correction: its stages, applied in order.
///
/// Represents: the stages of a supervised-descent cascade over 68 points.
/// Requires: points in dlib's iBUG order (136 values) on the image they were placed on.
/// Ensures: [`apply`](Self::apply) leaves degenerate shapes (no face frame) unchanged and never
/// makes a finite point non-finite; it allocates nothing once its scratch has grown.
#[derive(Clone, Debug)]
pub struct LocalCorrection {
    stages: Vec<Stage>,
}

/// The buffers of [`LocalCorrection::apply`], kept from call to call.
#[derive(Clone, Debug, Default)]
pub struct LocalScratch {
    patch: Vec<f32>,
    descriptor: Vec<f32>,
    offsets: Vec<f32>,
}

impl LocalCorrection {
    /// The correction shipped with the crate.
    pub fn shipped() -> Result<Self> {
        Self::from_bytes(SHIPPED)
    }

    /// Parses and checks a weight file (format in the module's documentation).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        let bad = |m: &str| Error::Weights(format!("local correction: {m}"));
        let mut r = Reader { bytes, at: 0 };
        if r.take(4).ok_or_else(|| bad("truncated header"))? != b"FMLC" {
            return Err(bad("not an FMLC file"));
        }
        let version = r.u32().ok_or_else(|| bad("truncated header"))?;
        if version != 1 {
            return Err(bad(&format!("version {version} is not supported (1 is)")));
        }
        let stages = r.u32().ok_or_else(|| bad("truncated header"))? as usize;
        if !(1..=MAX_STAGES).contains(&stages) {
            return Err(bad(&format!("{stages} stages (1..={MAX_STAGES} allowed)")));
        }
        let dim = r.u32().ok_or_else(|| bad("truncated header"))? as usize;
        if dim != DIM {
            return Err(bad(&format!("descriptor length {dim}, expected {DIM}")));
        }
        let mut out = Vec::with_capacity(stages);
        for s in 0..stages {
            let trunc = || bad(&format!("stage {s} truncated"));
            let scale = f32::from_bits(r.u32().ok_or_else(trunc)?);
            let n = r.u32().ok_or_else(trunc)? as usize;
            if n > 68 {
                return Err(bad(&format!("stage {s}: {n} points (1..=68 allowed)")));
            }
            let points = r.take(n).ok_or_else(trunc)?.to_vec();
            let raw = r.take(n * (DIM + 1) * 2 * 2).ok_or_else(trunc)?;
            let weights: Vec<f32> = raw
                .chunks_exact(2)
                .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
                .collect();
            let stage = Stage::stored(scale, points, &weights)
                .map_err(|m| bad(&format!("stage {s}: {m}")))?;
            out.push(stage);
        }
        if r.at != bytes.len() {
            return Err(bad(&format!(
                "{} bytes after the last stage",
                bytes.len() - r.at
            )));
        }
        Ok(LocalCorrection { stages: out })
    }

    /// Writes a weight file from stages given as `(step, points, weights)` (weights per point
    /// `(DIM + 1) * 2`, as the file orders them; stored as float16), checked as
    /// [`from_bytes`](Self::from_bytes) checks a file.
    pub fn to_bytes(stages: &[(f32, Vec<u8>, Vec<f32>)]) -> Result<Vec<u8>> {
        let bad = |m: String| Error::Weights(format!("local correction: {m}"));
        if !(1..=MAX_STAGES).contains(&stages.len()) {
            return Err(bad(format!(
                "{} stages (1..={MAX_STAGES} allowed)",
                stages.len()
            )));
        }
        let stages = stages
            .iter()
            .enumerate()
            .map(|(s, (scale, points, weights))| {
                Stage::stored(*scale, points.clone(), weights)
                    .map_err(|m| bad(format!("stage {s}: {m}")))
            })
            .collect::<Result<Vec<Stage>>>()?;
        Ok(LocalCorrection { stages }.to_vec())
    }

    /// The correction as a weight file (what [`from_bytes`](Self::from_bytes) reads).
    pub fn to_vec(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(b"FMLC");
        out.extend_from_slice(&1u32.to_le_bytes());
        out.extend_from_slice(&(self.stages.len() as u32).to_le_bytes());
        out.extend_from_slice(&(DIM as u32).to_le_bytes());
        for stage in &self.stages {
            out.extend_from_slice(&stage.scale.to_bits().to_le_bytes());
            out.extend_from_slice(&(stage.points.len() as u32).to_le_bytes());
            out.extend_from_slice(&stage.points);
            // The rows hold float16 values already: the conversion is exact.
            for w in interleaved(&stage.rows) {
                out.extend_from_slice(&half::f16::from_f32(w).to_le_bytes());
            }
        }
        out
    }

    /// Number of stages.
    pub fn stages(&self) -> usize {
        self.stages.len()
    }

    /// Moves the 68 `points` (dlib's order, pixels of `image`) by every stage in turn: each
    /// stage reads the descriptor of every point it moves at the points as they are, then
    /// moves them all at once. A shape with no face frame is left as it is, and so is a point
    /// whose move would not be finite.
    pub fn apply(&self, image: &ImageRef, points: &mut [f32], scratch: &mut LocalScratch) {
        for stage in &self.stages {
            if !stage.step(image, points, scratch) {
                return;
            }
        }
    }

    /// A correction of `stages` (at least one: [`LocalCorrection::learn`] makes them).
    pub(super) fn from_stages(stages: Vec<Stage>) -> LocalCorrection {
        LocalCorrection { stages }
    }
}

/// Per point, the file's interleaved weights (x, y for each feature, then the constants) as
/// rows: the x weights, the y weights, the two constants.
fn rows(interleaved: &[f32]) -> Vec<f32> {
    let mut out = Vec::with_capacity(interleaved.len());
    for w in interleaved.chunks_exact((DIM + 1) * 2) {
        out.extend(w[..2 * DIM].iter().step_by(2));
        out.extend(w[1..2 * DIM].iter().step_by(2));
        out.extend_from_slice(&w[2 * DIM..]);
    }
    out
}

/// The inverse of [`rows`].
fn interleaved(rows: &[f32]) -> Vec<f32> {
    let mut out = Vec::with_capacity(rows.len());
    for w in rows.chunks_exact((DIM + 1) * 2) {
        for j in 0..DIM {
            out.push(w[j]);
            out.push(w[DIM + j]);
        }
        out.extend_from_slice(&w[2 * DIM..]);
    }
    out
}

/// One stage's offsets for `points` into `scratch.offsets`; `false` for a degenerate shape.
fn stage_offsets(stage: &Stage, image: &ImageRef, points: &[f32], sc: &mut LocalScratch) -> bool {
    let Some((_, r, c, s)) = face_frame(points) else {
        return false;
    };
    sc.offsets.clear();
    sc.offsets.resize(136, 0.0);
    sc.descriptor.resize(DIM, 0.0);
    let step = r * stage.scale;
    for (k, &i) in stage.points.iter().enumerate() {
        let i = i as usize;
        let (x, y) = (points[2 * i], points[2 * i + 1]);
        local_descriptor(image, x, y, step, c, s, &mut sc.patch, &mut sc.descriptor);
        let w = &stage.rows[k * (DIM + 1) * 2..(k + 1) * (DIM + 1) * 2];
        let dx = w[2 * DIM] + dot(&sc.descriptor, &w[..DIM]);
        let dy = w[2 * DIM + 1] + dot(&sc.descriptor, &w[DIM..2 * DIM]);
        if dx.is_finite() && dy.is_finite() {
            sc.offsets[2 * i] = dx;
            sc.offsets[2 * i + 1] = dy;
        }
    }
    true
}

/// The dot product of two descriptors' worth of values, in eight running sums (vector code,
/// natively and in wasm32 with simd128).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 8];
    for (x, y) in a.chunks_exact(8).zip(b.chunks_exact(8)) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))
}

/// The descriptor of the patch about `(x, y)`: 10 x 10 grey samples (Rec. 601 luma, in
/// 256ths, of the bilinear RGB sample) `step` pixels apart along the face's axes (`(c, s)`:
/// the eye line's cosine and sine), their central-difference gradients binned by orientation
/// into 8 bins (linearly between the two nearest) in 4 x 4 cells of 2 x 2 samples, weighted by
/// the gradient's magnitude; then normalised to unit length, clipped at 0.2 and normalised
/// again (as SIFT does). `patch` is scratch; `out` gets 128 values (its first 128 are
/// written).
#[allow(clippy::too_many_arguments)]
pub fn local_descriptor(
    image: &ImageRef,
    x: f32,
    y: f32,
    step: f32,
    c: f32,
    s: f32,
    patch: &mut Vec<f32>,
    out: &mut [f32],
) {
    grey_patch(image, x, y, c * step, s * step, patch);
    let out = &mut out[..DIM];
    out.fill(0.0);
    const N: usize = SIDE - 2;
    let (mut m, mut fb) = ([0f32; N], [0f32; N]);
    for v in 1..SIDE - 1 {
        let above = &patch[(v - 1) * SIDE..v * SIDE];
        let row = &patch[v * SIDE..(v + 1) * SIDE];
        let below = &patch[(v + 1) * SIDE..(v + 2) * SIDE];
        // A row's gradients, magnitudes and directions (in bins) in straight lines, which the
        // compiler turns into vector code; then the votes, one by one.
        for u in 0..N {
            let gx = row[u + 2] - row[u];
            let gy = below[u + 1] - above[u + 1];
            m[u] = (gx * gx + gy * gy).sqrt();
            fb[u] = orientation(gx, gy) * (BINS as f32 / std::f32::consts::TAU);
        }
        let cells = &mut out[((v - 1) / PER) * CELLS * BINS..][..CELLS * BINS];
        for (u, (&m, &fb)) in m.iter().zip(&fb).enumerate() {
            // fb >= 0, so truncation is the floor (`f32::floor` is a libm call without SSE4.1).
            let f0 = fb as usize;
            let t = fb - f0 as f32;
            let cell = &mut cells[(u / PER) * BINS..][..BINS];
            cell[f0 % BINS] += m - m * t;
            cell[(f0 + 1) % BINS] += m * t;
        }
    }
    normalise(out);
    for x in out.iter_mut() {
        *x = if *x > CLIP { CLIP } else { *x };
    }
    normalise(out);
}

/// `v` scaled to unit length (left as it is when it is all zeros).
fn normalise(v: &mut [f32]) {
    let n2 = v.iter().map(|x| x * x).sum::<f32>();
    if n2 > 1e-12 {
        let k = 1.0 / n2.sqrt();
        v.iter_mut().for_each(|x| *x *= k);
    }
}

/// The [`SIDE`] x [`SIDE`] grey samples about `(x, y)` along the axes `(ux, uy)` (one sample
/// step along the eye line) and `(-uy, ux)`, into `patch`: per sample the bilinear blend of the
/// luma ([`LUMA`], 0..1) of the four pixels about it. A patch wholly
/// inside the image is read straight from its rows; one that is not, sample by sample with
/// the border replicated ([`ImageRef::sample_rgb`]).
fn grey_patch(image: &ImageRef, x: f32, y: f32, ux: f32, uy: f32, patch: &mut Vec<f32>) {
    patch.resize(SIDE * SIDE, 0.0);
    let half = (SIDE as f32 - 1.0) / 2.0;
    // The first sample of row v is o + v (-uy, ux); along a row each sample is (ux, uy) on.
    let (ox, oy) = (x - half * ux + half * uy, y - half * uy - half * ux);
    let end = SIDE as f32 - 1.0;
    let corners = [(0.0, 0.0), (end, 0.0), (0.0, end), (end, end)];
    let (w, h) = (image.width() as f32, image.height() as f32);
    let inside = corners.iter().all(|&(u, v)| {
        let (px, py) = (ox + u * ux - v * uy, oy + u * uy + v * ux);
        px >= 0.0 && py >= 0.0 && px < w - 1.0 && py < h - 1.0
    });
    if !inside {
        for (v, row) in patch.chunks_exact_mut(SIDE).enumerate() {
            let (rx, ry) = (ox - v as f32 * uy, oy + v as f32 * ux);
            for (u, p) in row.iter_mut().enumerate() {
                let [r, g, b] = image.sample_rgb(rx + u as f32 * ux, ry + u as f32 * uy);
                let [kr, kg, kb] = LUMA.map(|k| k as f32 / 256.0);
                *p = kr * r + kg * g + kb * b;
            }
        }
        return;
    }
    let d = image.data();
    let stride = image.width() as usize * 4;
    // Luma times 256 * 255 of the pixel at `k` of a run of two pixels' bytes.
    let lum = |p: &[u8], k: usize| {
        (LUMA[0] * p[k] as u32 + LUMA[1] * p[k + 1] as u32 + LUMA[2] * p[k + 2] as u32) as f32
    };
    for (v, row) in patch.chunks_exact_mut(SIDE).enumerate() {
        let (rx, ry) = (ox - v as f32 * uy, oy + v as f32 * ux);
        for (u, p) in row.iter_mut().enumerate() {
            let (px, py) = (rx + u as f32 * ux, ry + u as f32 * uy);
            // Inside the image (checked at the corners: the patch is convex), so truncation
            // is the floor and the pixel to the right and below exist.
            let (ix, iy) = (px as usize, py as usize);
            let (fx, fy) = (px - ix as f32, py - iy as f32);
            let i = iy * stride + ix * 4;
            let (a, b) = (&d[i..i + 8], &d[i + stride..i + stride + 8]);
            let top = lum(a, 0) + fx * (lum(a, 4) - lum(a, 0));
            let bot = lum(b, 0) + fx * (lum(b, 4) - lum(b, 0));
            *p = (top + fy * (bot - top)) * (1.0 / (256.0 * 255.0));
        }
    }
}

/// The luma weights of R, G and B in 256ths (0.301, 0.586, 0.113: Rec. 601's 0.299, 0.587,
/// 0.114 rounded), so a pixel's luma is exact in integers.
const LUMA: [u32; 3] = [77, 150, 29];

/// The gradient's direction `atan2(gy, gx) + pi`, in `[0, 2 pi]`, by a polynomial (error under
/// 2e-5 radians; `f32::atan2` is a call of libm's in wasm32, once per sample).
fn orientation(gx: f32, gy: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (gx.abs(), gy.abs());
    // Selects, not branches, so a row of them becomes vector code.
    let steep = ay > ax;
    let (lo, hi) = if steep { (ax, ay) } else { (ay, ax) };
    let z = if hi > 0.0 { lo / hi } else { 0.0 };
    let z2 = z * z;
    // atan(z) on [0, 1] (a minimax polynomial, odd in z).
    let a = z
        * (0.999_866
            + z2 * (-0.330_299_5 + z2 * (0.180_141 + z2 * (-0.085_133 + z2 * 0.020_835_1))));
    let a = if steep { FRAC_PI_2 - a } else { a };
    let a = if gx < 0.0 { PI - a } else { a };
    let a = if gy < 0.0 { -a } else { a };
    a + PI
}

/// A little-endian reader over a byte slice.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.at.checked_add(n)?;
        let s = self.bytes.get(self.at..end)?;
        self.at = end;
        Some(s)
    }

    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_matches_atan2() {
        let mut worst = 0f32;
        for k in 0..3600 {
            let t = k as f32 * 0.1f32.to_radians();
            for m in [0.01f32, 1.0, 250.0] {
                let (gx, gy) = (m * t.cos(), m * t.sin());
                let want = gy.atan2(gx) + std::f32::consts::PI;
                let got = orientation(gx, gy);
                // The two ends of the range are the same direction.
                let d = (got - want).abs();
                worst = worst.max(d.min((d - std::f32::consts::TAU).abs()));
            }
        }
        assert!(worst < 3e-5, "largest difference {worst}");
        assert_eq!(orientation(0.0, 0.0), std::f32::consts::PI);
    }

    #[test]
    fn the_shipped_weights_load() {
        let l = LocalCorrection::shipped().unwrap();
        assert!(l.stages() >= 1);
        // Read and written back, the same bytes (the rows and the file's order agree).
        assert!(l.to_vec() == SHIPPED);
        for st in &l.stages {
            assert!(
                st.points.iter().all(|&p| p >= 17),
                "the jaw is not corrected"
            );
        }
    }

    #[test]
    fn bad_files_are_refused() {
        let good = LocalCorrection::to_bytes(&[(0.03, vec![20, 30], vec![0.5; 2 * (DIM + 1) * 2])])
            .unwrap();
        assert!(LocalCorrection::from_bytes(&good).is_ok());
        let mut cases: Vec<(Vec<u8>, &str)> = vec![
            (Vec::new(), "truncated"),
            (b"FMLX".to_vec(), "not an FMLC"),
            (good[..good.len() - 1].to_vec(), "truncated"),
            ([good.clone(), vec![0]].concat(), "after the last stage"),
        ];
        let mut v = good.clone();
        v[4] = 2;
        cases.push((v, "version 2"));
        let mut v = good.clone();
        v[8..12].copy_from_slice(&99u32.to_le_bytes());
        cases.push((v, "99 stages"));
        let mut v = good.clone();
        v[12..16].copy_from_slice(&7u32.to_le_bytes());
        cases.push((v, "descriptor length 7"));
        let mut v = good.clone();
        v[16..20].copy_from_slice(&f32::NAN.to_bits().to_le_bytes());
        cases.push((v, "sample step"));
        let mut v = good.clone();
        v[20..24].copy_from_slice(&0u32.to_le_bytes());
        cases.push((v, "0 points"));
        let mut v = good.clone();
        v[24] = 40;
        cases.push((v, "increasing"));
        let mut v = good.clone();
        v[25] = 68;
        cases.push((v, "increasing"));
        let mut v = good.clone();
        v[26..28].copy_from_slice(&half::f16::NAN.to_le_bytes());
        cases.push((v, "non-finite"));
        for (bytes, want) in cases {
            let e = LocalCorrection::from_bytes(&bytes).unwrap_err().to_string();
            assert!(e.contains(want), "{e:?} should say {want:?}");
        }
    }

    #[test]
    fn bad_learning_options_are_refused() {
        use crate::find::LearnOptions;
        let d = LearnOptions::default();
        for (options, want) in [
            (
                LearnOptions {
                    points: vec![17, 68],
                    ..d.clone()
                },
                "increasing",
            ),
            (
                LearnOptions {
                    scales: vec![0.0],
                    ..d.clone()
                },
                "sample step",
            ),
            (
                LearnOptions {
                    scales: Vec::new(),
                    ..d.clone()
                },
                "0 stages",
            ),
            (
                LearnOptions {
                    stage_points: vec![None, Some(vec![48, 48])],
                    ..d.clone()
                },
                "increasing",
            ),
            (LearnOptions { ..d.clone() }, "no usable samples"),
        ] {
            let e = LocalCorrection::learn(&[], &options)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{e:?} should say {want:?}");
        }
    }

    #[test]
    fn degenerate_and_flat_input_leave_points_finite() {
        let l = LocalCorrection::shipped().unwrap();
        let data = vec![90u8; 64 * 48 * 4];
        let img = ImageRef::new(64, 48, &data).unwrap();
        let mut sc = LocalScratch::default();
        // All points in one place: no face frame, nothing moves.
        let mut p = vec![10.0f32; 136];
        l.apply(&img, &mut p, &mut sc);
        assert!(p.iter().all(|&v| v == 10.0));
        // A face shape on a flat image, partly outside it: finite points.
        let mut p: Vec<f32> = (0..68)
            .flat_map(|i| {
                let t = i as f32 * 0.37;
                [40.0 + 30.0 * t.cos(), 20.0 + 30.0 * t.sin()]
            })
            .collect();
        l.apply(&img, &mut p, &mut sc);
        assert!(p.iter().all(|v| v.is_finite()));
    }
}

/// The shipped weights are what `examples/finder_data.rs local` learns from the committed frames.
#[cfg(all(test, not(target_arch = "wasm32")))]
mod reproducible {
    use super::*;
    use crate::find::{FaceFinder, LearnOptions};
    use crate::io::{read_image, read_landmarks};

    #[test]
    fn weights_are_reproducible() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let frames: Vec<_> = crate::find::training_images(root)
            .unwrap()
            .into_iter()
            .map(|p| {
                let img = read_image(&p).unwrap();
                let truth = read_landmarks(&p.with_extension("pts"), img.width, img.height);
                (img, truth.unwrap())
            })
            .collect();
        let views: Vec<(ImageRef, &[f32])> = frames
            .iter()
            .map(|(img, t)| (img.view().unwrap(), t.as_slice()))
            .collect();
        let mut finder = FaceFinder::new().unwrap();
        let (learned, n) =
            LocalCorrection::learn_from_images(&mut finder, &views, &LearnOptions::default())
                .unwrap();
        assert!(
            n >= 890,
            "{n} samples from {} committed frames",
            frames.len()
        );
        assert!(
            finder.local_correction(),
            "the finder's setting is put back"
        );
        let shipped = LocalCorrection::shipped().unwrap();
        // The coarse first stage moves the mouth alone; the finer two every point but the
        // jaw's and the outer lips' middles.
        let points: Vec<Vec<u8>> = shipped.stages.iter().map(|s| s.points.clone()).collect();
        let all: Vec<u8> = (17..68).filter(|&p| p != 51 && p != 57).collect();
        let mouth: Vec<u8> = all.iter().copied().filter(|&p| p >= 48).collect();
        assert_eq!(points, [mouth, all.clone(), all]);
        assert_eq!(learned.stages.len(), shipped.stages.len());
        for (a, b) in learned.stages.iter().zip(&shipped.stages) {
            assert_eq!((a.scale, &a.points), (b.scale, &b.points));
            let top = b.rows.iter().fold(0f32, |m, w| m.max(w.abs()));
            let worst = a
                .rows
                .iter()
                .zip(&b.rows)
                .fold(0f32, |m, (x, y)| m.max((x - y).abs()));
            // float16 keeps about three digits: a rounding flipped here and there, no more.
            assert!(
                worst <= 2e-3 * top,
                "weights differ by {worst} (largest {top})"
            );
        }
    }
}

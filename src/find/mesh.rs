//! MediaPipe's face detector (BlazeFace, short range) and face mesh (468 points), Apache-2.0
//! (Google LLC; `data/weights/LICENSE-mediapipe`), converted by `scripts/convert-mediapipe.py`
//! and run by the crate's own layers ([`super::graph`]).
//!
//! The pre- and post-processing follow MediaPipe's graphs (v0.10.14,
//! `mediapipe/modules/face_detection/face_detection_short_range.pbtxt`,
//! `face_detection_front_detection_to_roi.pbtxt`, `face_landmark/face_landmark_cpu.pbtxt` and
//! `face_landmark_landmarks_to_roi.pbtxt`):
//!
//! - detector: the image letterboxed (centred, black) into 128x128, values in -1..1; 896 SSD
//!   anchors (`SsdAnchorsCalculator`: 4 layers, strides 8, 16, 16, 16, 2 anchors per layer and
//!   cell, fixed size 1, offset 0.5, i.e. 16x16x2 then 8x8x6); boxes and 6 keypoints decoded as
//!   `TensorsToDetectionsCalculator` does (scales 128, x/y/w/h order, scores `sigmoid` of the
//!   logit clipped to +-100, kept from 0.5), then weighted non-maximum suppression (IoU 0.3);
//! - the mesh's region: the detection's box centre, rotated so the eyes (keypoints 0 and 1) are
//!   level, a square of 1.5 times the box's longer side; from a previous mesh, its points' box
//!   centre, rotated by points 33 and 263, 1.5 times the longer side;
//! - mesh: that square resampled to 192x192 (the border replicated), values in 0..1; 468 points
//!   (x, y in the crop's pixels, z) and a face-presence logit.

use super::graph::{Graph, GraphScratch};
use super::nn::Map;
use crate::error::{Error, Result};
use crate::geometry::BBox;
use crate::image::ImageRef;

/// The detector's input side.
pub(crate) const DETECTOR_INPUT: usize = 128;
/// The mesh's input side.
pub(crate) const MESH_INPUT: usize = 192;
/// Points of the face mesh.
pub const MESH_POINTS: usize = 468;
/// Detector score below which a box is dropped (MediaPipe's `min_score_thresh`).
pub(crate) const DETECTOR_MIN_SCORE: f32 = 0.5;
/// IoU above which detections are merged (MediaPipe's `min_suppression_threshold`).
const NMS_IOU: f32 = 0.3;
/// The mesh's region is this many times the face box's longer side.
pub(crate) const ROI_SCALE: f32 = 1.5;

/// A detection: box (image pixels), score and the 6 keypoints (right eye, left eye, nose tip,
/// mouth centre, right ear tragion, left ear tragion; image pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Detection {
    pub bbox: BBox,
    pub score: f32,
    pub keypoints: [[f32; 2]; 6],
}

/// A rotated square of the image: centre, side (pixels) and angle (radians, the direction of
/// the square's x axis in the image, y pointing down).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Roi {
    pub cx: f32,
    pub cy: f32,
    pub side: f32,
    pub angle: f32,
}

impl Roi {
    /// The image point of the crop point `(u, v)` in 0..1.
    fn image_point(&self, u: f32, v: f32) -> (f32, f32) {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = ((u - 0.5) * self.side, (v - 0.5) * self.side);
        (self.cx + c * dx - s * dy, self.cy + s * dx + c * dy)
    }

    fn is_valid(&self) -> bool {
        crate::geometry::is_usable_region(&[self.cx, self.cy, self.angle], &[self.side], 4.0)
    }

    /// The mesh's region for a detection.
    pub fn from_detection(d: &Detection) -> Roi {
        let [r, l] = [d.keypoints[0], d.keypoints[1]];
        Roi {
            cx: d.bbox.x + 0.5 * d.bbox.width,
            cy: d.bbox.y + 0.5 * d.bbox.height,
            side: ROI_SCALE * d.bbox.width.max(d.bbox.height),
            angle: (l[1] - r[1]).atan2(l[0] - r[0]),
        }
    }

    /// The mesh's region for the next pass over the same face (from 468 points, interleaved
    /// x, y, z in image pixels).
    pub fn from_mesh(points: &[f32]) -> Roi {
        let b = BBox::of_pairs(points.chunks_exact(3).map(|p| (p[0], p[1])));
        let (r, l) = (&points[33 * 3..], &points[263 * 3..]);
        Roi {
            cx: b.x + 0.5 * b.width,
            cy: b.y + 0.5 * b.height,
            side: ROI_SCALE * b.width.max(b.height),
            angle: (l[1] - r[1]).atan2(l[0] - r[0]),
        }
    }
}

/// The two nets, their anchors and their buffers.
#[derive(Debug)]
pub(crate) struct MeshNets {
    detector: Graph,
    mesh: Graph,
    det_scratch: GraphScratch,
    mesh_scratch: GraphScratch,
    /// Anchor centres (x, y in 0..1 of the detector's input).
    anchors: Vec<[f32; 2]>,
    /// Decoded detections before suppression, kept between calls.
    raw: Vec<Detection>,
    /// The letterbox's scratch: per output column its input columns and weights, and the
    /// image's rows averaged across (`letterbox`).
    taps: Vec<(usize, usize, f32)>,
    rows: Vec<f32>,
    /// The mesh crop's scratch ([`crop`]).
    crop: CropScratch,
}

pub use super::graph::{BLAZEFACE_WEIGHTS, MESH_WEIGHTS};
#[cfg(all(test, not(target_arch = "wasm32")))]
pub use super::graph::{BLAZEFACE_WEIGHTS_F16, MESH_WEIGHTS_F16};

/// The SSD anchors of BlazeFace short range (see the module's documentation).
fn anchors() -> Vec<[f32; 2]> {
    let mut out = Vec::with_capacity(896);
    for (cells, per_cell) in [(16usize, 2usize), (8, 6)] {
        for row in 0..cells {
            for col in 0..cells {
                for _ in 0..per_cell {
                    out.push([
                        (col as f32 + 0.5) / cells as f32,
                        (row as f32 + 0.5) / cells as f32,
                    ]);
                }
            }
        }
    }
    out
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x.clamp(-100.0, 100.0)).exp())
}

impl MeshNets {
    /// The nets from converted weight files.
    pub fn load(detector: &[u8], mesh: &[u8]) -> Result<Self> {
        Ok(MeshNets {
            detector: Graph::load(detector, (DETECTOR_INPUT, 3))?,
            mesh: Graph::load(mesh, (MESH_INPUT, 3))?,
            det_scratch: GraphScratch::default(),
            mesh_scratch: GraphScratch::default(),
            anchors: anchors(),
            raw: Vec::new(),
            taps: Vec::new(),
            rows: Vec::new(),
            crop: CropScratch::default(),
        })
    }

    /// The detector's faces in `image` (image pixels), most confident first, into `out`.
    pub fn detect(&mut self, image: &ImageRef, min_score: f32, out: &mut Vec<Detection>) {
        out.clear();
        let (w, h) = (image.width() as f32, image.height() as f32);
        let side = w.max(h);
        // Letterbox: the image centred in a square of its longer side.
        let (x0, y0) = (0.5 * (w - side), 0.5 * (h - side));
        let n = DETECTOR_INPUT;
        if side >= n as f32 {
            letterbox(
                image,
                n,
                (&mut self.taps, &mut self.rows),
                self.det_scratch.input(),
            );
        } else {
            sample(
                image,
                |u, v| (x0 + u * side, y0 + v * side),
                side / n as f32,
                true,
                n,
                self.det_scratch.input(),
                |v| v * 2.0 - 1.0,
            );
        }
        if self.detector.run_fast(&mut self.det_scratch).is_err() {
            return;
        }
        let s = &self.det_scratch;
        let (reg16, reg8) = (s.output(&self.detector, 0), s.output(&self.detector, 1));
        let (cls16, cls8) = (s.output(&self.detector, 2), s.output(&self.detector, 3));
        if reg16.data.len() != 512 * 16
            || reg8.data.len() != 384 * 16
            || cls16.data.len() != 512
            || cls8.data.len() != 384
        {
            return;
        }
        self.raw.clear();
        let regs = reg16
            .data
            .chunks_exact(16)
            .chain(reg8.data.chunks_exact(16));
        let scores = cls16.data.iter().chain(&cls8.data);
        for ((r, &logit), a) in regs.zip(scores).zip(&self.anchors) {
            let score = sigmoid(logit);
            if !(score >= min_score) {
                continue;
            }
            let k = n as f32;
            // Normalised to the letterbox square, then to image pixels.
            let px = |x: f32| x0 + x * side;
            let py = |y: f32| y0 + y * side;
            let (cx, cy) = (r[0] / k + a[0], r[1] / k + a[1]);
            let (bw, bh) = (r[2] / k, r[3] / k);
            let mut keypoints = [[0.0; 2]; 6];
            for (j, kp) in keypoints.iter_mut().enumerate() {
                *kp = [px(r[4 + 2 * j] / k + a[0]), py(r[5 + 2 * j] / k + a[1])];
            }
            let bbox = BBox {
                x: px(cx - 0.5 * bw),
                y: py(cy - 0.5 * bh),
                width: bw * side,
                height: bh * side,
            };
            let finite = keypoints.iter().flatten().all(|v| v.is_finite());
            if finite && bbox.width > 0.0 && bbox.height > 0.0 && bbox.x.is_finite() {
                self.raw.push(Detection {
                    bbox,
                    score,
                    keypoints,
                });
            }
        }
        weighted_nms(&mut self.raw, NMS_IOU, out);
    }

    /// The mesh on the region `roi`: its face-presence score (0..1) and its 468 points
    /// (x, y, z interleaved; x, y in image pixels, z in the same scale) into `points`.
    pub fn mesh(&mut self, image: &ImageRef, roi: &Roi, points: &mut [f32]) -> Result<f32> {
        if points.len() != MESH_POINTS * 3 {
            return Err(Error::Landmarks(format!(
                "{} values, expected {}",
                points.len(),
                MESH_POINTS * 3
            )));
        }
        if !roi.is_valid() {
            return Err(Error::Image(format!("invalid face region {roi:?}")));
        }
        let n = MESH_INPUT;
        crop(image, roi, n, &mut self.crop, self.mesh_scratch.input());
        self.mesh.run_fast(&mut self.mesh_scratch)?;
        let s = &self.mesh_scratch;
        let (lm, flag) = (s.output(&self.mesh, 0), s.output(&self.mesh, 1));
        if lm.data.len() != MESH_POINTS * 3 || flag.data.len() != 1 {
            return Err(Error::Weights("unexpected mesh outputs".into()));
        }
        let k = n as f32;
        for (o, p) in points.chunks_exact_mut(3).zip(lm.data.chunks_exact(3)) {
            let (x, y) = roi.image_point(p[0] / k, p[1] / k);
            o[0] = x;
            o[1] = y;
            o[2] = p[2] / k * roi.side;
        }
        if !points.iter().all(|v| v.is_finite()) {
            return Err(Error::Image("the mesh gave non-finite points".into()));
        }
        Ok(sigmoid(flag.data[0]))
    }

    /// The nets, for the reference test.
    #[cfg(all(test, not(target_arch = "wasm32")))]
    pub fn graphs(&self) -> (&Graph, &Graph) {
        (&self.detector, &self.mesh)
    }
}

/// Samples `n x n` pixels of `image` into `out` (RGB, `norm` of values in 0..1): output pixel
/// `(ox, oy)` is the image near `at((ox + 0.5) / n, (oy + 0.5) / n)`: one bilinear sample
/// while an output pixel covers up to `step = 2` image pixels (MediaPipe's own crop is one
/// bilinear sample per pixel), else the mean of up to 4x4, `ceil(step / 2)` a side, so large
/// faces do not alias. Measured on every 4th frame of the four shared sets: the mesh's points as
/// accurate as with `ceil(step)` samples a side (0.0260 / 0.0277 / 0.0328 / 0.0286 against
/// 0.0261 / 0.0277 / 0.0329 / 0.0286), at a quarter of the samples for faces of 130-260
/// pixels. With `black_outside`, points outside the image are black; otherwise the border is
/// replicated.
fn sample(
    image: &ImageRef,
    at: impl Fn(f32, f32) -> (f32, f32),
    step: f32,
    black_outside: bool,
    n: usize,
    out: &mut Map,
    norm: impl Fn(f32) -> f32,
) {
    out.reset(n, n, 3);
    let (w, h) = (image.width() as f32, image.height() as f32);
    // Bilinear samples per output pixel along each axis: one up to two image pixels per
    // output pixel (a bilinear sample spans two), then one more per two pixels, at most 4.
    let k = ((0.5 * step).ceil() as usize).clamp(1, 4);
    let inv_n = 1.0 / n as f32;
    let inv = 1.0 / (k * k) as f32;
    for oy in 0..n {
        for ox in 0..n {
            let mut acc = [0.0f32; 3];
            for sy in 0..k {
                for sx in 0..k {
                    let u = (ox as f32 + (sx as f32 + 0.5) / k as f32) * inv_n;
                    let v = (oy as f32 + (sy as f32 + 0.5) / k as f32) * inv_n;
                    let (x, y) = at(u, v);
                    if black_outside && !(x >= 0.0 && y >= 0.0 && x < w && y < h) {
                        continue;
                    }
                    // The crate's bilinear sampler (pixel centres on integers, border clamped).
                    let px = image.sample_rgb(x - 0.5, y - 0.5);
                    for (a, p) in acc.iter_mut().zip(px) {
                        *a += p;
                    }
                }
            }
            let o = &mut out.data[(oy * n + ox) * 3..][..3];
            for c in 0..3 {
                o[c] = norm(acc[c] * inv);
            }
        }
    }
}

/// The per-column and per-row terms of a mesh crop's sample positions, and its sums
/// ([`crop`]).
#[derive(Debug, Default)]
struct CropScratch {
    /// Per sample column `j` (`n k` of them, then copies of the last up to a multiple of
    /// [`CROP_BLOCK`]): `cx + cos dx` and `cy + sin dx`.
    cols: Vec<[f32; 2]>,
    /// Per sample row `i`: `sin dy` and `cos dy`.
    rows: Vec<[f32; 2]>,
    /// One output row's sums (RGBA lanes).
    acc: Vec<[f32; 4]>,
}

/// Sample positions computed together by [`crop`] (a block of lanes the compiler vectorises).
const CROP_BLOCK: usize = 8;

/// The mesh's input: [`sample`] of the rotated square `roi` (the border replicated, values in
/// 0..1) with the same arithmetic, so the same values bit for bit, made faster: the sample
/// positions' terms that depend on the column or the row alone computed once per column and
/// row (`x = (cx + cos dx) - sin dy`, `y = (cy + sin dx) + cos dy`, the very sums [`sample`]
/// makes); the positions, their clamping and their bilinear fractions ([`ImageRef::sample_rgb`]'s
/// rule) computed [`CROP_BLOCK`] at a time; each sample reading its four pixels as RGBA vectors
/// of four lanes (the alpha lane computed and dropped) instead of twelve bytes one by one.
fn crop(image: &ImageRef, roi: &Roi, n: usize, s: &mut CropScratch, out: &mut Map) {
    out.reshape(n, n, 3);
    let step = roi.side / n as f32;
    let k = ((0.5 * step).ceil() as usize).clamp(1, 4);
    let inv_n = 1.0 / n as f32;
    let inv = 1.0 / (k * k) as f32;
    let (sin, cos) = roi.angle.sin_cos();
    let (cx, cy, side) = (roi.cx, roi.cy, roi.side);
    // `u` (and `v`) of sample column (row) `o k + t`, as `sample` computes it, then `d = (u -
    // 0.5) side`.
    let d = |j: usize| {
        let (o, t) = (j / k, j % k);
        let u = (o as f32 + (t as f32 + 0.5) / k as f32) * inv_n;
        (u - 0.5) * side
    };
    let samples = n * k;
    s.cols.clear();
    s.cols
        .extend((0..samples).map(|j| [cx + cos * d(j), cy + sin * d(j)]));
    let pad = samples.next_multiple_of(CROP_BLOCK);
    s.cols
        .resize(pad, s.cols.last().copied().unwrap_or_default());
    s.rows.clear();
    s.rows
        .extend((0..samples).map(|i| [sin * d(i), cos * d(i)]));
    s.acc.clear();
    s.acc.resize(n, [0.0; 4]);
    let (w, h) = (image.width() as usize, image.height() as usize);
    let (x1, y1) = ((w - 1) as f32, (h - 1) as f32);
    let data = image.data();
    let px = |i: usize| -> [f32; 4] {
        let p: &[u8; 4] = data[i..i + 4].try_into().unwrap();
        p.map(f32::from)
    };
    for (oy, line) in out.data.chunks_exact_mut(n * 3).enumerate() {
        s.acc.fill([0.0; 4]);
        for &[sdy, cdy] in &s.rows[oy * k..][..k] {
            // The output column and the sample within it of the next sample column.
            let (mut ox, mut sx) = (0, 0);
            for (jb, block) in s.cols.chunks_exact(CROP_BLOCK).enumerate() {
                // `filter::bilinear(x - 0.5, y - 0.5, 0, 0, x1, y1)` for the block: the
                // clamped position's integer part (exact in `i32` for any image side) and
                // fraction.
                let mut at = [[0i32; 2]; CROP_BLOCK];
                let mut frac = [[0f32; 2]; CROP_BLOCK];
                for ((&[xa, ya], at), frac) in block.iter().zip(&mut at).zip(&mut frac) {
                    let (x, y) = (xa - sdy - 0.5, ya + cdy - 0.5);
                    let x = if x.is_finite() { x.clamp(0.0, x1) } else { 0.0 };
                    let y = if y.is_finite() { y.clamp(0.0, y1) } else { 0.0 };
                    let (xi, yi) = (x as i32, y as i32);
                    *at = [xi, yi];
                    *frac = [x - xi as f32, y - yi as f32];
                }
                let real = samples.saturating_sub(jb * CROP_BLOCK).min(CROP_BLOCK);
                for (&[xi, yi], &[fx, fy]) in at.iter().zip(&frac).take(real) {
                    let (xi, yi) = (xi as usize, yi as usize);
                    // The next column and row, unless on the last (`(xi as f32) < x1`).
                    let i00 = (yi * w + xi) * 4;
                    let (i10, i01) = (
                        i00 + 4 * usize::from(xi + 1 < w),
                        i00 + 4 * w * usize::from(yi + 1 < h),
                    );
                    let i11 = i01 + i10 - i00;
                    let (p00, p10, p01, p11) = (px(i00), px(i10), px(i01), px(i11));
                    let a = &mut s.acc[ox];
                    for c in 0..4 {
                        let top = p00[c] * (1.0 - fx) + p10[c] * fx;
                        let bot = p01[c] * (1.0 - fx) + p11[c] * fx;
                        a[c] += (top * (1.0 - fy) + bot * fy) * (1.0 / 255.0);
                    }
                    sx += 1;
                    if sx == k {
                        sx = 0;
                        ox += 1;
                    }
                }
            }
        }
        for (o, a) in line.chunks_exact_mut(3).zip(&s.acc) {
            for c in 0..3 {
                o[c] = a[c] * inv;
            }
        }
    }
}

/// The detector's input from an image at least `n` pixels on its longer side: the image
/// centred in a square of its longer side (black around it), each of the `n x n` output pixels
/// the exact mean of the square's area it covers (values `2 v - 1`, `v` in 0..1). Separable:
/// the image's rows are first averaged across each output column's span (`rows`, `h x n x
/// 3`), then those down each output row's span; a span's first and last pixels count by the
/// part of them it covers. About a sixth of the work of [`sample`]'s 4x4 bilinear samples per
/// output pixel on a 640x480 frame, and an exact box filter where those approximate one.
fn letterbox(image: &ImageRef, n: usize, scratch: (&mut Taps, &mut Vec<f32>), out: &mut Map) {
    letterbox_by(image, n, scratch, out, across_rows);
}

/// Spans of [`letterbox_spans`]: `(output, input, overlap in pixels)`.
type Taps = Vec<(usize, usize, f32)>;

/// [`letterbox`] with its pass across the image's rows given: `across(data, w, taps, rows,
/// n)` sums every image row of `data` (RGBA rows of `w` pixels) into `n` RGB sums a row by the
/// column spans `taps`, into the zeroed `rows` (`h x n x 3`).
fn letterbox_by(
    image: &ImageRef,
    n: usize,
    (taps, rows): (&mut Taps, &mut Vec<f32>),
    out: &mut Map,
    across: impl Fn(&[u8], usize, &[(usize, usize, f32)], &mut [f32], usize),
) {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let side = w.max(h) as f32;
    let step = side / n as f32;
    letterbox_spans(side, step, n, w, taps);
    rows.clear();
    rows.resize(h * n * 3, 0.0);
    across(image.data(), w, taps, rows, n);
    letterbox_spans(side, step, n, h, taps);
    letterbox_down(rows, taps, n, 2.0 / (step * step * 255.0), out);
}

/// [`letterbox`]'s pass across: every image row into n columns (sums of pixel values times
/// overlaps), each output's sum made in registers (RGBA lanes, alpha dropped) in the order of
/// its taps, from 0: the sums `d += c p` into a zeroed row made, bit for bit. Four image rows
/// at a time (one pass over the taps for the four).
fn across_rows(data: &[u8], w: usize, taps: &[(usize, usize, f32)], rows: &mut [f32], n: usize) {
    let mut src = data.chunks_exact(4 * w * 4);
    let mut dst = rows.chunks_exact_mut(4 * n * 3);
    for (src, dst) in (&mut src).zip(&mut dst) {
        across::<4>(src, w, taps, dst, n);
    }
    for (src, dst) in src
        .remainder()
        .chunks_exact(w * 4)
        .zip(dst.into_remainder().chunks_exact_mut(n * 3))
    {
        across::<1>(src, w, taps, dst, n);
    }
}

/// Per output index of [`letterbox`] (`n` of them, each `step` pixels of the centred square of
/// side `side`), the input indices it covers (inside `0..len`) with their overlaps: `(output,
/// input, overlap in pixels)`, in output order, into `taps`.
fn letterbox_spans(
    side: f32,
    step: f32,
    n: usize,
    len: usize,
    taps: &mut Vec<(usize, usize, f32)>,
) {
    taps.clear();
    let off = 0.5 * (side - len as f32);
    for o in 0..n {
        let (a, b) = (o as f32 * step - off, (o + 1) as f32 * step - off);
        let (lo, hi) = (a.max(0.0), b.min(len as f32));
        if hi <= lo {
            continue;
        }
        let (first, last) = (lo.floor() as usize, (hi.ceil() as usize).min(len));
        for i in first..last {
            let cover = (hi.min((i + 1) as f32) - lo.max(i as f32)).max(0.0);
            if cover > 0.0 {
                taps.push((o, i, cover));
            }
        }
    }
}

/// [`letterbox`]'s second half: the rows' sums (`rows`, `n` RGB sums a row) into the `n`
/// output rows by the row spans `taps`, scaled by `norm` to `2 v - 1`; outside the image stays
/// black (0, i.e. -1).
fn letterbox_down(rows: &[f32], taps: &[(usize, usize, f32)], n: usize, norm: f32, out: &mut Map) {
    out.reset(n, n, 3);
    for &(o, i, c) in taps {
        let src = &rows[i * n * 3..(i + 1) * n * 3];
        let dst = &mut out.data[o * n * 3..(o + 1) * n * 3];
        for (d, s) in dst.iter_mut().zip(src) {
            *d += c * s;
        }
    }
    for v in out.data.iter_mut() {
        *v = *v * norm - 1.0;
    }
}

/// [`letterbox`]'s sums across `R` image rows (`src`, RGBA rows of `w` pixels) into `R` rows
/// of `n` RGB sums (`dst`): per output, `sum c p` over its taps `(output, input, c)` (in
/// output order) in their order, from 0.
#[inline(always)]
fn across<const R: usize>(
    src: &[u8],
    w: usize,
    taps: &[(usize, usize, f32)],
    dst: &mut [f32],
    n: usize,
) {
    let src: [&[u8]; R] = std::array::from_fn(|r| &src[r * w * 4..][..w * 4]);
    let mut rest = taps;
    while let Some(&(o, _, _)) = rest.first() {
        let len = rest.iter().take_while(|t| t.0 == o).count();
        let mut acc = [[0.0f32; 4]; R];
        for &(_, i, c) in &rest[..len] {
            for (acc, src) in acc.iter_mut().zip(&src) {
                let p: &[u8; 4] = src[i * 4..i * 4 + 4].try_into().unwrap();
                for (a, &p) in acc.iter_mut().zip(p) {
                    *a += c * f32::from(p);
                }
            }
        }
        for (r, acc) in acc.iter().enumerate() {
            dst[r * n * 3 + o * 3..][..3].copy_from_slice(&acc[..3]);
        }
        rest = &rest[len..];
    }
}

/// MediaPipe's weighted non-maximum suppression: the most confident detection and every other
/// overlapping it by more than `iou` become one, their boxes and keypoints averaged with the
/// scores as weights, the score the most confident one's. `raw` is sorted and its scores
/// overwritten.
fn weighted_nms(raw: &mut [Detection], iou: f32, out: &mut Vec<Detection>) {
    raw.sort_by(|a, b| b.score.total_cmp(&a.score));
    // A detection merged into an earlier one is marked by a negative score.
    for i in 0..raw.len() {
        if raw[i].score < 0.0 {
            continue;
        }
        let top = raw[i];
        let (mut wsum, mut b, mut kp) = (0.0f32, [0.0f32; 4], [[0.0f32; 2]; 6]);
        for j in i..raw.len() {
            if raw[j].score < 0.0 || (j != i && raw[j].bbox.iou(&top.bbox) <= iou) {
                continue;
            }
            let d = raw[j];
            raw[j].score = -1.0;
            let s = d.score;
            wsum += s;
            b[0] += s * d.bbox.x;
            b[1] += s * d.bbox.y;
            b[2] += s * d.bbox.right();
            b[3] += s * d.bbox.bottom();
            for (k, p) in kp.iter_mut().zip(&d.keypoints) {
                k[0] += s * p[0];
                k[1] += s * p[1];
            }
        }
        let inv = 1.0 / wsum;
        out.push(Detection {
            bbox: BBox {
                x: b[0] * inv,
                y: b[1] * inv,
                width: (b[2] - b[0]) * inv,
                height: (b[3] - b[1]) * inv,
            },
            score: top.score,
            keypoints: kp.map(|p| [p[0] * inv, p[1] * inv]),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An RGBA image of `w x h` pseudo-random bytes.
    fn noise(w: u32, h: u32) -> Vec<u8> {
        (0..w * h * 4)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect()
    }

    #[test]
    fn crop_is_sample_bit_for_bit() {
        for (w, h) in [(640u32, 480u32), (97, 61), (1, 1)] {
            let data = noise(w, h);
            let image = ImageRef::new(w, h, &data).unwrap();
            let mut scratch = CropScratch::default();
            for (cx, cy) in [
                (0.5 * w as f32, 0.4 * h as f32),
                (-30.0, 20.5),
                (600.0, 470.0),
            ] {
                // Steps of about 0.3 to 8 pixels an output pixel: 1 to 4 samples a side.
                for side in [57.3, 190.0, 380.0, 770.0, 1536.0] {
                    for angle in [0.0, 0.31, -2.2, std::f32::consts::PI] {
                        let roi = Roi {
                            cx,
                            cy,
                            side,
                            angle,
                        };
                        let (sin, cos) = angle.sin_cos();
                        let mut want = Map::default();
                        sample(
                            &image,
                            |u, v| {
                                let (dx, dy) = ((u - 0.5) * side, (v - 0.5) * side);
                                (cx + cos * dx - sin * dy, cy + sin * dx + cos * dy)
                            },
                            side / 48.0,
                            false,
                            48,
                            &mut want,
                            |v| v,
                        );
                        let mut got = Map {
                            data: vec![f32::NAN; 10],
                            ..Map::default()
                        };
                        crop(&image, &roi, 48, &mut scratch, &mut got);
                        assert_eq!((got.h, got.w, got.c), (48, 48, 3));
                        for (i, (a, b)) in got.data.iter().zip(&want.data).enumerate() {
                            assert_eq!(a.to_bits(), b.to_bits(), "{w}x{h} {roi:?} value {i}");
                        }
                    }
                }
            }
        }
    }

    /// The pass across as first written (`d += c p` into zeroed rows, tap by tap): with it,
    /// [`letterbox_by`] gives what [`letterbox`] must give bit for bit.
    fn across_plain(
        data: &[u8],
        w: usize,
        taps: &[(usize, usize, f32)],
        rows: &mut [f32],
        n: usize,
    ) {
        for (src, dst) in data.chunks_exact(w * 4).zip(rows.chunks_exact_mut(n * 3)) {
            for &(o, i, c) in taps {
                let p = &src[i * 4..i * 4 + 3];
                let d = &mut dst[o * 3..o * 3 + 3];
                d[0] += c * f32::from(p[0]);
                d[1] += c * f32::from(p[1]);
                d[2] += c * f32::from(p[2]);
            }
        }
    }

    #[test]
    fn letterbox_is_the_plain_sums_bit_for_bit() {
        let (mut taps, mut rows) = (Vec::new(), Vec::new());
        for (w, h) in [
            (640u32, 480u32),
            (480, 640),
            (129, 200),
            (128, 128),
            (301, 300),
        ] {
            let data = noise(w, h);
            let image = ImageRef::new(w, h, &data).unwrap();
            let mut want = Map::default();
            letterbox_by(&image, 128, (&mut taps, &mut rows), &mut want, across_plain);
            let mut got = Map {
                data: vec![f32::NAN; 10],
                ..Map::default()
            };
            letterbox(&image, 128, (&mut taps, &mut rows), &mut got);
            assert_eq!((got.h, got.w, got.c), (128, 128, 3));
            for (i, (a, b)) in got.data.iter().zip(&want.data).enumerate() {
                assert_eq!(a.to_bits(), b.to_bits(), "{w}x{h} value {i}");
            }
        }
    }
}

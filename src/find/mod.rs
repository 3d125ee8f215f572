//! Face finding: every face in an image, with a box, a confidence and the 68 iBUG landmarks.
//!
//! Two small pretrained nets from face-api.js (MIT; see `data/weights/LICENSE`), run by a
//! focused implementation of exactly their layers (`nn.rs`): the tiny face detector proposes
//! boxes, the 68-point landmark net places the points in each box, and a second landmark pass
//! on a box made from the first pass's points settles them. See `docs/finding.md` for the
//! measured rates and why the pipeline is what it is.

mod calibration;
#[cfg(feature = "mesh-finder")]
mod graph;
#[cfg(feature = "mesh-finder")]
mod mesh;
#[cfg(feature = "mesh-finder")]
mod mesh_finder;
#[cfg(feature = "mesh-finder")]
mod mesh_table;
mod nets;
mod nn;
mod weights;

#[cfg(all(feature = "mesh-finder", not(target_arch = "wasm32")))]
pub use graph::{profile_mesh_nets, NetProfile};
#[cfg(feature = "mesh-finder")]
pub use mesh::MESH_POINTS;
#[cfg(feature = "mesh-finder")]
pub use mesh_finder::MeshFinder;

pub use calibration::{
    add_face_offsets, convention_free_errors, face_frame, face_offsets, mean_face_offsets,
    NET_OFFSETS,
};

use crate::error::{Error, Result};
use crate::image::ImageRef;
use nets::{Detector, LandmarkNet, Scratch, ANCHORS, DETECTOR_MEAN, LANDMARK_INPUT, LANDMARK_MEAN};
use nn::Map;

/// The tiny face detector's weights (uint8-quantised, `scripts/convert-weights.mjs`).
pub const DETECTOR_WEIGHTS: &[u8] = include_bytes!("../../data/weights/tiny_face_detector.fmw");
/// The 68-point landmark net's weights.
pub const LANDMARK_WEIGHTS: &[u8] = include_bytes!("../../data/weights/face_landmark_68.fmw");

pub use crate::geometry::BBox;

/// The finder's boxes.
impl BBox {
    /// The box the detector would give for a face with these 68 landmarks: centred on the
    /// points' box (0.025 of its height higher), 1.27 times its width and 1.14 times its height
    /// (the mean relation between the detector's boxes and the dlib landmarks' boxes, measured on
    /// GRID, franck-dev and webcam-dev frames; see `docs/finding.md`).
    pub fn around_landmarks(points: &[f32]) -> BBox {
        let b = BBox::of_points(points);
        let (cx, cy) = (b.x + 0.5 * b.width, b.y + (0.5 - 0.025) * b.height);
        let (w, h) = (1.27 * b.width, 1.14 * b.height);
        BBox {
            x: cx - 0.5 * w,
            y: cy - 0.5 * h,
            width: w,
            height: h,
        }
    }

    fn is_valid(&self) -> bool {
        crate::geometry::is_usable_region(&[self.x, self.y], &[self.width, self.height], 1.0)
    }
}

/// Landmark passes per detector box at most (see [`FaceFinder::find`]).
const REFINE_PASSES: usize = 3;

/// One face found in an image.
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    /// The face's box (from the detector, or the landmarks' box refined).
    pub bbox: BBox,
    /// Confidence in 0..=1.
    pub score: f32,
    /// The 68 iBUG landmarks, interleaved `x0, y0, ... x67, y67`, image pixels (0-based).
    pub landmarks: Vec<f32>,
}

/// Tuning of [`FaceFinder::find`].
#[derive(Clone, Copy, Debug)]
pub struct FindOptions {
    /// The detector's input side (a multiple of 32); the image is scaled so its longer side
    /// fits it.
    pub input_size: u32,
    /// The detector's input side for a first, quicker pass (a multiple of 32; 0 for none): when
    /// it confirms a face, its faces are the result and the `input_size` pass is skipped. At
    /// 256 on a 640x480 frame it finds faces down to about 100 px wide; a much smaller face
    /// beside a larger one is then missed (set 0 to always search at `input_size`).
    pub quick_input_size: u32,
    /// Detector confidence below which a box is not considered.
    pub score_threshold: f32,
    /// Boxes overlapping a more confident one by more than this IoU are dropped.
    pub iou_threshold: f32,
    /// At most this many faces are returned.
    pub max_faces: usize,
    /// At most this many detector boxes (most confident first) are checked by the landmark net.
    pub max_candidates: usize,
    /// A box is a face only if its last two landmark passes differ by at most this (mean point
    /// distance over the distance between the outer eye corners, points 36 and 45).
    pub max_disagreement: f32,
    /// A face is reported only if its score (the detector's, lowered by the disagreement of
    /// its last two landmark passes) is at least this. The detector searches from
    /// `score_threshold` so that faces it is unsure of get their landmark check; the lettering,
    /// logos and fabric it also proposes there and whose passes happen to agree score 0.01-0.10
    /// (`tests/no_face.rs`), every face of the shared clips 0.25 or more (docs/finding.md).
    pub min_face_score: f32,
}

impl Default for FindOptions {
    fn default() -> Self {
        FindOptions {
            input_size: 416,
            quick_input_size: 256,
            score_threshold: 0.05,
            iou_threshold: 0.4,
            max_faces: 16,
            max_candidates: 10,
            max_disagreement: 0.05,
            min_face_score: 0.15,
        }
    }
}

/// Finds faces and places their landmarks. Holds the nets and all scratch buffers: reuse one
/// finder (after the first call, `find` and `landmarks` allocate only their results).
pub struct FaceFinder {
    detector: Detector,
    landmark_net: LandmarkNet,
    options: FindOptions,
    scratch: Scratch,
    input: Map,
    grid: Map,
    raw: [f32; 136],
    /// The scratch landmark pass of `refine`.
    pass: Vec<f32>,
    candidates: Vec<(BBox, f32)>,
    /// Whether results are moved onto the dlib convention (`calibration`); off only to
    /// measure the offsets.
    calibrate: bool,
}

impl FaceFinder {
    /// A finder with the weights shipped in the crate.
    pub fn new() -> Result<Self> {
        Self::from_weights(DETECTOR_WEIGHTS, LANDMARK_WEIGHTS)
    }

    /// A finder from weight files in the `scripts/convert-weights.mjs` format.
    pub fn from_weights(detector: &[u8], landmarks: &[u8]) -> Result<Self> {
        Ok(FaceFinder {
            detector: Detector::load(detector)?,
            landmark_net: LandmarkNet::load(landmarks)?,
            options: FindOptions::default(),
            scratch: Scratch::default(),
            input: Map::default(),
            grid: Map::default(),
            raw: [0.0; 136],
            pass: Vec::new(),
            candidates: Vec::new(),
            calibrate: true,
        })
    }

    /// Whether the points are moved onto the dlib convention (the default); switched off only
    /// to measure that calibration (`examples/finder_data.rs calibration`).
    pub fn set_calibrated(&mut self, on: bool) {
        self.calibrate = on;
    }

    /// The options [`find`](Self::find) uses.
    pub fn options(&self) -> FindOptions {
        self.options
    }

    /// Sets the options (`input_size` is rounded to a multiple of 32 in 64..=1024, and
    /// `quick_input_size` too unless it is 0).
    pub fn set_options(&mut self, mut options: FindOptions) {
        options.input_size = (options.input_size.clamp(64, 1024) / 32) * 32;
        if options.quick_input_size != 0 {
            options.quick_input_size = (options.quick_input_size.clamp(64, 1024) / 32) * 32;
        }
        if !options.score_threshold.is_finite() {
            options.score_threshold = FindOptions::default().score_threshold;
        }
        if !options.iou_threshold.is_finite() {
            options.iou_threshold = FindOptions::default().iou_threshold;
        }
        if !options.min_face_score.is_finite() {
            options.min_face_score = FindOptions::default().min_face_score;
        }
        self.options = options;
    }

    /// Every face in `image`, most confident first.
    ///
    /// The detector proposes boxes down to [`FindOptions::score_threshold`], first at
    /// [`FindOptions::quick_input_size`] and, only when that confirms no face, at
    /// [`FindOptions::input_size`]. On each box (skipping boxes that overlap a face already
    /// confirmed) the landmark net runs three times, each pass on the box of the previous
    /// pass's points ([`BBox::around_landmarks`]), and a box is kept as a face only if its last
    /// two passes agree ([`FindOptions::max_disagreement`]): a face's points settle, a
    /// non-face's wander. The score is the detector's, lowered by the disagreement, and only
    /// faces scoring [`FindOptions::min_face_score`] or more are reported. A face the quick
    /// pass is unsure of (agreeing passes, a score below that floor: a small face, which the
    /// detector sees at a few pixels there) sends the search on to `input_size` too, whose
    /// faces are added where they are not already found.
    pub fn find(&mut self, image: &ImageRef) -> Vec<Face> {
        let floor = self.options.min_face_score;
        let quick = self.options.quick_input_size;
        let mut sure = Vec::new();
        if quick != 0 && quick < self.options.input_size {
            let faces = self.find_at(image, quick);
            let unsure = faces.iter().any(|f| f.score < floor);
            sure.extend(faces.into_iter().filter(|f| f.score >= floor));
            if !sure.is_empty() && !unsure {
                return sure;
            }
        }
        for face in self.find_at(image, self.options.input_size) {
            if face.score >= floor
                && !sure
                    .iter()
                    .any(|f| f.bbox.iou(&face.bbox) > self.options.iou_threshold)
            {
                sure.push(face);
            }
        }
        sure.sort_by(|a, b| b.score.total_cmp(&a.score));
        sure.truncate(self.options.max_faces);
        sure
    }

    /// [`find`](Self::find) with the detector at one input side.
    fn find_at(&mut self, image: &ImageRef, input_size: u32) -> Vec<Face> {
        self.detect(image, input_size);
        let candidates = std::mem::take(&mut self.candidates);
        let mut faces: Vec<Face> = Vec::with_capacity(candidates.len());
        for &(bbox, score) in candidates.iter().take(self.options.max_candidates) {
            // A box over a face already confirmed (a second detection of it) costs no passes.
            if faces
                .iter()
                .any(|f| f.bbox.iou(&bbox) > self.options.iou_threshold)
            {
                continue;
            }
            let Some((face, disagreement)) = self.refine(image, bbox, score) else {
                continue;
            };
            if disagreement > self.options.max_disagreement {
                continue;
            }
            if faces
                .iter()
                .any(|f| f.bbox.iou(&face.bbox) > self.options.iou_threshold)
            {
                continue;
            }
            let mut face = face;
            if self.calibrate {
                calibration::apply(&mut face.landmarks);
            }
            faces.push(face);
        }
        faces.sort_by(|a, b| b.score.total_cmp(&a.score));
        faces.truncate(self.options.max_faces);
        self.candidates = candidates;
        faces
    }

    /// Landmark passes from a detector box, each on the box of the previous pass's points,
    /// until two successive passes agree within [`FindOptions::max_disagreement`] (two passes
    /// when the detector's box was good, three at most); the face (the last pass) and the
    /// disagreement of the last two passes (mean point distance over the outer-eye-corner
    /// distance).
    fn refine(&mut self, image: &ImageRef, bbox: BBox, score: f32) -> Option<(Face, f32)> {
        // `prev` becomes the face's landmarks (the result); `cur` is the finder's scratch pass,
        // kept between calls, so nothing else is allocated.
        let mut prev = vec![0.0; 136];
        self.net_landmarks_into(image, bbox, &mut prev).ok()?;
        let mut cur = std::mem::take(&mut self.pass);
        cur.resize(136, 0.0);
        let d = self.settle(image, &mut prev, &mut cur);
        self.pass = cur;
        let d = d?;
        let face = Face {
            bbox: BBox::around_landmarks(&prev),
            score: score
                * (1.0 - d / self.options.max_disagreement)
                    .clamp(0.0, 1.0)
                    .sqrt(),
            landmarks: prev,
        };
        Some((face, d))
    }

    /// Landmark passes after `prev` (the first), each on the box of the previous pass's points,
    /// until two successive passes agree within [`FindOptions::max_disagreement`] or
    /// [`REFINE_PASSES`] have run; leaves the last pass in `prev` and returns the disagreement
    /// of the last two (`None` on a failed or non-finite pass).
    fn settle(&mut self, image: &ImageRef, prev: &mut [f32], cur: &mut [f32]) -> Option<f32> {
        let mut d = f32::INFINITY;
        for _ in 0..REFINE_PASSES - 1 {
            let b = BBox::around_landmarks(prev);
            self.net_landmarks_into(image, b, cur).ok()?;
            d = landmark_error(prev, cur);
            if !d.is_finite() {
                return None;
            }
            prev.copy_from_slice(cur);
            if d <= self.options.max_disagreement {
                break;
            }
        }
        Some(d)
    }

    /// The detector's boxes and scores (after non-maximum suppression), most confident first,
    /// into `self.candidates`.
    fn detect(&mut self, image: &ImageRef, input_size: u32) {
        let s = input_size as usize;
        let side = image.width().max(image.height()) as f32;
        prepare(
            image,
            [0.0, 0.0, side],
            [0.0, 0.0, image.width() as f32, image.height() as f32],
            s,
            DETECTOR_MEAN,
            &mut self.input,
        );
        self.detector
            .run(&self.input, &mut self.scratch, &mut self.grid);
        decode(
            &self.grid,
            side,
            self.options.score_threshold,
            &mut self.candidates,
        );
        nms(&mut self.candidates, self.options.iou_threshold);
    }

    /// The 68 landmarks of the face in `bbox` (interleaved, image pixels): the landmark net on
    /// the square around `bbox`, its points moved onto the dlib convention by the mean offsets
    /// measured on GRID (see `src/find/calibration.rs`), as are those of [`find`](Self::find).
    pub fn landmarks(&mut self, image: &ImageRef, bbox: BBox) -> Result<Vec<f32>> {
        let mut out = vec![0.0; 136];
        self.landmarks_into(image, bbox, &mut out)?;
        Ok(out)
    }

    /// [`landmarks`](Self::landmarks) into a caller's buffer of 136 values.
    pub fn landmarks_into(&mut self, image: &ImageRef, bbox: BBox, out: &mut [f32]) -> Result<()> {
        self.net_landmarks_into(image, bbox, out)?;
        if self.calibrate {
            calibration::apply(out);
        }
        Ok(())
    }

    /// The landmark net's own points for the face in `bbox` (before the convention offsets of
    /// `calibration`): what the passes of [`find`](Self::find) compare.
    fn net_landmarks_into(&mut self, image: &ImageRef, bbox: BBox, out: &mut [f32]) -> Result<()> {
        if out.len() != 136 {
            return Err(Error::Landmarks(format!(
                "{} values, expected 136",
                out.len()
            )));
        }
        if !bbox.is_valid() {
            return Err(Error::Image(format!("invalid face box {bbox:?}")));
        }
        let side = bbox.width.max(bbox.height);
        let sq = [
            bbox.x + 0.5 * (bbox.width - side),
            bbox.y + 0.5 * (bbox.height - side),
            side,
        ];
        prepare(
            image,
            sq,
            [bbox.x, bbox.y, bbox.x + bbox.width, bbox.y + bbox.height],
            LANDMARK_INPUT,
            LANDMARK_MEAN,
            &mut self.input,
        );
        self.landmark_net
            .run(&self.input, &mut self.scratch, &mut self.raw);
        for (i, (o, r)) in out.iter_mut().zip(self.raw.iter()).enumerate() {
            *o = sq[i % 2] + r * side;
        }
        if out.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(Error::Image(
                "the landmark net gave non-finite points".into(),
            ))
        }
    }
}

/// Samples the square `sq = [x0, y0, side]` of `image` (pixels outside `region = [x0, y0, x1,
/// y1]` or outside the image are black, as face-api.js pads) into an `n x n x 3` map,
/// normalised `(v - mean) / 255`. Downscaling averages up to 4x4 bilinear samples per output
/// pixel, so small inputs do not alias.
fn prepare(
    image: &ImageRef,
    sq: [f32; 3],
    region: [f32; 4],
    n: usize,
    mean: [f32; 3],
    out: &mut Map,
) {
    out.reset(n, n, 3);
    let (w, h) = (image.width() as f32, image.height() as f32);
    let step = sq[2] / n as f32;
    let k = (step.ceil() as usize).clamp(1, 4);
    let sub = step / k as f32;
    let r = [
        region[0].max(0.0),
        region[1].max(0.0),
        region[2].min(w),
        region[3].min(h),
    ];
    let inv = 1.0 / (k * k) as f32;
    let mean = mean.map(|m| m / 255.0);
    for oy in 0..n {
        for ox in 0..n {
            let mut acc = [0.0f32; 3];
            for sy in 0..k {
                let y = sq[1] + oy as f32 * step + (sy as f32 + 0.5) * sub;
                if y < r[1] || y >= r[3] {
                    continue;
                }
                for sx in 0..k {
                    let x = sq[0] + ox as f32 * step + (sx as f32 + 0.5) * sub;
                    if x < r[0] || x >= r[2] {
                        continue;
                    }
                    // The crate's bilinear sampler (pixel centres on integers, 0..=1).
                    let v = image.sample_rgb(x - 0.5, y - 0.5);
                    for (a, v) in acc.iter_mut().zip(v) {
                        *a += v;
                    }
                }
            }
            let o = &mut out.data[(oy * n + ox) * 3..][..3];
            for c in 0..3 {
                o[c] = acc[c] * inv - mean[c];
            }
        }
    }
}

/// Mean distance between two 68-point shapes (interleaved x, y) over `b`'s outer-eye-corner
/// distance (points 36 and 45): the landmark error used throughout the project's figures, and
/// the finder's pass-to-pass disagreement. NaN unless both shapes have 68 points.
pub fn landmark_error(a: &[f32], b: &[f32]) -> f32 {
    if a.len() != 136 || b.len() != 136 {
        return f32::NAN;
    }
    let Some([dx, dy]) = crate::landmarks::eye_line(b) else {
        return f32::NAN;
    };
    let iod = (dx * dx + dy * dy).sqrt();
    let s: f32 = a
        .chunks_exact(2)
        .zip(b.chunks_exact(2))
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt())
        .sum();
    s / 68.0 / iod
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Decodes the detector's grid into image-pixel boxes with scores above `threshold`; `side` is
/// the image's longer side (the detector's input square, in pixels).
fn decode(grid: &Map, side: f32, threshold: f32, out: &mut Vec<(BBox, f32)>) {
    out.clear();
    let cells = grid.h as f32;
    for row in 0..grid.h {
        for col in 0..grid.w {
            let cell = &grid.data[(row * grid.w + col) * grid.c..][..grid.c];
            for (a, &(aw, ah)) in ANCHORS.iter().enumerate() {
                let v = &cell[a * 5..][..5];
                let score = sigmoid(v[4]);
                if !(score > threshold) {
                    continue;
                }
                let cx = (col as f32 + sigmoid(v[0])) / cells * side;
                let cy = (row as f32 + sigmoid(v[1])) / cells * side;
                let bw = v[2].exp() * aw / cells * side;
                let bh = v[3].exp() * ah / cells * side;
                let b = BBox {
                    x: cx - 0.5 * bw,
                    y: cy - 0.5 * bh,
                    width: bw,
                    height: bh,
                };
                if b.is_valid() {
                    out.push((b, score));
                }
            }
        }
    }
}

/// Greedy non-maximum suppression: sorts by score and drops boxes overlapping a kept one by
/// more than `iou`.
fn nms(boxes: &mut Vec<(BBox, f32)>, iou: f32) {
    boxes.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept = 0;
    for i in 0..boxes.len() {
        let cand = boxes[i];
        if boxes[..kept].iter().all(|k| k.0.iou(&cand.0) <= iou) {
            boxes[kept] = cand;
            kept += 1;
        }
    }
    boxes.truncate(kept);
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod reference;

impl std::fmt::Debug for FaceFinder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FaceFinder")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::landmark_error;

    #[test]
    fn landmark_error_is_relative_to_the_eye_distance_and_nan_for_other_shapes() {
        // Outer eye corners 10 px apart; every point 1 px off: an error of 0.1.
        let mut b = vec![0.0f32; 136];
        b[90] = 10.0;
        let a: Vec<f32> = b
            .iter()
            .enumerate()
            .map(|(k, v)| if k % 2 == 0 { v + 1.0 } else { *v })
            .collect();
        assert!((landmark_error(&a, &b) - 0.1).abs() < 1e-6);
        assert_eq!(landmark_error(&b, &b), 0.0);
        assert!(landmark_error(&a[..100], &b[..100]).is_nan());
        assert!(landmark_error(&a, &b[..134]).is_nan());
    }
}

//! Face finding: every face in an image, with a box, a confidence and the 68 iBUG landmarks.
//!
//! MediaPipe's face detector (BlazeFace, short range) and face mesh (468 points), Apache-2.0
//! (Google LLC; `data/weights/LICENSE-mediapipe`), converted from their TFLite files by
//! `scripts/convert-mediapipe.py` and run by the crate's own layers (`graph.rs`, `nn.rs`): the
//! detector proposes faces, the mesh places 468 points on each (twice, the second pass on the
//! region of the first pass's points), and 68 of its vertices, moved onto dlib's convention
//! by a constant per point and then by what the image shows about each point, are the iBUG
//! points (`mesh_table.rs`, `calibration.rs`, `local.rs`). See `docs/finding.md` for the
//! measured rates, errors and speed, and why the pipeline is what it is.

mod calibration;
mod finder;
mod graph;
mod local;
mod local_learn;
mod mesh;
mod mesh_table;
mod nn;
mod weights;

#[cfg(not(target_arch = "wasm32"))]
pub use graph::{profile_mesh_nets, NetProfile};
pub use mesh::MESH_POINTS;
pub use mesh_table::IBUG_DEPTH;

pub use calibration::{
    add_face_offsets, convention_free_errors, face_frame, face_offsets, mean_face_offsets,
    NET_OFFSETS,
};
pub use finder::FaceFinder;
pub use local::{local_descriptor, LocalCorrection, LocalScratch};
#[cfg(not(target_arch = "wasm32"))]
pub use local_learn::training_images;
pub use local_learn::{LearnOptions, LearnSample};

pub use crate::geometry::BBox;

/// The finder's boxes.
impl BBox {
    /// A face's box from its 68 landmarks, as [`Face::bbox`] and the box [`FaceFinder::landmarks`]
    /// takes: centred on the points' box (0.025 of its height higher), 1.27 times its width and
    /// 1.14 times its height (the mean relation between face-api.js's detector boxes, the
    /// crate's earlier finder, and dlib's landmark boxes, measured on GRID, franck-dev and
    /// webcam-dev frames; the mesh's region is 1.5 times its longer side).
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

/// One face found in an image.
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    /// The face's box ([`BBox::around_landmarks`] of its landmarks).
    pub bbox: BBox,
    /// Confidence in 0..=1.
    pub score: f32,
    /// The 68 iBUG landmarks, interleaved `x0, y0, ... x67, y67`, image pixels (0-based).
    pub landmarks: Vec<f32>,
}

/// Tuning of [`FaceFinder::find`].
#[derive(Clone, Copy, Debug)]
pub struct FindOptions {
    /// Detector confidence below which a detection is not considered (MediaPipe's
    /// `min_score_thresh`, 0.5).
    pub score_threshold: f32,
    /// Faces whose boxes overlap a more confident face's by more than this IoU are dropped.
    pub iou_threshold: f32,
    /// At most this many faces are returned.
    pub max_faces: usize,
    /// At most this many detections (most confident first) get mesh passes.
    pub max_candidates: usize,
    /// A region is a face only if the mesh's own face-presence score is at least this
    /// (MediaPipe's tracking threshold, 0.5).
    pub min_face_score: f32,
    /// `true`: each face's points are the mean of the mesh on the image and on its mirror
    /// image (two more mesh passes a face): the net's left-right biases cancel, closer to
    /// dlib's points on every shared set, at the cost of about 3 ms a face natively
    /// (`docs/finding.md`, "Precise"). Off by default (the speed of a frame); the `landmark`
    /// command turns it on.
    pub mirror: bool,
}

impl Default for FindOptions {
    fn default() -> Self {
        FindOptions {
            score_threshold: mesh::DETECTOR_MIN_SCORE,
            iou_threshold: 0.4,
            max_faces: 16,
            max_candidates: 10,
            min_face_score: 0.5,
            mirror: false,
        }
    }
}

/// Mean distance between two 68-point shapes (interleaved x, y) over `b`'s outer-eye-corner
/// distance (points 36 and 45): the landmark error used throughout the project's figures, and
/// what the finder's tests and figures measure. NaN unless both shapes have 68 points.
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

#[cfg(all(test, not(target_arch = "wasm32")))]
mod reference;

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

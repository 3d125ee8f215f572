//! Landmarks for enrolment: the face finder's points, steadied by averaging several passes of
//! its face mesh (on boxes shifted a little and on the mirrored image).
//!
//! Why: a model is built from ~20 frames chosen by farthest-point sampling
//! ([`crate::select_varied`]), which picks the most unusual shapes first, and a frame whose
//! points the finder misplaced is unusual. One such frame gives the model a mode that describes
//! the finder's mistake, and the tracker can then run away with it. Measured on webcam-dev
//! (docs/experiments/fitting-notebook.md, "Enrolment with the face finder's landmarks"): models from single-pass
//! landmarks lost the face in 6 of 11 runs, models from averaged ones never when every face
//! found was used (0.0320-0.0322 against dlib).

use crate::error::Result;
use crate::find::{BBox, Face, FaceFinder};
use crate::image::ImageRef;
use crate::summary::summary;

/// Box shifts (x, y as fractions of the box side) and scales of the passes, first the box the
/// finder settled on.
const JITTER: [(f32, f32, f32); 7] = [
    (0.0, 0.0, 1.0),
    (0.04, 0.0, 1.0),
    (-0.04, 0.0, 1.0),
    (0.0, 0.04, 1.0),
    (0.0, -0.04, 1.0),
    (0.0, 0.0, 1.06),
    (0.0, 0.0, 0.94),
];

/// A face found for enrolment.
#[derive(Clone, Debug, PartialEq)]
pub struct EnrolFace {
    /// The 68 landmarks averaged over the passes (image pixels, interleaved).
    pub landmarks: Vec<f32>,
    /// The finder's confidence (0..1).
    pub score: f32,
    /// Mean distance of the passes' points to their average, over the outer-eye-corner
    /// distance: how much the passes disagreed.
    pub spread: f32,
}

/// The face finder with the averaging of [`EnrolFinder::find`]; keeps its buffers between calls.
pub struct EnrolFinder {
    finder: FaceFinder,
    boxes: usize,
    mirror: Vec<u8>,
    passes: Vec<f32>,
}

impl std::fmt::Debug for EnrolFinder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        summary(
            f,
            "EnrolFinder",
            &[("finder", &self.finder), ("boxes", &self.boxes)],
        )
    }
}

impl EnrolFinder {
    /// A finder with the shipped weights, averaging `boxes` (1..=7) boxes, each on the image and
    /// on its mirror.
    pub fn new(boxes: usize) -> Result<Self> {
        Ok(EnrolFinder {
            finder: FaceFinder::new()?,
            boxes: boxes.clamp(1, JITTER.len()),
            mirror: Vec::new(),
            passes: Vec::new(),
        })
    }

    /// The underlying finder.
    pub fn finder(&mut self) -> &mut FaceFinder {
        &mut self.finder
    }

    /// The most confident face in `image` if its score reaches `min_score`, its landmarks
    /// averaged over the passes; `None` when there is no such face.
    pub fn find(&mut self, image: &ImageRef, min_score: f32) -> Result<Option<EnrolFace>> {
        let Some(face) = self.finder.find(image).into_iter().next() else {
            return Ok(None);
        };
        if face.score < min_score {
            return Ok(None);
        }
        self.average(image, &face)
    }

    /// The landmarks of a face the finder found in `image`, averaged over the passes (boxes
    /// around its points, on the image and on its mirror); `None` if they are not finite.
    pub fn average(&mut self, image: &ImageRef, face: &Face) -> Result<Option<EnrolFace>> {
        let w = image.width() as usize;
        image.mirror_into(&mut self.mirror);
        let mirror = ImageRef::new(image.width(), image.height(), &self.mirror)?;
        let b = BBox::around_landmarks(&face.landmarks);
        let n = 2 * self.boxes;
        self.passes.resize(n * 136, 0.0);
        let mut flipped = [0.0f32; 136];
        for (k, &(dx, dy, s)) in JITTER.iter().take(self.boxes).enumerate() {
            let bb = BBox {
                x: b.x + dx * b.width - 0.5 * (s - 1.0) * b.width,
                y: b.y + dy * b.height - 0.5 * (s - 1.0) * b.height,
                width: b.width * s,
                height: b.height * s,
            };
            self.finder.landmarks_into(
                image,
                bb,
                &mut self.passes[2 * k * 136..(2 * k + 1) * 136],
            )?;
            let mb = BBox {
                x: w as f32 - bb.x - bb.width,
                ..bb
            };
            self.finder.landmarks_into(&mirror, mb, &mut flipped)?;
            crate::landmarks::mirror_points(
                &flipped,
                w as f32,
                &mut self.passes[(2 * k + 1) * 136..(2 * k + 2) * 136],
            );
        }
        let mut avg = vec![0.0f32; 136];
        for p in self.passes.chunks_exact(136) {
            for (a, v) in avg.iter_mut().zip(p) {
                *a += v / n as f32;
            }
        }
        let spread = self
            .passes
            .chunks_exact(136)
            .map(|p| crate::find::landmark_error(p, &avg))
            .sum::<f32>()
            / n as f32;
        if avg.iter().any(|v| !v.is_finite()) {
            return Ok(None);
        }
        Ok(Some(EnrolFace {
            landmarks: avg,
            score: face.score,
            spread,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_face_in_a_flat_image() {
        let data = vec![128u8; 160 * 120 * 4];
        let img = ImageRef::new(160, 120, &data).unwrap();
        let mut f = EnrolFinder::new(3).unwrap();
        assert_eq!(f.find(&img, 0.0).unwrap(), None);
    }
}

//! Which enrolment frames are good enough to build from (issue 33): a frame whose face is
//! covered (a hand, a cup, hair), badly lit, blurred, turned too far or partly out of the
//! picture is rejected with its [`FrameProblem`], so a model never learns a hand as a face.
//!
//! Two kinds of check:
//! - **per frame** ([`FrameQuality::measure`], [`FrameQuality::problem`]), from the frame and
//!   its 68 landmarks alone: the points inside the picture, the yaw the points imply, the face's
//!   luminance and contrast, its sharpness (the variance of a Laplacian over the face, relative
//!   to the face's own contrast, on a grid at the face's scale), and the finder's two looks
//!   (frame and mirror) agreeing;
//! - **against the others** ([`occlusion_scores`]): occlusion is local, so each frame's face is
//!   sampled into the canonical reference frame, normalised in luminance, and compared, cell by
//!   cell of a grid over the face, with the per-pixel median of the frames; a frame with one
//!   cell much further from the median than that cell usually is has something over its face.
//!
//! The thresholds were measured on webcam-dev and franck-dev with synthetic occluders
//! (`tests/integration/enrol_quality.rs`, docs/fitting.md "Enrolment that keeps only good
//! frames").

use crate::error::{Error, Result};
use crate::geometry::inside_polygon;
use crate::image::ImageRef;

/// Why a frame is not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrameProblem {
    /// No face found (or none scoring the minimum).
    NoFace,
    /// Part of the face is outside the picture.
    Outside,
    /// The head is turned too far from the camera.
    Turned,
    /// Too dark or too flat in contrast.
    Dark,
    /// Blurred (motion or focus).
    Blurred,
    /// Something covers part of the face (a hand, a cup, hair).
    Occluded,
    /// The same picture as the frame before (a frozen camera).
    Frozen,
}

impl FrameProblem {
    /// Its stable name: "no-face", "outside", "turned", "dark", "blurred", "occluded",
    /// "frozen".
    pub fn code(self) -> &'static str {
        match self {
            FrameProblem::NoFace => "no-face",
            FrameProblem::Outside => "outside",
            FrameProblem::Turned => "turned",
            FrameProblem::Dark => "dark",
            FrameProblem::Blurred => "blurred",
            FrameProblem::Occluded => "occluded",
            FrameProblem::Frozen => "frozen",
        }
    }
}

impl std::fmt::Display for FrameProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.code())
    }
}

/// Points may lie this far (in outer-eye-corner distances) outside the picture.
pub const MAX_OUTSIDE: f32 = 0.05;
/// Largest yaw proxy accepted ([`FrameQuality::yaw`]).
pub const MAX_YAW: f32 = 0.6;
/// Darkest median face luminance accepted (0..1).
pub const MIN_LUMINANCE: f32 = 0.12;
/// Least face contrast accepted (the 95th minus the 5th percentile of luminance, 0..1).
pub const MIN_CONTRAST: f32 = 0.08;
/// Least relative sharpness accepted ([`FrameQuality::sharpness`]).
pub const MIN_SHARPNESS: f32 = 0.3;
/// Most disagreement accepted between the finder's passes ([`crate::EnrolFace::spread`]).
pub const MAX_SPREAD: f32 = 0.02;
/// Largest occlusion score accepted ([`occlusion_scores`]).
pub const MAX_OCCLUSION: f32 = 0.72;
/// Fewest frames [`occlusion_scores`] compares; with fewer every score is 0.
pub const MIN_CONSENSUS_FRAMES: usize = 6;

/// Least [`FrameQuality::lips`] accepted.
/// Measured (dlib's points on clean faces, the finder's on covered ones; `enrol_quality::
/// print_lip_contrast`): clean faces 0.061 at the least (330 GRID frames, London's 120 photos,
/// webcam-dev and franck-dev every 7th frame); a skin-coloured ellipse over the mouth 0.014 at
/// the most; a synthetic hand over the mouth 0.012-0.13 (the rest is left to
/// [`occlusion_scores`]).
pub const MIN_LIP_CONTRAST: f32 = 0.03;
/// The skin ring around the lips: between these scales of the outer lip contour about its
/// centre.
const LIP_RING: (f32, f32) = (1.2, 1.5);
/// Samples across and down the ring's box for [`lip_contrast`].
const LIP_SAMPLES: usize = 32;

/// Side of the grid a face is resampled to for its luminance and sharpness.
const GRID: usize = 48;
/// Cells across and down the canonical frame for the occlusion scores.
const CELLS: usize = 5;

/// The per-frame measures of one face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameQuality {
    /// How far the farthest point lies outside the picture, in outer-eye-corner distances (0
    /// when all are inside).
    pub outside: f32,
    /// Yaw proxy: where the nose tip lies between the jaw's ends along the eye line, -1..1 (0
    /// frontal).
    pub yaw: f32,
    /// Median luminance over the face, 0..1.
    pub luminance: f32,
    /// 95th minus 5th percentile of luminance over the face.
    pub contrast: f32,
    /// Standard deviation of a Laplacian over the face grid over the face's standard deviation
    /// of luminance.
    pub sharpness: f32,
    /// The finder's passes' disagreement, when the finder placed the points.
    pub spread: Option<f32>,
    /// How far the lips' colour stands from the skin around them (`lip_contrast`): near 0
    /// when something flat covers the mouth (a hand, a cup, a sleeve).
    pub lips: f32,
}

impl FrameQuality {
    /// Measures the face at `landmarks` (68 points, image pixels) in `image`; `spread` is the
    /// finder's ([`crate::EnrolFace::spread`]) when it placed them.
    pub fn measure(image: &ImageRef, landmarks: &[f32], spread: Option<f32>) -> Result<Self> {
        if landmarks.len() != 136 || landmarks.iter().any(|v| !v.is_finite()) {
            return Err(Error::Training(
                "quality: 68 finite landmarks are needed".into(),
            ));
        }
        let eye = crate::landmarks::eye_line(landmarks).unwrap_or([1.0, 0.0]);
        let iod = eye[0].hypot(eye[1]).max(1.0);
        let (w, h) = (image.width() as f32, image.height() as f32);
        let outside = landmarks
            .chunks_exact(2)
            .map(|p| {
                let dx = (-p[0]).max(p[0] - (w - 1.0)).max(0.0);
                let dy = (-p[1]).max(p[1] - (h - 1.0)).max(0.0);
                dx.max(dy)
            })
            .fold(0.0f32, f32::max)
            / iod;
        let yaw = yaw_of(landmarks);
        let grid = face_grid(image, landmarks);
        let (luminance, contrast) = luminance_figures(&grid);
        Ok(FrameQuality {
            outside,
            yaw,
            luminance,
            contrast,
            sharpness: sharpness(&grid),
            spread,
            lips: lip_contrast(image, landmarks),
        })
    }

    /// The first problem the per-frame checks find, in the order outside, turned, dark,
    /// blurred, occluded (the finder's passes disagreeing, or no lips to be seen); `None` for
    /// a good frame.
    pub fn problem(&self) -> Option<FrameProblem> {
        if self.outside > MAX_OUTSIDE {
            Some(FrameProblem::Outside)
        } else if self.yaw.abs() > MAX_YAW {
            Some(FrameProblem::Turned)
        } else if self.luminance < MIN_LUMINANCE || self.contrast < MIN_CONTRAST {
            Some(FrameProblem::Dark)
        } else if self.sharpness < MIN_SHARPNESS {
            Some(FrameProblem::Blurred)
        } else if self.spread.is_some_and(|s| s > MAX_SPREAD) || self.lips < MIN_LIP_CONTRAST {
            Some(FrameProblem::Occluded)
        } else {
            None
        }
    }
}

/// Where the nose tip (point 30) lies between the jaw's ends (points 0 and 16) along the eye
/// line, -1..1 (0 frontal, 1 when the jaw's ends are not apart). Requires 68 points.
pub(crate) fn yaw_of(landmarks: &[f32]) -> f32 {
    let eye = crate::landmarks::eye_line(landmarks).unwrap_or([1.0, 0.0]);
    let along = |i: usize| landmarks[2 * i] * eye[0] + landmarks[2 * i + 1] * eye[1];
    let (a, b) = (along(30) - along(0), along(16) - along(30));
    if a + b > 1e-3 {
        ((a - b) / (a + b)).clamp(-1.0, 1.0)
    } else {
        1.0
    }
}

/// The face's luminance on a `GRID` x `GRID` grid over its landmarks' box (the brows to the
/// chin, the jaw's width), sampled bilinearly.
fn face_grid(image: &ImageRef, landmarks: &[f32]) -> Vec<f32> {
    let b = crate::geometry::BBox::of_points(landmarks);
    let mut out = Vec::with_capacity(GRID * GRID);
    for gy in 0..GRID {
        for gx in 0..GRID {
            let x = b.x + b.width * (gx as f32 + 0.5) / GRID as f32;
            let y = b.y + b.height * (gy as f32 + 0.5) / GRID as f32;
            out.push(luma(image.sample_rgb(x, y)));
        }
    }
    out
}

fn luma(c: [f32; 3]) -> f32 {
    0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]
}

/// How much the lips stand out: the distance between the lips' mean colour and the mean colour
/// of the skin ring around them ([`LIP_RING`]) in an opponent space (luminance, red-green,
/// yellow-blue; 0..1 units), combined (root of the sum of squares) with the spread of the lips'
/// luminance (the line between them, their shading). The lips are the outer lip contour (points
/// 48-59) less the mouth's opening (60-67). Lips differ from skin in every face, darker or
/// redder or both, and are never flat; a flat occluder over the mouth (a hand, a cup, a sleeve)
/// is one colour inside and around, wherever the finder put the points on it. Depends on the
/// light: a dim face scores lower (the dark check comes first). Requires 68 finite points.
pub(crate) fn lip_contrast(image: &ImageRef, landmarks: &[f32]) -> f32 {
    let outer = 48..60;
    let c = outer.clone().fold([0.0, 0.0], |a, i| {
        [
            a[0] + landmarks[2 * i] / 12.0,
            a[1] + landmarks[2 * i + 1] / 12.0,
        ]
    });
    // The outer lip contour scaled by `k` about its centre (12 points, interleaved).
    let scaled = |k: f32| -> [f32; 24] {
        let mut out = [0.0; 24];
        for (o, i) in out.chunks_exact_mut(2).zip(outer.clone()) {
            o[0] = c[0] + k * (landmarks[2 * i] - c[0]);
            o[1] = c[1] + k * (landmarks[2 * i + 1] - c[1]);
        }
        out
    };
    let (near, far) = (scaled(LIP_RING.0), scaled(LIP_RING.1));
    let b = crate::geometry::BBox::of_points(&far);
    let (mut lips, mut ring) = (([0.0f32; 3], 0usize), ([0.0f32; 3], 0usize));
    let mut lips_sq = 0.0f32;
    for gy in 0..LIP_SAMPLES {
        for gx in 0..LIP_SAMPLES {
            let x = b.x + b.width * (gx as f32 + 0.5) / LIP_SAMPLES as f32;
            let y = b.y + b.height * (gy as f32 + 0.5) / LIP_SAMPLES as f32;
            let inside = |s: &[f32], r| inside_polygon([x, y], s, r);
            let on_lips = inside(landmarks, 48..60);
            if (on_lips && inside(landmarks, 60..68))
                || (!on_lips && (!inside(&far, 0..12) || inside(&near, 0..12)))
            {
                continue;
            }
            let [r, g, bl] = image.sample_rgb(x, y);
            let o = [luma([r, g, bl]), r - g, 0.5 * (r + g) - bl];
            let into = if on_lips {
                lips_sq += o[0] * o[0];
                &mut lips
            } else {
                &mut ring
            };
            for k in 0..3 {
                into.0[k] += o[k];
            }
            into.1 += 1;
        }
    }
    if lips.1 == 0 || ring.1 == 0 {
        return 0.0;
    }
    let apart = (0..3)
        .map(|k| (lips.0[k] / lips.1 as f32 - ring.0[k] / ring.1 as f32).powi(2))
        .sum::<f32>()
        .sqrt();
    let mean = lips.0[0] / lips.1 as f32;
    let spread = (lips_sq / lips.1 as f32 - mean * mean).max(0.0).sqrt();
    apart.hypot(spread)
}

/// The median and the 5-95 percentile range of `v`.
fn luminance_figures(v: &[f32]) -> (f32, f32) {
    let mut s = v.to_vec();
    s.sort_unstable_by(f32::total_cmp);
    let at = |q: f32| s[((s.len() - 1) as f32 * q).round() as usize];
    (at(0.5), at(0.95) - at(0.05))
}

/// Standard deviation of the 4-neighbour Laplacian of the grid over its standard deviation.
fn sharpness(g: &[f32]) -> f32 {
    let n = GRID;
    let mean = g.iter().sum::<f32>() / g.len() as f32;
    let var = g.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / g.len() as f32;
    let mut lap = Vec::with_capacity((n - 2) * (n - 2));
    for y in 1..n - 1 {
        for x in 1..n - 1 {
            let c = g[y * n + x];
            lap.push(
                g[y * n + x - 1] + g[y * n + x + 1] + g[(y - 1) * n + x] + g[(y + 1) * n + x]
                    - 4.0 * c,
            );
        }
    }
    let lm = lap.iter().sum::<f32>() / lap.len() as f32;
    let lv = lap.iter().map(|v| (v - lm).powi(2)).sum::<f32>() / lap.len() as f32;
    if var <= 1e-8 {
        0.0
    } else {
        (lv / var).sqrt()
    }
}

/// Each face sampled into the canonical frame, its luminance normalised to zero mean and unit
/// deviation.
pub(crate) fn normalised_faces(faces: &[(ImageRef, &[f32])]) -> Result<Vec<Vec<f32>>> {
    let frame = crate::train::canonical::canonical_frame();
    let mut rgb = vec![0.0f32; frame.n_pixels() * 3];
    faces
        .iter()
        .map(|(image, lm)| {
            crate::model::warp::sample_rgb(frame, image, lm, &mut rgb)?;
            let mut v: Vec<f32> = rgb
                .chunks_exact(3)
                .map(|c| luma([c[0], c[1], c[2]]))
                .collect();
            let mean = v.iter().sum::<f32>() / v.len() as f32;
            let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / v.len() as f32)
                .sqrt()
                .max(1e-3);
            v.iter_mut().for_each(|x| *x = (*x - mean) / sd);
            Ok(v)
        })
        .collect()
}

/// Occlusion scores of faces (each a picture and its 68 landmarks) compared with each other.
/// Each face is sampled into the canonical frame (luminance normalised to zero mean and unit
/// deviation) and compared with the per-pixel median of the faces nearest it in yaw (a third
/// of them, at least `MIN_CONSENSUS_FRAMES` (6); a turned head is compared with turned heads);
/// its score is the largest, over the cells of a grid on the frame, of its mean absolute
/// difference from that median in the cell. Occlusion is local: a hand, a cup or a bar over
/// the eyes makes one cell differ by about 1 (in deviations of the face's luminance); a face
/// like the others stays under about 0.6 (webcam-dev). With fewer than
/// `MIN_CONSENSUS_FRAMES` (6) faces every score is 0 (nothing to compare with).
pub fn occlusion_scores(faces: &[(ImageRef, &[f32])]) -> Result<Vec<f32>> {
    if faces.len() < MIN_CONSENSUS_FRAMES {
        return Ok(vec![0.0; faces.len()]);
    }
    if faces.iter().any(|(_, lm)| lm.len() != 136) {
        return Err(Error::Training(
            "quality: 68 landmarks a face are needed".into(),
        ));
    }
    let v = normalised_faces(faces)?;
    let yaws: Vec<f32> = faces.iter().map(|(_, lm)| yaw_of(lm)).collect();
    let frame = crate::train::canonical::canonical_frame();
    let (fw, fh) = (frame.width() as usize, frame.height() as usize);
    let cell: Vec<usize> = frame
        .pixels()
        .iter()
        .map(|p| {
            (p.y as usize * CELLS / fh).min(CELLS - 1) * CELLS
                + (p.x as usize * CELLS / fw).min(CELLS - 1)
        })
        .collect();
    let mut count = [0usize; CELLS * CELLS];
    cell.iter().for_each(|&c| count[c] += 1);
    let k = (faces.len() / 3).max(MIN_CONSENSUS_FRAMES).min(faces.len());
    let mut order: Vec<usize> = (0..faces.len()).collect();
    let mut column = vec![0.0f32; k];
    Ok((0..faces.len())
        .map(|f| {
            order.sort_by(|&a, &b| {
                (yaws[a] - yaws[f])
                    .abs()
                    .total_cmp(&(yaws[b] - yaws[f]).abs())
            });
            let near = &order[..k];
            let mut d = [0.0f32; CELLS * CELLS];
            for (px, &c) in cell.iter().enumerate() {
                column
                    .iter_mut()
                    .zip(near)
                    .for_each(|(x, &j)| *x = v[j][px]);
                d[c] += (v[f][px] - median_of(&mut column)).abs() / count[c] as f32;
            }
            (0..CELLS * CELLS)
                .filter(|&c| count[c] >= 40)
                .map(|c| d[c])
                .fold(0.0, f32::max)
        })
        .collect())
}

fn median_of(v: &mut [f32]) -> f32 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f32::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic face: a light oval on a mid-grey background with dark eyes, brows, a nose
    /// and a mouth, and the 68 points of a frontal face placed on it (jaw, brows, nose, eyes,
    /// mouth), 200x200.
    fn face(w: u32, h: u32) -> (Vec<u8>, Vec<f32>) {
        let mut lm = Vec::with_capacity(136);
        let (cx, cy) = (100.0f32, 105.0f32);
        for i in 0..17 {
            let a = std::f32::consts::PI * (i as f32 / 16.0);
            lm.extend([cx - 55.0 * a.cos(), cy - 10.0 + 60.0 * a.sin()]);
        }
        for i in 0..10 {
            let x = if i < 5 {
                55.0 + 9.0 * i as f32
            } else {
                109.0 + 9.0 * (i - 5) as f32
            };
            lm.extend([x, 70.0]);
        }
        for i in 0..4 {
            lm.extend([cx, 82.0 + 8.0 * i as f32]);
        }
        for i in 0..5 {
            lm.extend([cx - 12.0 + 6.0 * i as f32, 116.0]);
        }
        for e in [70.0f32, 130.0] {
            for i in 0..6 {
                let a = std::f32::consts::TAU * i as f32 / 6.0;
                lm.extend([e - 12.0 * a.cos(), 85.0 - 4.0 * a.sin()]);
            }
        }
        for i in 0..20 {
            let a = std::f32::consts::TAU * i as f32 / 20.0;
            let r = if i < 12 { 22.0 } else { 12.0 };
            lm.extend([cx - r * a.cos(), 135.0 - 0.4 * r * a.sin()]);
        }
        let mut rgba = vec![0u8; (w * h * 4) as usize];
        for y in 0..h {
            for x in 0..w {
                let (fx, fy) = (x as f32, y as f32);
                let inside = ((fx - cx) / 58.0).powi(2) + ((fy - cy) / 72.0).powi(2) < 1.0;
                let near = |px: f32, py: f32, rx: f32, ry: f32| {
                    ((fx - px) / rx).powi(2) + ((fy - py) / ry).powi(2) < 1.0
                };
                let dark = near(70.0, 85.0, 9.0, 4.0)
                    || near(130.0, 85.0, 9.0, 4.0)
                    || near(75.0, 70.0, 18.0, 3.0)
                    || near(125.0, 70.0, 18.0, 3.0)
                    || near(100.0, 135.0, 20.0, 5.0)
                    || near(100.0, 114.0, 6.0, 3.0);
                // A little texture everywhere (skin is not flat).
                let tex = ((x * 7 + y * 13) % 5) as f32 * 3.0;
                let v = if dark {
                    50.0
                } else if inside {
                    190.0 + tex
                } else {
                    110.0 + tex
                };
                let i = 4 * (y * w + x) as usize;
                rgba[i..i + 4].copy_from_slice(&[v as u8, (v * 0.85) as u8, (v * 0.75) as u8, 255]);
            }
        }
        (rgba, lm)
    }

    fn measure(rgba: &[u8], lm: &[f32]) -> FrameQuality {
        let img = ImageRef::new(200, 200, rgba).unwrap();
        FrameQuality::measure(&img, lm, Some(0.01)).unwrap()
    }

    #[test]
    fn a_clear_frontal_face_passes() {
        let (rgba, lm) = face(200, 200);
        let q = measure(&rgba, &lm);
        assert_eq!(q.problem(), None, "{q:?}");
        assert!(q.yaw.abs() < 0.05, "{q:?}");
    }

    #[test]
    fn a_dark_face_is_dark() {
        let (mut rgba, lm) = face(200, 200);
        rgba.chunks_exact_mut(4)
            .for_each(|p| p[..3].iter_mut().for_each(|v| *v /= 8));
        assert_eq!(measure(&rgba, &lm).problem(), Some(FrameProblem::Dark));
    }

    #[test]
    fn a_blurred_face_is_blurred() {
        let (rgba, lm) = face(200, 200);
        let mut out = rgba.clone();
        let r = 5i32;
        for y in 0..200i32 {
            for x in 0..200i32 {
                for c in 0..3 {
                    let (mut s, mut n) = (0u32, 0u32);
                    for yy in (y - r).max(0)..(y + r + 1).min(200) {
                        for xx in (x - r).max(0)..(x + r + 1).min(200) {
                            s += rgba[(4 * (yy * 200 + xx)) as usize + c] as u32;
                            n += 1;
                        }
                    }
                    out[(4 * (y * 200 + x)) as usize + c] = (s / n) as u8;
                }
            }
        }
        let (sharp, blurred) = (measure(&rgba, &lm), measure(&out, &lm));
        assert!(
            blurred.sharpness < 0.5 * sharp.sharpness,
            "{sharp:?} {blurred:?}"
        );
        assert_eq!(
            blurred.problem(),
            Some(FrameProblem::Blurred),
            "{blurred:?}"
        );
    }

    #[test]
    fn points_outside_the_picture_and_a_turned_head_are_named() {
        let (rgba, lm) = face(200, 200);
        let shifted: Vec<f32> = lm
            .chunks_exact(2)
            .flat_map(|p| [p[0] - 70.0, p[1]])
            .collect();
        assert_eq!(
            measure(&rgba, &shifted).problem(),
            Some(FrameProblem::Outside)
        );
        // The nose tip near the jaw's right end: a head turned far.
        let mut turned = lm.clone();
        turned[60] = lm[32] - 5.0;
        assert_eq!(
            measure(&rgba, &turned).problem(),
            Some(FrameProblem::Turned)
        );
        let mut passes = measure(&rgba, &lm);
        passes.spread = Some(2.0 * MAX_SPREAD);
        assert_eq!(passes.problem(), Some(FrameProblem::Occluded));
    }

    #[test]
    fn a_hand_over_one_face_among_many_is_found() {
        let (rgba, lm) = face(200, 200);
        let mut covered = rgba.clone();
        // A flat skin-coloured patch over the left eye and brow.
        for y in 60..100 {
            for x in 45..100 {
                let i = 4 * (y * 200 + x);
                covered[i..i + 3].copy_from_slice(&[215, 180, 160]);
            }
        }
        let mut pictures = vec![rgba.clone(); 9];
        pictures.push(covered);
        let faces: Vec<(ImageRef, &[f32])> = pictures
            .iter()
            .map(|p| (ImageRef::new(200, 200, p).unwrap(), lm.as_slice()))
            .collect();
        let s = occlusion_scores(&faces).unwrap();
        assert!(s[..9].iter().all(|&v| v < 0.1), "{s:?}");
        assert!(s[9] > MAX_OCCLUSION, "{s:?}");
        // Too few faces to compare: no verdict.
        assert_eq!(occlusion_scores(&faces[..3]).unwrap(), vec![0.0; 3]);
    }

    /// Bad input never makes a model silently: every frame covered, or the face leaving the
    /// picture half way, is an error naming the frames and why.
    #[test]
    fn enrolment_from_bad_frames_says_why() {
        use crate::{enrol, EnrolFrame, EnrolOptions, Image, QualityScope};
        let (rgba, lm) = face(200, 200);
        // Each picture a little brighter than the one before (the same picture again is a
        // frozen camera).
        let frame = |i: usize, lm: &[f32], rgba: &[u8]| EnrolFrame {
            name: format!("frame{i}"),
            image: Image {
                width: 200,
                height: 200,
                data: rgba.iter().map(|v| v.saturating_add(2 * i as u8)).collect(),
            },
            landmarks: Some(lm.to_vec()),
        };
        let options = EnrolOptions {
            quality: QualityScope::All,
            min_frames: 4,
            ..EnrolOptions::default()
        };
        let dark: Vec<u8> = rgba.iter().map(|v| v / 8).collect();
        let all_dark = (0..5).map(|i| frame(i, &lm, &dark)).collect();
        let e = enrol(all_dark, &options, None, None, &mut |_| true).unwrap_err();
        assert!(
            e.to_string()
                .contains("a usable face in 0 of 5 frames, at least 4 are needed; rejected: frames 0, 1, 2, 3, 4 dark"),
            "{e}"
        );
        // The face leaves the picture after two frames.
        let gone: Vec<f32> = lm
            .chunks_exact(2)
            .flat_map(|p| [p[0] + 90.0, p[1]])
            .collect();
        let leaving = (0..6)
            .map(|i| frame(i, if i < 2 { &lm } else { &gone }, &rgba))
            .collect();
        let e = enrol(leaving, &options, None, None, &mut |_| true).unwrap_err();
        assert!(
            e.to_string()
                .contains("a usable face in 2 of 6 frames, at least 4 are needed; rejected: frames 2, 3, 4, 5 outside"),
            "{e}"
        );
        // A frozen camera: the same picture again and again.
        let frozen = (0..6).map(|_| frame(0, &lm, &rgba)).collect();
        let e = enrol(frozen, &options, None, None, &mut |_| true).unwrap_err();
        assert!(
            e.to_string().contains(
                "the camera seems frozen: frames 1, 2, 3, 4, 5 show the same picture as the frame before"
            ),
            "{e}"
        );
        // A repeated frame now and then is a live camera's; four repeats in a row are frozen,
        // rejected and named, and the rest is built from.
        let mut frames: Vec<EnrolFrame> = (0..8).map(|i| frame(i, &lm, &rgba)).collect();
        frames.insert(3, frame(2, &lm, &rgba));
        let made = enrol(frames, &options, None, None, &mut |_| true).unwrap();
        assert!(made.rejected.is_empty(), "{:?}", made.rejected);
        let mut frames: Vec<EnrolFrame> = (0..8).map(|i| frame(i, &lm, &rgba)).collect();
        for _ in 0..4 {
            frames.insert(6, frame(5, &lm, &rgba));
        }
        let made = enrol(frames, &options, None, None, &mut |_| true).unwrap();
        let frozen = |i| (i, FrameProblem::Frozen);
        assert_eq!(
            made.rejected,
            vec![frozen(6), frozen(7), frozen(8), frozen(9)]
        );
        assert_eq!(made.used.len(), 8);
    }
}

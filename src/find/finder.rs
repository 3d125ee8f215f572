//! [`FaceFinder`]: faces and their 68 iBUG points from MediaPipe's face detector and face mesh
//! (`mesh.rs`).

use super::calibration;
use super::local::{LocalCorrection, LocalScratch};
use super::mesh::{self, Detection, MeshNets, Roi, MESH_POINTS};
use super::mesh_table;
use super::{Face, FindOptions};
use crate::error::{Error, Result};
use crate::geometry::BBox;
use crate::image::ImageRef;
use crate::summary::summary;

/// Mesh passes per face in [`FaceFinder::find`] and [`FaceFinder::landmarks`]: the first on
/// the detector's region (or the box given), the next on the region of the previous pass's
/// points (as MediaPipe does from frame to frame). Measured on every 4th frame of franck-dev,
/// franck-dev2 and webcam-dev: one pass 0.0288 / 0.0344 / 0.0309, two passes 0.0279 / 0.0329 /
/// 0.0287.
const MESH_PASSES: usize = 2;

/// A region whose mesh vertices lie on flat-filled pixels this often is a drawing, not a face
/// (see [`flat_fraction`]).
const MAX_FLAT: f32 = 0.5;

/// Finds faces and places their 68 landmarks with MediaPipe's BlazeFace (short range) and its
/// 468-point face mesh (Apache-2.0, Google LLC; `data/weights/LICENSE-mediapipe`), run by the
/// crate's own layers (`graph.rs`).
///
/// Represents: the two nets, their anchors and every scratch buffer; reuse one finder (after
/// the first call, `find` and `landmarks` allocate only their results).
///
/// Ensures: every face reported has 68 finite points in dlib's iBUG convention (blends of the
/// mesh's vertices, `mesh_table.rs`, the jaw moved out to the outline of a turned face,
/// `mesh_table::silhouette`, then moved by the convention offsets of `calibration.rs` and by
/// the local correction of `local.rs`, every point but the jaw's), a box
/// ([`BBox::around_landmarks`]) and a score in 0..=1; see `docs/finding.md` for the measured
/// rates, errors and speed.
pub struct FaceFinder {
    nets: MeshNets,
    options: FindOptions,
    calibrate: bool,
    /// The local correction (`local.rs`), applied after the calibration when `local_on`.
    local: LocalCorrection,
    local_on: bool,
    local_scratch: LocalScratch,
    detections: Vec<Detection>,
    /// The dense mesh of the last `scored_landmarks_into` or `follow_into` (where
    /// `follow_into` looks next); empty when there is none.
    pass: Vec<f32>,
    /// Scratch of [`FindOptions::mirror`]: the mirror image (RGBA) and a mesh.
    mirror: Vec<u8>,
    mirror_pass: Vec<f32>,
}

impl std::fmt::Debug for FaceFinder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        summary(f, "FaceFinder", &[("options", &self.options)])
    }
}

impl FaceFinder {
    /// A finder with the converted MediaPipe weights shipped in the crate.
    pub fn new() -> Result<Self> {
        Self::from_weights(mesh::BLAZEFACE_WEIGHTS, mesh::MESH_WEIGHTS)
    }

    /// A finder from weight files in the `scripts/convert-mediapipe.py` format (the detector's,
    /// then the mesh's).
    pub fn from_weights(detector: &[u8], mesh: &[u8]) -> Result<Self> {
        Ok(FaceFinder {
            nets: MeshNets::load(detector, mesh)?,
            options: FindOptions::default(),
            calibrate: true,
            local: LocalCorrection::shipped()?,
            local_on: true,
            local_scratch: LocalScratch::default(),
            detections: Vec::new(),
            pass: Vec::new(),
            mirror: Vec::new(),
            mirror_pass: Vec::new(),
        })
    }

    /// Whether the points are moved onto dlib's convention (the default); off only to measure
    /// that calibration (`examples/finder_data.rs calibration`).
    pub fn set_calibrated(&mut self, on: bool) {
        self.calibrate = on;
    }

    /// Whether the calibrated points are then moved by the local correction (`local.rs`; the
    /// default); off to learn it (`examples/finder_data.rs local`) and to measure it. No effect
    /// on points that are not calibrated.
    pub fn set_local_correction(&mut self, on: bool) {
        self.local_on = on;
    }

    /// Whether the local correction is on ([`set_local_correction`](Self::set_local_correction)).
    pub fn local_correction(&self) -> bool {
        self.local_on
    }

    /// The options [`find`](Self::find) uses.
    pub fn options(&self) -> FindOptions {
        self.options
    }

    /// Sets the options (a threshold that is not a finite number keeps its default).
    pub fn set_options(&mut self, mut options: FindOptions) {
        let d = FindOptions::default();
        for (v, d) in [
            (&mut options.score_threshold, d.score_threshold),
            (&mut options.iou_threshold, d.iou_threshold),
            (&mut options.min_face_score, d.min_face_score),
        ] {
            if !v.is_finite() {
                *v = d;
            }
        }
        self.options = options;
    }

    /// Every face's dense mesh (468 points, x, y, z interleaved; x, y in image pixels), its
    /// detection and face score, most confident detection first; drawings (see
    /// [`flat_fraction`]) left out.
    fn meshes(&mut self, image: &ImageRef) -> Vec<(Detection, f32, Vec<f32>)> {
        let mut dets = std::mem::take(&mut self.detections);
        self.nets
            .detect(image, self.options.score_threshold, &mut dets);
        let mut out: Vec<(Detection, f32, Vec<f32>)> = Vec::new();
        for det in dets.iter().take(self.options.max_candidates) {
            // A second detection of a face already meshed costs no passes.
            if out.iter().any(|(_, _, m)| {
                BBox::of_pairs(m.chunks_exact(3).map(|p| (p[0], p[1]))).iou(&det.bbox) > 0.3
            }) {
                continue;
            }
            let mut pts = vec![0.0; MESH_POINTS * 3];
            if let Some(score) = self.passes(image, Roi::from_detection(det), &mut pts) {
                if score >= self.options.min_face_score && flat_fraction(image, &pts) <= MAX_FLAT {
                    out.push((*det, score, pts));
                }
            }
        }
        self.detections = dets;
        out
    }

    /// Every face's dense mesh ([`MESH_POINTS`](super::MESH_POINTS) points, x, y, z
    /// interleaved; x, y in image pixels, z in the same scale), most confident detection
    /// first: the points [`FaceFinder::find`] takes its 68 from (`examples/mesh_table.rs`
    /// learns which from these). The forehead and the face's outline are there too.
    pub fn dense_meshes(&mut self, image: &ImageRef) -> Vec<Vec<f32>> {
        self.meshes(image).into_iter().map(|(_, _, m)| m).collect()
    }

    /// [`MESH_PASSES`] mesh passes from `roi` into `pts`; the last pass's face score (`None`
    /// when a pass fails).
    fn passes(&mut self, image: &ImageRef, roi: Roi, pts: &mut [f32]) -> Option<f32> {
        let mut score = self.nets.mesh(image, &roi, pts).ok()?;
        for _ in 1..MESH_PASSES {
            if score < self.options.min_face_score {
                break;
            }
            let roi = Roi::from_mesh(pts);
            score = self.nets.mesh(image, &roi, pts).ok()?;
        }
        Some(score)
    }

    /// Every face in `image`, most confident first.
    ///
    /// The detector (BlazeFace on the image letterboxed into 128x128) proposes faces down to
    /// [`FindOptions::score_threshold`]; on each of the [`FindOptions::max_candidates`] most
    /// confident (skipping those over a face already meshed) the mesh runs twice, first on
    /// the detection's region (1.5 times its box, turned level with its eyes), then on the
    /// region of the first pass's points. A region is a face when the mesh's own face score is
    /// [`FindOptions::min_face_score`] or more and its vertices do not lie on flat-filled
    /// pixels (a drawing: see `docs/finding.md`, "False faces"). The score is the geometric
    /// mean of the detector's and the mesh's. With [`FindOptions::mirror`] each face's points
    /// are the mean of these and of two more passes on the mirror image (each calibrated and
    /// corrected in its own image).
    pub fn find(&mut self, image: &ImageRef) -> Vec<Face> {
        let mut faces: Vec<Face> = Vec::new();
        let mut mirrored = false;
        for (det, score, pts) in self.meshes(image) {
            let mut landmarks = vec![0.0; 136];
            mesh_table::to_ibug(&pts, &mut landmarks);
            let bbox = BBox::around_landmarks(&landmarks);
            if faces
                .iter()
                .any(|f| f.bbox.iou(&bbox) > self.options.iou_threshold)
            {
                continue;
            }
            mesh_table::silhouette(&pts, &mut landmarks);
            if self.calibrate {
                calibration::apply(&mut landmarks);
            }
            self.correct(image, &mut landmarks);
            if self.options.mirror {
                if !mirrored {
                    image.mirror_into(&mut self.mirror);
                    mirrored = true;
                }
                self.add_mirror(image, &det, &mut landmarks);
            }
            if landmarks.iter().all(|v| v.is_finite()) {
                faces.push(Face {
                    bbox,
                    score: (det.score * score).sqrt(),
                    landmarks,
                });
            }
        }
        faces.sort_by(|a, b| b.score.total_cmp(&a.score));
        faces.truncate(self.options.max_faces);
        faces
    }

    /// The local correction of calibrated points (when on), in the image they were placed on.
    fn correct(&mut self, image: &ImageRef, points: &mut [f32]) {
        if self.calibrate && self.local_on {
            self.local.apply(image, points, &mut self.local_scratch);
        }
    }

    /// [`FindOptions::mirror`]: the face of `det` meshed on the mirror image (`self.mirror`,
    /// made from `image`), its 68 points mirrored back and averaged into `landmarks` (each
    /// pass's points calibrated and corrected in its own image, so the convention offsets and
    /// the local correction are averaged with their mirror too). Leaves `landmarks` as they
    /// are when the mirror pass finds no face.
    fn add_mirror(&mut self, image: &ImageRef, det: &Detection, landmarks: &mut [f32]) {
        let w = image.width() as f32;
        let mirror = std::mem::take(&mut self.mirror);
        let Ok(view) = ImageRef::new(image.width(), image.height(), &mirror) else {
            self.mirror = mirror;
            return;
        };
        // The detection's region, mirrored: the centre across the image, the turn reversed.
        let roi = Roi::from_detection(det);
        let roi = Roi {
            cx: w - roi.cx,
            angle: -roi.angle,
            ..roi
        };
        let mut pts = std::mem::take(&mut self.mirror_pass);
        pts.resize(MESH_POINTS * 3, 0.0);
        let score = self.passes(&view, roi, &mut pts);
        if score.is_some_and(|s| s >= self.options.min_face_score) {
            let mut m = [0.0f32; 136];
            mesh_table::to_ibug(&pts, &mut m);
            mesh_table::silhouette(&pts, &mut m);
            if self.calibrate {
                calibration::apply(&mut m);
            }
            self.correct(&view, &mut m);
            let mut back = [0.0f32; 136];
            crate::landmarks::mirror_points(&m, w, &mut back);
            for (l, p) in landmarks.chunks_exact_mut(2).zip(back.chunks_exact(2)) {
                if p.iter().all(|v| v.is_finite()) {
                    l[0] = 0.5 * (l[0] + p[0]);
                    l[1] = 0.5 * (l[1] + p[1]);
                }
            }
        }
        self.mirror_pass = pts;
        self.mirror = mirror;
    }

    /// The 68 points of the face in `bbox` (a box like [`Face::bbox`]), in dlib's convention.
    pub fn landmarks(&mut self, image: &ImageRef, bbox: BBox) -> Result<Vec<f32>> {
        let mut out = vec![0.0; 136];
        self.landmarks_into(image, bbox, &mut out)?;
        Ok(out)
    }

    /// [`landmarks`](Self::landmarks) into a caller's buffer of 136 values.
    pub fn landmarks_into(&mut self, image: &ImageRef, bbox: BBox, out: &mut [f32]) -> Result<()> {
        self.scored_landmarks_into(image, bbox, out).map(|_| ())
    }

    /// [`landmarks_into`](Self::landmarks_into), returning the mesh's face score (0..1: under
    /// [`FindOptions::min_face_score`] the box holds no face): a mesh pass on the square of
    /// 1.5 times the box's longer side about its centre, then one on the region of that pass's
    /// points.
    pub fn scored_landmarks_into(
        &mut self,
        image: &ImageRef,
        bbox: BBox,
        out: &mut [f32],
    ) -> Result<f32> {
        if let Err(e) = check_points(out) {
            self.pass.clear();
            return Err(e);
        }
        if !bbox.is_valid() {
            self.pass.clear();
            return Err(Error::Image(format!("invalid face box {bbox:?}")));
        }
        let roi = Roi {
            cx: bbox.x + 0.5 * bbox.width,
            cy: bbox.y + 0.5 * bbox.height,
            side: mesh::ROI_SCALE * bbox.width.max(bbox.height),
            angle: 0.0,
        };
        let mut pts = std::mem::take(&mut self.pass);
        pts.resize(MESH_POINTS * 3, 0.0);
        let r = self.nets.mesh(image, &roi, &mut pts).and_then(|_| {
            let roi = Roi::from_mesh(&pts);
            self.nets.mesh(image, &roi, &mut pts)
        });
        self.pass = pts;
        self.finish(image, r, out)
    }

    /// Follows the face of the last [`scored_landmarks_into`](Self::scored_landmarks_into) or
    /// `follow_into` into the next frame `image`: one mesh pass on the region of that call's
    /// mesh (MediaPipe's tracking from frame to frame, half the cost of a call from a box); the
    /// 68 points into `out` and the mesh's face score, as `scored_landmarks_into`. Fails with
    /// [`Error::Landmarks`] when there is no such face (no call yet, or the last one failed).
    pub fn follow_into(&mut self, image: &ImageRef, out: &mut [f32]) -> Result<f32> {
        check_points(out)?;
        if self.pass.len() != MESH_POINTS * 3 {
            return Err(Error::Landmarks("no face to follow".into()));
        }
        let roi = Roi::from_mesh(&self.pass);
        let mut pts = std::mem::take(&mut self.pass);
        let r = self.nets.mesh(image, &roi, &mut pts);
        self.pass = pts;
        self.finish(image, r, out)
    }

    /// The end of a mesh call: on success the 68 points of `self.pass` into `out` (calibrated
    /// and corrected in `image`) and the score; on failure `self.pass` is cleared, so `follow_into` fails until a new face
    /// is given.
    fn finish(&mut self, image: &ImageRef, r: Result<f32>, out: &mut [f32]) -> Result<f32> {
        let score = match r {
            Ok(s) => s,
            Err(e) => {
                self.pass.clear();
                return Err(e);
            }
        };
        mesh_table::to_ibug(&self.pass, out);
        mesh_table::silhouette(&self.pass, out);
        if self.calibrate {
            calibration::apply(out);
        }
        self.correct(image, out);
        if out.iter().all(|v| v.is_finite()) {
            Ok(score)
        } else {
            self.pass.clear();
            Err(Error::Image("the mesh gave non-finite points".into()))
        }
    }
}

/// Fails with [`Error::Landmarks`] unless `out` holds 68 points (136 values).
fn check_points(out: &[f32]) -> Result<()> {
    if out.len() == 136 {
        Ok(())
    } else {
        Err(Error::Landmarks(format!(
            "{} values, expected 136",
            out.len()
        )))
    }
}

/// The fraction of a mesh's vertices (inside the image) whose 5x5 pixel neighbourhood is one
/// flat colour: the filled areas of a drawing (a smiley, a logo) that a photographed face,
/// with its shading, sensor noise and compression, does not have.
///
/// Measured (every 5th frame of GRID, franck-dev, franck-dev2 and webcam-dev, 833 faces): at
/// most 0.004 on a face; the drawn smiley of the no-face test set, which the mesh scores 0.70,
/// is flat at 0.95 of its vertices even with the 1-pixel neighbourhood (faces: 0.043 at most).
/// A face magnified with nearest-neighbour scaling by 5 or more would look flat too.
pub(crate) fn flat_fraction(image: &ImageRef, mesh: &[f32]) -> f32 {
    let (w, h) = (image.width() as i64, image.height() as i64);
    let data = image.data();
    let grey = |x: i64, y: i64| {
        let i = ((y * w + x) * 4) as usize;
        u32::from(data[i]) + u32::from(data[i + 1]) + u32::from(data[i + 2])
    };
    let (mut inside, mut flat) = (0u32, 0u32);
    for p in mesh.chunks_exact(3) {
        if !(p[0].is_finite() && p[1].is_finite()) {
            continue;
        }
        let (x, y) = (p[0].round() as i64, p[1].round() as i64);
        if x < 2 || y < 2 || x + 2 >= w || y + 2 >= h {
            continue;
        }
        inside += 1;
        let c = grey(x, y);
        if (-2..=2).all(|dy| (-2..=2).all(|dx| grey(x + dx, y + dy) == c)) {
            flat += 1;
        }
    }
    if inside == 0 {
        0.0
    } else {
        flat as f32 / inside as f32
    }
}

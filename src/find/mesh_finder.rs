//! [`MeshFinder`]: faces and their 68 iBUG points from MediaPipe's face detector and face mesh
//! (`mesh.rs`), with the interface of [`FaceFinder`](super::FaceFinder). Built with the cargo
//! feature `mesh-finder`; not the crate's finder (see `docs/finding.md`, "MediaPipe's nets").

use super::calibration;
use super::mesh::{self, Detection, MeshNets, Roi, DETECTOR_MIN_SCORE, MESH_POINTS};
use super::mesh_table;
use super::{Face, FindOptions};
use crate::error::{Error, Result};
use crate::geometry::BBox;
use crate::image::ImageRef;

/// Mesh passes per face: the first on the detector's region, the next on the region of the
/// previous pass's points (as MediaPipe does from frame to frame). Measured on every 4th frame
/// of franck-dev, franck-dev2 and webcam-dev: one pass 0.0288 / 0.0344 / 0.0309, two passes
/// 0.0279 / 0.0329 / 0.0287.
const MESH_PASSES: usize = 2;
/// Face-presence score below which the mesh's region is not a face (MediaPipe's tracking
/// threshold).
const MESH_MIN_FACE: f32 = 0.5;

/// Finds faces with MediaPipe's BlazeFace (short range) and places the 68 iBUG points from its
/// 468-point face mesh, moved onto dlib's convention like [`FaceFinder`](super::FaceFinder)'s.
/// Holds the nets and all scratch buffers: reuse one finder.
pub struct MeshFinder {
    nets: MeshNets,
    options: FindOptions,
    calibrate: bool,
    detections: Vec<Detection>,
    /// The scratch mesh of `landmarks_into`.
    pass: Vec<f32>,
}

impl std::fmt::Debug for MeshFinder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshFinder")
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl MeshFinder {
    /// A finder with the converted MediaPipe weights shipped in the crate.
    pub fn new() -> Result<Self> {
        Ok(MeshFinder {
            nets: MeshNets::load(mesh::BLAZEFACE_WEIGHTS, mesh::MESH_WEIGHTS)?,
            options: FindOptions::default(),
            calibrate: true,
            detections: Vec::new(),
            pass: Vec::new(),
        })
    }

    /// Whether the points are moved onto dlib's convention (the default); off only to measure
    /// that calibration.
    pub fn set_calibrated(&mut self, on: bool) {
        self.calibrate = on;
    }

    /// The options: of [`FindOptions`], `max_faces`, `max_candidates` and `iou_threshold` are
    /// used (the detector's own threshold is MediaPipe's, 0.5).
    pub fn set_options(&mut self, options: FindOptions) {
        self.options = options;
    }

    /// Every face's dense mesh (468 points, x, y, z interleaved; x, y in image pixels), its
    /// detection and face score, most confident detection first.
    pub(crate) fn meshes(&mut self, image: &ImageRef) -> Vec<(Detection, f32, Vec<f32>)> {
        let mut dets = std::mem::take(&mut self.detections);
        self.nets.detect(image, DETECTOR_MIN_SCORE, &mut dets);
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
                if score >= MESH_MIN_FACE {
                    out.push((*det, score, pts));
                }
            }
        }
        self.detections = dets;
        out
    }

    /// Every face's dense mesh ([`MESH_POINTS`] points, x, y, z interleaved; x, y in image
    /// pixels), most confident detection first: the points [`MeshFinder::find`] takes its 68
    /// from (`examples/mesh_table.rs` learns which from these).
    pub fn dense_meshes(&mut self, image: &ImageRef) -> Vec<Vec<f32>> {
        self.meshes(image).into_iter().map(|(_, _, m)| m).collect()
    }

    /// [`MESH_PASSES`] mesh passes from `roi` into `pts`; the last pass's face score (`None`
    /// when a pass fails).
    fn passes(&mut self, image: &ImageRef, roi: Roi, pts: &mut [f32]) -> Option<f32> {
        let mut score = self.nets.mesh(image, &roi, pts).ok()?;
        for _ in 1..MESH_PASSES {
            if score < MESH_MIN_FACE {
                break;
            }
            let roi = Roi::from_mesh(pts);
            score = self.nets.mesh(image, &roi, pts).ok()?;
        }
        Some(score)
    }

    /// Every face in `image`, most confident first: boxes (as
    /// [`BBox::around_landmarks`]), scores (the geometric mean of the detector's and the
    /// mesh's face score) and 68 points in dlib's convention.
    pub fn find(&mut self, image: &ImageRef) -> Vec<Face> {
        let mut faces: Vec<Face> = Vec::new();
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
            if self.calibrate {
                calibration::apply_mesh(&mut landmarks);
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

    /// The 68 points of the face in `bbox` (a box like [`Face::bbox`]).
    pub fn landmarks(&mut self, image: &ImageRef, bbox: BBox) -> Result<Vec<f32>> {
        let mut out = vec![0.0; 136];
        self.landmarks_into(image, bbox, &mut out)?;
        Ok(out)
    }

    /// [`landmarks`](Self::landmarks) into a caller's buffer of 136 values: a mesh pass on the
    /// square of 1.5 times the box's longer side about its centre, then one on the region of
    /// that pass's points.
    pub fn landmarks_into(&mut self, image: &ImageRef, bbox: BBox, out: &mut [f32]) -> Result<()> {
        if out.len() != 136 {
            return Err(Error::Landmarks(format!(
                "{} values, expected 136",
                out.len()
            )));
        }
        if !(bbox.x.is_finite()
            && bbox.y.is_finite()
            && bbox.width.is_finite()
            && bbox.height.is_finite()
            && bbox.width >= 1.0
            && bbox.height >= 1.0)
        {
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
        if r.is_ok() {
            mesh_table::to_ibug(&pts, out);
        }
        self.pass = pts;
        r?;
        if self.calibrate {
            calibration::apply_mesh(out);
        }
        if out.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(Error::Image("the mesh gave non-finite points".into()))
        }
    }
}

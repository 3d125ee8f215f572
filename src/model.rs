//! The person-specific AAM: shape model, appearance model and reference frame together.

use serde::{Deserialize, Serialize};

use crate::appearance::AppearanceModel;
use crate::error::{check_len, Error, Result};
use crate::frame::ReferenceFrame;
use crate::image::ImageRef;
use crate::shape::ShapeModel;
use crate::similarity::Similarity;

/// The landmark layout a model uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LandmarkScheme {
    /// The 68-point iBUG / 300-W layout (0-16 jaw, 17-26 brows, 27-35 nose, 36-47 eyes,
    /// 48-67 mouth).
    Ibug68,
    /// Any other layout with the given number of points (e.g. IMM's 58).
    Generic(u32),
}

impl LandmarkScheme {
    /// The scheme for `n` landmarks.
    pub fn for_count(n: usize) -> Self {
        if n == 68 {
            LandmarkScheme::Ibug68
        } else {
            LandmarkScheme::Generic(n as u32)
        }
    }
    /// Number of landmarks.
    pub fn count(&self) -> usize {
        match self {
            LandmarkScheme::Ibug68 => 68,
            LandmarkScheme::Generic(n) => *n as usize,
        }
    }
}

/// Which face the model's bases `s0` and `A0` show (the paper's section 5 extension).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Reference {
    /// The mean of the training set (the paper's default).
    Mean,
    /// One training image, by its name (file stem); the modes are computed about it.
    Training(String),
}

/// The parameters of one face instance: pose, shape parameters `p`, appearance parameters
/// `lambda`. Serialised as the JSON that `facemimic project` prints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Params {
    /// Similarity from model coordinates to image pixels.
    pub pose: Similarity,
    /// Shape parameters `p` (length `m`).
    pub shape: Vec<f32>,
    /// Appearance parameters `lambda` (length `l`).
    pub appearance: Vec<f32>,
}

/// A person-specific Active Appearance Model.
///
/// Represents: a shape model (Eq. 1), an appearance model (Eq. 2) on the pixels of a
/// reference frame, the base mesh of that frame, which face the bases show, and the average
/// pose and size of the training images (for placing the face on a canvas).
/// Ensures (after [`crate::Builder::build`] or [`crate::format::read_model`]): all dimensions
/// agree (`2n` shape values, `3N` appearance values with `N` the frame's pixel count), every
/// number finite, the frame's landmark count equals the shape's.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// A short name (for people; e.g. "spk07").
    pub name: String,
    /// The landmark layout.
    pub scheme: LandmarkScheme,
    /// Shape model in model coordinates.
    pub shape: ShapeModel,
    /// Appearance model over the frame pixels.
    pub appearance: AppearanceModel,
    /// Reference frame (mesh, pixel grid, barycentrics).
    pub frame: ReferenceFrame,
    /// Which face the bases show.
    pub reference: Reference,
    /// Average pose of the training faces in their images.
    pub mean_pose: Similarity,
    /// Size of the training images `(width, height)`.
    pub image_size: [u32; 2],
}

impl Model {
    /// Number of landmarks.
    pub fn landmarks(&self) -> usize {
        self.shape.landmarks()
    }

    /// The parameters of the base face at the average training pose.
    pub fn base_params(&self) -> Params {
        Params {
            pose: self.mean_pose,
            shape: vec![0.0; self.shape.n_modes()],
            appearance: vec![0.0; self.appearance.n_modes()],
        }
    }

    /// Checks that `params` fits this model: lengths, finite values within
    /// [`crate::bounds::MAX_PARAM`], a pose within the pose bounds (see [`crate::bounds`]).
    pub fn check_params(&self, params: &Params) -> Result<()> {
        crate::bounds::check_params(self, params)
    }

    /// The instance's landmarks in image coordinates: `pose(s0 + S p)` into `out` (`2n`).
    pub fn image_shape(&self, params: &Params, out: &mut [f32]) -> Result<()> {
        self.check_params(params)?;
        check_len("shape buffer", out, self.shape.base.len())?;
        self.shape.instance_unchecked(&params.shape, out);
        params.pose.apply_in_place(out);
        crate::bounds::check_output("instance landmarks", out)
    }

    /// Projects a face: its landmarks (image coordinates) give the pose and `p`; the image
    /// sampled at the landmarks into the frame gives `lambda`.
    pub fn project(&self, image: &ImageRef<'_>, landmarks: &[f32]) -> Result<Params> {
        if landmarks.len() != self.shape.base.len() {
            return Err(Error::Landmarks(format!(
                "{} points given, the model '{}' has {} landmarks",
                landmarks.len() / 2,
                self.name,
                self.landmarks()
            )));
        }
        let mut shape = vec![0.0; self.shape.n_modes()];
        let pose = self.shape.project_image_shape(landmarks, &mut shape)?;
        let mut g = vec![0.0; self.appearance.len()];
        crate::warp::sample_rgb(&self.frame, image, landmarks, &mut g)?;
        let mut appearance = vec![0.0; self.appearance.n_modes()];
        self.appearance.project(&g, &mut appearance);
        crate::bounds::check_output("appearance parameters", &appearance)?;
        crate::bounds::check_output("shape parameters", &shape)?;
        Ok(Params {
            pose,
            shape,
            appearance,
        })
    }

    /// Fails with [`Error::Incompatible`] unless `other` uses the same landmark scheme and the
    /// same reference frame (same pixels), naming what differs.
    pub fn check_compatible(&self, other: &Model) -> Result<()> {
        if self.scheme != other.scheme {
            return Err(Error::Incompatible(format!(
                "'{}' has {} landmarks ({:?}), '{}' has {} ({:?})",
                self.name,
                self.landmarks(),
                self.scheme,
                other.name,
                other.landmarks(),
                other.scheme
            )));
        }
        if self.frame != other.frame {
            return Err(Error::Incompatible(format!(
                "'{}' and '{}' use different reference frames (fingerprints {:016x} and {:016x}, \
                 {}x{} with {} pixels and {}x{} with {} pixels); build one in the other's frame \
                 with `facemimic build --frame`",
                self.name,
                other.name,
                self.frame.fingerprint(),
                other.frame.fingerprint(),
                self.frame.width(),
                self.frame.height(),
                self.frame.n_pixels(),
                other.frame.width(),
                other.frame.height(),
                other.frame.n_pixels()
            )));
        }
        Ok(())
    }
}

//! The person-specific AAM: shape model, appearance model and reference frame together, and
//! what holds them: the model file ([`format`]), the input limits ([`bounds`]), the backdrop
//! and the piecewise-affine sampling through the frame.
//!
//! - `mod.rs`: [`Model`], [`Params`], [`ModelParts`] (a model is built by [`crate::Builder`] or
//!   read by [`format::read_model`]).
//! - `shape.rs` / `appearance.rs`: the two linear models (Eq. 1, Eq. 2), both a
//!   `linear::LinearModel` with their own meaning on top.
//! - `frame.rs`: the triangulated reference frame; `warp.rs`: sampling an image through it.
//! - `format/`: the `.fmm` file (layout, reader, writer, appearance codec).
//! - `limits.rs` / `bounds.rs`: the limits every input is checked against.
//! - `backdrop.rs`: the picture a model's face is composited into.

pub(crate) mod appearance;
pub(crate) mod backdrop;
pub mod bounds;
pub mod format;
pub(crate) mod frame;
pub(crate) mod limits;
pub(crate) mod linear;
pub(crate) mod shape;
pub(crate) mod warp;

use serde::{Deserialize, Serialize};

use std::sync::Arc;

use crate::error::{check_len, Error, Result};
use crate::image::ImageRef;
use crate::model::appearance::AppearanceModel;
use crate::model::backdrop::Backdrop;
use crate::model::frame::ReferenceFrame;
use crate::model::limits::{check_output, check_param_values, check_pose_range};
use crate::model::shape::ShapeModel;
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
/// Ensures: all dimensions agree (`2n` shape values, `3N` appearance values with `N` the
/// frame's pixel count, `n` the scheme's and the frame's landmark count, one variance per
/// mode) and every number is finite. The fields are private: a `Model` only comes from
/// [`Model::new`] (which checks all of this), [`crate::Builder`] or
/// [`crate::model::format::read_model`], so code holding one need not check it again. The value
/// bounds of the file format ([`crate::model::bounds`]) are checked when a model is read or written.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// The parts, checked by [`Model::new`].
    parts: ModelParts,
    /// The picture the face is composited into, if any (shared: models are cloned per target).
    backdrop: Option<Arc<Backdrop>>,
}

/// Everything a [`Model`] is made of, with public fields: build one, then check it with
/// [`Model::new`]; [`Model::into_parts`] takes a model apart again.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelParts {
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
    /// Checks `parts` and makes a model of them. Fails with [`Error::Incompatible`] ("model
    /// 'name' is inconsistent: ...") naming the first part that does not fit: the scheme's,
    /// the shape's and the frame's landmark counts, the modes' lengths against the bases (`3N`
    /// appearance values for a frame of `N` pixels), a value that is not finite, a negative
    /// variance, or a mean pose of zero scale.
    pub fn new(parts: ModelParts) -> Result<Model> {
        if let Err(what) = check_parts(&parts) {
            return Err(Error::Incompatible(format!(
                "model '{}' is inconsistent: {what}",
                parts.name
            )));
        }
        Ok(Model {
            parts,
            backdrop: None,
        })
    }

    /// The model with `backdrop` as the picture its face is composited into. Fails with
    /// [`Error::Landmarks`] unless the backdrop's landmarks are this model's landmark count.
    pub fn with_backdrop(mut self, backdrop: Backdrop) -> Result<Model> {
        if backdrop.landmarks().len() != self.parts.shape.base.len() {
            return Err(Error::Landmarks(format!(
                "the backdrop has {} landmarks, the model '{}' has {}",
                backdrop.landmarks().len() / 2,
                self.parts.name,
                self.landmarks()
            )));
        }
        self.backdrop = Some(Arc::new(backdrop));
        Ok(self)
    }

    /// The model without its backdrop (it then renders face only, as before backdrops).
    pub fn without_backdrop(mut self) -> Model {
        self.backdrop = None;
        self
    }

    /// The picture the face is composited into, if the model carries one.
    pub fn backdrop(&self) -> Option<&Backdrop> {
        self.backdrop.as_deref()
    }

    /// True for a model made from one photo: no shape or appearance modes of its own (it is a
    /// base face; cloning onto it substitutes the source's modes, Fig. 4 A).
    pub fn is_photo(&self) -> bool {
        self.parts.shape.n_modes() == 0 && self.parts.appearance.n_modes() == 0
    }

    /// Where the face sits at rest: the pose of the base shape on the backdrop's landmarks when
    /// the model has a backdrop (the face composited in its own picture), the mean training pose
    /// otherwise. Cloned targets move about this pose.
    pub fn home_pose(&self) -> Similarity {
        match &self.backdrop {
            Some(b) => {
                let pose = Similarity::align(&self.parts.shape.base, b.landmarks());
                if pose.is_valid() {
                    pose
                } else {
                    self.parts.mean_pose
                }
            }
            None => self.parts.mean_pose,
        }
    }

    /// The size of the picture the face is shown in: the backdrop's when there is one, the
    /// training images' otherwise.
    pub fn home_size(&self) -> [u32; 2] {
        match &self.backdrop {
            Some(b) => [b.width(), b.height()],
            None => self.parts.image_size,
        }
    }

    /// Takes the model apart (to change a part and check it again with [`Model::new`]; the
    /// backdrop is not among the parts: add it again with [`Model::with_backdrop`]).
    pub fn into_parts(self) -> ModelParts {
        self.parts
    }

    /// A short name (for people; e.g. "spk07").
    pub fn name(&self) -> &str {
        &self.parts.name
    }

    /// Renames the model (any text; the file format limits its length when it is written).
    pub fn set_name(&mut self, name: impl Into<String>) {
        self.parts.name = name.into();
    }

    /// The landmark layout.
    pub fn scheme(&self) -> LandmarkScheme {
        self.parts.scheme
    }

    /// The shape model (Eq. 1), in model coordinates.
    pub fn shape(&self) -> &ShapeModel {
        &self.parts.shape
    }

    /// The appearance model (Eq. 2) over the frame's pixels.
    pub fn appearance(&self) -> &AppearanceModel {
        &self.parts.appearance
    }

    /// The reference frame (mesh, pixel grid, barycentrics).
    pub fn frame(&self) -> &ReferenceFrame {
        &self.parts.frame
    }

    /// Which face the bases show.
    pub fn reference(&self) -> &Reference {
        &self.parts.reference
    }

    /// The average pose of the training faces in their images.
    pub fn mean_pose(&self) -> Similarity {
        self.parts.mean_pose
    }

    /// The size of the training images `[width, height]`.
    pub fn image_size(&self) -> [u32; 2] {
        self.parts.image_size
    }

    /// Number of landmarks.
    pub fn landmarks(&self) -> usize {
        self.parts.shape.landmarks()
    }

    /// The parameters of the base face at the average training pose.
    pub fn base_params(&self) -> Params {
        Params {
            pose: self.parts.mean_pose,
            shape: vec![0.0; self.parts.shape.n_modes()],
            appearance: vec![0.0; self.parts.appearance.n_modes()],
        }
    }

    /// Checks that `params` fits this model: lengths, finite values within
    /// [`crate::model::bounds::MAX_PARAM`], a pose within the pose bounds (see [`crate::model::bounds`]).
    pub fn check_params(&self, params: &Params) -> Result<()> {
        check_len(
            "shape parameters",
            &params.shape,
            self.parts.shape.n_modes(),
        )?;
        check_len(
            "appearance parameters",
            &params.appearance,
            self.parts.appearance.n_modes(),
        )?;
        check_param_values("shape parameters", &params.shape)?;
        check_param_values("appearance parameters", &params.appearance)?;
        check_pose_range("pose", &params.pose)
    }

    /// The instance's landmarks in image coordinates: `pose(s0 + S p)` into `out` (`2n`).
    pub fn image_shape(&self, params: &Params, out: &mut [f32]) -> Result<()> {
        self.check_params(params)?;
        check_len("shape buffer", out, self.parts.shape.base.len())?;
        self.parts.shape.instance_unchecked(&params.shape, out);
        params.pose.apply_in_place(out);
        check_output("instance landmarks", out)
    }

    /// Projects a face: its landmarks (image coordinates) give the pose and `p`; the image
    /// sampled at the landmarks into the frame gives `lambda`.
    pub fn project(&self, image: &ImageRef<'_>, landmarks: &[f32]) -> Result<Params> {
        if landmarks.len() != self.parts.shape.base.len() {
            return Err(Error::Landmarks(format!(
                "{} points given, the model '{}' has {} landmarks",
                landmarks.len() / 2,
                self.parts.name,
                self.landmarks()
            )));
        }
        let mut shape = vec![0.0; self.parts.shape.n_modes()];
        let pose = self
            .parts
            .shape
            .project_image_shape(landmarks, &mut shape)?;
        let mut g = vec![0.0; self.parts.appearance.len()];
        crate::model::warp::sample_rgb(&self.parts.frame, image, landmarks, &mut g)?;
        let mut appearance = vec![0.0; self.parts.appearance.n_modes()];
        self.parts.appearance.project(&g, &mut appearance);
        check_output("appearance parameters", &appearance)?;
        check_output("shape parameters", &shape)?;
        Ok(Params {
            pose,
            shape,
            appearance,
        })
    }

    /// Fails with [`Error::Incompatible`] unless `other` uses the same landmark scheme and the
    /// same reference frame (same pixels), naming what differs.
    pub fn check_compatible(&self, other: &Model) -> Result<()> {
        if self.parts.scheme != other.parts.scheme {
            return Err(Error::Incompatible(format!(
                "'{}' has {} landmarks ({:?}), '{}' has {} ({:?})",
                self.parts.name,
                self.landmarks(),
                self.parts.scheme,
                other.parts.name,
                other.landmarks(),
                other.parts.scheme
            )));
        }
        if self.parts.frame != other.parts.frame {
            return Err(Error::Incompatible(format!(
                "'{}' and '{}' use different reference frames (fingerprints {:016x} and {:016x}, \
                 {}x{} with {} pixels and {}x{} with {} pixels); build one in the other's frame \
                 with `facemimic build --frame`",
                self.parts.name,
                other.parts.name,
                self.parts.frame.fingerprint(),
                other.parts.frame.fingerprint(),
                self.parts.frame.width(),
                self.parts.frame.height(),
                self.parts.frame.n_pixels(),
                other.parts.frame.width(),
                other.parts.frame.height(),
                other.parts.frame.n_pixels()
            )));
        }
        Ok(())
    }
}

/// What [`Model::new`] checks, as a message naming the first problem.
fn check_parts(m: &ModelParts) -> std::result::Result<(), String> {
    let d = m.shape.base.len();
    let da = m.appearance.linear().base.len();
    if d == 0 || d != 2 * m.frame.landmarks() || d != 2 * m.scheme.count() {
        return Err(format!(
            "{} shape values for {} frame landmarks ({:?})",
            d,
            m.frame.landmarks(),
            m.scheme
        ));
    }
    if da != 3 * m.frame.n_pixels() {
        return Err(format!(
            "{da} appearance values for {} frame pixels",
            m.frame.n_pixels()
        ));
    }
    if Some(m.shape.modes.len()) != d.checked_mul(m.shape.variances.len()) {
        return Err(format!(
            "{} shape mode values for {} modes",
            m.shape.modes.len(),
            m.shape.variances.len()
        ));
    }
    if Some(m.appearance.linear().modes.len())
        != da.checked_mul(m.appearance.linear().variances.len())
    {
        return Err(format!(
            "{} appearance mode values for {} modes",
            m.appearance.linear().modes.len(),
            m.appearance.linear().variances.len()
        ));
    }
    let pose = [m.mean_pose.a, m.mean_pose.b, m.mean_pose.tx, m.mean_pose.ty];
    for (what, values) in [
        ("shape base", &m.shape.base[..]),
        ("shape modes", &m.shape.modes[..]),
        ("appearance base", &m.appearance.linear().base[..]),
        ("appearance modes", &m.appearance.linear().modes[..]),
        ("mean pose", &pose[..]),
    ] {
        crate::error::check_finite(what, values).map_err(|e| e.to_string())?;
    }
    if m.shape
        .variances
        .iter()
        .chain(m.appearance.variances())
        .any(|v| !(v.is_finite() && *v >= 0.0))
    {
        return Err("a variance is negative or not finite".into());
    }
    if !m.mean_pose.is_valid() {
        return Err("its mean pose is not a valid similarity".into());
    }
    Ok(())
}

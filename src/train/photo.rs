//! Models of a single picture: a target made from one photo, and the backdrop of a built
//! model (the picture its face is composited into).

use crate::error::{Error, Result};
use crate::image::ImageRef;
use crate::model::appearance::AppearanceModel;
use crate::model::backdrop::Backdrop;
use crate::model::frame::ReferenceFrame;
use crate::model::shape::ShapeModel;
use crate::model::{LandmarkScheme, Model, ModelParts, Reference};
use crate::similarity::Similarity;
use crate::train::TrainingImage;

/// Smallest face a photo target accepts: the landmarks' bounding box must be at least this many
/// pixels wide (smaller faces have too little appearance to show on a canvas).
pub const MIN_PHOTO_FACE: f32 = 64.0;

/// The longer side (pixels) a photo target's picture is kept at: a larger photo is scaled down
/// to it before its model is made (its backdrop stays sharp on a large canvas without costing a
/// camera-sized picture's memory per target).
pub const PHOTO_MAX_SIDE: u32 = 1024;

/// Fitting passes on a still photo used as a source: the AAM fit of one picture, refined from
/// its own result, settles within a few.
pub const PHOTO_FIT_PASSES: u32 = 3;

/// A target model made from one photo and its landmarks (the paper's substitution, Fig. 4 A,
/// taken to a single picture).
///
/// The photo's shape, aligned into `frame`'s model coordinates, is the base shape `s0`; the
/// photo sampled on the frame's pixels is the base appearance `A0`; the model has no modes of
/// its own, so cloning onto it adds the SOURCE's modes to the photo's face
/// ([`crate::clone::Method::Substitute`]; the other methods fall back to it). The photo is the
/// model's backdrop, so the face is composited into it.
///
/// Fails with [`Error::Landmarks`] when the landmarks do not fit the frame, fall outside the
/// photo or span a face under [`MIN_PHOTO_FACE`] pixels, and with [`Error::Image`] for a photo
/// outside the size limits.
pub fn photo_model(
    name: &str,
    photo: &ImageRef<'_>,
    landmarks: &[f32],
    frame: &ReferenceFrame,
) -> Result<Model> {
    if landmarks.len() != frame.vertices().len() {
        return Err(Error::Landmarks(format!(
            "{} points given, the reference frame has {}",
            landmarks.len() / 2,
            frame.landmarks()
        )));
    }
    crate::model::limits::check_landmarks(landmarks)?;
    let width = crate::geometry::BBox::of_points(landmarks).width;
    if !(width >= MIN_PHOTO_FACE) {
        return Err(Error::Landmarks(format!(
            "the face is {width:.0} pixels wide; a photo target needs at least {MIN_PHOTO_FACE:.0}"
        )));
    }
    let backdrop = Backdrop::encode(photo, landmarks)?;
    // Where the photo's face goes in model coordinates: the similarity onto the frame's mesh.
    let to_model = Similarity::align(landmarks, frame.vertices());
    let pose = to_model
        .inverse()
        .filter(|p| p.is_valid())
        .ok_or_else(|| Error::Landmarks("the photo's landmarks are degenerate".into()))?;
    let mut base = landmarks.to_vec();
    to_model.apply_in_place(&mut base);
    // Sample the decoded backdrop, so the base appearance is the picture the model carries.
    let mut a0 = vec![0.0; 3 * frame.n_pixels()];
    crate::model::warp::sample_rgb(frame, &backdrop.image(), landmarks, &mut a0)?;
    let model = Model::new(ModelParts {
        name: name.to_string(),
        scheme: LandmarkScheme::for_count(landmarks.len() / 2),
        shape: ShapeModel(crate::model::linear::LinearModel {
            base,
            modes: Vec::new(),
            variances: Vec::new(),
        }),
        appearance: AppearanceModel::new(a0, Vec::new(), Vec::new()),
        frame: frame.clone(),
        reference: Reference::Training(name.to_string()),
        mean_pose: pose,
        image_size: [photo.width(), photo.height()],
    })?;
    model.with_backdrop(backdrop)
}

/// The training image closest to the model's base face: the one whose projection has the
/// smallest Mahalanobis norm (shape and appearance parameters over their standard deviations).
/// `None` when no image can be projected.
pub fn closest_to_mean(model: &Model, images: &[TrainingImage]) -> Option<usize> {
    let ss = model.shape().sigmas();
    let sa = model.appearance().sigmas();
    let norm = |p: &[f32], s: &[f32]| -> f64 {
        p.iter()
            .zip(s)
            .filter(|(_, s)| **s > 0.0)
            .map(|(v, s)| ((v / s) as f64).powi(2))
            .sum()
    };
    images
        .iter()
        .enumerate()
        .filter_map(|(i, t)| {
            let image = t.image.view().ok()?;
            let params = model.project(&image, &t.landmarks).ok()?;
            Some((i, norm(&params.shape, &ss) + norm(&params.appearance, &sa)))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// `model` with a backdrop: `chosen` (a picture and its landmarks) when given, otherwise the
/// training image closest to the mean ([`closest_to_mean`]). Fails when the chosen picture
/// cannot be a backdrop (landmarks outside it, size limits); with no usable training image the
/// model is returned as it is.
pub fn with_default_backdrop(
    model: Model,
    images: &[TrainingImage],
    chosen: Option<(&ImageRef<'_>, &[f32])>,
) -> Result<Model> {
    if let Some((image, landmarks)) = chosen {
        let b = Backdrop::encode(image, landmarks)?;
        return model.with_backdrop(b);
    }
    // Closest first; a frame whose face touches the border cannot be a backdrop, try the next.
    let first = closest_to_mean(&model, images);
    let order = first
        .into_iter()
        .chain((0..images.len()).filter(|i| Some(*i) != first));
    for i in order {
        let t = &images[i];
        let Ok(view) = t.image.view() else { continue };
        if let Ok(b) = Backdrop::encode(&view, &t.landmarks) {
            return model.with_backdrop(b);
        }
    }
    Ok(model)
}

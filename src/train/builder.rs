//! Building a person-specific AAM from landmarked images.

use crate::error::{Error, Result};
pub use crate::image::TrainingImage;
use crate::model::appearance::AppearanceModel;
use crate::model::frame::ReferenceFrame;
use crate::model::shape::{generalised_procrustes, ShapeModel};
use crate::model::{LandmarkScheme, Model, ModelParts, Reference};
use crate::pca::{mean, pca};
use crate::similarity::{CentredFit, Similarity};
use crate::train::canonical::{canonical_frame, CANONICAL_LANDMARKS};

/// Which face the bases `s0`, `A0` show, and so what the modes are computed about.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum ReferenceChoice {
    /// The training mean (the paper's default).
    #[default]
    Mean,
    /// The training image with this name.
    Named(String),
    /// The training image whose aligned shape is closest to the frame model's base shape
    /// (requires building in another model's frame).
    ClosestToFrame,
    /// The training image most at rest ([`crate::most_at_rest`]: mouth closed, no smile, brows
    /// level, eyes open, facing the camera; 68-point landmarks): a person's own model, whose
    /// base is then their face at rest, the neutral a tracker measures their expressions from
    /// (section 5: cloning assumes the bases show a similar expression, and a target's
    /// reference is usually a face at rest too).
    Rest,
}

/// Which reference frame a model is built in when no frame model is given to
/// [`Builder::build`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FrameChoice {
    /// The canonical frame shipped with the crate ([`crate::canonical_frame`]) for 68-point
    /// (iBUG) landmarks, so that models built separately can be cloned between; other landmark
    /// counts have no canonical frame and get their own.
    #[default]
    Canonical,
    /// A frame of the model's own, made from its base shape (`face_width` wide).
    Own,
}

/// Options of [`Builder`].
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// A short name stored in the model.
    pub name: String,
    /// Fraction of shape variance kept (default 0.99; see [`BuildOptions::max_shape_modes`]).
    pub shape_variance: f64,
    /// Fraction of appearance variance kept (default 0.98).
    pub appearance_variance: f64,
    /// Width of the base face in frame pixels when the model has its own frame (default 150).
    pub face_width: f32,
    /// Most shape modes kept (default 12). With the 15-20 training images of a person-specific
    /// model, the modes past about a dozen describe a few images each and are poorly estimated:
    /// kept, they let the fitter's appearance-aware steps push them far off (GRID spk07 at 99%
    /// of the variance, 15 modes: a reset per frame with a weak shape prior). Measured in
    /// docs/experiments/fitting-notebook.md ("Towards franck-dev2 <= 0.016").
    pub max_shape_modes: usize,
    /// Most appearance modes kept.
    pub max_appearance_modes: usize,
    /// The reference face.
    pub reference: ReferenceChoice,
    /// The frame used when [`Builder::build`] is given no frame model.
    pub frame: FrameChoice,
    /// Estimate the shape modes from each training shape's deviation from the base shape and
    /// its mirror image (68-point landmarks; default on; the symmetric samples of the builder's
    /// `mirrored_deviations`). A face
    /// turns and moves both ways; 20 frames often show a head turn or a lopsided expression one
    /// way only, and a model without the other side has no mode for it. Measured in
    /// docs/experiments/fitting-notebook.md ("The control model").
    pub symmetric_shapes: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            name: String::from("model"),
            shape_variance: 0.99,
            appearance_variance: 0.98,
            face_width: 150.0,
            max_shape_modes: 12,
            max_appearance_modes: 64,
            reference: ReferenceChoice::Mean,
            frame: FrameChoice::Canonical,
            symmetric_shapes: true,
        }
    }
}

/// Progress of [`Builder::build_with_progress`]: `done` of `total` steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BuildProgress {
    /// Steps done.
    pub done: usize,
    /// Steps in all (training images + 2).
    pub total: usize,
}

/// Builds models (menpofit's "builder": it knows training, not fitting or rendering).
#[derive(Clone, Debug, Default)]
pub struct Builder {
    /// The options used by [`Builder::build`].
    pub options: BuildOptions,
}

impl Builder {
    /// A builder with these options.
    pub fn new(options: BuildOptions) -> Self {
        Builder { options }
    }

    /// Builds a model from landmarked images, in the reference frame of another model
    /// (`frame_of = Some(source)`: its training shapes are aligned to the source's base shape
    /// and its images sampled on the source's frame pixels, so both models share one coordinate
    /// system and one pixel grid), or with `None` in the frame chosen by
    /// [`BuildOptions::frame`]: by default the canonical frame (68 points; aligned to its base
    /// mesh), else a frame of its own.
    ///
    /// Requires: at least 2 images, all with the same landmark count (and the frame model's,
    /// when given), finite landmarks, variance fractions in `(0, 1]`.
    /// Ensures: a valid [`Model`] whose shape modes are orthonormal with descending variances.
    pub fn build(&self, images: &[TrainingImage], frame_of: Option<&Model>) -> Result<Model> {
        self.build_with_progress(images, frame_of, &mut |_| true)
    }

    /// [`Builder::build`], reporting progress after each step: `progress` gets how many of the
    /// steps are done (one per training image sampled, one for the shape model, one for the
    /// appearance model) and returns `false` to cancel, which ends the build with
    /// [`Error::Cancelled`] and no model.
    pub fn build_with_progress(
        &self,
        images: &[TrainingImage],
        frame_of: Option<&Model>,
        progress: &mut dyn FnMut(BuildProgress) -> bool,
    ) -> Result<Model> {
        let o = &self.options;
        let total = images.len() + 2;
        let mut step = |done: usize| -> Result<()> {
            if progress(BuildProgress { done, total }) {
                Ok(())
            } else {
                Err(Error::Cancelled)
            }
        };
        let n = check_inputs(o, images)?;
        let target = frame_target(o, frame_of, n)?;
        // Shape: Procrustes alignment into model coordinates, the reference, PCA (Eq. 1).
        let aligned = align_shapes(o, images, target);
        let ref_index = reference_index(o, images, &aligned, target)?;
        let shape = shape_model(o, &aligned, ref_index, n)?;
        step(1)?;
        // The reference frame: the target's, or one of the model's own.
        let frame = match target {
            Some((f, _)) => f.clone(),
            None => ReferenceFrame::from_base(&shape.base)?,
        };
        // Appearance: each image sampled at its landmarks into the frame, PCA (Eq. 2).
        let appearance = appearance_model(o, images, &frame, ref_index, &mut step)?;
        step(total)?;
        // Average pose (for placing the base face on a canvas like the training images).
        let poses: Vec<Similarity> = images
            .iter()
            .map(|t| Similarity::align(&shape.base, &t.landmarks))
            .collect();
        let mean_pose = Similarity::mean(&poses).ok_or_else(|| {
            Error::Training("the training faces' poses have no mean (degenerate landmarks)".into())
        })?;

        let model = Model::new(ModelParts {
            name: o.name.clone(),
            scheme: LandmarkScheme::for_count(n / 2),
            shape,
            appearance,
            frame,
            reference: match ref_index {
                Some(i) => Reference::Training(images[i].name.clone()),
                None => Reference::Mean,
            },
            mean_pose,
            image_size: [images[0].image.width, images[0].image.height],
        })?;
        // The builder refuses what the reader would reject (a file it writes reads back).
        crate::model::bounds::check_model_values(&model)
            .map_err(|e| Error::Training(e.to_string()))?;
        Ok(model)
    }
}

/// The frame to build in and the shape the training shapes are aligned to (`None`: a frame of
/// the model's own).
type Target<'a> = Option<(&'a ReferenceFrame, &'a [f32])>;

/// Checks the options and the images; returns the landmark values per image (`2n`).
fn check_inputs(o: &BuildOptions, images: &[TrainingImage]) -> Result<usize> {
    let max_name = crate::model::bounds::LIMITS.max_name_bytes as usize;
    if o.name.len() > max_name {
        return Err(Error::Training(format!(
            "the model name is {} bytes long, the file format allows at most {max_name}",
            o.name.len()
        )));
    }
    if images.len() < 2 {
        return Err(Error::Training(format!(
            "{} training image(s); at least 2 are needed (15-20 recommended)",
            images.len()
        )));
    }
    for (what, f) in [
        ("shape", o.shape_variance),
        ("appearance", o.appearance_variance),
    ] {
        if !(f > 0.0 && f <= 1.0) {
            return Err(Error::Training(format!(
                "{what} variance fraction {f} not in (0, 1]"
            )));
        }
    }
    if !(o.face_width >= 8.0 && o.face_width <= 1024.0) {
        return Err(Error::Training(format!(
            "face width {} not in 8..=1024",
            o.face_width
        )));
    }
    let n = images[0].landmarks.len();
    for t in images {
        if t.landmarks.len() != n || n < 6 || n % 2 != 0 {
            return Err(Error::Training(format!(
                "'{}' has {} landmarks, '{}' has {}",
                t.name,
                t.landmarks.len() / 2,
                images[0].name,
                n / 2
            )));
        }
        if t.landmarks.iter().any(|v| !v.is_finite()) {
            return Err(Error::Training(format!(
                "'{}' has non-finite landmarks",
                t.name
            )));
        }
        t.image.view()?;
    }
    Ok(n)
}

/// The frame to build in: `frame_of`'s, else the canonical frame for 68 points (unless the
/// options ask for a frame of the model's own), else none.
fn frame_target<'a>(o: &BuildOptions, frame_of: Option<&'a Model>, n: usize) -> Result<Target<'a>> {
    let target: Target<'a> = match frame_of {
        Some(f) => Some((f.frame(), &f.shape().base)),
        None if o.frame == FrameChoice::Canonical && n == 2 * CANONICAL_LANDMARKS => {
            let c = canonical_frame();
            Some((c, c.vertices()))
        }
        None => None,
    };
    if let Some(f) = frame_of {
        if f.shape().base.len() != n {
            return Err(Error::Incompatible(format!(
                "training landmarks have {} points, the frame model '{}' has {}",
                n / 2,
                f.name(),
                f.landmarks()
            )));
        }
    }

    Ok(target)
}

/// The training shapes Procrustes-aligned into model coordinates: onto the target's shape, or
/// among themselves and scaled to the options' face width.
fn align_shapes(o: &BuildOptions, images: &[TrainingImage], target: Target<'_>) -> Vec<Vec<f64>> {
    let raw: Vec<Vec<f64>> = images
        .iter()
        .map(|t| t.landmarks.iter().map(|&v| v as f64).collect())
        .collect();
    match target {
        Some((_, base)) => {
            let r: Vec<f64> = base.iter().map(|&v| v as f64).collect();
            let (mut aligned, mean) = generalised_procrustes(&raw, Some(&r));
            scale_to_size_of(&mut aligned, &mean, &r);
            aligned
        }
        None => {
            let (aligned, unit_mean) = generalised_procrustes(&raw, None);
            let xs = unit_mean.iter().step_by(2);
            let width =
                xs.clone().copied().fold(f64::MIN, f64::max) - xs.copied().fold(f64::MAX, f64::min);
            let k = o.face_width as f64 / width.max(1e-12);
            aligned
                .into_iter()
                .map(|s| s.into_iter().map(|v| v * k).collect())
                .collect()
        }
    }
}

/// Which training image is the reference face (`None`: the mean).
fn reference_index(
    o: &BuildOptions,
    images: &[TrainingImage],
    aligned: &[Vec<f64>],
    target: Target<'_>,
) -> Result<Option<usize>> {
    Ok(match &o.reference {
        ReferenceChoice::Mean => None,
        ReferenceChoice::Named(name) => {
            Some(images.iter().position(|t| &t.name == name).ok_or_else(|| {
                Error::Training(format!(
                    "reference image '{name}' is not among the training images"
                ))
            })?)
        }
        ReferenceChoice::Rest => {
            let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
            Some(
                crate::train::expression::most_at_rest(&shapes).map_err(|e| {
                    Error::Training(format!("the reference at rest needs 68-point faces: {e}"))
                })?,
            )
        }
        ReferenceChoice::ClosestToFrame => {
            let (_, base) = target.ok_or_else(|| {
                Error::Training(
                    "the closest-to-reference choice needs a frame to be close to (the \
                     canonical frame or --frame)"
                        .into(),
                )
            })?;
            let d = |s: &Vec<f64>| -> f64 {
                s.iter()
                    .zip(base)
                    .map(|(a, &b)| (a - b as f64).powi(2))
                    .sum()
            };
            (0..aligned.len()).min_by(|&a, &b| d(&aligned[a]).total_cmp(&d(&aligned[b])))
        }
    })
}

/// The shape model (Eq. 1): PCA of the aligned shapes about the reference (mirrored too when
/// the options ask for symmetric shapes).
fn shape_model(
    o: &BuildOptions,
    aligned: &[Vec<f64>],
    ref_index: Option<usize>,
    n: usize,
) -> Result<ShapeModel> {
    let shape_centre = match ref_index {
        Some(i) => aligned[i].clone(),
        None => mean(aligned),
    };
    let sp = if o.symmetric_shapes && n == 2 * CANONICAL_LANDMARKS {
        let mut both = aligned.to_vec();
        both.extend(mirrored_deviations(aligned, &shape_centre));
        let mut sp = pca(&both, &shape_centre, o.shape_variance, o.max_shape_modes)?;
        // `pca` divides by 2k - 1 for the 2k samples; the symmetric covariance
        // `(C + M C M^T) / 2` of the k training shapes' `C` (denominator k - 1) has the
        // same total variance as `C`, so the variances are rescaled to it.
        let k = aligned.len() as f64;
        let r = ((2.0 * k - 1.0) / (2.0 * (k - 1.0))) as f32;
        sp.variances.iter_mut().for_each(|v| *v *= r);
        sp.total_variance *= r as f64;
        sp
    } else {
        pca(aligned, &shape_centre, o.shape_variance, o.max_shape_modes)?
    };
    Ok(ShapeModel(crate::model::linear::LinearModel {
        base: shape_centre.iter().map(|&v| v as f32).collect(),
        modes: sp.modes,
        variances: sp.variances,
    }))
}

/// The appearance model (Eq. 2): each image sampled through the frame at its landmarks, PCA
/// about the reference; `step(2 + i)` after image `i`.
fn appearance_model(
    o: &BuildOptions,
    images: &[TrainingImage],
    frame: &ReferenceFrame,
    ref_index: Option<usize>,
    step: &mut dyn FnMut(usize) -> Result<()>,
) -> Result<AppearanceModel> {
    let npx = frame.n_pixels() * 3;
    let mut buf = vec![0f32; npx];
    let mut samples: Vec<Vec<f64>> = Vec::with_capacity(images.len());
    for (i, t) in images.iter().enumerate() {
        crate::model::warp::sample_rgb(frame, &t.image.view()?, &t.landmarks, &mut buf)?;
        samples.push(buf.iter().map(|&v| v as f64).collect());
        step(2 + i)?;
    }
    let app_centre = match ref_index {
        Some(i) => samples[i].clone(),
        None => mean(&samples),
    };
    let ap = pca(
        &samples,
        &app_centre,
        o.appearance_variance,
        o.max_appearance_modes,
    )?;
    Ok(AppearanceModel::new(
        app_centre.iter().map(|&v| v as f32).collect(),
        ap.modes,
        ap.variances,
    ))
}

/// Symmetric shape samples: each aligned shape's deviation from `centre` mirrored, added back
/// to `centre` (`centre + M d_i`, `d_i = s_i - centre`). `M` renumbers the points left for right
/// ([`crate::landmarks::MIRROR_68`]) and reflects the vectors across the face's vertical axis: the
/// reflection `R(beta) F` (`F` negates x, `R(beta)` the rotation that best maps the mirrored,
/// renumbered `centre` onto `centre`, least squares about their centroids), so the model
/// coordinates need not be upright. The deviations are mirrored, not the shapes: the person's
/// own asymmetry stays in `centre`, and the samples' covariance is that of the training
/// deviations made mirror-symmetric, the assumption being that a face turns and moves both
/// ways. With `centre` the training mean the samples' mean is still `centre`.
fn mirrored_deviations(aligned: &[Vec<f64>], centre: &[f64]) -> Vec<Vec<f64>> {
    let map = &crate::landmarks::MIRROR_68;
    // F P centre (renumbered, x negated) fitted onto centre: the rotation `R(beta)` (the
    // similarity fit centres both; only its direction is used).
    let reflected: Vec<f64> = map
        .iter()
        .flat_map(|&j| [-centre[2 * j], centre[2 * j + 1]])
        .collect();
    let fit = CentredFit::new(&reflected, centre);
    let beta = fit.b.atan2(fit.a);
    let (sn, cs) = beta.sin_cos();
    aligned
        .iter()
        .map(|s| {
            let mut out = centre.to_vec();
            for (i, &j) in map.iter().enumerate() {
                let (dx, dy) = (
                    -(s[2 * j] - centre[2 * j]),
                    s[2 * j + 1] - centre[2 * j + 1],
                );
                out[2 * i] += cs * dx - sn * dy;
                out[2 * i + 1] += sn * dx + cs * dy;
            }
            out
        })
        .collect()
}

/// Scales shapes aligned onto `r` about `r`'s centroid so that their mean has `r`'s size
/// (centroid size). Least-squares alignment shrinks shapes a little towards the reference
/// (their mean is smaller than `r` by the spread of the set); undoing that keeps a model built in
/// a frame the size of that frame's mesh, so that the person the frame was made from gets back
/// exactly the frame's mesh as the base shape (and any person a base of the mesh's size).
fn scale_to_size_of(aligned: &mut [Vec<f64>], mean: &[f64], r: &[f64]) {
    let n = (r.len() / 2).max(1) as f64;
    let centroid = |s: &[f64]| -> (f64, f64) {
        let (mut x, mut y) = (0.0, 0.0);
        for p in s.chunks_exact(2) {
            x += p[0];
            y += p[1];
        }
        (x / n, y / n)
    };
    let size = |s: &[f64], c: (f64, f64)| -> f64 {
        s.chunks_exact(2)
            .map(|p| (p[0] - c.0).powi(2) + (p[1] - c.1).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let c = centroid(r);
    let have = size(mean, centroid(mean));
    if !(have > 1e-12) {
        return;
    }
    let k = size(r, c) / have;
    for s in aligned.iter_mut() {
        for p in s.chunks_exact_mut(2) {
            p[0] = c.0 + k * (p[0] - c.0);
            p[1] = c.1 + k * (p[1] - c.1);
        }
    }
}

#[cfg(test)]
mod symmetric_tests {
    use super::*;

    /// The mirrored samples keep each deviation's length, mirror back onto the original
    /// deviations, and map a deviation that moves the face's left side
    /// to one that moves its right side.
    #[test]
    fn mirrored_deviations_reflect_about_the_face() {
        let centre: Vec<f64> = canonical_frame()
            .vertices()
            .iter()
            .map(|&v| v as f64)
            .collect();
        // A rotated copy of the frame as the centre: the reflection axis follows the face.
        let (sn, cs) = 0.3f64.sin_cos();
        let centre: Vec<f64> = centre
            .chunks_exact(2)
            .flat_map(|p| [cs * p[0] - sn * p[1], sn * p[0] + cs * p[1]])
            .collect();
        let mut a = centre.clone();
        a[2 * 36] += 3.0; // the left outer eye corner moves
        let mut b = centre.clone();
        for (i, v) in b.iter_mut().enumerate() {
            *v += 0.5 * ((i * 7919) % 13) as f64 - 3.0;
        }
        let c: Vec<f64> = a
            .iter()
            .zip(&b)
            .zip(&centre)
            .map(|((x, y), z)| x + y - z)
            .collect();
        let shapes = vec![a.clone(), b.clone(), c];
        let m = mirrored_deviations(&shapes, &centre);
        let norm = |s: &[f64]| {
            s.iter()
                .zip(&centre)
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
        };
        for (s, t) in shapes.iter().zip(&m) {
            assert!((norm(s) - norm(t)).abs() < 1e-9 * norm(s).max(1.0));
        }
        let back = mirrored_deviations(&m, &centre);
        for (s, t) in shapes.iter().zip(&back) {
            for (x, y) in s.iter().zip(t) {
                assert!((x - y).abs() < 1e-6, "{x} vs {y}");
            }
        }
        // The moved point is now the right outer eye corner (45), by the same distance.
        let moved: Vec<usize> = (0..68)
            .filter(|&i| {
                (m[0][2 * i] - centre[2 * i]).hypot(m[0][2 * i + 1] - centre[2 * i + 1]) > 1e-6
            })
            .collect();
        assert_eq!(moved, vec![45]);
    }
}

//! Refining a model with its own fits: build, fit the model to each of its training images
//! starting from the given landmarks, rebuild from the fitted landmarks.
//!
//! Landmarks from a face finder are noisy (a few percent of the eye distance, worst on the jaw
//! and brows), and noise in the training shapes becomes spurious shape modes and blurs the
//! appearance model (pixels sampled at the wrong places). Fitting the first model to its own
//! training images moves each shape to where the model explains the image best, consistently
//! across the set; the second build is then sharper and its shape modes cleaner. What this gains,
//! measured, is in docs/experiments/fitting-notebook.md ("Refining an enrolled model").

use crate::error::{Error, Result};
use crate::fit::{FitOptions, Fitter};
use crate::model::Model;
use crate::train::{BuildProgress, Builder, TrainingImage};

/// Fits `model` to each training image from its landmarks; returns the fitted landmarks, or the
/// given ones for an image whose fit did not converge to finite points. `progress(i)` is called
/// after image `i` and returns `false` to cancel.
pub fn refine_landmarks(
    model: &Model,
    images: &[TrainingImage],
    progress: &mut dyn FnMut(usize) -> bool,
) -> Result<Vec<Vec<f32>>> {
    // No shape prior: it would pull every fitted shape towards the mean and shrink the modes.
    let mut fitter = Fitter::new(
        model,
        FitOptions {
            shape_prior: 0.0,
            ..FitOptions::default()
        },
    )?;
    let mut out = Vec::with_capacity(images.len());
    for (i, t) in images.iter().enumerate() {
        let fitted = match fitter.fit(&t.image.view()?, &t.landmarks) {
            Ok(r) if r.landmarks.iter().all(|v| v.is_finite()) => r.landmarks.clone(),
            _ => t.landmarks.clone(),
        };
        out.push(fitted);
        if !progress(i) {
            return Err(Error::Cancelled);
        }
    }
    Ok(out)
}

impl Builder {
    /// Builds a model, fits it to its own training images and rebuilds it from the fitted
    /// landmarks (`rounds` times; 0 is [`Builder::build`]). Progress counts every step of every
    /// build and fit; returning `false` cancels with [`Error::Cancelled`].
    pub fn build_refined(
        &self,
        images: &[TrainingImage],
        frame_of: Option<&Model>,
        rounds: usize,
        progress: &mut dyn FnMut(BuildProgress) -> bool,
    ) -> Result<Model> {
        let per_build = images.len() + 2;
        let total = per_build * (rounds + 1) + images.len() * rounds;
        let mut offset = 0;
        let mut model = self.build_with_progress(images, frame_of, &mut |p| {
            progress(BuildProgress {
                done: p.done,
                total,
            })
        })?;
        offset += per_build;
        let mut current: Vec<TrainingImage> = images.to_vec();
        for _ in 0..rounds {
            let base = offset;
            let fitted = refine_landmarks(&model, &current, &mut |i| {
                progress(BuildProgress {
                    done: base + i + 1,
                    total,
                })
            })?;
            offset += images.len();
            for (t, l) in current.iter_mut().zip(fitted) {
                t.landmarks = l;
            }
            let base = offset;
            model = self.build_with_progress(&current, frame_of, &mut |p| {
                progress(BuildProgress {
                    done: base + p.done,
                    total,
                })
            })?;
            offset += per_build;
        }
        Ok(model)
    }
}

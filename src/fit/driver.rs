//! The multi-level driver (menpofit's `aam/fitter.py`): runs an [`Algorithm`] on each level,
//! coarse to fine, with several starts of the coarsest level for a cold fit, and reports the
//! result.

use crate::error::{check_finite, check_len, Error, Result};
use crate::image::ImageRef;
use crate::model::{Model, Params};
use crate::similarity::Similarity;
use crate::summary::summary;

use super::algorithm::{
    level_cost, residual, run, Ctx, FitState, PixelWork, ProjectOut, Simultaneous, System, Work,
};
use super::geometry::Geometry;
use super::grey::Grey;
use super::precompute::{Level, ShapeBasis};
use super::{FitOptions, FitResult};

/// An AAM fitter for one model: all image-independent work is done in [`Fitter::new`]; a fit
/// allocates nothing (except when the image size changes, for its grey copy).
pub struct Fitter {
    options: FitOptions,
    pub(super) geom: Geometry,
    basis: ShapeBasis,
    levels: Vec<Level>,
    model_sigmas: Vec<f32>,
    appearance: crate::model::appearance::AppearanceModel,
    frame: crate::model::frame::ReferenceFrame,
    grey: Grey,
    work: Work,
    result: FitResult,
    contrast: f32,
    /// Width of the base shape `s0` (model coordinates): the unit of the start offsets.
    face_width: f32,
}

impl Fitter {
    /// Precomputes everything for fitting `model`: the combined basis, the grey appearance on
    /// each level, gradients, Jacobians, steepest-descent images and Hessians.
    ///
    /// Fails with [`Error::Params`] for invalid options or a model that cannot be fitted
    /// (degenerate base shape, flat appearance, too few pixels for a level).
    pub fn new(model: &Model, options: FitOptions) -> Result<Fitter> {
        options.check()?;
        crate::model::bounds::check_tracking_budget(
            model,
            options.levels.len(),
            options.channels as usize,
        )?;
        let n2 = model.shape().base.len();
        if n2 < 6 || model.frame().vertices().len() != n2 {
            return Err(Error::Params("the model's shape and frame disagree".into()));
        }
        if model.appearance().len() != model.frame().n_pixels() * 3 {
            return Err(Error::Params(
                "the model's appearance and frame disagree".into(),
            ));
        }
        let basis = ShapeBasis::new(model)?;
        let levels = options
            .levels
            .iter()
            .map(|l| {
                Level::new(
                    model,
                    &basis,
                    l.step,
                    l.sigma,
                    options.gain_bias,
                    options.shape_prior,
                    options.channels as usize,
                )
            })
            .collect::<Result<Vec<_>>>()?;
        let k = basis.k;
        let nmax = levels.iter().map(|l| l.n).max().unwrap_or(0);
        let lmax = levels.iter().map(|l| l.la).max().unwrap_or(0);
        let m = model.shape().n_modes();
        let work = Work {
            init: vec![0.0; n2],
            cur: vec![0.0; n2],
            next: vec![0.0; n2],
            scratch: vec![0.0; n2],
            delta: vec![0.0; n2],
            p: vec![0.0; m],
            pose: Similarity::IDENTITY,
            px: PixelWork::new(nmax, lmax, k),
            sys: System::new(k, lmax),
            saved: FitState::new(n2, m),
            start_cur: vec![0.0; n2],
            best: FitState::new(n2, m),
            before: FitState::new(n2, m),
            rgb: if options.appearance {
                vec![0.0; model.appearance().len()]
            } else {
                Vec::new()
            },
        };
        Ok(Fitter {
            geom: Geometry::new(model),
            basis,
            levels,
            model_sigmas: model.shape().sigmas(),
            appearance: model.appearance().clone(),
            frame: model.frame().clone(),
            contrast: 0.0,
            face_width: shape_width(&model.shape().base),
            grey: Grey::new(options.channels as usize),
            work,
            result: FitResult {
                landmarks: vec![0.0; n2],
                params: model.base_params(),
                error: 0.0,
                iterations: 0,
                converged: false,
                lost: false,
                reacquired: false,
                status: crate::fit::TrackStatus::Tracking,
                reasons: crate::fit::Reasons::NONE,
            },
            options,
        })
    }

    /// The options in use.
    pub fn options(&self) -> &FitOptions {
        &self.options
    }

    /// Number of fitted parameters `k` (4 similarity + shape modes).
    pub fn n_params(&self) -> usize {
        self.basis.k
    }

    /// Pixels per level, coarse to fine.
    pub fn level_pixels(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.n).collect()
    }

    /// Grey appearance images per level (including gain and bias).
    pub fn level_appearance_modes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.la).collect()
    }

    /// Number of landmarks.
    pub fn landmarks(&self) -> usize {
        self.geom.n()
    }

    /// `sigma_i` of the model's shape modes.
    pub fn shape_sigmas(&self) -> &[f32] {
        &self.model_sigmas
    }

    /// Contrast of the last fit: the standard deviation of the grey image samples under the
    /// fitted mesh divided by that of the template `A0`. Near 1 on a face; near 0 on a flat
    /// region (which the gain and bias images would otherwise explain perfectly).
    pub fn contrast(&self) -> f32 {
        self.contrast
    }

    /// The last result.
    pub fn result(&self) -> &FitResult {
        &self.result
    }

    /// Fits the model to `image` starting from `init` landmarks (image coordinates, `2n`
    /// values; they are first projected onto the model).
    ///
    /// Fails with [`Error::Params`] if `init` has the wrong length, is not finite or is
    /// degenerate. A fit that diverges does not fail: it stops at the last finite state and
    /// reports `converged = false` (and a large error).
    pub fn fit(&mut self, image: &ImageRef<'_>, init: &[f32]) -> Result<&FitResult> {
        self.fit_with(image, init, None, self.options.coarse_starts)
    }

    /// [`Fitter::fit`] starting from parameters (pose and shape; appearance is ignored).
    pub fn fit_params(&mut self, image: &ImageRef<'_>, init: &Params) -> Result<&FitResult> {
        check_len("shape parameters", &init.shape, self.work.p.len())?;
        check_finite("shape parameters", &init.shape)?;
        if !init.pose.is_valid() {
            return Err(Error::Params(
                "initial pose is not finite or has zero scale".into(),
            ));
        }
        let mut shape = std::mem::take(&mut self.work.init);
        self.geom.instance(&init.pose, &init.shape, &mut shape);
        let r = self
            .fit_with(image, &shape, None, self.options.coarse_starts)
            .map(|_| ());
        self.work.init = shape;
        r?;
        Ok(&self.result)
    }

    /// Fits with an optional override of the iterations (used by the tracker to retry
    /// harder) and `starts` starts of the coarsest level (see [`FitOptions::coarse_starts`]).
    pub(crate) fn fit_with(
        &mut self,
        image: &ImageRef<'_>,
        init: &[f32],
        refine_override: Option<(u32, u32)>,
        starts: u32,
    ) -> Result<&FitResult> {
        check_len("initial landmarks", init, self.work.cur.len())?;
        check_finite("initial landmarks", init)?;
        self.grey.load(image);
        let w = &mut self.work;
        let pose = self
            .geom
            .project(init, &mut w.p, &mut w.scratch, &mut w.cur)
            .ok_or_else(|| Error::Params("initial landmarks are degenerate".into()))?;
        w.pose = pose;
        let (max_iters, refine) =
            refine_override.unwrap_or((self.options.max_iters, self.options.refine_iters));
        let mut iterations = 0;
        let mut converged = false;
        for li in 0..self.levels.len() {
            converged = self.fit_level(li, starts, (max_iters, refine), &mut iterations);
        }
        self.finish(image, converged, iterations)?;
        Ok(&self.result)
    }

    /// Fits pyramid level `li` from the current state: the level check on the second level
    /// (see [`FitOptions::level_check`]), `starts` starts on the coarsest (`max_iters`
    /// project-out iterations each), and `refine` simultaneous iterations after the finest.
    /// Counts the iterations in `iterations`; returns whether the last fit converged.
    fn fit_level(
        &mut self,
        li: usize,
        starts: u32,
        (max_iters, refine): (u32, u32),
        iterations: &mut u32,
    ) -> bool {
        let nl = self.levels.len();
        let sigma = self.levels[li].sigma;
        let view = if sigma > 0.0 {
            self.grey
                .smooth(&self.work.cur, sigma * self.work.pose.scale())
        } else {
            self.grey.full()
        };
        let ctx = Ctx {
            level: &self.levels[li],
            geom: &self.geom,
            basis: &self.basis,
            img: view,
        };
        let w = &mut self.work;
        if li == 1 && self.options.level_check {
            // Undo the previous level if this finer level judges its start better: a
            // heavily smoothed level can be pulled off by what its smoothing spreads over
            // the face (a hand under the chin).
            let after = level_cost(&ctx, w);
            w.swap_before();
            let before = level_cost(&ctx, w);
            if !(before < after) {
                w.swap_before();
            }
        }
        if li == 0 && self.options.level_check {
            // The state the first level starts from, for the check above.
            w.before.save(&w.cur, &w.p, w.pose);
        }
        let starts = if li == 0 { starts } else { 1 };
        let mut converged = if starts <= 1 {
            run(
                &ProjectOut,
                &ctx,
                &mut self.work,
                max_iters,
                self.options.tolerance,
                iterations,
            )
        } else {
            multi_start(
                &ctx,
                &mut self.work,
                starts,
                self.options.start_offset,
                self.face_width,
                (max_iters, self.options.tolerance),
                iterations,
            )
        };
        if li + 1 == nl && refine > 0 {
            converged = run(
                &Simultaneous,
                &ctx,
                &mut self.work,
                refine,
                self.options.tolerance,
                iterations,
            );
        }
        converged
    }

    /// Writes the fit's result from the final state: the error and contrast on the finest
    /// level, the landmarks and parameters, and the appearance projected from `image` when
    /// [`FitOptions::appearance`] asks for it.
    fn finish(&mut self, image: &ImageRef<'_>, converged: bool, iterations: u32) -> Result<()> {
        // Final error on the finest level.
        let level = &self.levels[self.levels.len() - 1];
        let w = &mut self.work;
        let err = residual(level, self.grey.full(), w);
        self.contrast = contrast(&w.px.w[..level.n]) / level.a0_std.max(1e-6);
        // Result.
        let r = &mut self.result;
        r.landmarks.copy_from_slice(&w.cur);
        r.params.pose = w.pose;
        r.params.shape.copy_from_slice(&w.p);
        if self.options.appearance {
            crate::model::warp::sample_rgb(&self.frame, image, &w.cur, &mut w.rgb)?;
            self.appearance.project(&w.rgb, &mut r.params.appearance);
        } else {
            r.params.appearance.iter_mut().for_each(|v| *v = 0.0);
        }
        r.error = if err.is_finite() { err } else { f32::MAX };
        r.iterations = iterations;
        r.converged = converged && err.is_finite();
        r.lost = false;
        r.reacquired = false;
        r.status = super::TrackStatus::Tracking;
        r.reasons = super::Reasons::NONE;
        Ok(())
    }
}

/// The coarsest level fitted from `starts` starts (the current state, then offsets of
/// `offset` face widths and radians, see [`start_offset`]); the state ends at the start whose
/// fit cost least. Returns whether that fit converged.
fn multi_start(
    ctx: &Ctx<'_>,
    w: &mut Work,
    starts: u32,
    offset: f32,
    face_width: f32,
    (max_iters, tolerance): (u32, f32),
    iterations: &mut u32,
) -> bool {
    let mut converged = false;
    w.start_cur.copy_from_slice(&w.cur);
    let mut best = f64::INFINITY;
    let dt = offset * (face_width * w.pose.scale());
    for s in 0..starts {
        let (dx, dy, da) = start_offset(s, dt, offset);
        if s > 0 {
            offset_shape(&w.start_cur, dx, dy, da, &mut w.next);
            let Some(pose) = ctx
                .geom
                .project(&w.next, &mut w.p, &mut w.scratch, &mut w.cur)
            else {
                continue;
            };
            w.pose = pose;
        }
        let conv = run(&ProjectOut, ctx, w, max_iters, tolerance, iterations);
        let cost = level_cost(ctx, w);
        if cost.is_finite() && cost < best {
            best = cost;
            converged = conv;
            w.best.save(&w.cur, &w.p, w.pose);
        }
    }
    if best.is_finite() {
        w.best.restore(&mut w.cur, &mut w.p, &mut w.pose);
    }
    converged
}

/// Offset `(dx, dy, angle)` of the `s`-th coarse start: the given start, then +-x, +-y, +-angle.
fn start_offset(s: u32, dt: f32, dr: f32) -> (f32, f32, f32) {
    match s {
        0 => (0.0, 0.0, 0.0),
        1 => (dt, 0.0, 0.0),
        2 => (-dt, 0.0, 0.0),
        3 => (0.0, dt, 0.0),
        4 => (0.0, -dt, 0.0),
        5 => (0.0, 0.0, dr),
        6 => (0.0, 0.0, -dr),
        _ => (0.0, 0.0, 0.0),
    }
}

/// `shape` rotated by `angle` about its centroid and moved by `(dx, dy)`.
fn offset_shape(shape: &[f32], dx: f32, dy: f32, angle: f32, out: &mut [f32]) {
    let n = (shape.len() / 2).max(1) as f32;
    let cx = shape.iter().step_by(2).sum::<f32>() / n;
    let cy = shape.iter().skip(1).step_by(2).sum::<f32>() / n;
    let (sn, cs) = angle.sin_cos();
    for (o, p) in out.chunks_exact_mut(2).zip(shape.chunks_exact(2)) {
        let (x, y) = (p[0] - cx, p[1] - cy);
        o[0] = cx + cs * x - sn * y + dx;
        o[1] = cy + sn * x + cs * y + dy;
    }
}

/// Standard deviation of some values.
fn contrast(v: &[f32]) -> f32 {
    let n = v.len().max(1) as f32;
    let mean = v.iter().sum::<f32>() / n;
    (v.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / n).sqrt()
}

/// Width of a shape (`max x - min x`).
fn shape_width(shape: &[f32]) -> f32 {
    crate::geometry::BBox::of_points(shape).width.max(0.0)
}

impl std::fmt::Debug for Fitter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        summary(
            f,
            "Fitter",
            &[
                ("options", &self.options),
                ("landmarks", &self.landmarks()),
                ("params", &self.n_params()),
            ],
        )
    }
}

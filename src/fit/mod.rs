//! AAM fitting and tracking (issue 5): inverse compositional fitting of a [`Model`] with the
//! global similarity composed with the shape (Matthews & Baker, "Active Appearance Models
//! Revisited", IJCV 2004), and a [`Tracker`] that follows a face through video.
//!
//! Design (see `docs/fitting.md` for the measurements behind it):
//! - The fit runs on a grey-level appearance model derived once per model (luminance of `A0`
//!   and of the RGB modes, plus optional gain and bias images, re-orthonormalised) on a
//!   subsampled set of frame pixels per level (coarse to fine).
//! - Each level first runs project-out inverse compositional iterations (steepest-descent
//!   images and Hessian precomputed; an iteration costs `O(kN)`), then, on the finest level, a
//!   few appearance-aware refinement steps: the appearance `lambda` is estimated by projection,
//!   the template gradient is that of `A0 + A lambda` (not of `A0` alone), and the Hessian is
//!   the Schur complement that eliminates `lambda` (the Wiberg / simultaneous Gauss-Newton
//!   step). This is what keeps a talking face (teeth, tongue, shadows the mean does not have)
//!   from dragging the mesh off.
//! - A Tikhonov prior on `p / sigma` conditions the shape update.

mod geometry;
mod linalg;
mod precompute;
mod tracker;

use serde::{Deserialize, Serialize};

use crate::error::{check_finite, check_len, Error, Result};
use crate::image::ImageRef;
use crate::model::{Model, Params};
use crate::similarity::Similarity;

use geometry::Geometry;
use linalg::{axpy, cholesky, cholesky_solve, dot};
use precompute::{channel_weights, regularise, Level, ShapeBasis};

pub use tracker::{Tracker, MIN_CONTRAST};

/// Options of the [`Fitter`] and [`Tracker`]. `Default` is tuned for real-time tracking.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Most project-out iterations per level.
    pub max_iters: u32,
    /// Appearance-aware (simultaneous / Wiberg) refinement iterations on the finest level,
    /// after the project-out iterations (0 = plain project-out).
    pub refine_iters: u32,
    /// The levels, coarse to fine. The finest level also gives the reported error.
    pub levels: Vec<LevelSpec>,
    /// Convergence tolerance: the fit stops when no landmark moves more than this many image
    /// pixels in an iteration.
    pub tolerance: f32,
    /// Weight `rho` of the Tikhonov prior `rho * N * sum (p_i / sigma_i)^2` on the shape
    /// parameters (`N` = level pixels). 0 disables it.
    pub shape_prior: f32,
    /// Add gain and bias images to the grey appearance basis, making the fit invariant to
    /// global brightness and contrast changes.
    pub gain_bias: bool,
    /// Fitting channels: 1 = luminance only, 2 = luminance and red chroma (lips against
    /// skin).
    pub channels: u32,
    /// Compute the RGB appearance parameters `lambda` of the result (projection of the image
    /// sampled at the final landmarks; costs one full-frame sample).
    pub appearance: bool,
    /// Tracker: a fit whose error (RMS grey residual) exceeds this is a lost face.
    pub max_error: f32,
    /// Tracker: a fit whose shape parameters' RMS in standard deviations,
    /// `sqrt(mean_i (p_i / sigma_i)^2)`, exceeds this is a lost face (an implausible shape).
    pub max_sigmas: f32,
    /// Tracker: a fit whose scale changes by more than this fraction from the previous frame
    /// (or whose rotation by more than 0.5 rad) is a lost face.
    pub max_scale_jump: f32,
    /// Starts of the coarsest level in a cold fit ([`Fitter::fit`], [`Fitter::fit_params`],
    /// the tracker's first frame and re-initialisations), 1 to 7: the given start, then the
    /// start moved by `+-start_offset` of the face width along x, along y, then rotated by
    /// `+-start_offset` radians. The coarse result with the lowest cost (projected-out
    /// residual plus prior) is refined on the finer levels. Widens the convergence basin.
    #[serde(default = "default_coarse_starts")]
    pub coarse_starts: u32,
    /// Starts of the coarsest level for a tracked frame (started from the previous frame's
    /// result), 1 to 7.
    #[serde(default = "default_tracking_starts")]
    pub tracking_starts: u32,
    /// Offset of the extra coarse starts: a fraction of the face width (and radians).
    #[serde(default = "default_start_offset")]
    pub start_offset: f32,
}

fn default_coarse_starts() -> u32 {
    3
}

fn default_tracking_starts() -> u32 {
    1
}

fn default_start_offset() -> f32 {
    0.06
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            max_iters: 10,
            refine_iters: 0,
            levels: vec![
                LevelSpec {
                    step: 4,
                    sigma: 4.0,
                },
                LevelSpec {
                    step: 4,
                    sigma: 2.0,
                },
                LevelSpec {
                    step: 2,
                    sigma: 0.0,
                },
            ],
            tolerance: 0.05,
            shape_prior: 3e-5,
            gain_bias: true,
            channels: 1,
            appearance: true,
            max_error: 0.12,
            max_sigmas: 3.5,
            max_scale_jump: 0.25,
            coarse_starts: 3,
            tracking_starts: 1,
            start_offset: 0.06,
        }
    }
}

impl FitOptions {
    fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Params(format!("fit options: {m}")));
        if self.levels.is_empty() || self.levels.len() > 4 {
            return bad(format!("{} levels (1 to 4 expected)", self.levels.len()));
        }
        for l in &self.levels {
            // `contains` is false for NaN, so a NaN sigma is rejected too.
            if !(1..=8).contains(&l.step) || !(0.0..=8.0).contains(&l.sigma) {
                return bad(format!(
                    "level {l:?}: step must be in 1..=8, sigma in 0..=8"
                ));
            }
        }
        if !(1..=2).contains(&self.channels) {
            return bad(format!("channels = {} must be 1 or 2", self.channels));
        }
        for (what, v) in [
            ("coarse_starts", self.coarse_starts),
            ("tracking_starts", self.tracking_starts),
        ] {
            if !(1..=7).contains(&v) {
                return bad(format!("{what} = {v} must be in 1..=7"));
            }
        }
        if !(self.start_offset.is_finite() && (0.0..=0.5).contains(&self.start_offset)) {
            return bad(format!(
                "start_offset = {} must be in 0..=0.5",
                self.start_offset
            ));
        }
        if self.max_iters > 1000 || self.refine_iters > 1000 {
            return bad("more than 1000 iterations".into());
        }
        for (what, v) in [
            ("tolerance", self.tolerance),
            ("shape_prior", self.shape_prior),
            ("max_error", self.max_error),
            ("max_sigmas", self.max_sigmas),
            ("max_scale_jump", self.max_scale_jump),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{what} = {v} must be finite and non-negative"));
            }
        }
        Ok(())
    }
}

/// One level of the coarse-to-fine schedule.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LevelSpec {
    /// Use every `step`-th frame pixel along x and y.
    pub step: u32,
    /// Gaussian smoothing (standard deviation, frame pixels) of the template; the image is
    /// smoothed by the same amount in its own pixels (times the pose's scale). 0 = none.
    pub sigma: f32,
}

/// The result of one fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitResult {
    /// Fitted landmarks, image coordinates, interleaved `(x0, y0, ..., x_{n-1}, y_{n-1})`.
    pub landmarks: Vec<f32>,
    /// Pose, shape parameters `p` and RGB appearance parameters `lambda` (zeros when
    /// [`FitOptions::appearance`] is off).
    pub params: Params,
    /// Final error: RMS of the grey residual `I(W(x)) - A0(x) - sum lambda_i A_i(x)` over the
    /// finest level's pixels (grey levels in `0..=1`).
    pub error: f32,
    /// Iterations run (all levels and both stages).
    pub iterations: u32,
    /// True when the last iteration moved no landmark more than the tolerance.
    pub converged: bool,
    /// Set by the [`Tracker`]: the fit was judged a lost face and the result is the last good
    /// one (the tracker re-initialised from it).
    pub lost: bool,
}

/// Grey-level copy of the frame being fitted (reused between fits) and a smoothed copy of
/// the region around the face for coarse levels.
struct Grey {
    width: usize,
    height: usize,
    /// Channel planes, each `width * height`.
    channels: usize,
    data: Vec<f32>,
    blur: Vec<f32>,
    tmp: Vec<f32>,
}

/// A grey image to sample: the full frame, or the smoothed region `[x0, x1] x [y0, y1]`.
#[derive(Clone, Copy)]
struct GreyView<'a> {
    data: &'a [f32],
    stride: usize,
    plane: usize,
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
}

impl Grey {
    fn load(&mut self, image: &ImageRef<'_>) {
        self.width = image.width() as usize;
        self.height = image.height() as usize;
        let len = self.width * self.height;
        if self.data.len() != len * self.channels {
            self.data.resize(len * self.channels, 0.0);
            self.blur.resize(len * self.channels, 0.0);
            self.tmp.resize(len, 0.0);
        }
        for (c, wc) in channel_weights(self.channels).iter().enumerate() {
            let k = [wc[0] / 255.0, wc[1] / 255.0, wc[2] / 255.0];
            let plane = &mut self.data[c * len..(c + 1) * len];
            for (o, px) in plane.iter_mut().zip(image.data().chunks_exact(4)) {
                *o = k[0] * px[0] as f32 + k[1] * px[1] as f32 + k[2] * px[2] as f32;
            }
        }
    }

    fn full(&self) -> GreyView<'_> {
        GreyView {
            data: &self.data,
            stride: self.width,
            plane: self.width * self.height,
            x0: 0.0,
            y0: 0.0,
            x1: (self.width - 1) as f32,
            y1: (self.height - 1) as f32,
        }
    }

    /// Smooths the region around `shape` (its bounding box grown by half its size) with a
    /// Gaussian of `sigma` image pixels (separable, at most radius 24) into `blur`.
    fn smooth(&mut self, shape: &[f32], sigma: f32) -> GreyView<'_> {
        let (mut minx, mut miny, mut maxx, mut maxy) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for p in shape.chunks_exact(2) {
            minx = minx.min(p[0]);
            maxx = maxx.max(p[0]);
            miny = miny.min(p[1]);
            maxy = maxy.max(p[1]);
        }
        let (mw, mh) = (
            0.2 * (maxx - minx) + 3.0 * sigma + 2.0,
            0.2 * (maxy - miny) + 3.0 * sigma + 2.0,
        );
        let clampx = |v: f32| {
            if v.is_finite() {
                v.clamp(0.0, (self.width - 1) as f32) as usize
            } else {
                0
            }
        };
        let clampy = |v: f32| {
            if v.is_finite() {
                v.clamp(0.0, (self.height - 1) as f32) as usize
            } else {
                0
            }
        };
        let (x0, x1) = (clampx((minx - mw).floor()), clampx((maxx + mw).ceil()));
        let (y0, y1) = (clampy((miny - mh).floor()), clampy((maxy + mh).ceil()));
        let mut kernel = [0f32; 49];
        let r = ((2.5 * sigma).ceil() as usize).clamp(1, 24);
        let mut ksum = 0.0;
        for i in 0..=2 * r {
            let d = i as f32 - r as f32;
            kernel[i] = (-(d * d) / (2.0 * sigma * sigma).max(1e-6)).exp();
            ksum += kernel[i];
        }
        kernel.iter_mut().for_each(|k| *k /= ksum);
        let w = self.width;
        let len = w * self.height;
        for c in 0..self.channels {
            let data = &self.data[c * len..(c + 1) * len];
            let blur = &mut self.blur[c * len..(c + 1) * len];
            let k = &kernel[..=2 * r];
            // Horizontal pass (clamped at the region's edges): a window dot product inside.
            for y in y0..=y1 {
                let row = &data[y * w..(y + 1) * w];
                let out = &mut self.tmp[y * w..(y + 1) * w];
                for x in x0..=x1 {
                    out[x] = if x >= x0 + r && x + r <= x1 {
                        dot(k, &row[x - r..=x + r])
                    } else {
                        let mut acc = 0.0;
                        for (i, kv) in k.iter().enumerate() {
                            acc += kv * row[(x + i).saturating_sub(r).clamp(x0, x1)];
                        }
                        acc
                    };
                }
            }
            // Vertical pass: each output row is a weighted sum of (clamped) input rows.
            for y in y0..=y1 {
                let out = &mut blur[y * w + x0..=y * w + x1];
                out.iter_mut().for_each(|v| *v = 0.0);
                for (i, kv) in k.iter().enumerate() {
                    let yy = (y + i).saturating_sub(r).clamp(y0, y1);
                    axpy(*kv, &self.tmp[yy * w + x0..=yy * w + x1], out);
                }
            }
        }
        GreyView {
            data: &self.blur,
            stride: w,
            plane: len,
            x0: x0 as f32,
            y0: y0 as f32,
            x1: x1 as f32,
            y1: y1 as f32,
        }
    }
}

impl GreyView<'_> {
    /// Bilinear sample, clamped to the view's region.
    #[inline]
    fn sample(&self, x: f32, y: f32, channel: usize) -> f32 {
        let x = if x.is_finite() {
            x.clamp(self.x0, self.x1)
        } else {
            self.x0
        };
        let y = if y.is_finite() {
            y.clamp(self.y0, self.y1)
        } else {
            self.y0
        };
        let xi = x as usize;
        let yi = y as usize;
        let fx = x - xi as f32;
        let fy = y - yi as f32;
        let dx = if (xi as f32) < self.x1 { 1 } else { 0 };
        let dy = if (yi as f32) < self.y1 {
            self.stride
        } else {
            0
        };
        let i = channel * self.plane + yi * self.stride + xi;
        let d = self.data;
        let top = d[i] + fx * (d[i + dx] - d[i]);
        let bot = d[i + dy] + fx * (d[i + dy + dx] - d[i + dy]);
        top + fy * (bot - top)
    }
}

/// Buffers of one fit, allocated once per fitter.
struct Work {
    init: Vec<f32>,
    cur: Vec<f32>,
    next: Vec<f32>,
    scratch: Vec<f32>,
    delta: Vec<f32>,
    p: Vec<f32>,
    pose: Similarity,
    w: Vec<f32>,
    e: Vec<f32>,
    lam: Vec<f32>,
    tgx: Vec<f32>,
    tgy: Vec<f32>,
    sd: Vec<f32>,
    proj: Vec<f64>,
    g: Vec<f64>,
    h: Vec<f64>,
    hf: Vec<f64>,
    dc: Vec<f64>,
    saved_cur: Vec<f32>,
    saved_p: Vec<f32>,
    saved_pose: Similarity,
    saved_g: Vec<f64>,
    saved_h: Vec<f64>,
    start_cur: Vec<f32>,
    best_cur: Vec<f32>,
    best_p: Vec<f32>,
    best_pose: Similarity,
    rgb: Vec<f32>,
}

/// An AAM fitter for one model: all image-independent work is done in [`Fitter::new`]; a fit
/// allocates nothing (except when the image size changes, for its grey copy).
pub struct Fitter {
    options: FitOptions,
    geom: Geometry,
    basis: ShapeBasis,
    levels: Vec<Level>,
    model_sigmas: Vec<f32>,
    appearance: crate::appearance::AppearanceModel,
    frame: crate::frame::ReferenceFrame,
    grey: Grey,
    work: Work,
    result: FitResult,
    contrast: f32,
}

/// What one iteration did.
enum Step {
    /// Moved by at most this many pixels.
    Moved(f32),
    /// The update was not finite or degenerate: state unchanged, stop.
    Failed,
}

impl Fitter {
    /// Precomputes everything for fitting `model`: the combined basis, the grey appearance on
    /// each level, gradients, Jacobians, steepest-descent images and Hessians.
    ///
    /// Fails with [`Error::Params`] for invalid options or a model that cannot be fitted
    /// (degenerate base shape, flat appearance, too few pixels for a level).
    pub fn new(model: &Model, options: FitOptions) -> Result<Fitter> {
        options.check()?;
        let n2 = model.shape.base.len();
        if n2 < 6 || model.frame.vertices().len() != n2 {
            return Err(Error::Params("the model's shape and frame disagree".into()));
        }
        if model.appearance.len() != model.frame.n_pixels() * 3 {
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
        let m = model.shape.n_modes();
        let work = Work {
            init: vec![0.0; n2],
            cur: vec![0.0; n2],
            next: vec![0.0; n2],
            scratch: vec![0.0; n2],
            delta: vec![0.0; n2],
            p: vec![0.0; m],
            pose: Similarity::IDENTITY,
            w: vec![0.0; nmax],
            e: vec![0.0; nmax],
            lam: vec![0.0; lmax],
            tgx: vec![0.0; nmax],
            tgy: vec![0.0; nmax],
            sd: vec![0.0; k * nmax],
            proj: vec![0.0; lmax * k],
            g: vec![0.0; k],
            h: vec![0.0; k * k],
            hf: vec![0.0; k * k],
            dc: vec![0.0; k],
            saved_cur: vec![0.0; n2],
            saved_p: vec![0.0; m],
            saved_pose: Similarity::IDENTITY,
            saved_g: vec![0.0; k],
            saved_h: vec![0.0; k * k],
            start_cur: vec![0.0; n2],
            best_cur: vec![0.0; n2],
            best_p: vec![0.0; m],
            best_pose: Similarity::IDENTITY,
            rgb: if options.appearance {
                vec![0.0; model.appearance.len()]
            } else {
                Vec::new()
            },
        };
        Ok(Fitter {
            geom: Geometry::new(model),
            basis,
            levels,
            model_sigmas: model.shape.sigmas(),
            appearance: model.appearance.clone(),
            frame: model.frame.clone(),
            contrast: 0.0,
            grey: Grey {
                channels: options.channels as usize,
                width: 0,
                height: 0,
                data: Vec::new(),
                blur: Vec::new(),
                tmp: Vec::new(),
            },
            work,
            result: FitResult {
                landmarks: vec![0.0; n2],
                params: model.base_params(),
                error: 0.0,
                iterations: 0,
                converged: false,
                lost: false,
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
        let nl = self.levels.len();
        for li in 0..nl {
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
            let starts = if li == 0 { starts } else { 1 };
            if starts <= 1 {
                converged = run_stage(
                    &ctx,
                    &mut self.work,
                    Kind::ProjectOut,
                    max_iters,
                    self.options.tolerance,
                    &mut iterations,
                );
            } else {
                let w = &mut self.work;
                w.start_cur.copy_from_slice(&w.cur);
                let mut best = f64::INFINITY;
                let width = 150.0 * w.pose.scale();
                let dt = self.options.start_offset * width;
                let dr = self.options.start_offset;
                for s in 0..starts {
                    let (dx, dy, da) = start_offset(s, dt, dr);
                    if s > 0 {
                        offset_shape(&w.start_cur, dx, dy, da, &mut w.next);
                        let Some(pose) =
                            ctx.geom
                                .project(&w.next, &mut w.p, &mut w.scratch, &mut w.cur)
                        else {
                            continue;
                        };
                        w.pose = pose;
                    }
                    let conv = run_stage(
                        &ctx,
                        w,
                        Kind::ProjectOut,
                        max_iters,
                        self.options.tolerance,
                        &mut iterations,
                    );
                    let rms = residual(ctx.level, ctx.img, w) as f64;
                    let mut cost = rms * rms * ctx.level.n as f64;
                    for (j, m) in ctx.basis.mode_of.iter().enumerate() {
                        if let Some(m) = m {
                            let p = w.p[*m] as f64;
                            cost += ctx.level.prior[j] * p * p;
                        }
                    }
                    if cost.is_finite() && cost < best {
                        best = cost;
                        converged = conv;
                        w.best_cur.copy_from_slice(&w.cur);
                        w.best_p.copy_from_slice(&w.p);
                        w.best_pose = w.pose;
                    }
                }
                if best.is_finite() {
                    w.cur.copy_from_slice(&w.best_cur);
                    w.p.copy_from_slice(&w.best_p);
                    w.pose = w.best_pose;
                }
            }
            if li + 1 == nl && refine > 0 {
                converged = run_stage(
                    &ctx,
                    &mut self.work,
                    Kind::Simultaneous,
                    refine,
                    self.options.tolerance,
                    &mut iterations,
                );
            }
        }
        // Final error on the finest level.
        let level = &self.levels[nl - 1];
        let w = &mut self.work;
        let err = residual(level, self.grey.full(), w);
        self.contrast = contrast(&w.w[..level.n]) / level.a0_std.max(1e-6);
        // Result.
        let r = &mut self.result;
        r.landmarks.copy_from_slice(&w.cur);
        r.params.pose = w.pose;
        r.params.shape.copy_from_slice(&w.p);
        if self.options.appearance {
            crate::warp::sample_rgb(&self.frame, image, &w.cur, &mut w.rgb)?;
            self.appearance.project(&w.rgb, &mut r.params.appearance);
        } else {
            r.params.appearance.iter_mut().for_each(|v| *v = 0.0);
        }
        r.error = if err.is_finite() { err } else { f32::MAX };
        r.iterations = iterations;
        r.converged = converged && err.is_finite();
        r.lost = false;
        Ok(&self.result)
    }
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

/// Samples the grey image at the level pixels through the current mesh.
fn sample(level: &Level, img: GreyView<'_>, shape: &[f32], out: &mut [f32]) {
    let np = level.np.max(1);
    for (c, block) in out[..level.n].chunks_exact_mut(np).enumerate() {
        for ((t, b), o) in level.verts.iter().zip(&level.bary).zip(block.iter_mut()) {
            let (a0, a1, a2) = (t[0] as usize, t[1] as usize, t[2] as usize);
            let x = b[0] * shape[2 * a0] + b[1] * shape[2 * a1] + b[2] * shape[2 * a2];
            let y = b[0] * shape[2 * a0 + 1] + b[1] * shape[2 * a1 + 1] + b[2] * shape[2 * a2 + 1];
            *o = img.sample(x, y, c);
        }
    }
}

/// Samples, estimates `lambda` by projection and leaves the residual in `w.e`; returns its
/// RMS.
fn residual(level: &Level, img: GreyView<'_>, w: &mut Work) -> f32 {
    let n = level.n;
    sample(level, img, &w.cur, &mut w.w[..n]);
    let e = &mut w.e[..n];
    for ((o, a), b) in e.iter_mut().zip(&w.w[..n]).zip(&level.a0) {
        *o = a - b;
    }
    for i in 0..level.la {
        let mode = &level.app[i * n..(i + 1) * n];
        w.lam[i] = dot(mode, e);
    }
    for i in 0..level.la {
        let mode = &level.app[i * n..(i + 1) * n];
        axpy(-w.lam[i], mode, e);
    }
    (dot(e, e) / n as f32).sqrt()
}

/// What one stage iterates.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Project-out inverse compositional (precomputed Hessian).
    ProjectOut,
    /// Appearance-aware simultaneous (Wiberg) inverse compositional.
    Simultaneous,
}

/// What a stage works with.
struct Ctx<'a> {
    level: &'a Level,
    geom: &'a Geometry,
    basis: &'a ShapeBasis,
    img: GreyView<'a>,
}

/// Runs up to `max_iters` Levenberg-Marquardt-safeguarded Gauss-Newton iterations of `kind`:
/// a step that increases the cost (projected-out residual plus prior) is undone and retried
/// with more damping `mu` (`H + mu diag(H)`); accepted steps relax the damping. Returns
/// whether the last step moved no landmark more than `tol` pixels.
fn run_stage(
    c: &Ctx<'_>,
    w: &mut Work,
    kind: Kind,
    max_iters: u32,
    tol: f32,
    iterations: &mut u32,
) -> bool {
    let k = c.basis.k;
    let mut mu = 0.0f64;
    let mut best = f64::INFINITY;
    for _ in 0..max_iters {
        *iterations += 1;
        let cost = match kind {
            Kind::ProjectOut => po_system(c, w),
            Kind::Simultaneous => sim_system(c, w),
        };
        if cost.is_finite() && cost <= best {
            best = cost;
            w.saved_cur.copy_from_slice(&w.cur);
            w.saved_p.copy_from_slice(&w.p);
            w.saved_pose = w.pose;
            w.saved_g.copy_from_slice(&w.g);
            w.saved_h.copy_from_slice(&w.h);
            mu = if mu < 1e-4 { 0.0 } else { mu * 0.1 };
        } else {
            if !best.is_finite() {
                return false;
            }
            // Undo the last step; retry from the saved state with more damping.
            w.cur.copy_from_slice(&w.saved_cur);
            w.p.copy_from_slice(&w.saved_p);
            w.pose = w.saved_pose;
            w.g.copy_from_slice(&w.saved_g);
            w.h.copy_from_slice(&w.saved_h);
            mu = if mu == 0.0 { 1e-2 } else { mu * 10.0 };
            if mu > 1e4 {
                return true;
            }
        }
        // Solve (H + prior + mu diag H) dc = g.
        w.hf.copy_from_slice(&w.h);
        for j in 0..k {
            let d = w.hf[j * k + j];
            w.hf[j * k + j] = d + mu * d;
        }
        regularise(&mut w.hf, &c.level.prior, k);
        if !cholesky(&mut w.hf, k) {
            return false;
        }
        w.dc.copy_from_slice(&w.g);
        cholesky_solve(&w.hf, k, &mut w.dc);
        match apply_update(c.geom, c.basis, w) {
            Step::Moved(d) if d <= tol => return true,
            Step::Moved(_) => {}
            Step::Failed => {
                w.cur.copy_from_slice(&w.saved_cur);
                w.p.copy_from_slice(&w.saved_p);
                w.pose = w.saved_pose;
                return false;
            }
        }
    }
    false
}

/// Prior cost `sum_j w_j p_j^2` and gradient term `w_j p_j` added to `w.g`.
fn add_prior(c: &Ctx<'_>, w: &mut Work) -> f64 {
    let mut cost = 0.0;
    for (j, m) in c.basis.mode_of.iter().enumerate() {
        if let Some(m) = m {
            let p = w.p[*m] as f64;
            w.g[j] += c.level.prior[j] * p;
            cost += c.level.prior[j] * p * p;
        }
    }
    cost
}

/// Project-out system at the current state: `g = SD^T e`, `H` precomputed; returns the cost
/// `|e|^2 - |A^T e|^2 + prior`.
fn po_system(c: &Ctx<'_>, w: &mut Work) -> f64 {
    let l = c.level;
    let n = l.n;
    sample(l, c.img, &w.cur, &mut w.w[..n]);
    for ((o, a), b) in w.e[..n].iter_mut().zip(&w.w[..n]).zip(&l.a0) {
        *o = a - b;
    }
    let e = &w.e[..n];
    let mut cost = dot(e, e) as f64;
    for i in 0..l.la {
        let v = dot(&l.app[i * n..(i + 1) * n], e) as f64;
        cost -= v * v;
    }
    for j in 0..c.basis.k {
        w.g[j] = dot(&l.sd_po[j * n..(j + 1) * n], e) as f64;
    }
    w.h.copy_from_slice(&l.h_po);
    cost + add_prior(c, w)
}

/// Appearance-aware (simultaneous, Wiberg) system: `lambda` by projection, template
/// `T = A0 + A lambda`, steepest-descent images from `grad T`, Hessian
/// `SD^T SD - (A^T SD)^T (A^T SD)` (appearance eliminated), `g = SD^T e`.
fn sim_system(c: &Ctx<'_>, w: &mut Work) -> f64 {
    let l = c.level;
    let n = l.n;
    let k = c.basis.k;
    let la = l.la;
    let rms = residual(l, c.img, w) as f64;
    let cost = rms * rms * n as f64;
    w.tgx[..n].copy_from_slice(&l.a0_gx);
    w.tgy[..n].copy_from_slice(&l.a0_gy);
    for i in 0..la {
        let lam = w.lam[i];
        axpy(lam, &l.app_gx[i * n..(i + 1) * n], &mut w.tgx[..n]);
        axpy(lam, &l.app_gy[i * n..(i + 1) * n], &mut w.tgy[..n]);
    }
    for j in 0..k {
        let sd = &mut w.sd[j * n..(j + 1) * n];
        let (jx, jy) = (&l.jx[j * n..(j + 1) * n], &l.jy[j * n..(j + 1) * n]);
        for i in 0..n {
            sd[i] = w.tgx[i] * jx[i] + w.tgy[i] * jy[i];
        }
    }
    for i in 0..la {
        let mode = &l.app[i * n..(i + 1) * n];
        for j in 0..k {
            w.proj[i * k + j] = dot(mode, &w.sd[j * n..(j + 1) * n]) as f64;
        }
    }
    for a in 0..k {
        let sa = &w.sd[a * n..(a + 1) * n];
        for b in 0..=a {
            let mut v = dot(sa, &w.sd[b * n..(b + 1) * n]) as f64;
            for i in 0..la {
                v -= w.proj[i * k + a] * w.proj[i * k + b];
            }
            w.h[a * k + b] = v;
            w.h[b * k + a] = v;
        }
        w.g[a] = dot(sa, &w.e[..n]) as f64;
    }
    cost + add_prior(c, w)
}

/// Applies the parameter update `w.dc` (combined basis): compose the inverse incremental
/// warp, project onto the model. Returns the largest landmark movement.
fn apply_update(geom: &Geometry, basis: &ShapeBasis, w: &mut Work) -> Step {
    if w.dc.iter().any(|v| !v.is_finite()) {
        return Step::Failed;
    }
    let d = w.delta.len();
    w.delta.iter_mut().for_each(|v| *v = 0.0);
    for (j, &c) in w.dc.iter().enumerate() {
        axpy(c as f32, &basis.vectors[j * d..(j + 1) * d], &mut w.delta);
    }
    geom.compose_inverse(&w.cur, &w.delta, &mut w.scratch);
    // Project onto the model (`delta` is free again and serves as scratch).
    let Some(pose) = geom.project(&w.scratch, &mut w.p, &mut w.delta, &mut w.next) else {
        return Step::Failed;
    };
    let moved = w
        .cur
        .iter()
        .zip(&w.next)
        .map(|(a, b)| (a - b).abs())
        .fold(0f32, f32::max);
    std::mem::swap(&mut w.cur, &mut w.next);
    w.pose = pose;
    Step::Moved(moved)
}

//! Expression cloning (section 3 of the paper): map a source face's parameters onto any number
//! of target faces.
//!
//! A source model (`s0, S, A0, A`) and a target model (`s0*, S*, A0*, A*`) built in the same
//! reference frame (same landmark scheme, same frame pixels; build the target with
//! `facemimic build --frame SOURCE.fmm`) form a [`Pair`]. Per pair, once:
//! `R = S*^T S` ([`inner_products`]), `Ra = A*^T A`, and the shape residual directions
//! `delta_i = (I - S* S*^T) s_i` ([`residual_directions`]). Per frame the [`Cloner`] then
//! costs a few small matrix-vector products plus one appearance synthesis per target.
//!
//! The three methods ([`Method`]), each in one named function:
//! - `substitute` (Fig. 4 A, the baseline), [`substitute_shape`]: `s = s0* + S p`,
//!   `A = A0* + A lambda`.
//! - `map` (Eq. 3, Fig. 4 B), [`map_params`] then [`map_shape`]: `s = s0* + S* (R p)`,
//!   `A = A0* + A* (Ra lambda)`.
//! - `map-residual` (Eq. 4, Fig. 4 C), [`map_shape`] then [`add_residual`]:
//!   `s = s0* + S* (R p) + sum_i delta_i p_i`. The residual is ADDED back (the paper's printed
//!   `delta_t - delta_s` would remove it; see docs/cloning.md). Appearance residuals are not added.
//!
//! Before mapping, [`apply_gains`] scales the source parameters (global and per-mode gain);
//! after mapping, [`constrain`] limits the target parameters to `+-k sigma*`.
//!
//! What the constraint bounds, precisely: for `map` and `map-residual`, every mapped target
//! parameter (`p*_j`, `lambda*_j`) is clamped to `[-k sigma*_j, k sigma*_j]`, with `sigma*_j`
//! the target mode's training standard deviation; for `substitute`, whose instance uses the
//! SOURCE modes, the (gained) source parameters are clamped to `+-k sigma_i` of the source
//! modes. It does NOT bound the residual term of `map-residual`: `sum_i delta_i p_i` lies
//! outside the span of the target's shape modes (it is exactly what the target model cannot
//! express), so it has no target parameter to clamp; it grows linearly with the (gained)
//! source parameters. Nor does it bound the pose.

use crate::model::linear::dot64;
pub use crate::model::linear::inner_products;
use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

mod expressive;
mod prior;
mod transfer;

pub use expressive::{
    expressive_appearance, expressive_shape, highlight_knee, limit_mahalanobis, luma, region_of,
    residual_after_limit, ExpressiveOptions, ExpressiveTarget, RegionGains, SourceFrame,
    SourceSide, KNEE, LIGHT_RATIO, RATIO_OFFSET, RATIO_RANGE, RATIO_SKIN_SHARE,
};
pub use prior::{
    expression_displacement, learn_prior, ExpressionPrior, ShapePairs, SpeakerShapes,
    MAX_PRIOR_MODES, STABLE_POINTS,
};
pub use transfer::{transfer_displacement, transfer_operator};

use crate::error::{check_len, Error, Result};
use crate::model::{Model, Params};
use crate::similarity::Similarity;

/// How source parameters become a target face.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// Fig. 4 A, the baseline: the target's base shape and appearance plus the SOURCE's modes
    /// times the source parameters (see [`substitute_shape`]).
    Substitute,
    /// Eq. 3, Fig. 4 B: source parameters mapped into the target's basis by inner products
    /// (see [`map_params`], [`map_shape`]).
    Map,
    /// Eq. 4, Fig. 4 C: `Map` plus the shape residual the target basis cannot express, added
    /// back (see [`add_residual`]).
    MapResidual,
    /// Strong expressions in the target's own proportions and colours: the source's
    /// displacement by deformation transfer, bounded by a generic expression prior, the
    /// target's own modes where they can follow and a residual after the limit; the appearance
    /// change as a luminance ratio image, the inner mouth and the eyelids recoloured for the
    /// target (see [`expressive_shape`], [`expressive_appearance`]).
    /// The default: it keeps strong expressions the paper's methods mute (docs/cloning.md).
    #[default]
    Expressive,
}

impl Method {
    /// All methods: the paper's three in the order of its Fig. 4, then the expressive one.
    /// The one list the CLI, the wasm package's types, the page and the docs are made from.
    pub const ALL: [Method; 4] = [
        Method::Substitute,
        Method::Map,
        Method::MapResidual,
        Method::Expressive,
    ];

    /// The method's name as used by the API, the CLI and the page.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Substitute => "substitute",
            Method::Map => "map",
            Method::MapResidual => "map-residual",
            Method::Expressive => "expressive",
        }
    }

    /// True when the method expresses the source in the target's own modes (`map`,
    /// `map-residual`), which a photo target ([`Model::is_photo`]) does not have.
    pub fn needs_target_modes(&self) -> bool {
        matches!(self, Method::Map | Method::MapResidual)
    }

    /// A short label for the page's controls.
    pub fn label(&self) -> &'static str {
        match self {
            Method::Substitute => "Substitute",
            Method::Map => "Map",
            Method::MapResidual => "Map + residual",
            Method::Expressive => "Expressive",
        }
    }

    /// One sentence on what the method does, for the CLI's help and the page.
    pub fn description(&self) -> &'static str {
        match self {
            Method::Substitute => {
                "the source's modes on the target's face (Fig. 4 A): the source's motion verbatim, its identity too"
            }
            Method::Map => "the source's parameters mapped into the target's modes (Eq. 3): under-articulates",
            Method::MapResidual => {
                "map plus the shape the target's modes cannot express (Eq. 4); the appearance as map"
            }
            Method::Expressive => {
                "the source's full expression in the target's proportions and colours: teeth, blinks and creases arrive (the default)"
            }
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                Error::Params(format!(
                    "unknown cloning method '{s}' (expected one of {})",
                    names.join(", ")
                ))
            })
    }
}

/// Options of one cloned frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CloneOptions {
    /// The method (default [`Method::Expressive`]).
    pub method: Method,
    /// Global gain on the source parameters (default 1; 0 gives the target's reference face,
    /// >1 exaggerates, negative inverts). Must be finite.
    pub gain: f32,
    /// Per source shape mode gains, multiplied with `gain`. Empty = all 1; a shorter vector
    /// leaves the remaining modes at 1; longer than the source's mode count is an error.
    pub shape_gains: Vec<f32>,
    /// Per source appearance mode gains (same rules as `shape_gains`).
    pub appearance_gains: Vec<f32>,
    /// `Some(k)`: mapped target parameters limited to `+-k sigma*` (see the module docs for
    /// what this does and does not bound); `None`: no limit. Default `Some(3.0)`. `k` must be
    /// finite and non-negative.
    pub clamp: Option<f32>,
    /// `true`: the target follows the source's head motion (the source pose relative to the
    /// source's mean pose, applied around the target's mean pose); `false` (default): the
    /// target stays at its own mean pose, and with [`Method::Expressive`] keeps its own view
    /// too: the part of the source's shape a turn of the head to the side explains is left out
    /// of the expression (the follower leaves it out of its displacement in either case), and
    /// so is the slope of the light across the face that a turn towards a lamp makes.
    pub follow_pose: bool,
    /// [`Method::Expressive`]: per-region gains (mouth, eyes, brows), multiplied with `gain`.
    pub regions: RegionGains,
    /// [`Method::Expressive`]: 0 = the target's own range only (its modes, limited), 1 (the
    /// default) = the source's full motion (plus the residual after the limit, and the ratio
    /// image); in between, a blend. Must be in `0..=1`.
    pub style: f32,
}

impl Default for CloneOptions {
    fn default() -> Self {
        CloneOptions {
            method: Method::Expressive,
            gain: 1.0,
            shape_gains: Vec::new(),
            appearance_gains: Vec::new(),
            clamp: Some(3.0),
            follow_pose: false,
            regions: RegionGains::default(),
            style: 1.0,
        }
    }
}

impl CloneOptions {
    /// Checks the options against a source model: finite gains, per-mode gain vectors no
    /// longer than the source's mode counts, a finite non-negative clamp.
    pub fn validate(&self, source: &Model) -> Result<()> {
        crate::model::bounds::check_gain("gain", self.gain)?;
        for (what, g, m) in [
            ("shape gains", &self.shape_gains, source.shape().n_modes()),
            (
                "appearance gains",
                &self.appearance_gains,
                source.appearance().n_modes(),
            ),
        ] {
            if g.len() > m {
                return Err(Error::Params(format!(
                    "{} {what} given, the source '{}' has {m} modes",
                    g.len(),
                    source.name()
                )));
            }
            for (i, &v) in g.iter().enumerate() {
                crate::model::bounds::check_gain(&format!("{what}[{i}]"), v)?;
            }
        }
        for (what, g) in [
            ("mouth gain", self.regions.mouth),
            ("eyes gain", self.regions.eyes),
            ("brows gain", self.regions.brows),
        ] {
            crate::model::bounds::check_gain(what, g)?;
        }
        if !(0.0..=1.0).contains(&self.style) {
            return Err(Error::Params(format!(
                "style {} must be in 0..=1 (0 the target's own range, 1 the source's full motion)",
                self.style
            )));
        }
        if let Some(k) = self.clamp {
            if !(0.0..=crate::model::bounds::MAX_GAIN).contains(&k) {
                return Err(Error::Params(format!(
                    "clamp {k} must be a number of standard deviations in 0..={}",
                    crate::model::bounds::MAX_GAIN
                )));
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------
// The equations, one function each.

/// The gain (section 3): `out_i = gain * g_i * p_i`, with `g_i = per_mode[i]` or 1 where
/// `per_mode` is shorter. Scales the source parameters before mapping: 0 gives the target's
/// reference face, 1 the faithful expression, >1 an exaggerated one.
pub fn apply_gains(p: &[f32], gain: f32, per_mode: &[f32], out: &mut [f32]) {
    for (i, (o, &v)) in out.iter_mut().zip(p).enumerate() {
        *o = gain * per_mode.get(i).copied().unwrap_or(1.0) * v;
    }
}

/// The residual directions of section 3.2 (Eq. 4), per unit of source parameter:
/// `delta_i = (I - S* S*^T) s_i = s_i - sum_j R[j][i] s*_j`, the part of source shape mode
/// `i` the target's shape basis cannot express. (The paper perturbs by one sigma, `sqrt
/// gamma_i`, which is the same direction scaled.) Row-major `r x 2n`, computed in f64.
pub fn residual_directions(target: &[f32], source: &[f32], dim: usize) -> Vec<f32> {
    if dim == 0 {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(source.len());
    let mut acc = vec![0f64; dim];
    for s in source.chunks_exact(dim) {
        acc.iter_mut().zip(s).for_each(|(a, &v)| *a = v as f64);
        for t in target.chunks_exact(dim) {
            let c = dot64(t, s);
            acc.iter_mut().zip(t).for_each(|(a, &v)| *a -= c * v as f64);
        }
        out.extend(acc.iter().map(|&v| v as f32));
    }
    out
}

/// Eq. 3's parameter mapping: `p* = R p` (`R` row-major `q x r`, `p` length `r`, `out`
/// length `q`). A target mode pointing the other way than the source's has a negative inner
/// product, so signs need no care; a source mode spread over several target modes maps onto
/// all of them.
pub fn map_params(r: &[f32], p: &[f32], out: &mut [f32]) {
    let cols = p.len();
    if cols == 0 {
        out.iter_mut().for_each(|o| *o = 0.0);
        return;
    }
    for (o, row) in out.iter_mut().zip(r.chunks_exact(cols)) {
        *o = row.iter().zip(p).map(|(a, b)| a * b).sum();
    }
}

/// The constraint (section 3.1): every parameter limited to `[-k sigma_j, k sigma_j]` of the
/// model it multiplies (the target's for `map`, the source's for `substitute`), so only
/// plausible faces are produced. Per parameter (a box, not an ellipsoid).
///
/// NaN-safe and total: a NaN parameter becomes 0 (the mean), a negative or NaN `k` or sigma
/// counts as 0, an overflowing `k sigma` as `f32::MAX` (see
/// [`crate::model::bounds::clamp_symmetric`]); parameters beyond `sigmas.len()` are left as they
/// are. Never panics; every clamped value is finite.
pub fn constrain(params: &mut [f32], sigmas: &[f32], k: f32) {
    for (p, s) in params.iter_mut().zip(sigmas) {
        *p = crate::model::bounds::clamp_symmetric(*p, k * s);
    }
}

/// Substitute (Fig. 4 A, the baseline of section 4): `s = s0* + S p`, the target's base shape
/// with the SOURCE's shape modes; in f64 into `acc` (`2n`). The appearance is
/// `A = A0* + A lambda` ([`crate::numerics::synthesise`] with the target's base and the source's
/// modes).
pub fn substitute_shape(target_base: &[f32], source_modes: &[f32], p: &[f32], acc: &mut [f64]) {
    linear_f64(target_base, source_modes, p, acc);
}

/// Eq. 3, shape: `s = s0* + S* p*` with `p* = R p` already mapped (and constrained), in f64
/// into `acc` (`2n`). The appearance is `A = A0* + A* lambda*` ([`crate::numerics::synthesise`]).
pub fn map_shape(target_base: &[f32], target_modes: &[f32], mapped: &[f32], acc: &mut [f64]) {
    linear_f64(target_base, target_modes, mapped, acc);
}

/// Eq. 4's residual term, with the sign that ADDS BACK what the target basis cannot express:
/// `acc += sum_i delta_i p_i` (`delta` row-major `r x 2n` from [`residual_directions`], `p`
/// the gained source parameters). Without the constraint, [`map_shape`] followed by this gives
/// exactly the source's displacement `S p` on the target's base shape.
pub fn add_residual(delta: &[f32], p: &[f32], acc: &mut [f64]) {
    let d = acc.len();
    if d == 0 {
        return;
    }
    for (&pi, row) in p.iter().zip(delta.chunks_exact(d)) {
        if pi != 0.0 {
            let pi = pi as f64;
            acc.iter_mut()
                .zip(row)
                .for_each(|(a, &v)| *a += pi * v as f64);
        }
    }
}

/// Pose (section 3; the paper places the cloned face on the target's video): with
/// `follow = false` the target stays at its `target_mean` pose; with `follow = true` it
/// moves as the source moves relative to the source's mean pose:
/// `target_mean ∘ source_mean^-1 ∘ source_pose` (the relative motion is taken in model
/// coordinates, so a source head turned by 10 degrees and shifted by a tenth of its face width
/// turns the target by 10 degrees and shifts it by a tenth of ITS face width).
pub fn target_pose(
    source_mean_inverse: &Similarity,
    source_pose: &Similarity,
    target_mean: &Similarity,
    follow: bool,
) -> Similarity {
    if follow {
        target_mean.compose(&source_mean_inverse.compose(source_pose))
    } else {
        *target_mean
    }
}

/// The method a target is cloned with: `method`, except for a photo target ([`Model::is_photo`]:
/// no modes of its own), which `map` and `map-residual` cannot express anything on; it is
/// cloned by substitution (Fig. 4 A: the source's modes on the photo's face). The expressive
/// method needs no target modes and is kept.
pub fn effective_method(method: Method, target: &Model) -> Method {
    if target.is_photo() && method.needs_target_modes() {
        Method::Substitute
    } else {
        method
    }
}

/// A pose that keeps every posed coordinate finite: valid, scale and translation below 1e15.
fn pose_in_range(p: &Similarity) -> bool {
    const MAX: f32 = 1e15;
    p.is_valid() && p.scale() < MAX && p.tx.abs() < MAX && p.ty.abs() < MAX
}

/// `base + modes^T w` into `acc`, in f64.
fn linear_f64(base: &[f32], modes: &[f32], w: &[f32], acc: &mut [f64]) {
    acc.iter_mut().zip(base).for_each(|(a, &b)| *a = b as f64);
    add_residual(modes, w, acc);
}

// ---------------------------------------------------------------------------------------
// Per-pair precomputation.

/// The per source-target precomputation of section 3: `R = S*^T S`, `Ra = A*^T A` and the
/// residual directions `delta_i = (I - S* S*^T) s_i`, plus the target's sigmas for the
/// constraint. Depends on the two models only, never on a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Pair {
    shape_map: Vec<f32>,
    appearance_map: Vec<f32>,
    residual: Vec<f32>,
    target_shape_sigmas: Vec<f32>,
    target_appearance_sigmas: Vec<f32>,
    source_modes: [usize; 2],
    target_modes: [usize; 2],
}

impl Pair {
    /// Precomputes the pair, after checking that both models are compatible (same landmark
    /// scheme, same reference frame) and have an invertible mean pose: [`Error::Incompatible`]
    /// naming what differs otherwise.
    pub fn new(source: &Model, target: &Model) -> Result<Pair> {
        for m in [source, target] {
            if m.mean_pose().inverse().is_none() {
                return Err(Error::Incompatible(format!(
                    "model '{}' is inconsistent: its mean pose is not a valid similarity",
                    m.name()
                )));
            }
        }
        source.check_compatible(target)?;
        let d = source.shape().base.len();
        Ok(Pair {
            shape_map: inner_products(&target.shape().modes, &source.shape().modes, d),
            appearance_map: target.appearance().mode_products(source.appearance()),
            residual: residual_directions(&target.shape().modes, &source.shape().modes, d),
            target_shape_sigmas: target.shape().sigmas(),
            target_appearance_sigmas: target.appearance().sigmas(),
            source_modes: [source.shape().n_modes(), source.appearance().n_modes()],
            target_modes: [target.shape().n_modes(), target.appearance().n_modes()],
        })
    }

    /// `R = S*^T S`, row-major `q x r` (target shape modes x source shape modes).
    pub fn shape_map(&self) -> &[f32] {
        &self.shape_map
    }

    /// `Ra = A*^T A`, row-major `l* x l`.
    pub fn appearance_map(&self) -> &[f32] {
        &self.appearance_map
    }

    /// The residual direction `delta_i` of source shape mode `i` (`2n` values, model
    /// coordinates per unit of `p_i`). `None` when `i` is out of range.
    pub fn residual(&self, i: usize) -> Option<&[f32]> {
        let d = self.residual.len().checked_div(self.source_modes[0])?;
        self.residual.get(i * d..(i + 1) * d)
    }

    /// `|delta_i|` per source shape mode: the fraction (0..1, source modes being unit vectors)
    /// of each source mode that the target's shape basis cannot express. A diagnostic of how
    /// much `map` under-articulates each mode.
    pub fn residual_norms(&self) -> Vec<f32> {
        (0..self.source_modes[0])
            .filter_map(|i| self.residual(i))
            .map(|r| dot64(r, r).sqrt() as f32)
            .collect()
    }
}

// ---------------------------------------------------------------------------------------
// The cloner.

/// One target's output of a cloned frame: the target parameters, the posed target shape
/// (image coordinates) and the target appearance (frame pixels). [`Cloner`] keeps one per
/// target; [`Cloner::clone_target`] writes into one of the caller's.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetFrame {
    params: Params,
    shape: Vec<f32>,
    appearance: Vec<f32>,
}

impl TargetFrame {
    /// The target's reference face at its mean pose.
    fn reference(model: &Model) -> TargetFrame {
        let params = model.base_params();
        let mut shape = model.shape().base.clone();
        params.pose.apply_in_place(&mut shape);
        TargetFrame {
            params,
            shape,
            appearance: model.appearance().base().to_vec(),
        }
    }

    /// The target parameters (see [`Cloner::target_params`]).
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The posed target shape in image coordinates (`2n` values).
    pub fn shape(&self) -> &[f32] {
        &self.shape
    }

    /// The target appearance on the frame pixels (`3N` RGB values).
    pub fn appearance(&self) -> &[f32] {
        &self.appearance
    }
}

/// One target: its model, the pair's precomputation and the output of the last frame.
#[derive(Clone, Debug)]
struct Target {
    model: Arc<Model>,
    pair: Pair,
    expressive: ExpressiveTarget,
    out: TargetFrame,
}

impl Target {
    fn new(source: &Model, side: &SourceSide, model: Arc<Model>) -> Result<Target> {
        let pair = Pair::new(source, &model)?;
        let expressive = ExpressiveTarget::new(side, source, &model)?;
        let out = TargetFrame::reference(&model);
        Ok(Target {
            model,
            pair,
            expressive,
            out,
        })
    }
}

/// What every target of one frame shares: the source, its gained parameters (as they are,
/// and constrained to the source's range for substitution) and the options.
struct Step<'a> {
    source: &'a Model,
    source_mean_inverse: &'a Similarity,
    source_pose: &'a Similarity,
    p: &'a [f32],
    lambda: &'a [f32],
    p_sub: &'a [f32],
    lambda_sub: &'a [f32],
    side: &'a SourceSide,
    frame: &'a SourceFrame,
    prior: &'a ExpressionPrior,
    options: &'a CloneOptions,
}

impl<'a> Step<'a> {
    /// The step of one source frame (`source` its parameters) prepared in `prepared`.
    fn of(
        model: &'a Model,
        prepared: &'a Prepared,
        source: &'a Params,
        options: &'a CloneOptions,
    ) -> Step<'a> {
        Step {
            source: model,
            source_mean_inverse: &prepared.source_mean_inverse,
            source_pose: &source.pose,
            p: &prepared.shape,
            lambda: &prepared.appearance,
            p_sub: &prepared.sub_shape,
            lambda_sub: &prepared.sub_appearance,
            side: &prepared.side,
            frame: &prepared.frame,
            prior: &prepared.prior,
            options,
        }
    }

    /// Clones the step onto one target (`model`, `pair`) into `out`; `acc` is shape scratch.
    /// Fails with [`Error::Overflow`] naming an output that is not finite.
    fn clone_onto(
        &self,
        (m, pair, ex): (&Model, &Pair, &mut ExpressiveTarget),
        out: &mut TargetFrame,
        acc: &mut [f64],
    ) -> Result<()> {
        let options = self.options;
        let method = effective_method(options.method, m);
        let (p, lambda) = if method == Method::Substitute {
            (self.p_sub, self.lambda_sub)
        } else {
            (self.p, self.lambda)
        };
        self.map_onto(m, pair, method, (p, lambda), out);
        // The target's own mapped appearance, `A0* + A* lambda*` (Eq. 3).
        let own_appearance = |params: &Params, out: &mut [f32]| {
            m.appearance().instance_unchecked(&params.appearance, out)
        };
        match method {
            Method::Substitute => {
                substitute_shape(&m.shape().base, &self.source.shape().modes, p, acc);
                self.source.appearance().instance_on(
                    m.appearance().base(),
                    lambda,
                    &mut out.appearance,
                );
            }
            Method::Map | Method::MapResidual => {
                if let Some(k) = options.clamp {
                    constrain(&mut out.params.shape, &pair.target_shape_sigmas, k);
                }
                map_shape(&m.shape().base, &m.shape().modes, &out.params.shape, acc);
                if method == Method::MapResidual {
                    add_residual(&pair.residual, p, acc);
                }
                own_appearance(&out.params, &mut out.appearance);
            }
            Method::Expressive => {
                let eo = ExpressiveOptions {
                    clamp: options.clamp,
                    style: options.style,
                    prior: self.prior,
                };
                expressive_shape(
                    ex,
                    self.side,
                    self.frame,
                    m,
                    &eo,
                    &mut out.params.shape,
                    acc,
                );
                if options.style < 1.0 {
                    own_appearance(&out.params, &mut out.appearance);
                }
                expressive_appearance(
                    ex,
                    self.side,
                    self.frame,
                    m,
                    options.style,
                    &mut out.appearance,
                );
            }
        }
        let pose = out.params.pose;
        for (o, a) in out.shape.chunks_exact_mut(2).zip(acc.chunks_exact(2)) {
            let (x, y) = pose.apply_point(a[0] as f32, a[1] as f32);
            o[0] = x;
            o[1] = y;
        }
        check_outputs(m, out)
    }

    /// The target's pose and mapped parameters for the step: the pose from the source's
    /// (see [`CloneOptions::follow_pose`]), the source's `p` and `lambda` through the pair's
    /// maps, the appearance limited to the clamp unless `method` substitutes.
    fn map_onto(
        &self,
        m: &Model,
        pair: &Pair,
        method: Method,
        (p, lambda): (&[f32], &[f32]),
        out: &mut TargetFrame,
    ) {
        let options = self.options;
        out.params.pose = target_pose(
            self.source_mean_inverse,
            self.source_pose,
            &m.home_pose(),
            options.follow_pose,
        );
        map_params(&pair.shape_map, p, &mut out.params.shape);
        map_params(&pair.appearance_map, lambda, &mut out.params.appearance);
        if method != Method::Substitute {
            if let Some(k) = options.clamp {
                constrain(
                    &mut out.params.appearance,
                    &pair.target_appearance_sigmas,
                    k,
                );
            }
        }
    }
}

/// Checks that a cloned frame of target `m` is finite: the entry bounds keep it so; checked so
/// that no NaN can ever leave. Fails with [`Error::Overflow`] naming the first output that is
/// not.
fn check_outputs(m: &Model, out: &TargetFrame) -> Result<()> {
    let name = &m.name();
    crate::model::bounds::check_output(&format!("target '{name}' shape"), &out.shape)?;
    crate::model::bounds::check_output(&format!("target '{name}' appearance"), &out.appearance)?;
    crate::model::bounds::check_output(
        &format!("target '{name}' shape parameters"),
        &out.params.shape,
    )?;
    crate::model::bounds::check_output(
        &format!("target '{name}' appearance parameters"),
        &out.params.appearance,
    )
}

/// One source model cloned onto any number of target models.
///
/// Represents: the source [`Model`], `N` target models each with its [`Pair`] precomputation,
/// and per target the output of the last [`Cloner::clone_frame`]: the target parameters, the
/// posed target shape (image coordinates) and the target appearance (frame pixels). Before
/// the first frame (and right after [`Cloner::add_target`]) a target's outputs hold its
/// reference face at its mean pose.
///
/// Ensures: every target is compatible with the source (same landmark scheme and frame);
/// `clone_frame` allocates nothing; a failed call leaves every output untouched.
///
/// Drawing target `i`: `drawer.draw(&cloner.target(i).frame, cloner.target_appearance(i),
/// cloner.target_shape(i), &view, &mut pixmap)` with a [`crate::FaceDrawer`].
#[derive(Clone, Debug)]
pub struct Cloner {
    source: Arc<Model>,
    source_shape_sigmas: Vec<f32>,
    source_appearance_sigmas: Vec<f32>,
    targets: Vec<Target>,
    scratch: Prepared,
    acc: Vec<f64>,
}

/// The source's side of a frame, written by `Cloner::prepare` and read by every target's
/// [`Step`]: kept apart from the targets and the shape scratch so both can be borrowed at once.
#[derive(Clone, Debug)]
struct Prepared {
    /// The inverse of the source's mean pose.
    source_mean_inverse: Similarity,
    /// The gained source shape parameters (what `map` and `map-residual` map).
    shape: Vec<f32>,
    /// The gained source appearance parameters.
    appearance: Vec<f32>,
    /// The gained shape parameters constrained to the source's range, when the options clamp
    /// (what `substitute` uses, and every photo target whatever the method).
    sub_shape: Vec<f32>,
    /// The gained and constrained appearance parameters, likewise.
    sub_appearance: Vec<f32>,
    /// The expressive method's view of the source and the frame (made once).
    side: SourceSide,
    /// The expressive method's source frame: displacement, appearance, ratio image.
    frame: SourceFrame,
    /// What `frame` was prepared from (the gained parameters and the region gains), and
    /// whether it holds anything yet.
    frame_key: Vec<f32>,
    frame_ready: bool,
    /// The source's appearance observed in its frame's pixels and the person's neutral one
    /// (`3N` each; [`Cloner::set_observed`]), used instead of the synthesised appearance
    /// while `observed_on`.
    observed: Vec<f32>,
    observed_neutral: Vec<f32>,
    observed_on: bool,
    /// The observed whole shape displacement (`2n`), when `observed_shape`.
    observed_displacement: Vec<f32>,
    observed_shape: bool,
    /// The head's turn the observed displacement leaves out (`2n`), when `observed_turn_on`.
    observed_turn: Vec<f32>,
    observed_turn_on: bool,
    /// The prior that bounds the expressive method's displacements.
    prior: ExpressionPrior,
}

impl Cloner {
    /// A cloner for `source`, with no targets yet. The model is shared, not copied: pass an
    /// `Arc<Model>` to keep using it elsewhere (a `Model` is moved in).
    pub fn new(source: impl Into<Arc<Model>>) -> Result<Cloner> {
        let source: Arc<Model> = source.into();
        let inv = source
            .mean_pose()
            .inverse()
            .ok_or_else(|| Error::Incompatible("the source's mean pose is degenerate".into()))?;
        let side = SourceSide::new(&source);
        let frame = side.frame_buffer(&source);
        Ok(Cloner {
            source_shape_sigmas: source.shape().sigmas(),
            source_appearance_sigmas: source.appearance().sigmas(),
            targets: Vec::new(),
            scratch: Prepared {
                source_mean_inverse: inv,
                shape: vec![0.0; source.shape().n_modes()],
                appearance: vec![0.0; source.appearance().n_modes()],
                sub_shape: vec![0.0; source.shape().n_modes()],
                sub_appearance: vec![0.0; source.appearance().n_modes()],
                side,
                frame,
                frame_key: vec![0.0; source.shape().n_modes() + source.appearance().n_modes() + 5],
                frame_ready: false,
                observed: Vec::new(),
                observed_neutral: Vec::new(),
                observed_on: false,
                observed_displacement: Vec::new(),
                observed_shape: false,
                observed_turn: Vec::new(),
                observed_turn_on: false,
                prior: ExpressionPrior::builtin().clone(),
            },
            acc: vec![0.0; source.shape().base.len()],
            source,
        })
    }

    /// The source model.
    pub fn source(&self) -> &Model {
        &self.source
    }

    /// The expression prior that bounds [`Method::Expressive`]'s displacements (by default
    /// [`ExpressionPrior::builtin`]).
    pub fn prior(&self) -> &ExpressionPrior {
        &self.scratch.prior
    }

    /// Replaces the expression prior (for example one learned without some people, to
    /// measure on them); kept across [`Cloner::set_source`].
    pub fn set_prior(&mut self, prior: ExpressionPrior) {
        self.scratch.prior = prior;
    }

    /// Gives [`Method::Expressive`] the source's face as observed in the frame
    /// ([`crate::fit::Observed`], kept by a [`crate::fit::Follower`]): from the next frame the
    /// ratio image, the inner mouth and the gaze are taken from the observed appearance
    /// against the person's own neutral one instead of from the source model's synthesis
    /// `A0 + A lambda` against `A0` (the person in front of the camera is not the source
    /// model's person, and their appearance parameters are not read), and the displacement
    /// `d` from the observed whole displacement when there is one (gained like `S p`) instead
    /// of `S p` (a speech model's modes hold no smile). `None` returns to the parameters.
    /// Other methods ignore it.
    ///
    /// Requires `3N` values each (the source model's frame pixels), all finite; otherwise
    /// [`Error::Params`] and nothing changes. Allocates only the first time.
    pub fn set_observed(&mut self, observed: Option<crate::fit::Observed<'_>>) -> Result<()> {
        let s = &mut self.scratch;
        let Some(o) = observed else {
            s.frame_ready &= !s.observed_on;
            s.observed_on = false;
            return Ok(());
        };
        let n = self.source.appearance().len();
        check_len("observed appearance", o.appearance, n)?;
        check_len("observed neutral appearance", o.neutral, n)?;
        let d = o.displacement.unwrap_or(&[]);
        if o.displacement.is_some() {
            check_len("observed displacement", d, self.source.shape().base.len())?;
        }
        let turn = o.turn.unwrap_or(&[]);
        if o.turn.is_some() {
            check_len("observed head turn", turn, self.source.shape().base.len())?;
        }
        if !o
            .appearance
            .iter()
            .chain(o.neutral)
            .chain(d)
            .chain(turn)
            .all(|v| v.is_finite())
        {
            return Err(Error::Params(
                "the observed appearance has a value that is not a finite number".into(),
            ));
        }
        s.observed.resize(n, 0.0);
        s.observed_neutral.resize(n, 0.0);
        s.observed.copy_from_slice(o.appearance);
        s.observed_neutral.copy_from_slice(o.neutral);
        s.observed_displacement.resize(d.len(), 0.0);
        s.observed_displacement.copy_from_slice(d);
        s.observed_shape = o.displacement.is_some();
        s.observed_turn.resize(turn.len(), 0.0);
        s.observed_turn.copy_from_slice(turn);
        s.observed_turn_on = o.turn.is_some();
        s.observed_on = true;
        s.frame_ready = false;
        Ok(())
    }

    /// Whether the expressive method reads an observed appearance ([`Cloner::set_observed`]).
    pub fn has_observed(&self) -> bool {
        self.scratch.observed_on
    }

    /// Replaces the source model, recomputing every pair. On error (the new source is
    /// inconsistent or incompatible with a target, named in the message) the cloner keeps its
    /// old state untouched. Targets' outputs are reset to their reference faces.
    pub fn set_source(&mut self, source: impl Into<Arc<Model>>) -> Result<()> {
        let mut fresh = Cloner::new(source)?;
        fresh.scratch.prior = self.scratch.prior.clone();
        let mut targets = Vec::with_capacity(self.targets.len());
        for t in &self.targets {
            targets.push(Target::new(
                &fresh.source,
                &fresh.scratch.side,
                t.model.clone(),
            )?);
        }
        fresh.targets = targets;
        *self = fresh;
        Ok(())
    }

    /// Adds a target model (precomputing its pair) and returns its index. Fails with
    /// [`Error::Incompatible`] naming what differs (landmark count/scheme, frame
    /// fingerprint, size, pixel count) when it is not in the source's reference frame.
    pub fn add_target(&mut self, target: impl Into<Arc<Model>>) -> Result<usize> {
        let t = Target::new(&self.source, &self.scratch.side, target.into())?;
        self.targets.push(t);
        Ok(self.targets.len() - 1)
    }

    /// Removes target `index` and returns its model; later targets move down by one.
    pub fn remove_target(&mut self, index: usize) -> Result<Arc<Model>> {
        self.check_index(index)?;
        Ok(self.targets.remove(index).model)
    }

    /// Replaces target `index` (same checks as [`Cloner::add_target`]; on error nothing
    /// changes).
    pub fn replace_target(&mut self, index: usize, target: impl Into<Arc<Model>>) -> Result<()> {
        self.check_index(index)?;
        self.targets[index] = Target::new(&self.source, &self.scratch.side, target.into())?;
        Ok(())
    }

    fn check_index(&self, index: usize) -> Result<()> {
        if index < self.targets.len() {
            Ok(())
        } else {
            Err(Error::Params(format!(
                "target index {index} out of range ({} target(s))",
                self.targets.len()
            )))
        }
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.targets.len()
    }

    /// Target model `index`. Panics when `index >= n_targets()` (like slice indexing); use
    /// [`Cloner::get_target`] for a checked lookup.
    pub fn target(&self, index: usize) -> &Model {
        &self.targets[index].model
    }

    /// Target model `index`, or `None` when out of range.
    pub fn get_target(&self, index: usize) -> Option<&Model> {
        self.targets.get(index).map(|t| &*t.model)
    }

    /// The precomputation of the pair (source, target `index`), or `None`.
    pub fn pair(&self, index: usize) -> Option<&Pair> {
        self.targets.get(index).map(|t| &t.pair)
    }

    /// Clones one source frame onto every target in one call. Allocates nothing.
    ///
    /// Requires: `source` fits the source model (lengths, finite values within the bounds of
    /// [`crate::model::bounds`], pose in range) and the options are valid
    /// ([`CloneOptions::validate`]); otherwise [`Error::Params`] and no output changes. An
    /// output that overflows anyway is [`Error::Overflow`] naming it (then outputs are
    /// partly written and must not be used).
    /// Ensures, per target: [`Cloner::target_params`] holds the target parameters (for
    /// `substitute`, see there), [`Cloner::target_shape`] the posed shape in image
    /// coordinates, [`Cloner::target_appearance`] the appearance on the frame pixels.
    pub fn clone_frame(&mut self, source: &Params, options: &CloneOptions) -> Result<()> {
        self.prepare(source, options, 0..self.targets.len())?;
        let step = Step::of(&self.source, &self.scratch, source, options);
        for t in &mut self.targets {
            step.clone_onto(
                (&t.model, &t.pair, &mut t.expressive),
                &mut t.out,
                &mut self.acc,
            )?;
        }
        Ok(())
    }

    /// Clones one source frame onto target `index` alone, into `out` (for example with
    /// another method than the one every target follows: the paper's Fig. 4 side by side),
    /// leaving the cloner's own outputs untouched. Allocates nothing.
    ///
    /// Requires what [`Cloner::clone_frame`] requires, and `out` made for this target by
    /// [`Cloner::target_frame`]; otherwise an error and `out` is unchanged.
    pub fn clone_target(
        &mut self,
        index: usize,
        source: &Params,
        options: &CloneOptions,
        out: &mut TargetFrame,
    ) -> Result<()> {
        self.check_index(index)?;
        let t = &self.targets[index];
        if out.shape.len() != t.out.shape.len()
            || out.appearance.len() != t.out.appearance.len()
            || out.params.shape.len() != t.out.params.shape.len()
            || out.params.appearance.len() != t.out.params.appearance.len()
        {
            return Err(Error::Params(format!(
                "the output was not made for target '{}' (use Cloner::target_frame)",
                t.model.name()
            )));
        }
        self.prepare(source, options, index..index + 1)?;
        let step = Step::of(&self.source, &self.scratch, source, options);
        let t = &mut self.targets[index];
        step.clone_onto((&t.model, &t.pair, &mut t.expressive), out, &mut self.acc)
    }

    /// A copy of target `index`'s output of the last frame (a buffer for
    /// [`Cloner::clone_target`]), or `None` when out of range.
    pub fn target_frame(&self, index: usize) -> Option<TargetFrame> {
        self.targets.get(index).map(|t| t.out.clone())
    }

    /// Checks the source parameters, the options and the poses of `targets`, then writes the
    /// gained source parameters, as they are and constrained for substitution, into the scratch.
    fn prepare(
        &mut self,
        source: &Params,
        options: &CloneOptions,
        targets: std::ops::Range<usize>,
    ) -> Result<()> {
        self.source.check_params(source)?;
        options.validate(&self.source)?;
        for t in &self.targets[targets] {
            let pose = target_pose(
                &self.scratch.source_mean_inverse,
                &source.pose,
                &t.model.home_pose(),
                options.follow_pose,
            );
            if !pose_in_range(&pose) {
                return Err(Error::Params(format!(
                    "the pose for target '{}' is out of range (scale {}, translation {}, {})",
                    t.model.name(),
                    pose.scale(),
                    pose.tx,
                    pose.ty
                )));
            }
        }
        apply_gains(
            &source.shape,
            options.gain,
            &options.shape_gains,
            &mut self.scratch.shape,
        );
        apply_gains(
            &source.appearance,
            options.gain,
            &options.appearance_gains,
            &mut self.scratch.appearance,
        );
        let s = &mut self.scratch;
        s.sub_shape.copy_from_slice(&s.shape);
        s.sub_appearance.copy_from_slice(&s.appearance);
        if let Some(k) = options.clamp {
            constrain(&mut s.sub_shape, &self.source_shape_sigmas, k);
            constrain(&mut s.sub_appearance, &self.source_appearance_sigmas, k);
        }
        if options.method == Method::Expressive {
            // The same source frame again (the compare view after the main update): its
            // synthesis and ratio image are already there.
            let r = &options.regions;
            // The head's turn is held out of the expression unless the targets follow the pose.
            let hold_turn = !options.follow_pose;
            let gains = [
                r.mouth,
                r.eyes,
                r.brows,
                options.gain,
                hold_turn as u8 as f32,
            ];
            let key = s.shape.iter().chain(&s.appearance).chain(&gains);
            if !(s.frame_ready && s.frame_key.iter().eq(key.clone())) {
                s.frame_key.iter_mut().zip(key).for_each(|(k, v)| *k = *v);
                if s.observed_on {
                    s.frame.prepare_observed(
                        &s.side,
                        &self.source,
                        &s.shape,
                        crate::fit::Observed {
                            appearance: &s.observed,
                            neutral: &s.observed_neutral,
                            displacement: s.observed_shape.then_some(&s.observed_displacement[..]),
                            turn: s.observed_turn_on.then_some(&s.observed_turn[..]),
                        },
                        &options.regions,
                        options.gain,
                        hold_turn,
                    );
                } else {
                    s.frame.prepare(
                        &s.side,
                        &self.source,
                        &s.shape,
                        &s.appearance,
                        &options.regions,
                        hold_turn,
                    );
                }
                s.frame_ready = true;
            }
        }
        Ok(())
    }

    /// The target parameters of the last frame for target `index`: pose, `p*`, `lambda*`.
    ///
    /// For `map` and `map-residual`: the mapped (and, with a clamp, constrained) target
    /// parameters `R p`, `Ra lambda` (for `map-residual` the shape additionally carries the
    /// residual, which no target parameter describes). For `substitute`: the least-squares
    /// projection of the substituted instance onto the target model, `S*^T (s - s0*) = R p`
    /// and `A*^T (A - A0*) = Ra lambda`, with `p`, `lambda` the gained source parameters
    /// after the constraint (which for `substitute` limits them to `+-k sigma` of the
    /// SOURCE; the projection itself is not clamped to the target's range). The instance uses
    /// the source's modes and is in [`Cloner::target_shape`] / [`Cloner::target_appearance`].
    /// Panics when `index` is out of range.
    pub fn target_params(&self, index: usize) -> &Params {
        &self.targets[index].out.params
    }

    /// Target `index`'s instance landmarks of the last frame, posed, in image coordinates
    /// (`2n` values). Panics when `index` is out of range.
    pub fn target_shape(&self, index: usize) -> &[f32] {
        &self.targets[index].out.shape
    }

    /// Target `index`'s appearance of the last frame: `3N` RGB values on the frame pixels,
    /// ready for [`crate::FaceDrawer::upload`]. Panics when `index` is out of range.
    pub fn target_appearance(&self, index: usize) -> &[f32] {
        &self.targets[index].out.appearance
    }
}

//! The appearance model (Eq. 2).

use crate::error::Result;
use crate::model::linear::LinearModel;

/// A linear appearance model `A(x) = A0(x) + sum_i lambda_i A_i(x)` over the reference frame's
/// pixels (the paper's Eq. 2).
///
/// Represents: the base appearance `A0` (`3N` values, RGB in `0..=1` per frame pixel, in the
/// frame's pixel order), `l` orthonormal modes `A_i` and their variances `eta_i`.
///
/// Its storage is private: the cloner, the fitter, the model file and the bounds reach it only
/// through the operations below (the mean, an instance, a projection, the mapping between two
/// models' modes), so another kind of appearance (e.g. the paper's multi-segment appearance,
/// section 5) is a new type behind the same operations, not an edit of every reader.
///
/// Ensures (when built by [`crate::Builder`], [`crate::photo_model`] or read from a model file
/// and accepted by [`crate::Model::new`]): `3N` base values, `l x 3N` mode values, `l`
/// non-negative variances, every value finite.
#[derive(Clone, Debug, PartialEq)]
pub struct AppearanceModel {
    linear: LinearModel,
}

impl AppearanceModel {
    /// The model of this base `A0` (`3N`), these modes (row-major `l x 3N`) and their
    /// variances (`l`). Dimensions are checked by [`crate::Model::new`].
    pub fn new(base: Vec<f32>, modes: Vec<f32>, variances: Vec<f32>) -> AppearanceModel {
        AppearanceModel {
            linear: LinearModel {
                base,
                modes,
                variances,
            },
        }
    }

    /// The linear model behind it (the model file, the bounds and the checks of
    /// [`crate::Model::new`] read its arrays).
    pub(crate) fn linear(&self) -> &LinearModel {
        &self.linear
    }

    /// The arrays it is made of, `(base, modes, variances)`, as [`AppearanceModel::new`] takes
    /// them (for tools that edit a model, and tests that damage one on purpose).
    pub fn into_arrays(self) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
        (self.linear.base, self.linear.modes, self.linear.variances)
    }

    /// The base appearance `A0`: `3N` values, RGB per frame pixel.
    pub fn base(&self) -> &[f32] {
        &self.linear.base
    }

    /// Number of modes `l`.
    pub fn n_modes(&self) -> usize {
        self.linear.n_modes()
    }

    /// Dimension `3N` of an instance.
    pub fn len(&self) -> usize {
        self.linear.len()
    }

    /// True when the model has dimension 0 (never the case for a valid model).
    pub fn is_empty(&self) -> bool {
        self.linear.is_empty()
    }

    /// Mode `i` (`3N` values); `None` when `i >= l`.
    pub fn mode(&self, i: usize) -> Option<&[f32]> {
        self.linear.mode(i)
    }

    /// The variance `eta_i` of each mode.
    pub fn variances(&self) -> &[f32] {
        &self.linear.variances
    }

    /// The standard deviation `sqrt(eta_i)` of each mode.
    pub fn sigmas(&self) -> Vec<f32> {
        self.linear.sigmas()
    }

    /// Each mode's share of the kept variance (summing to 1; all 0 without variance).
    pub fn variance_shares(&self) -> Vec<f32> {
        self.linear.variance_shares()
    }

    /// Eq. 2, `A = A0 + sum_i lambda_i A_i`, into `out` (`3N`), checked. Allocates nothing.
    pub fn instance(&self, lambda: &[f32], out: &mut [f32]) -> Result<()> {
        self.linear
            .instance_checked("appearance parameters", lambda, out)
    }

    /// Eq. 2 without checks (hot paths that validated `lambda`; nothing is written when
    /// `out.len() != 3N`). Cache-blocked, bit-identical to the plain sum.
    pub fn instance_unchecked(&self, lambda: &[f32], out: &mut [f32]) {
        self.linear.instance_unchecked(lambda, out);
    }

    /// This model's modes added to another base: `base + sum_i lambda_i A_i` into `out`
    /// (substitution, Eq. 3 with the target's `A0*`; `base` has `3N` values). Allocates nothing;
    /// nothing is written when the lengths differ.
    pub fn instance_on(&self, base: &[f32], lambda: &[f32], out: &mut [f32]) {
        if base.len() == self.len() {
            synthesise(base, &self.linear.modes, lambda, out);
        }
    }

    /// The projection of an appearance onto the modes, `lambda_i = A_i . (x - A0)`, into
    /// `out` (`l` values).
    pub fn project(&self, x: &[f32], out: &mut [f32]) {
        self.linear.project(x, out);
    }

    /// The inner products of this model's modes with `source`'s (`l x l_source`, row-major,
    /// in f64 then rounded): how a source appearance parameter reads in this model's modes
    /// (the appearance half of the mapping, Eq. 3). Both models must share the reference frame
    /// (the same `3N`); an empty matrix otherwise.
    pub fn mode_products(&self, source: &AppearanceModel) -> Vec<f32> {
        if source.len() != self.len() {
            return Vec::new();
        }
        crate::model::linear::inner_products(&self.linear.modes, &source.linear.modes, self.len())
    }
}

pub use crate::model::linear::synthesise;

//! The appearance model (Eq. 2).

use crate::error::Result;
use crate::model::linear::LinearModel;

/// A linear appearance model `A(x) = A0(x) + sum_i lambda_i A_i(x)` over the reference frame's
/// pixels (the paper's Eq. 2): a [`LinearModel`] (it dereferences to one for the base, the
/// modes, the variances and the shared operations).
///
/// Represents: the base appearance `A0` (`3N` values, RGB in `0..=1` per frame pixel, in the
/// frame's pixel order), `l` orthonormal modes (row-major `l x 3N`) and their variances `eta_i`.
#[derive(Clone, Debug, PartialEq)]
pub struct AppearanceModel(pub LinearModel);

crate::model::linear::linear_newtype!(AppearanceModel);

impl AppearanceModel {
    /// Eq. 2, `A = A0 + sum_i lambda_i A_i`, into `out` (`3N`). Allocates nothing.
    pub fn instance(&self, lambda: &[f32], out: &mut [f32]) -> Result<()> {
        self.0
            .instance_checked("appearance parameters", lambda, out)
    }
}

pub use crate::model::linear::synthesise;

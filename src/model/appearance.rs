//! The appearance model (Eq. 2).

use std::ops::{Deref, DerefMut};

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

impl AppearanceModel {
    /// The appearance model of base `A0`, modes (row-major `l x 3N`) and variances `eta_i`.
    pub fn new(base: Vec<f32>, modes: Vec<f32>, variances: Vec<f32>) -> AppearanceModel {
        AppearanceModel(LinearModel {
            base,
            modes,
            variances,
        })
    }

    /// Eq. 2, `A = A0 + sum_i lambda_i A_i`, into `out` (`3N`). Allocates nothing.
    pub fn instance(&self, lambda: &[f32], out: &mut [f32]) -> Result<()> {
        self.0
            .instance_checked("appearance parameters", lambda, out)
    }
}

impl Deref for AppearanceModel {
    type Target = LinearModel;
    fn deref(&self) -> &LinearModel {
        &self.0
    }
}

impl DerefMut for AppearanceModel {
    fn deref_mut(&mut self) -> &mut LinearModel {
        &mut self.0
    }
}

pub use crate::model::linear::synthesise;

//! The appearance model (Eq. 2).

use crate::error::{check_len, Result};

/// A linear appearance model `A(x) = A0(x) + sum_i lambda_i A_i(x)` over the reference frame's
/// pixels (the paper's Eq. 2).
///
/// Represents: the base appearance `A0` (`3N` values, RGB in `0..=1` per frame pixel, in the
/// frame's pixel order), `l` orthonormal modes (row-major `l x 3N`) and their variances `eta_i`.
#[derive(Clone, Debug, PartialEq)]
pub struct AppearanceModel {
    /// Base appearance `A0`.
    pub base: Vec<f32>,
    /// Modes, row-major `l x 3N`.
    pub modes: Vec<f32>,
    /// Variance `eta_i` of each mode.
    pub variances: Vec<f32>,
}

impl AppearanceModel {
    /// Number of modes `l`.
    pub fn n_modes(&self) -> usize {
        self.variances.len()
    }

    /// Length of an appearance vector (`3N`).
    pub fn len(&self) -> usize {
        self.base.len()
    }

    /// True when the model has no pixels (never the case for a valid model).
    pub fn is_empty(&self) -> bool {
        self.base.is_empty()
    }

    /// Mode `i` (`3N` values); `None` when `i >= l`.
    pub fn mode(&self, i: usize) -> Option<&[f32]> {
        let d = self.base.len();
        if i >= self.n_modes() {
            return None;
        }
        self.modes.get(i * d..(i + 1) * d)
    }

    /// `sqrt(eta_i)` per mode.
    pub fn sigmas(&self) -> Vec<f32> {
        self.variances.iter().map(|v| v.sqrt()).collect()
    }

    /// Each mode's share of the kept variance (summing to 1; all 0 without variance).
    pub fn variance_shares(&self) -> Vec<f32> {
        crate::pca::variance_shares(&self.variances)
    }

    /// Eq. 2, `A = A0 + sum_i lambda_i A_i`, into `out` (`3N`). Allocates nothing.
    pub fn instance(&self, lambda: &[f32], out: &mut [f32]) -> Result<()> {
        check_len("appearance parameters", lambda, self.n_modes())?;
        crate::limits::check_param_values("appearance parameters", lambda)?;
        check_len("appearance buffer", out, self.base.len())?;
        self.instance_unchecked(lambda, out);
        crate::limits::check_output("appearance instance", out)
    }

    /// [`AppearanceModel::instance`] without checks (hot path).
    pub fn instance_unchecked(&self, lambda: &[f32], out: &mut [f32]) {
        synthesise(&self.base, &self.modes, lambda, out);
    }

    /// Projects an appearance vector: `lambda = A^T (g - A0)` into `out` (length `l`).
    pub fn project(&self, g: &[f32], out: &mut [f32]) {
        let d = self.base.len();
        for (o, mode) in out.iter_mut().zip(self.modes.chunks_exact(d)) {
            *o = dot_diff(mode, g, &self.base);
        }
    }
}

/// `out = base + sum_i w_i modes_i` (modes row-major, `base.len()` each): the linear
/// combination behind Eq. 2 (and the mapped appearance of Eq. 3).
///
/// Processed in cache-sized blocks of the output, so each block stays in L1 while every mode
/// streams through once; zero weights are skipped. Per element the sum runs in mode order (the
/// result equals the plain loop bit for bit). Allocates nothing; extra weights beyond the
/// number of modes are ignored.
pub fn synthesise(base: &[f32], modes: &[f32], w: &[f32], out: &mut [f32]) {
    const BLOCK: usize = 2048;
    let d = base.len();
    if d == 0 || out.len() != d {
        return;
    }
    let n = w.len().min(modes.len() / d);
    let mut start = 0;
    while start < d {
        let end = (start + BLOCK).min(d);
        let o = &mut out[start..end];
        o.copy_from_slice(&base[start..end]);
        for (i, &wi) in w[..n].iter().enumerate() {
            if wi != 0.0 {
                let m = &modes[i * d + start..i * d + end];
                for (a, &b) in o.iter_mut().zip(m) {
                    *a += wi * b;
                }
            }
        }
        start = end;
    }
}

/// `sum_k a_k (g_k - b_k)`, accumulated in 8 lanes for speed and accuracy.
pub fn dot_diff(a: &[f32], g: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 8];
    let chunks = a.len() / 8;
    for c in 0..chunks {
        let o = c * 8;
        for l in 0..8 {
            acc[l] += a[o + l] * (g[o + l] - b[o + l]);
        }
    }
    let mut s: f32 = acc.iter().sum();
    for k in chunks * 8..a.len() {
        s += a[k] * (g[k] - b[k]);
    }
    s
}

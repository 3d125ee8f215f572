//! The linear model both halves of an AAM are: a base vector plus a weighted sum of orthonormal
//! modes, each with its variance. The shape model (Eq. 1) and the appearance model (Eq. 2) are
//! this type with their own meaning on top ([`crate::ShapeModel`], [`crate::AppearanceModel`]
//! dereference to it).

use crate::error::{check_len, Result};

/// A linear model `x = x0 + sum_i w_i x_i` with `k` orthonormal modes of dimension `d`.
///
/// Represents: the base `x0` (`d` values), the modes row-major (`k x d`: mode `i` is
/// `modes[i*d..(i+1)*d]`) and the variance of each mode.
/// Requires (for the methods to mean anything): `modes.len() == k * d` with `k =
/// variances.len()`. Ensures (when built by [`crate::Builder`] or read from a model file):
/// modes orthonormal to within float precision, variances non-negative and descending.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearModel {
    /// The base `x0` (the mean, or the chosen reference).
    pub base: Vec<f32>,
    /// Modes, row-major `k x d`.
    pub modes: Vec<f32>,
    /// Variance of each mode.
    pub variances: Vec<f32>,
}

impl LinearModel {
    /// Number of modes `k`.
    pub fn n_modes(&self) -> usize {
        self.variances.len()
    }

    /// Dimension `d` of an instance.
    pub fn len(&self) -> usize {
        self.base.len()
    }

    /// True when the model has dimension 0 (never the case for a valid model).
    pub fn is_empty(&self) -> bool {
        self.base.is_empty()
    }

    /// Mode `i` (`d` values); `None` when `i >= k`.
    pub fn mode(&self, i: usize) -> Option<&[f32]> {
        let d = self.base.len();
        if i >= self.n_modes() {
            return None;
        }
        self.modes.get(i * d..(i + 1) * d)
    }

    /// The standard deviation `sqrt(variance)` of each mode.
    pub fn sigmas(&self) -> Vec<f32> {
        self.variances.iter().map(|v| v.sqrt()).collect()
    }

    /// Each mode's share of the kept variance (summing to 1; all 0 without variance).
    pub fn variance_shares(&self) -> Vec<f32> {
        crate::pca::variance_shares(&self.variances)
    }

    /// `x0 + sum_i w_i x_i` into `out` (`d`), checked: `w` has `k` finite values within the
    /// parameter limit, `out` has `d` values, and the instance stays finite (`what` names the
    /// parameters in errors). Allocates nothing.
    pub fn instance_checked(&self, what: &'static str, w: &[f32], out: &mut [f32]) -> Result<()> {
        check_len(what, w, self.n_modes())?;
        crate::model::limits::check_param_values(what, w)?;
        check_len("instance buffer", out, self.base.len())?;
        self.instance_unchecked(w, out);
        crate::model::limits::check_output("instance", out)
    }

    /// `x0 + sum_i w_i x_i` into `out` without checks (hot paths that validated their input;
    /// nothing is written when `out.len() != d`).
    pub fn instance_unchecked(&self, w: &[f32], out: &mut [f32]) {
        synthesise(&self.base, &self.modes, w, out);
    }

    /// Projects a vector onto the modes: `w_i = x_i . (x - x0)` into `out` (`k` values).
    pub fn project(&self, x: &[f32], out: &mut [f32]) {
        let d = self.base.len();
        if d == 0 {
            return;
        }
        for (o, mode) in out.iter_mut().zip(self.modes.chunks_exact(d)) {
            *o = dot_diff(mode, x, &self.base);
        }
    }
}

/// A newtype over [`LinearModel`] with its meaning on top: `new(base, modes, variances)`, and
/// `Deref`/`DerefMut` to the linear model for the fields and the shared operations.
macro_rules! linear_newtype {
    ($name:ident) => {
        impl $name {
            /// The model of this base, these modes (row-major) and their variances.
            pub fn new(base: Vec<f32>, modes: Vec<f32>, variances: Vec<f32>) -> $name {
                $name($crate::model::linear::LinearModel {
                    base,
                    modes,
                    variances,
                })
            }
        }

        impl std::ops::Deref for $name {
            type Target = $crate::model::linear::LinearModel;
            fn deref(&self) -> &Self::Target {
                &self.0
            }
        }

        impl std::ops::DerefMut for $name {
            fn deref_mut(&mut self) -> &mut Self::Target {
                &mut self.0
            }
        }
    };
}
pub(crate) use linear_newtype;

/// `out = base + sum_i w_i modes_i` (modes row-major, `base.len()` each): the linear
/// combination behind Eq. 1 and Eq. 2 (and the mapped appearance of Eq. 3).
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

/// The inner-product matrix of section 3.1, `R = T^T S` (rows = target modes, columns =
/// source modes, row-major `q x r`): `R[j][i] = <t_j, s_i>`. Used for shape (`R = S*^T S`) and
/// appearance (`Ra = A*^T A`). Accumulates in f64. `target` and `source` are row-major mode
/// matrices whose rows are `dim` long.
pub fn inner_products(target: &[f32], source: &[f32], dim: usize) -> Vec<f32> {
    if dim == 0 {
        return Vec::new();
    }
    let mut r = Vec::with_capacity((target.len() / dim) * (source.len() / dim));
    for t in target.chunks_exact(dim) {
        for s in source.chunks_exact(dim) {
            r.push(dot64(t, s) as f32);
        }
    }
    r
}

/// The dot product of `a` and `b` (their common length), accumulated in f64 over four lanes.
pub fn dot64(a: &[f32], b: &[f32]) -> f64 {
    let mut acc = [0f64; 4];
    let n = a.len().min(b.len());
    let chunks = n / 4;
    for c in 0..chunks {
        let o = c * 4;
        for l in 0..4 {
            acc[l] += a[o + l] as f64 * b[o + l] as f64;
        }
    }
    let mut s = acc.iter().sum::<f64>();
    for k in chunks * 4..n {
        s += a[k] as f64 * b[k] as f64;
    }
    s
}

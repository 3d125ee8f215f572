//! Principal component analysis about a given centre (the mean, or a reference sample).

use nalgebra::{DMatrix, SymmetricEigen};

/// The result of [`pca`]: orthonormal modes (row-major, one mode per row of length `dim`) and
/// their variances, in descending order.
#[derive(Clone, Debug)]
pub struct Pca {
    /// `modes.len() == variances.len() * dim`; mode `i` is `modes[i*dim..(i+1)*dim]`.
    pub modes: Vec<f32>,
    /// Variance of each mode (eigenvalue of the covariance about the centre), descending.
    pub variances: Vec<f32>,
    /// Sum of all eigenvalues (total variance about the centre).
    pub total_variance: f64,
}

/// PCA of `samples` (each of length `dim`) about `centre`.
///
/// Uses the Gram ("snapshot") matrix when there are fewer samples than dimensions (always the
/// case for appearance: 20 images of ~50k values), the covariance matrix otherwise. Both go
/// through nalgebra's symmetric eigensolver. Variances use the `1/(n-1)` normalisation.
///
/// Keeps the fewest leading modes whose variances add up to at least `fraction` of the total,
/// at most `max_modes`, and never modes of (numerically) zero variance.
/// Ensures: modes orthonormal (re-orthogonalised in f64), each mode's sign chosen so that its
/// largest-magnitude component is positive (deterministic output).
///
/// Fails with [`crate::error::Error::Training`] when a sample's length differs from the centre's or a
/// value is not finite.
pub fn pca(
    samples: &[Vec<f64>],
    centre: &[f64],
    fraction: f64,
    max_modes: usize,
) -> crate::error::Result<Pca> {
    let n = samples.len();
    let dim = centre.len();
    if let Some(i) = samples.iter().position(|s| s.len() != dim) {
        return Err(crate::error::Error::Training(format!(
            "PCA sample {i} has {} values, the centre has {dim}",
            samples[i].len()
        )));
    }
    if samples
        .iter()
        .flatten()
        .chain(centre)
        .any(|v| !v.is_finite())
    {
        return Err(crate::error::Error::Training(
            "PCA samples or centre are not finite".into(),
        ));
    }
    let denom = (n.max(2) - 1) as f64;
    // Deviations, n x dim.
    let x = DMatrix::from_fn(n, dim, |r, c| samples[r][c] - centre[c]);
    let (eigvals, dirs): (Vec<f64>, Vec<Vec<f64>>) = if n < dim {
        let gram = (&x * x.transpose()) / denom;
        let eig = SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let mut vals = Vec::new();
        let mut dirs = Vec::new();
        for k in order {
            let lam = eig.eigenvalues[k].max(0.0);
            let v = eig.eigenvectors.column(k);
            // mode = X^T v, normalised.
            let m = x.transpose() * v;
            vals.push(lam);
            dirs.push(m.iter().copied().collect());
        }
        (vals, dirs)
    } else {
        let cov = (x.transpose() * &x) / denom;
        let eig = SymmetricEigen::new(cov);
        let mut order: Vec<usize> = (0..dim).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let vals = order.iter().map(|&k| eig.eigenvalues[k].max(0.0)).collect();
        let dirs = order
            .iter()
            .map(|&k| eig.eigenvectors.column(k).iter().copied().collect())
            .collect();
        (vals, dirs)
    };
    let total: f64 = eigvals.iter().sum();
    // The leading directions until the kept variance reaches the fraction.
    let mut variances = Vec::new();
    let mut acc = 0.0;
    for &lam in &eigvals {
        if variances.len() >= max_modes || total <= 0.0 || lam <= total * 1e-9 {
            break;
        }
        if acc >= fraction * total && !variances.is_empty() {
            break;
        }
        acc += lam;
        variances.push(lam as f32);
    }
    // Orthonormalised in f64 (the snapshot directions are not normalised); a direction
    // that vanishes ends the list.
    let mut modes: Vec<Vec<f64>> = dirs.into_iter().take(variances.len()).collect();
    let mut none = vec![Vec::new(); modes.len()];
    let kept = gram_schmidt(&mut modes, &mut none, 1e-12);
    let prefix = kept
        .iter()
        .enumerate()
        .take_while(|(i, &k)| *i == k)
        .count();
    modes.truncate(prefix);
    variances.truncate(prefix);
    for d in &mut modes {
        let big = d
            .iter()
            .copied()
            .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
        if big < 0.0 {
            d.iter_mut().for_each(|v| *v = -*v);
        }
    }
    Ok(Pca {
        modes: modes
            .iter()
            .flat_map(|m| m.iter().map(|&v| v as f32))
            .collect(),
        variances,
        total_variance: total,
    })
}

/// The mean of equal-length samples.
pub fn mean(samples: &[Vec<f64>]) -> Vec<f64> {
    let dim = samples.first().map_or(0, Vec::len);
    let mut m = vec![0.0; dim];
    for s in samples {
        m.iter_mut().zip(s).for_each(|(a, b)| *a += b);
    }
    let n = samples.len().max(1) as f64;
    m.iter_mut().for_each(|v| *v /= n);
    m
}

/// Each variance's share of their sum, computed in f64 (all 0 when the sum is not positive).
pub fn variance_shares(variances: &[f32]) -> Vec<f32> {
    let total: f64 = variances.iter().map(|&v| v as f64).sum();
    variances
        .iter()
        .map(|&v| {
            if total > 0.0 {
                (v as f64 / total) as f32
            } else {
                0.0
            }
        })
        .collect()
}

/// The crate's one Gram-Schmidt: modified Gram-Schmidt (two passes) over `vectors`, keeping those whose residual norm is at
/// least `rel_tol` of their original norm. Every operation applied to a vector is applied to
/// its `companions` too (so linear functionals of the vectors, like their gradients, follow).
/// Returns the indices (into the input) of the kept vectors; kept vectors are orthonormal.
pub(crate) fn gram_schmidt(
    vectors: &mut Vec<Vec<f64>>,
    companions: &mut Vec<Vec<Vec<f64>>>,
    rel_tol: f64,
) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    let mut out_v: Vec<Vec<f64>> = Vec::new();
    let mut out_c: Vec<Vec<Vec<f64>>> = Vec::new();
    let vs = std::mem::take(vectors);
    let cs = std::mem::take(companions);
    for (idx, (mut v, mut c)) in vs.into_iter().zip(cs).enumerate() {
        let norm0 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if !(norm0 > 0.0) || !norm0.is_finite() {
            continue;
        }
        for _pass in 0..2 {
            for (u, uc) in out_v.iter().zip(&out_c) {
                let d: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(a, b)| *a -= d * b);
                for (cv, ucv) in c.iter_mut().zip(uc) {
                    cv.iter_mut().zip(ucv).for_each(|(a, b)| *a -= d * b);
                }
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm < rel_tol * norm0 {
            continue;
        }
        v.iter_mut().for_each(|x| *x /= norm);
        for cv in c.iter_mut() {
            cv.iter_mut().for_each(|x| *x /= norm);
        }
        kept.push(idx);
        out_v.push(v);
        out_c.push(c);
    }
    *vectors = out_v;
    *companions = out_c;
    kept
}

//! Choosing varied training frames: farthest-point sampling of Procrustes-aligned shapes.
//!
//! A person-specific model needs training faces that span the person's expressions and poses;
//! many consecutive video frames are nearly the same face. Given the landmarks of many frames,
//! [`select_varied`] keeps `n` of them that are spread out in shape space: the frame closest to
//! the mean first (a typical face), then repeatedly the frame farthest from every frame kept so
//! far (Gonzalez's greedy farthest-point sampling, a 2-approximation of the k-center problem).
//! Shapes are compared after generalised Procrustes alignment, so head position, size and
//! in-plane rotation do not count as variety; expression and out-of-plane pose do.

use crate::error::{Error, Result};
use crate::model::shape::generalised_procrustes;

/// Indices of `n` varied shapes among `shapes` (each `2k` interleaved image coordinates, all of
/// one length), in the order they were chosen. Deterministic (ties go to the lower index).
///
/// Requires: `2 <= n`, at least `n` shapes, equal lengths of at least 3 points, finite values.
/// With `n >= shapes.len()` every index is returned (in choice order).
pub fn select_varied(shapes: &[&[f32]], n: usize) -> Result<Vec<usize>> {
    let aligned = aligned_shapes(shapes)?;
    let n = n.min(aligned.len());
    let mean = crate::pca::mean(&aligned);
    let dist =
        |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum() };
    let first = (0..aligned.len())
        .min_by(|&a, &b| dist(&aligned[a], &mean).total_cmp(&dist(&aligned[b], &mean)))
        .unwrap_or(0);
    let mut chosen = vec![first];
    let mut nearest: Vec<f64> = aligned.iter().map(|s| dist(s, &aligned[first])).collect();
    while chosen.len() < n {
        let mut best = None;
        for (i, &d) in nearest.iter().enumerate() {
            if chosen.contains(&i) {
                continue;
            }
            if best.is_none_or(|(_, bd)| d > bd) {
                best = Some((i, d));
            }
        }
        let Some((i, _)) = best else { break };
        chosen.push(i);
        for (j, s) in aligned.iter().enumerate() {
            nearest[j] = nearest[j].min(dist(s, &aligned[i]));
        }
    }
    Ok(chosen)
}

/// How much of a shape set's variety a subset covers, in `[0, 1]`: one minus the ratio of the
/// largest distance from any shape to its nearest chosen shape to the largest distance from any
/// shape to the mean (after Procrustes alignment). 1 means every shape is one of the chosen
/// ones; 0 means the chosen ones are no better than the mean face.
pub fn coverage(shapes: &[&[f32]], chosen: &[usize]) -> Result<f32> {
    let aligned = aligned_shapes(shapes)?;
    if chosen.iter().any(|&i| i >= aligned.len()) || chosen.is_empty() {
        return Err(Error::Training("coverage: bad choice of shapes".into()));
    }
    let mean = crate::pca::mean(&aligned);
    let dist = |a: &[f64], b: &[f64]| -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let spread = aligned.iter().map(|s| dist(s, &mean)).fold(0.0, f64::max);
    if !(spread > 1e-12) {
        return Ok(1.0);
    }
    let worst = aligned
        .iter()
        .map(|s| {
            chosen
                .iter()
                .map(|&c| dist(s, &aligned[c]))
                .fold(f64::MAX, f64::min)
        })
        .fold(0.0, f64::max);
    Ok((1.0 - worst / spread).clamp(0.0, 1.0) as f32)
}

/// Checks the shapes and aligns them (unit-size Procrustes frame).
fn aligned_shapes(shapes: &[&[f32]]) -> Result<Vec<Vec<f64>>> {
    let Some(first) = shapes.first() else {
        return Err(Error::Training("no shapes to choose from".into()));
    };
    let len = first.len();
    if len < 6 || len % 2 != 0 {
        return Err(Error::Training(format!(
            "shapes of {} values; at least 3 interleaved points are needed",
            len
        )));
    }
    for (i, s) in shapes.iter().enumerate() {
        if s.len() != len {
            return Err(Error::Training(format!(
                "shape {i} has {} points, shape 0 has {}",
                s.len() / 2,
                len / 2
            )));
        }
        if s.iter().any(|v| !v.is_finite()) {
            return Err(Error::Training(format!("shape {i} has non-finite points")));
        }
    }
    let raw: Vec<Vec<f64>> = shapes
        .iter()
        .map(|s| s.iter().map(|&v| v as f64).collect())
        .collect();
    Ok(generalised_procrustes(&raw, None).0)
}

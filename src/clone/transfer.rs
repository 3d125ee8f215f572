//! Deformation transfer in the shared reference frame (Sumner & Popović, "Deformation transfer
//! for triangle meshes", SIGGRAPH 2004), taken to 2D landmark meshes.
//!
//! A source displacement `d` (from the source's base shape `s0`) deforms every triangle of the
//! frame's mesh by an affine map `Q_t = W_t V_t^-1` (`V_t` the triangle's edge matrix on `s0`,
//! `W_t` on `s0 + d`). The transferred displacement `u` of the target's base shape `t0` is the
//! one whose triangles deform by the same maps, in least squares weighted by the target
//! triangles' areas: the source's smile, fitted to the target's proportions. Everything here is
//! linear in `d`, so a pair precomputes one `2n x 2n` matrix ([`transfer_operator`]) and a frame
//! costs one matrix-vector product ([`transfer_displacement`]).

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// The deformation-transfer operator `L` of a source base shape onto a target base shape over
/// one mesh (Sumner & Popović 2004, Eq. 5 in 2D): `u = L d`, row-major `2n x 2n` on
/// interleaved `x, y` coordinates.
///
/// Per triangle `t = (a, b, c)`, `K_t = V_t^-1 E_t` (`V_t`, `E_t` the edge matrices
/// `[v_b - v_a, v_c - v_a]` of the source and target base), so the target's edge
/// displacements are `dV_t K_t`. `u` minimises `sum_t area_t |E_t(u) - dV_t K_t|^2 +
/// mu_i |u_i - d_i|^2`: the anchor term (`mu_i` = `ANCHOR`, or `JAW_ANCHOR` on a jaw, times the mesh term's mean diagonal) keeps
/// each vertex near the source's own displacement, which in the shared frame is already in
/// comparable units, and fixes the translation the edges do not see; without it, a target's
/// smaller mouth would shrink the smile's lift by a quarter (measured: docs/cloning.md). With
/// equal bases, `L d = d` exactly (both terms vanish). Triangles too thin in either base to have a meaningful
/// deformation gradient (a closed mouth's inner lips) are skipped; their vertices follow their
/// other triangles.
///
/// Requires `source.len() == target.len() == 2n`, every triangle index `< n` (otherwise
/// [`Error::Incompatible`]). A vertex in no usable triangle follows the anchor alone: the
/// source's own displacement.
pub fn transfer_operator(
    source: &[f32],
    target: &[f32],
    triangles: &[[u32; 3]],
) -> Result<Vec<f32>> {
    let n = source.len() / 2;
    if target.len() != source.len() || n == 0 {
        return Err(Error::Incompatible(format!(
            "deformation transfer: {} source and {} target coordinates",
            source.len(),
            target.len()
        )));
    }
    let (mut h, used) = mesh_system(source, target, triangles)?;
    let mu = add_anchor(&mut h);
    let chol = h
        .cholesky()
        .ok_or_else(|| Error::Incompatible("deformation transfer: singular mesh system".into()))?;
    Ok(operator_columns(&chol, &used, &mu))
}

/// A usable triangle of [`transfer_operator`]'s mesh term: its vertices `(a, b, c)`, its weight
/// (the target triangle's area) and `K_t = V_t^-1 E_t`.
type MeshTerm = ([usize; 3], f64, [[f64; 2]; 2]);

/// The mesh term of [`transfer_operator`]: the `n x n` normal matrix of
/// `sum_t area_t |E_t(u)|^2` (the same for either coordinate) and the usable triangles, those
/// thick enough in both bases. Fails with [`Error::Incompatible`] on a triangle index `>= n`.
fn mesh_system(
    source: &[f32],
    target: &[f32],
    triangles: &[[u32; 3]],
) -> Result<(DMatrix<f64>, Vec<MeshTerm>)> {
    let n = source.len() / 2;
    let mut h = DMatrix::<f64>::zeros(n, n);
    // Per usable triangle: its vertices, weight and K = V^-1 E.
    let mut used = Vec::with_capacity(triangles.len());
    for t in triangles {
        let [a, b, c] = t.map(|i| i as usize);
        if a >= n || b >= n || c >= n {
            return Err(Error::Incompatible(
                "deformation transfer: triangle index out of range".into(),
            ));
        }
        let (v, e) = (edge_matrix(source, t), edge_matrix(target, t));
        let (det_v, det_e) = (det(&v), det(&e));
        if sliver(&v, det_v) || sliver(&e, det_e) {
            continue;
        }
        let vi = [
            [v[1][1] / det_v, -v[0][1] / det_v],
            [-v[1][0] / det_v, v[0][0] / det_v],
        ];
        let mut k = [[0f64; 2]; 2];
        for (r, kr) in k.iter_mut().enumerate() {
            for (col, kv) in kr.iter_mut().enumerate() {
                *kv = vi[r][0] * e[0][col] + vi[r][1] * e[1][col];
            }
        }
        let w = det_e.abs() / 2.0;
        for j in [b, c] {
            h[(a, a)] += w;
            h[(j, j)] += w;
            h[(a, j)] -= w;
            h[(j, a)] -= w;
        }
        used.push(([a, b, c], w, k));
    }
    Ok((h, used))
}

/// Adds the anchor term of [`transfer_operator`] to the mesh term's normal matrix `h` and
/// returns its weights `mu_i`: [`ANCHOR`], or [`JAW_ANCHOR`] on a jaw, times `h`'s mean
/// diagonal.
fn add_anchor(h: &mut DMatrix<f64>) -> Vec<f64> {
    let n = h.nrows();
    let scale = h.trace() / n as f64;
    // 68 points: the jaw's outline (0-16) follows the target's proportions more freely.
    let mu: Vec<f64> = (0..n)
        .map(|i| {
            scale
                * if n == 68 && i <= 16 {
                    JAW_ANCHOR
                } else {
                    ANCHOR
                }
        })
        .collect();
    for (i, m) in mu.iter().enumerate() {
        h[(i, i)] += m;
    }
    mu
}

/// The operator `L` of [`transfer_operator`] (row-major `2n x 2n`), column by column: column
/// `k` is the solution (through `chol`, the factored system) for a unit displacement of
/// coordinate `k`.
fn operator_columns(
    chol: &nalgebra::Cholesky<f64, nalgebra::Dyn>,
    used: &[MeshTerm],
    mu: &[f64],
) -> Vec<f32> {
    let n = mu.len();
    // Column k of L: the response to a unit displacement of coordinate k.
    let mut l = vec![0f32; 4 * n * n];
    let mut rhs = [DVector::<f64>::zeros(n), DVector::<f64>::zeros(n)];
    for k in 0..2 * n {
        let (vk, ck) = (k / 2, k % 2);
        rhs.iter_mut().for_each(|r| r.fill(0.0));
        // The anchor: each vertex pulled towards the source's own displacement.
        rhs[ck][vk] += mu[vk];
        for &([a, b, c], w, kt) in used {
            // dV = [d_b - d_a, d_c - d_a] restricted to coordinate ck of vertex vk.
            let de = [
                (vk == b) as i32 as f64 - (vk == a) as i32 as f64,
                (vk == c) as i32 as f64 - (vk == a) as i32 as f64,
            ];
            if de == [0.0, 0.0] {
                continue;
            }
            // Target edge displacement j (coordinate ck): sum_r dV[ck][r] K[r][j].
            for (j, tj) in [b, c].into_iter().enumerate() {
                let f = de[0] * kt[0][j] + de[1] * kt[1][j];
                rhs[ck][tj] += w * f;
                rhs[ck][a] -= w * f;
            }
        }
        for (cc, r) in rhs.iter().enumerate() {
            if r.iter().all(|v| *v == 0.0) {
                continue;
            }
            let u = chol.solve(r);
            for i in 0..n {
                l[(2 * i + cc) * 2 * n + k] = u[i] as f32;
            }
        }
    }
    l
}

/// The weight of the anchor term of [`transfer_operator`], relative to the mesh term's mean
/// diagonal (chosen on franck-dev's and franck-dev2's frames against GRID targets, with
/// [`JAW_ANCHOR`]: 0.1 to 1 tried; less lets a smaller mouth shrink the lips' lift, more keeps
/// the jaw's drop from following the target's face).
pub const ANCHOR: f64 = 0.8;

/// The anchor's weight on a 68-point jaw outline (points 0-16), whose motion is the mandible's
/// turn and so scales with the target's face (the lips' and brows' motions keep the source's).
pub const JAW_ANCHOR: f64 = 0.1;

/// The edge matrix `[v_b - v_a, v_c - v_a]` (columns) of triangle `t = (a, b, c)` on shape `s`.
fn edge_matrix(s: &[f32], t: &[u32; 3]) -> [[f64; 2]; 2] {
    let [a, b, c] = t.map(|i| [s[2 * i as usize] as f64, s[2 * i as usize + 1] as f64]);
    [[b[0] - a[0], c[0] - a[0]], [b[1] - a[1], c[1] - a[1]]]
}

fn det(m: &[[f64; 2]; 2]) -> f64 {
    m[0][0] * m[1][1] - m[0][1] * m[1][0]
}

/// True when triangle `t` of shape `s` is a [`sliver`].
pub(crate) fn is_sliver(s: &[f32], t: &[u32; 3]) -> bool {
    let m = edge_matrix(s, t);
    sliver(&m, det(&m))
}

/// True when a triangle (edge matrix `m`, determinant `det`) is too thin for its deformation
/// gradient to mean anything: its area under a tenth of its longest edge squared (its smallest
/// height under a fifth of that edge, so `V^-1` magnifies at most about five times; a closed
/// mouth's inner-lip triangles, for one, and their neighbours). An equilateral triangle has
/// 0.43.
fn sliver(m: &[[f64; 2]; 2], det: f64) -> bool {
    let e1 = m[0][0] * m[0][0] + m[1][0] * m[1][0];
    let e2 = m[0][1] * m[0][1] + m[1][1] * m[1][1];
    let e3 = (m[0][1] - m[0][0]).powi(2) + (m[1][1] - m[1][0]).powi(2);
    let longest = e1.max(e2).max(e3);
    !(det.abs() * 0.5 >= 0.1 * longest) || longest == 0.0
}

/// `u = L d` (Sumner & Popović 2004): the source displacement `d` (`2n`) transferred onto the
/// target's proportions into `u` (`2n`), with `L` from [`transfer_operator`]. Allocates
/// nothing.
pub fn transfer_displacement(l: &[f32], d: &[f32], u: &mut [f32]) {
    let m = d.len();
    for (o, row) in u.iter_mut().zip(l.chunks_exact(m.max(1))) {
        *o = row.iter().zip(d).map(|(a, b)| a * b).sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> (Vec<f32>, Vec<[u32; 3]>) {
        let mut pts = Vec::new();
        for y in 0..3 {
            for x in 0..3 {
                pts.extend([x as f32 * 10.0, y as f32 * 10.0]);
            }
        }
        let tris = crate::model::frame::triangulate(&pts).unwrap();
        (pts, tris)
    }

    #[test]
    fn equal_bases_transfer_the_displacement_itself() {
        let (pts, tris) = grid();
        let l = transfer_operator(&pts, &pts, &tris).unwrap();
        let d: Vec<f32> = (0..pts.len())
            .map(|i| ((i * 7) % 5) as f32 * 0.3 - 0.6)
            .collect();
        let mut u = vec![0.0; d.len()];
        transfer_displacement(&l, &d, &mut u);
        for (a, b) in u.iter().zip(&d) {
            assert!((a - b).abs() < 1e-3, "{a} vs {b}");
        }
    }

    #[test]
    fn a_wider_target_moves_further_sideways() {
        let (pts, tris) = grid();
        let wide: Vec<f32> = pts.chunks(2).flat_map(|p| [p[0] * 2.0, p[1]]).collect();
        let l = transfer_operator(&pts, &wide, &tris).unwrap();
        // Stretch the source horizontally by 10% about its centre.
        let d: Vec<f32> = pts
            .chunks(2)
            .flat_map(|p| [(p[0] - 10.0) * 0.1, 0.0])
            .collect();
        let mut u = vec![0.0; d.len()];
        transfer_displacement(&l, &d, &mut u);
        // The right column moves further than the source's (the target is wider), but less
        // than a pure transfer's 10% of ITS half-width (the anchor holds it back); no vertical
        // motion; the centre column about stays
        for (p, q) in u.chunks(2).zip(d.chunks(2)) {
            assert!(p[1].abs() < 1e-4);
            if q[0] > 0.0 {
                assert!(
                    p[0] > q[0] * 1.05 && p[0] < q[0] * 2.0,
                    "{} vs {}",
                    p[0],
                    q[0]
                );
            }
        }
        // (up to the grid's arbitrary Delaunay diagonals, which make the mesh asymmetric).
        assert!(
            u[2].abs() < 0.3 && u[8].abs() < 0.3 && u[14].abs() < 0.3,
            "{u:?}"
        );
    }
}

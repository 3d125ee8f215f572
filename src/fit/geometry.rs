//! Mesh geometry for warp composition: the base mesh, its triangles' inverse edge matrices and
//! the vertex-to-triangle incidence, plus the projection of an image shape onto the model.

use crate::model::Model;
use crate::similarity::Similarity;

use super::precompute::frame_to_base_gradient;

/// Per-model geometry used by the warp composition (Matthews & Baker 2004, section 4.1.1).
pub(crate) struct Geometry {
    /// Base shape `s0` (model coordinates).
    pub s0: Vec<f32>,
    /// Shape modes of the model (row-major `m x 2n`).
    pub modes: Vec<f32>,
    /// Triangles (vertex indices).
    pub tris: Vec<[u32; 3]>,
    /// Per triangle: the inverse of the base edge matrix `[b - a, c - a]` (row-major 2x2).
    pub base_inv: Vec<[f32; 4]>,
    /// CSR incidence: triangles containing vertex `v` are
    /// `inc[inc_start[v]..inc_start[v + 1]]`.
    pub inc_start: Vec<u32>,
    /// Incidence list.
    pub inc: Vec<u32>,
    /// Per triangle: whether the composition may map vertices through it, i.e. the base shape
    /// keeps the reference frame's triangle in shape (not folded over, not flattened; see
    /// `frame_to_base_gradient`). The barycentric coordinates of a point in a nearly flat
    /// triangle explode, so one such sliver would throw its vertices off.
    pub usable: Vec<bool>,
}

impl Geometry {
    pub(crate) fn new(model: &Model) -> Geometry {
        let s0 = model.shape().base.clone();
        let tris = model.frame().triangles().to_vec();
        let usable = frame_to_base_gradient(model.frame().vertices(), &s0, &tris)
            .iter()
            .map(Option::is_some)
            .collect();
        let n = s0.len() / 2;
        let p = |i: u32| (s0[2 * i as usize], s0[2 * i as usize + 1]);
        let base_inv = tris
            .iter()
            .map(|t| {
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                let (e1x, e1y, e2x, e2y) = (b.0 - a.0, b.1 - a.1, c.0 - a.0, c.1 - a.1);
                let det = e1x * e2y - e2x * e1y;
                if det.abs() < 1e-12 {
                    [0.0; 4]
                } else {
                    [e2y / det, -e2x / det, -e1y / det, e1x / det]
                }
            })
            .collect();
        let mut counts = vec![0u32; n + 1];
        for t in &tris {
            for &v in t {
                counts[v as usize + 1] += 1;
            }
        }
        for v in 0..n {
            counts[v + 1] += counts[v];
        }
        let mut fill = counts.clone();
        let mut inc = vec![0u32; counts[n] as usize];
        for (ti, t) in tris.iter().enumerate() {
            for &v in t {
                inc[fill[v as usize] as usize] = ti as u32;
                fill[v as usize] += 1;
            }
        }
        Geometry {
            s0,
            modes: model.shape().modes.clone(),
            tris,
            base_inv,
            inc_start: counts,
            inc,
            usable,
        }
    }

    /// Number of landmarks.
    pub(crate) fn n(&self) -> usize {
        self.s0.len() / 2
    }

    /// Composes the current warp (base mesh -> `current`, image coordinates) with the inverse
    /// of the incremental warp whose base-mesh displacement is `delta` (model coordinates):
    /// each vertex of `s0 - delta` is mapped through the affine maps of the triangles that
    /// contain it (base triangle -> current triangle) and the results averaged; triangles the
    /// base shape folds or flattens are left out (see [`Geometry::usable`]). Writes `out`.
    ///
    /// A vertex in no usable triangle moves by `delta` mapped through `pose` (the current warp's
    /// similarity part).
    pub(crate) fn compose_inverse(
        &self,
        current: &[f32],
        delta: &[f32],
        pose: &Similarity,
        out: &mut [f32],
    ) {
        let n = self.n();
        for v in 0..n {
            let ux = self.s0[2 * v] - delta[2 * v];
            let uy = self.s0[2 * v + 1] - delta[2 * v + 1];
            let (s, e) = (self.inc_start[v] as usize, self.inc_start[v + 1] as usize);
            let (mut sx, mut sy, mut used) = (0f32, 0f32, 0u32);
            for &ti in &self.inc[s..e] {
                if !self.usable[ti as usize] {
                    continue;
                }
                used += 1;
                let t = self.tris[ti as usize];
                let m = self.base_inv[ti as usize];
                let (a0, a1) = (t[0] as usize, t[1] as usize);
                let a2 = t[2] as usize;
                // Barycentric (beta, gamma) of u in the base triangle.
                let (dx, dy) = (ux - self.s0[2 * a0], uy - self.s0[2 * a0 + 1]);
                let beta = m[0] * dx + m[1] * dy;
                let gamma = m[2] * dx + m[3] * dy;
                let (cx, cy) = (current[2 * a0], current[2 * a0 + 1]);
                sx += cx + beta * (current[2 * a1] - cx) + gamma * (current[2 * a2] - cx);
                sy += cy + beta * (current[2 * a1 + 1] - cy) + gamma * (current[2 * a2 + 1] - cy);
            }
            if used == 0 {
                // In no usable triangle: move by the increment through the pose's linear part.
                let (dx, dy) = (delta[2 * v], delta[2 * v + 1]);
                out[2 * v] = current[2 * v] - (pose.a * dx - pose.b * dy);
                out[2 * v + 1] = current[2 * v + 1] - (pose.b * dx + pose.a * dy);
                continue;
            }
            let k = 1.0 / used as f32;
            out[2 * v] = sx * k;
            out[2 * v + 1] = sy * k;
        }
    }

    /// Projects an image shape onto the model: the least-squares similarity from `s0` (the
    /// pose), then `p = S^T (pose^-1(shape) - s0)`; writes the model's instance
    /// `pose(s0 + S p)` into `out`. `scratch` has `2n` values. Returns `None` for a degenerate
    /// (zero-scale or non-finite) shape.
    pub(crate) fn project(
        &self,
        shape: &[f32],
        p: &mut [f32],
        scratch: &mut [f32],
        out: &mut [f32],
    ) -> Option<Similarity> {
        if shape.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let pose = Similarity::align(&self.s0, shape);
        let inv = pose.inverse()?;
        inv.apply(shape, scratch);
        let d = self.s0.len();
        for (pi, mode) in p.iter_mut().zip(self.modes.chunks_exact(d)) {
            *pi = mode
                .iter()
                .zip(scratch.iter().zip(&self.s0))
                .map(|(m, (s, b))| m * (s - b))
                .sum();
        }
        self.instance(&pose, p, out);
        if out.iter().all(|v| v.is_finite()) {
            Some(pose)
        } else {
            None
        }
    }

    /// `pose(s0 + S p)` into `out`.
    pub(crate) fn instance(&self, pose: &Similarity, p: &[f32], out: &mut [f32]) {
        let d = self.s0.len();
        out.copy_from_slice(&self.s0);
        for (pi, mode) in p.iter().zip(self.modes.chunks_exact(d)) {
            out.iter_mut().zip(mode).for_each(|(o, m)| *o += pi * m);
        }
        pose.apply_in_place(out);
    }
}

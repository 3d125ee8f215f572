//! Everything the fitter computes once per model: the combined similarity + shape basis, the
//! grey-level appearance model on each level's pixels, template gradients, warp Jacobians,
//! project-out steepest-descent images and their Hessians.

use crate::error::{Error, Result};
use crate::model::Model;

use super::linalg::cholesky;
use crate::pca::gram_schmidt;

use crate::image::LUMA;

/// Red-difference chroma weights (Rec. 601 `Cr`): separates lips and skin, which luminance
/// barely does.
pub(crate) const CHROMA: [f32; 3] = [0.5, -0.4187, -0.0813];

/// The channel weights used for `channels` fitting channels (1: luminance; 2: luminance and
/// red chroma).
pub(crate) fn channel_weights(channels: usize) -> &'static [[f32; 3]] {
    const BOTH: [[f32; 3]; 2] = [LUMA, CHROMA];
    &BOTH[..channels.clamp(1, 2)]
}

/// The combined basis of mesh displacements in model coordinates (Matthews & Baker 2004,
/// section 4.3): the four similarity vectors `s*_1..s*_4` (scale/rotation about the base shape,
/// x and y translation), orthonormalised, followed by the model's shape modes
/// Gram-Schmidt-orthogonalised against them and each other.
pub(crate) struct ShapeBasis {
    /// Number of parameters `k` (4 + kept shape modes).
    pub k: usize,
    /// Basis vectors, row-major `k x 2n`.
    pub vectors: Vec<f32>,
    /// For parameter `j`, the model's shape mode it comes from (`None` for the similarity).
    pub mode_of: Vec<Option<usize>>,
}

impl ShapeBasis {
    pub(crate) fn new(model: &Model) -> Result<ShapeBasis> {
        let s0 = &model.shape().base;
        let d = s0.len();
        let mut cands: Vec<Vec<f64>> = Vec::new();
        cands.push(s0.iter().map(|&v| v as f64).collect());
        cands.push(
            s0.chunks_exact(2)
                .flat_map(|p| [-(p[1] as f64), p[0] as f64])
                .collect(),
        );
        cands.push((0..d).map(|i| if i % 2 == 0 { 1.0 } else { 0.0 }).collect());
        cands.push((0..d).map(|i| if i % 2 == 1 { 1.0 } else { 0.0 }).collect());
        for i in 0..model.shape().n_modes() {
            cands.push(
                model
                    .shape()
                    .mode(i)
                    .unwrap_or(&[])
                    .iter()
                    .map(|&v| v as f64)
                    .collect(),
            );
        }
        let mut comps: Vec<Vec<Vec<f64>>> = vec![Vec::new(); cands.len()];
        let kept = gram_schmidt(&mut cands, &mut comps, 1e-4);
        if kept.len() < 4 || kept[..4] != [0, 1, 2, 3] {
            return Err(Error::Params(
                "the model's base shape is degenerate: no similarity basis can be built".into(),
            ));
        }
        let mode_of = kept
            .iter()
            .map(|&i| if i < 4 { None } else { Some(i - 4) })
            .collect();
        Ok(ShapeBasis {
            k: cands.len(),
            vectors: cands.iter().flatten().map(|&v| v as f32).collect(),
            mode_of,
        })
    }
}

/// One resolution level: a subset of the frame pixels (every `step`-th column and row) with
/// everything the inverse compositional iterations need there.
pub(crate) struct Level {
    /// Gaussian smoothing of the template (and of the image, scaled by the pose), frame px.
    pub sigma: f32,
    /// Number of values `N` on this level: `channels x pixels`, channel-major.
    pub n: usize,
    /// Number of pixels per channel.
    pub np: usize,
    /// Mesh vertices of each pixel's triangle.
    pub verts: Vec<[u32; 3]>,
    /// Barycentric coordinates of each pixel.
    pub bary: Vec<[f32; 3]>,
    /// Grey base appearance `A0` on the level pixels.
    pub a0: Vec<f32>,
    /// Standard deviation of `a0`.
    pub a0_std: f32,
    /// Number of grey appearance basis images (including gain and bias when enabled).
    pub la: usize,
    /// Orthonormal grey appearance basis, row-major `la x N`.
    pub app: Vec<f32>,
    /// Gradient of `A0` (x, y), per pixel.
    pub a0_gx: Vec<f32>,
    /// Gradient of `A0` along y.
    pub a0_gy: Vec<f32>,
    /// Gradients of the appearance basis images, row-major `la x N`.
    pub app_gx: Vec<f32>,
    /// Gradients along y.
    pub app_gy: Vec<f32>,
    /// Warp Jacobian `dW/dc_j` (x part), row-major `k x N`.
    pub jx: Vec<f32>,
    /// Warp Jacobian (y part).
    pub jy: Vec<f32>,
    /// Project-out steepest-descent images, row-major `k x N`.
    pub sd_po: Vec<f32>,
    /// Project-out Gauss-Newton Hessian `SD^T SD` (`k x k`, f64), without the prior.
    pub h_po: Vec<f64>,
    /// Prior weights per parameter (0 for the similarity).
    pub prior: Vec<f64>,
}

/// Fills a full-resolution frame grid with per-pixel values (plus the frame's padding ring),
/// NaN elsewhere.
fn fill_grid(model: &Model, values: &[f64], grid: &mut [f64]) {
    let f = &model.frame();
    let w = f.width() as usize;
    grid.iter_mut().for_each(|g| *g = f64::NAN);
    for (px, v) in f.pixels().iter().zip(values) {
        grid[px.y as usize * w + px.x as usize] = *v;
    }
    for &(k, src) in f.padding() {
        grid[k as usize] = values[src as usize];
    }
}

/// Gaussian blur of a grid in place, ignoring (and keeping) NaN cells: normalised
/// convolution, so values near the mesh border are averages of defined neighbours only.
fn blur_grid(grid: &mut [f64], w: usize, h: usize, sigma: f64) {
    let mut k32 = [0f32; 49];
    let r = crate::filter::gaussian_kernel(sigma as f32, 3.0, 24, &mut k32) as isize;
    let kernel: Vec<f64> = k32[..=2 * r as usize].iter().map(|&k| k as f64).collect();
    let mut tmp = vec![f64::NAN; w * h];
    for pass in 0..2 {
        let (src, dst): (&[f64], &mut [f64]) = if pass == 0 {
            (&*grid, &mut tmp)
        } else {
            (&tmp, &mut *grid)
        };
        let mut out = vec![f64::NAN; w * h];
        for y in 0..h as isize {
            for x in 0..w as isize {
                if !src[y as usize * w + x as usize].is_finite() {
                    continue;
                }
                let (mut acc, mut wsum) = (0.0, 0.0);
                for (ki, kv) in kernel.iter().enumerate() {
                    let o = ki as isize - r;
                    let (xx, yy) = if pass == 0 { (x + o, y) } else { (x, y + o) };
                    if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
                        continue;
                    }
                    let v = src[yy as usize * w + xx as usize];
                    if v.is_finite() {
                        acc += kv * v;
                        wsum += kv;
                    }
                }
                out[y as usize * w + x as usize] = acc / wsum;
            }
        }
        dst.copy_from_slice(&out);
    }
}

/// Central-difference gradient of a grid at `(x, y)`, one-sided where a neighbour is missing.
fn grid_gradient(grid: &[f64], w: usize, h: usize, x: usize, y: usize) -> (f64, f64) {
    let at = |xx: isize, yy: isize| -> f64 {
        if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
            f64::NAN
        } else {
            grid[yy as usize * w + xx as usize]
        }
    };
    let (xi, yi) = (x as isize, y as isize);
    let c = at(xi, yi);
    let diff = |m: f64, p: f64| -> f64 {
        match (m.is_finite(), p.is_finite()) {
            (true, true) => 0.5 * (p - m),
            (true, false) => c - m,
            (false, true) => p - c,
            _ => 0.0,
        }
    };
    (
        diff(at(xi - 1, yi), at(xi + 1, yi)),
        diff(at(xi, yi - 1), at(xi, yi + 1)),
    )
}

/// The frame pixels a level fits: every `step`-th pixel in x and y whose triangle the base
/// shape keeps in shape, with its triangle's vertices, its barycentric coordinates and the
/// matrix turning a frame-grid gradient into one in the base shape's coordinates.
struct LevelPixels {
    /// Indices into the frame's pixels.
    sel: Vec<usize>,
    verts: Vec<[u32; 3]>,
    bary: Vec<[f32; 3]>,
    grad_map: Vec<[f64; 4]>,
}

impl LevelPixels {
    /// Selects the pixels of a level with `nc` channels for `k` parameters; an error when they
    /// are too few, or when the base shape folds most of the frame's mesh.
    fn select(model: &Model, step: u32, nc: usize, k: usize) -> Result<LevelPixels> {
        let f = &model.frame();
        let npx = f.n_pixels();
        let tris = f.triangles();
        // Template gradients are taken on the frame's pixel grid, but the warp is
        // parameterised on the base shape `s0`: per triangle, the matrix turning a frame-grid
        // gradient into one in `s0`'s coordinates, or none where `s0` folds or squashes the
        // frame's triangle (those pixels are left out of the fit; see `frame_to_base_gradient`).
        let to_base = frame_to_base_gradient(f.vertices(), &model.shape().base, tris);
        let in_fit = |i: usize| to_base[f.pixels()[i].triangle as usize].is_some();
        let sel: Vec<usize> = f
            .pixels()
            .iter()
            .enumerate()
            .filter(|(i, p)| p.x as u32 % step == 0 && p.y as u32 % step == 0 && in_fit(*i))
            .map(|(i, _)| i)
            .collect();
        let np = sel.len();
        if np < k * 4 {
            return Err(Error::Params(format!(
                "fitting level with step {step} has only {} pixels for {k} parameters",
                np * nc
            )));
        }
        let kept = (0..npx).filter(|&i| in_fit(i)).count();
        if 2 * kept < npx {
            return Err(Error::Params(format!(
                "the model's base shape folds its reference frame's mesh: only {kept} of {npx} \
                 frame pixels lie in triangles it keeps in shape"
            )));
        }
        let pixel = |i: usize| f.pixels()[i];
        Ok(LevelPixels {
            verts: sel
                .iter()
                .map(|&i| tris[pixel(i).triangle as usize])
                .collect(),
            bary: sel.iter().map(|&i| pixel(i).bary).collect(),
            grad_map: sel
                .iter()
                .map(|&i| to_base[pixel(i).triangle as usize].unwrap_or([1.0, 0.0, 0.0, 1.0]))
                .collect(),
            sel,
        })
    }
}

/// The grey template of a level: `A0` and the orthonormalised appearance basis (gain and bias
/// images first when `gain_bias`, then each mode) sampled at the level's pixels after a
/// Gaussian of `sigma` frame pixels, with their gradients in the base shape's coordinates.
struct Template {
    a0: Vec<f64>,
    a0_gx: Vec<f64>,
    a0_gy: Vec<f64>,
    /// The basis images, and per image its x and y gradients.
    vecs: Vec<Vec<f64>>,
    comps: Vec<Vec<Vec<f64>>>,
}

impl Template {
    fn new(
        model: &Model,
        pixels: &LevelPixels,
        weights: &[[f32; 3]],
        sigma: f32,
        gain_bias: bool,
    ) -> Template {
        let nc = weights.len();
        let f = &model.frame();
        let (w, h) = (f.width() as usize, f.height() as usize);
        let npx = f.n_pixels();
        let n = pixels.sel.len() * nc;
        // Channel images on the full frame (channel-major): A0 and each RGB mode.
        let app = &model.appearance();
        let grey = |v: &[f32]| -> Vec<f64> {
            let mut out = Vec::with_capacity(npx * nc);
            for wc in weights {
                out.extend(
                    v.chunks_exact(3)
                        .map(|c| (wc[0] * c[0] + wc[1] * c[1] + wc[2] * c[2]) as f64),
                );
            }
            out
        };
        let a0_full = grey(app.base());
        let mut raw: Vec<Vec<f64>> = Vec::new();
        if gain_bias {
            for c in 0..nc {
                let mut b = vec![0.0; npx * nc];
                b[c * npx..(c + 1) * npx].iter_mut().for_each(|v| *v = 1.0);
                raw.push(b);
            }
            raw.push(a0_full.clone());
        }
        for i in 0..app.n_modes() {
            raw.push(grey(app.mode(i).unwrap_or(&[])));
        }
        // Values and gradients at the level pixels.
        let mut grid = vec![0f64; w * h];
        let mut sample = |full: &[f64]| -> (Vec<f64>, Vec<f64>, Vec<f64>) {
            let mut v = Vec::with_capacity(n);
            let mut gx = Vec::with_capacity(n);
            let mut gy = Vec::with_capacity(n);
            for c in 0..nc {
                fill_grid(model, &full[c * npx..(c + 1) * npx], &mut grid);
                if sigma > 0.0 {
                    blur_grid(&mut grid, w, h, sigma as f64);
                }
                for (&i, m) in pixels.sel.iter().zip(&pixels.grad_map) {
                    let p = f.pixels()[i];
                    v.push(grid[p.y as usize * w + p.x as usize]);
                    let (a, b) = grid_gradient(&grid, w, h, p.x as usize, p.y as usize);
                    gx.push(m[0] * a + m[1] * b);
                    gy.push(m[2] * a + m[3] * b);
                }
            }
            (v, gx, gy)
        };
        let (a0, a0_gx, a0_gy) = sample(&a0_full);
        let mut vecs = Vec::new();
        let mut comps = Vec::new();
        for r in &raw {
            let (v, gx, gy) = sample(r);
            vecs.push(v);
            comps.push(vec![gx, gy]);
        }
        gram_schmidt(&mut vecs, &mut comps, 1e-3);
        Template {
            a0,
            a0_gx,
            a0_gy,
            vecs,
            comps,
        }
    }
}

/// The warp Jacobians `dW/dc_j` (x and y parts, row-major `k x n`) at each of the `n` values
/// of a level whose `np` pixels have triangles `verts` and barycentric coordinates `bary`.
fn warp_jacobians(basis: &ShapeBasis, d: usize, pixels: &LevelPixels, n: usize) -> [Vec<f32>; 2] {
    let (k, np) = (basis.k, pixels.sel.len());
    let mut jx = vec![0f32; k * n];
    let mut jy = vec![0f32; k * n];
    for j in 0..k {
        let b = &basis.vectors[j * d..(j + 1) * d];
        for i in 0..n {
            let (t, w3) = (pixels.verts[i % np], pixels.bary[i % np]);
            let (mut x, mut y) = (0f32, 0f32);
            for c in 0..3 {
                x += w3[c] * b[2 * t[c] as usize];
                y += w3[c] * b[2 * t[c] as usize + 1];
            }
            jx[j * n + i] = x;
            jy[j * n + i] = y;
        }
    }
    [jx, jy]
}

/// The project-out steepest-descent images (f64 for the projection: the template gradient
/// along each Jacobian, the appearance basis projected out) and their Hessian `SD^T SD`.
fn project_out(
    template: &Template,
    [jx, jy]: &[Vec<f32>; 2],
    k: usize,
    n: usize,
) -> (Vec<Vec<f64>>, Vec<f64>) {
    let (gx, gy) = (&template.a0_gx, &template.a0_gy);
    let mut sd: Vec<Vec<f64>> = (0..k)
        .map(|j| {
            (0..n)
                .map(|i| gx[i] * jx[j * n + i] as f64 + gy[i] * jy[j * n + i] as f64)
                .collect()
        })
        .collect();
    for s in &mut sd {
        for _ in 0..2 {
            for u in &template.vecs {
                let dd: f64 = s.iter().zip(u).map(|(a, b)| a * b).sum();
                s.iter_mut().zip(u).for_each(|(a, b)| *a -= dd * b);
            }
        }
    }
    let mut h_po = vec![0f64; k * k];
    for a in 0..k {
        for b in 0..=a {
            let v: f64 = sd[a].iter().zip(&sd[b]).map(|(x, y)| x * y).sum();
            h_po[a * k + b] = v;
            h_po[b * k + a] = v;
        }
    }
    (sd, h_po)
}

impl Level {
    /// Precomputes a level. `smooth` is the number of 3x3 box-blur passes applied to the
    /// template images before taking gradients (coarse levels see a smoother template).
    pub(crate) fn new(
        model: &Model,
        basis: &ShapeBasis,
        step: u32,
        sigma: f32,
        gain_bias: bool,
        shape_prior: f32,
        channels: usize,
    ) -> Result<Level> {
        let weights = channel_weights(channels);
        let nc = weights.len();
        let npx = model.frame().n_pixels();
        let step = step.max(1);
        let pixels = LevelPixels::select(model, step, nc, basis.k)?;
        let np = pixels.sel.len();
        let n = np * nc;
        let template = Template::new(model, &pixels, weights, sigma, gain_bias);
        let to32 = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let k = basis.k;
        let jacobians = warp_jacobians(basis, model.shape().base.len(), &pixels, n);
        let (sd, h_po) = project_out(&template, &jacobians, k, n);
        let [jx, jy] = jacobians;
        // Shape prior: w_j = rho * (N_level / N_frame) / sigma_j^2 on the shape parameters.
        let frac = n as f64 / npx as f64;
        let prior: Vec<f64> = basis
            .mode_of
            .iter()
            .map(|m| match m {
                Some(i) => {
                    let var = model.shape().variances[*i].max(1e-12) as f64;
                    shape_prior.max(0.0) as f64 * frac * npx as f64 / var
                }
                None => 0.0,
            })
            .collect();
        let mut h_po_chol = h_po.clone();
        regularise(&mut h_po_chol, &prior, k);
        if !cholesky(&mut h_po_chol, k) {
            return Err(Error::Params(format!(
                "the fitting Hessian of level {step} is singular (is the appearance flat?)"
            )));
        }
        let a0 = &template.a0;
        let a0_std = {
            let m = a0.iter().sum::<f64>() / n as f64;
            (a0.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n as f64).sqrt() as f32
        };
        Ok(Level {
            np,
            a0_std,
            sigma,
            n,
            verts: pixels.verts,
            bary: pixels.bary,
            a0: to32(a0),
            la: template.vecs.len(),
            app: template.vecs.iter().flat_map(|v| to32(v)).collect(),
            a0_gx: to32(&template.a0_gx),
            a0_gy: to32(&template.a0_gy),
            app_gx: template.comps.iter().flat_map(|c| to32(&c[0])).collect(),
            app_gy: template.comps.iter().flat_map(|c| to32(&c[1])).collect(),
            jx,
            jy,
            sd_po: sd.iter().flat_map(|s| to32(s)).collect(),
            h_po,
            prior,
        })
    }
}

/// Largest distortion of a frame triangle by the base shape (ratio of the singular values of
/// the affine map between them) for which its pixels are fitted.
pub(crate) const MAX_TRIANGLE_DISTORTION: f64 = 4.0;

/// Per triangle, the matrix `M` (row-major 2x2) that turns a template gradient taken on the
/// frame's grid into the gradient with respect to the base shape's coordinates,
/// `grad_s0 T = M grad_frame T`, or `None` where the base shape folds the triangle over or
/// distorts it by more than [`MAX_TRIANGLE_DISTORTION`].
///
/// The fitter's warp is parameterised on the base shape `s0` (the mesh the similarity and shape
/// modes move; `W(x; 0)` maps a frame pixel to its place on `s0`), while the appearance images
/// live on the frame's mesh. In a model built in its own frame the two meshes are one (up to a
/// translation) and `M` is the identity. In the canonical frame, or another model's, they
/// differ by another face's proportions, and the inverse compositional steepest-descent images
/// `grad T . dW/dp` (Matthews & Baker 2004, Eq. 31) need the template's gradient in `s0`'s
/// coordinates: with `L` the linear part of the affine map from the frame triangle to the `s0`
/// triangle, `grad_s0 T = L^-T grad_frame T`. The frame's Delaunay mesh, made for another face,
/// can have slivers along the jaw and brows that this face's `s0` folds over or flattens
/// (`L` singular or reflecting): their gradients mean nothing in `s0`, so their pixels are not
/// fitted.
pub(crate) fn frame_to_base_gradient(
    frame_vertices: &[f32],
    base: &[f32],
    tris: &[[u32; 3]],
) -> Vec<Option<[f64; 4]>> {
    let edges = |v: &[f32], t: &[u32; 3]| -> [f64; 4] {
        let p = |i: u32| (v[2 * i as usize] as f64, v[2 * i as usize + 1] as f64);
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        // Columns b - a and c - a.
        [b.0 - a.0, c.0 - a.0, b.1 - a.1, c.1 - a.1]
    };
    tris.iter()
        .map(|t| {
            let f = edges(frame_vertices, t);
            let s = edges(base, t);
            let det_s = s[0] * s[3] - s[1] * s[2];
            let det_f = f[0] * f[3] - f[1] * f[2];
            // A folded (or flat) triangle: the signs differ (or one is zero).
            if !(det_s * det_f > 0.0) {
                return None;
            }
            // L^-1 = F S^-1, so M = L^-T = (F S^-1)^T.
            let s_inv = [s[3] / det_s, -s[1] / det_s, -s[2] / det_s, s[0] / det_s];
            let fs = [
                f[0] * s_inv[0] + f[1] * s_inv[2],
                f[0] * s_inv[1] + f[1] * s_inv[3],
                f[2] * s_inv[0] + f[3] * s_inv[2],
                f[2] * s_inv[1] + f[3] * s_inv[3],
            ];
            let m = [fs[0], fs[2], fs[1], fs[3]];
            // Singular values of M: sqrt of the eigenvalues of M^T M.
            let fro2 = m.iter().map(|v| v * v).sum::<f64>();
            let det = (m[0] * m[3] - m[1] * m[2]).abs();
            let disc = (fro2 * fro2 - 4.0 * det * det).max(0.0).sqrt();
            let (hi, lo) = (
                (0.5 * (fro2 + disc)).sqrt(),
                (0.5 * (fro2 - disc)).max(0.0).sqrt(),
            );
            if !(hi.is_finite() && hi <= MAX_TRIANGLE_DISTORTION * lo) {
                return None;
            }
            Some(m)
        })
        .collect()
}

/// Adds the prior diagonal plus a tiny ridge (relative to the trace) to a `k x k` matrix.
pub(crate) fn regularise(h: &mut [f64], prior: &[f64], k: usize) {
    let trace: f64 = (0..k).map(|i| h[i * k + i]).sum::<f64>().abs();
    let ridge = 1e-9 * trace / k as f64 + 1e-12;
    for i in 0..k {
        h[i * k + i] += prior[i] + ridge;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [f32; 6] = [0.0, 0.0, 10.0, 0.0, 0.0, 10.0];

    #[test]
    fn gradient_map_is_the_identity_on_the_same_mesh() {
        let shifted: Vec<f32> = TRI.iter().map(|v| v + 3.0).collect();
        let m = frame_to_base_gradient(&TRI, &shifted, &[[0, 1, 2]])[0].unwrap();
        for (a, b) in m.iter().zip([1.0, 0.0, 0.0, 1.0]) {
            assert!((a - b).abs() < 1e-12, "{m:?}");
        }
    }

    #[test]
    fn gradient_map_is_the_inverse_transpose() {
        // s0 = L frame with L = [[2, 1], [0, 1]]: a frame gradient g becomes L^-T g.
        let base = [0.0, 0.0, 20.0, 0.0, 10.0, 10.0];
        let m = frame_to_base_gradient(&TRI, &base, &[[0, 1, 2]])[0].unwrap();
        // L^-1 = [[0.5, -0.5], [0, 1]], so L^-T = [[0.5, 0], [-0.5, 1]].
        for (a, b) in m.iter().zip([0.5, 0.0, -0.5, 1.0]) {
            assert!((a - b).abs() < 1e-12, "{m:?}");
        }
        // A template T(x) = x_frame: along s0, T(y) = (L^-1 y)_x = 0.5 y_x - 0.5 y_y.
        let g = [1.0, 0.0];
        let gs = [m[0] * g[0] + m[1] * g[1], m[2] * g[0] + m[3] * g[1]];
        assert_eq!(gs, [0.5, -0.5]);
    }

    #[test]
    fn folded_and_flattened_triangles_are_left_out() {
        let folded = [0.0, 0.0, 10.0, 0.0, 0.0, -10.0];
        let flat = [0.0, 0.0, 10.0, 0.0, 20.0, 0.5];
        let squashed = [0.0, 0.0, 10.0, 0.0, 0.0, 2.0];
        let tris = [[0, 1, 2]];
        assert!(frame_to_base_gradient(&TRI, &folded, &tris)[0].is_none());
        assert!(frame_to_base_gradient(&TRI, &flat, &tris)[0].is_none());
        assert!(frame_to_base_gradient(&TRI, &squashed, &tris)[0].is_none());
        let stretched = [0.0, 0.0, 10.0, 0.0, 0.0, 30.0];
        assert!(frame_to_base_gradient(&TRI, &stretched, &tris)[0].is_some());
    }
}

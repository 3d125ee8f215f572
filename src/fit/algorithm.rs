//! The fitting algorithms, one type per algorithm in the manner of menpofit's
//! `aam/algorithm/lk.py`: each builds its Gauss-Newton system at the current state
//! ([`Algorithm::system`]; what it can precompute lives in the level, see `precompute.rs`),
//! [`run`] solves it under a Levenberg-Marquardt safeguard, and [`update`] composes the
//! increment with the current warp and projects the result onto the model.

use crate::similarity::Similarity;

use super::geometry::Geometry;
use super::grey::{sample, GreyView};
use super::linalg::{axpy, cholesky, cholesky_solve, dot};
use super::precompute::{regularise, Level, ShapeBasis};

/// Buffers of one fit, allocated once per fitter.
pub(super) struct Work {
    /// The landmarks a fit starts from, in level coordinates.
    pub init: Vec<f32>,
    /// The current landmarks, the next estimate, a scratch copy and the last step.
    pub cur: Vec<f32>,
    pub next: Vec<f32>,
    pub scratch: Vec<f32>,
    pub delta: Vec<f32>,
    /// The shape parameters and the pose of `cur`.
    pub p: Vec<f32>,
    pub pose: Similarity,
    /// What is computed per frame pixel.
    pub px: PixelWork,
    /// The Gauss-Newton system and its saved copy.
    pub sys: System,
    /// The state before the last step of [`run`], to undo it.
    pub saved: FitState,
    /// The landmarks the starts of a multi-start level are offset from.
    pub start_cur: Vec<f32>,
    /// The best state over a multi-start level's starts.
    pub best: FitState,
    /// The state the first level started from (for [`super::FitOptions::level_check`]).
    pub before: FitState,
    /// The appearance synthesised for the appearance-aware refinement (empty without it).
    pub rgb: Vec<f32>,
}

/// The per-pixel buffers of a fit (`n` pixels of the largest level, `l` its grey appearance
/// modes, `k` warp parameters).
pub(super) struct PixelWork {
    /// The warped image's grey levels (`n`) and the error image (`n`).
    pub w: Vec<f32>,
    pub e: Vec<f32>,
    /// The grey appearance parameters (`l`).
    pub lam: Vec<f32>,
    /// The warped image's gradients (`n` each).
    pub tgx: Vec<f32>,
    pub tgy: Vec<f32>,
    /// The steepest-descent images (`k x n`).
    pub sd: Vec<f32>,
}

impl PixelWork {
    pub fn new(n: usize, l: usize, k: usize) -> PixelWork {
        PixelWork {
            w: vec![0.0; n],
            e: vec![0.0; n],
            lam: vec![0.0; l],
            tgx: vec![0.0; n],
            tgy: vec![0.0; n],
            sd: vec![0.0; k * n],
        }
    }
}

/// The Gauss-Newton system of `k` warp parameters, in f64: the appearance projection
/// (`l x k`), the gradient `g`, the Hessian `h`, its factor `hf` and the step `dc`, and the
/// system saved with the state before a step (to undo it).
pub(super) struct System {
    pub proj: Vec<f64>,
    pub g: Vec<f64>,
    pub h: Vec<f64>,
    pub hf: Vec<f64>,
    pub dc: Vec<f64>,
    pub saved_g: Vec<f64>,
    pub saved_h: Vec<f64>,
}

impl System {
    pub fn new(k: usize, l: usize) -> System {
        System {
            proj: vec![0.0; l * k],
            g: vec![0.0; k],
            h: vec![0.0; k * k],
            hf: vec![0.0; k * k],
            dc: vec![0.0; k],
            saved_g: vec![0.0; k],
            saved_h: vec![0.0; k * k],
        }
    }
}

/// A copy of the fitting state of [`Work`] (its `cur`, `p` and `pose`): the landmarks in level
/// coordinates, the shape parameters and the pose. Copies in and out allocate nothing.
pub(super) struct FitState {
    pub cur: Vec<f32>,
    pub p: Vec<f32>,
    pub pose: Similarity,
}

impl FitState {
    /// A state for `n2` landmark values and `m` shape parameters.
    pub fn new(n2: usize, m: usize) -> FitState {
        FitState {
            cur: vec![0.0; n2],
            p: vec![0.0; m],
            pose: Similarity::IDENTITY,
        }
    }

    /// Keeps a copy of the state `(cur, p, pose)`.
    pub fn save(&mut self, cur: &[f32], p: &[f32], pose: Similarity) {
        self.cur.copy_from_slice(cur);
        self.p.copy_from_slice(p);
        self.pose = pose;
    }

    /// Writes the kept state back into `(cur, p, pose)`.
    pub fn restore(&self, cur: &mut [f32], p: &mut [f32], pose: &mut Similarity) {
        cur.copy_from_slice(&self.cur);
        p.copy_from_slice(&self.p);
        *pose = self.pose;
    }
}

/// What one iteration did.
pub(super) enum Step {
    /// Moved by at most this many pixels.
    Moved(f32),
    /// The update was not finite or degenerate: state unchanged, stop.
    Failed,
}

/// Samples, estimates `lambda` by projection and leaves the residual in `w.px.e`; returns its
/// RMS.
pub(super) fn residual(level: &Level, img: GreyView<'_>, w: &mut Work) -> f32 {
    let n = level.n;
    sample(level, img, &w.cur, &mut w.px.w[..n]);
    let e = &mut w.px.e[..n];
    for ((o, a), b) in e.iter_mut().zip(&w.px.w[..n]).zip(&level.a0) {
        *o = a - b;
    }
    for i in 0..level.la {
        let mode = &level.app[i * n..(i + 1) * n];
        w.px.lam[i] = dot(mode, e);
    }
    for i in 0..level.la {
        let mode = &level.app[i * n..(i + 1) * n];
        axpy(-w.px.lam[i], mode, e);
    }
    (dot(e, e) / n as f32).sqrt()
}

impl Work {
    /// Exchanges the current state (landmarks, shape parameters, pose) with the kept one
    /// (`before`).
    pub(super) fn swap_before(&mut self) {
        std::mem::swap(&mut self.cur, &mut self.before.cur);
        std::mem::swap(&mut self.p, &mut self.before.p);
        std::mem::swap(&mut self.pose, &mut self.before.pose);
    }
}

/// The cost a level minimises at the current state: the projected-out residual
/// `|e|^2 - |A^T e|^2` plus the shape prior (leaves the residual in `w.px.e`).
pub(super) fn level_cost(c: &Ctx<'_>, w: &mut Work) -> f64 {
    let rms = residual(c.level, c.img, w) as f64;
    let mut cost = rms * rms * c.level.n as f64;
    for (j, m) in c.basis.mode_of.iter().enumerate() {
        if let Some(m) = m {
            let p = w.p[*m] as f64;
            cost += c.level.prior[j] * p * p;
        }
    }
    cost
}

/// One fitting algorithm: builds the Gauss-Newton system `H dc = g` at the current state
/// (into `w.sys.h` and `w.sys.g`) and returns the cost it minimises. The step itself (solve, update)
/// is shared: [`run`] and [`update`].
pub(super) trait Algorithm {
    /// Samples the image at the current state, fills `w.sys.g` and `w.sys.h`, returns the cost.
    fn system(&self, c: &Ctx<'_>, w: &mut Work) -> f64;
}

/// Project-out inverse compositional (Matthews & Baker 2004, section 4.2): the appearance
/// span is projected out of the steepest-descent images once per model, so the Hessian is
/// precomputed (`Level::sd_po`, `Level::h_po`) and an iteration costs `O(kN)`.
pub(super) struct ProjectOut;

/// Simultaneous (Wiberg) inverse compositional with the appearance eliminated (Tzimiropoulos
/// & Pantic, ICCV 2013; menpofit's `WibergInverseCompositional`): `lambda` by projection, the
/// template gradient that of `A0 + A lambda`, the Hessian recomputed each iteration (`O(k^2 N)`).
pub(super) struct Simultaneous;

/// What a stage works with.
pub(super) struct Ctx<'a> {
    pub level: &'a Level,
    pub geom: &'a Geometry,
    pub basis: &'a ShapeBasis,
    pub img: GreyView<'a>,
}

/// Runs up to `max_iters` Levenberg-Marquardt-safeguarded Gauss-Newton iterations of `alg`:
/// a step that increases the cost (projected-out residual plus prior) is undone and retried
/// with more damping `mu` (`H + mu diag(H)`); accepted steps relax the damping. Returns
/// whether the last step moved no landmark more than `tol` pixels.
pub(super) fn run<A: Algorithm>(
    alg: &A,
    c: &Ctx<'_>,
    w: &mut Work,
    max_iters: u32,
    tol: f32,
    iterations: &mut u32,
) -> bool {
    let k = c.basis.k;
    let mut mu = 0.0f64;
    let mut best = f64::INFINITY;
    for _ in 0..max_iters {
        *iterations += 1;
        let cost = alg.system(c, w);
        if cost.is_finite() && cost <= best {
            best = cost;
            w.saved.save(&w.cur, &w.p, w.pose);
            w.sys.saved_g.copy_from_slice(&w.sys.g);
            w.sys.saved_h.copy_from_slice(&w.sys.h);
            mu = if mu < 1e-4 { 0.0 } else { mu * 0.1 };
        } else {
            if !best.is_finite() {
                return false;
            }
            // Undo the last step; retry from the saved state with more damping.
            w.saved.restore(&mut w.cur, &mut w.p, &mut w.pose);
            w.sys.g.copy_from_slice(&w.sys.saved_g);
            w.sys.h.copy_from_slice(&w.sys.saved_h);
            mu = if mu == 0.0 { 1e-2 } else { mu * 10.0 };
            if mu > 1e4 {
                return true;
            }
        }
        // Solve (H + prior + mu diag H) dc = g.
        w.sys.hf.copy_from_slice(&w.sys.h);
        for j in 0..k {
            let d = w.sys.hf[j * k + j];
            w.sys.hf[j * k + j] = d + mu * d;
        }
        regularise(&mut w.sys.hf, &c.level.prior, k);
        if !cholesky(&mut w.sys.hf, k) {
            return false;
        }
        w.sys.dc.copy_from_slice(&w.sys.g);
        cholesky_solve(&w.sys.hf, k, &mut w.sys.dc);
        match update(c.geom, c.basis, w) {
            Step::Moved(d) if d <= tol => return true,
            Step::Moved(_) => {}
            Step::Failed => {
                w.saved.restore(&mut w.cur, &mut w.p, &mut w.pose);
                return false;
            }
        }
    }
    false
}

/// Prior cost `sum_j w_j p_j^2` and gradient term `w_j p_j` added to `w.sys.g`.
fn add_prior(c: &Ctx<'_>, w: &mut Work) -> f64 {
    let mut cost = 0.0;
    for (j, m) in c.basis.mode_of.iter().enumerate() {
        if let Some(m) = m {
            let p = w.p[*m] as f64;
            w.sys.g[j] += c.level.prior[j] * p;
            cost += c.level.prior[j] * p * p;
        }
    }
    cost
}

/// Project-out system at the current state: `g = SD^T e`, `H` precomputed; returns the cost
/// `|e|^2 - |A^T e|^2 + prior`.
impl Algorithm for ProjectOut {
    fn system(&self, c: &Ctx<'_>, w: &mut Work) -> f64 {
        let l = c.level;
        let n = l.n;
        sample(l, c.img, &w.cur, &mut w.px.w[..n]);
        for ((o, a), b) in w.px.e[..n].iter_mut().zip(&w.px.w[..n]).zip(&l.a0) {
            *o = a - b;
        }
        let e = &w.px.e[..n];
        let mut cost = dot(e, e) as f64;
        for i in 0..l.la {
            let v = dot(&l.app[i * n..(i + 1) * n], e) as f64;
            cost -= v * v;
        }
        for j in 0..c.basis.k {
            w.sys.g[j] = dot(&l.sd_po[j * n..(j + 1) * n], e) as f64;
        }
        w.sys.h.copy_from_slice(&l.h_po);
        cost + add_prior(c, w)
    }
}

/// Appearance-aware (simultaneous, Wiberg) system: `lambda` by projection, template
/// `T = A0 + A lambda`, steepest-descent images from `grad T`, Hessian
/// `SD^T SD - (A^T SD)^T (A^T SD)` (appearance eliminated), `g = SD^T e`.
impl Algorithm for Simultaneous {
    fn system(&self, c: &Ctx<'_>, w: &mut Work) -> f64 {
        let l = c.level;
        let n = l.n;
        let k = c.basis.k;
        let la = l.la;
        let rms = residual(l, c.img, w) as f64;
        let cost = rms * rms * n as f64;
        w.px.tgx[..n].copy_from_slice(&l.a0_gx);
        w.px.tgy[..n].copy_from_slice(&l.a0_gy);
        for i in 0..la {
            let lam = w.px.lam[i];
            axpy(lam, &l.app_gx[i * n..(i + 1) * n], &mut w.px.tgx[..n]);
            axpy(lam, &l.app_gy[i * n..(i + 1) * n], &mut w.px.tgy[..n]);
        }
        for j in 0..k {
            let sd = &mut w.px.sd[j * n..(j + 1) * n];
            let (jx, jy) = (&l.jx[j * n..(j + 1) * n], &l.jy[j * n..(j + 1) * n]);
            for i in 0..n {
                sd[i] = w.px.tgx[i] * jx[i] + w.px.tgy[i] * jy[i];
            }
        }
        for i in 0..la {
            let mode = &l.app[i * n..(i + 1) * n];
            for j in 0..k {
                w.sys.proj[i * k + j] = dot(mode, &w.px.sd[j * n..(j + 1) * n]) as f64;
            }
        }
        for a in 0..k {
            let sa = &w.px.sd[a * n..(a + 1) * n];
            for b in 0..=a {
                let mut v = dot(sa, &w.px.sd[b * n..(b + 1) * n]) as f64;
                for i in 0..la {
                    v -= w.sys.proj[i * k + a] * w.sys.proj[i * k + b];
                }
                w.sys.h[a * k + b] = v;
                w.sys.h[b * k + a] = v;
            }
            w.sys.g[a] = dot(sa, &w.px.e[..n]) as f64;
        }
        cost + add_prior(c, w)
    }
}

/// Applies the parameter update `w.sys.dc` (combined basis): compose the inverse incremental
/// warp, project onto the model. Returns the largest landmark movement.
pub(super) fn update(geom: &Geometry, basis: &ShapeBasis, w: &mut Work) -> Step {
    if w.sys.dc.iter().any(|v| !v.is_finite()) {
        return Step::Failed;
    }
    let d = w.delta.len();
    w.delta.iter_mut().for_each(|v| *v = 0.0);
    for (j, &c) in w.sys.dc.iter().enumerate() {
        axpy(c as f32, &basis.vectors[j * d..(j + 1) * d], &mut w.delta);
    }
    geom.compose_inverse(&w.cur, &w.delta, &w.pose, &mut w.scratch);
    // Project onto the model (`delta` is free again and serves as scratch).
    let Some(pose) = geom.project(&w.scratch, &mut w.p, &mut w.delta, &mut w.next) else {
        return Step::Failed;
    };
    let moved = w
        .cur
        .iter()
        .zip(&w.next)
        .map(|(a, b)| (a - b).abs())
        .fold(0f32, f32::max);
    std::mem::swap(&mut w.cur, &mut w.next);
    w.pose = pose;
    Step::Moved(moved)
}

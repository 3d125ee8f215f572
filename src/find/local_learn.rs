//! Learning the local correction (`local.rs`) from landmarked images: the cascade of ridge
//! regressions of supervised descent, each stage trained on the points the stages before it
//! leave, from the finder's points and perturbed copies of them.

use super::calibration::{face_frame, face_offsets};
use super::local::{
    check_stage, local_descriptor, LocalCorrection, LocalScratch, Stage, DIM, MAX_STAGES,
};
use crate::error::{Error, Result};
use crate::find::FaceFinder;
use crate::image::ImageRef;
use crate::landmarks::mirror_points;
use nalgebra::{DMatrix, DVector};

/// The committed landmarked images the shipped correction is learned from, under the
/// repository root `root`: GRID's 330 frames of ten speakers' speech (`data/grid`) and the
/// London set's 120 photos of 60 people, neutral and smiling (`data/london`), both CC BY 4.0,
/// in path order. The London photos were added on 29 Nov: GRID never laughs, and with them the
/// finder reads a laugh's mouth opening nearer dlib's and every held-out clip's mean error is
/// lower (docs/finding.md, "Learned from London's faces too"). Native only (it reads folders).
#[cfg(not(target_arch = "wasm32"))]
pub fn training_images(root: &std::path::Path) -> Result<Vec<std::path::PathBuf>> {
    let mut paths = crate::io::annotated_images(&root.join("data/grid"))?;
    paths.extend(crate::io::annotated_images(&root.join("data/london"))?);
    Ok(paths)
}

/// One landmarked image to learn from.
#[derive(Clone, Copy, Debug)]
pub struct LearnSample<'a> {
    /// The image.
    pub image: ImageRef<'a>,
    /// The finder's 68 points on it (calibrated, before the local correction).
    pub found: &'a [f32],
    /// dlib's 68 points on it.
    pub truth: &'a [f32],
}

/// How [`LocalCorrection::learn`] learns.
#[derive(Clone, Debug)]
pub struct LearnOptions {
    /// Per stage, the patch's sample step as a fraction of the face's RMS radius (the number of
    /// stages is this list's length).
    pub scales: Vec<f32>,
    /// Perturbed copies of each sample's points trained on beside the points themselves.
    pub perturb: usize,
    /// Ridge weight per training start (added to the diagonal times the number of starts).
    pub ridge: f64,
    /// The points corrected, increasing.
    pub points: Vec<u8>,
    /// Seed of the perturbations.
    pub seed: u64,
    /// Per stage (entry `k` for stage `k`), the points it moves instead of
    /// [`points`](Self::points); `None`, or no entry, for all of them. A stage of fewer points
    /// costs less to ship and to run.
    pub stage_points: Vec<Option<Vec<u8>>>,
    /// [`LocalCorrection::learn_from_images`] also learns from each image's mirror image (the
    /// finder run on it, dlib's points mirrored), so a face and its mirror image get mirrored
    /// corrections.
    pub mirror: bool,
}

impl Default for LearnOptions {
    /// Three stages (sample steps 0.1, 0.06 and 0.04 of the radius), four perturbed copies,
    /// ridge 0.01, every point but the jaw's (0-16), the mirror images too: chosen on GRID's
    /// speakers 1-5 against 6-10 and the reverse (`examples/local_figures.rs`; docs/finding.md,
    /// "The local correction").
    ///
    /// Nor the outer lips' middles (51, 57): learned from GRID's speech, which never laughs,
    /// their correction drew a laughing mouth's lips towards a speaking one's and took away
    /// almost half of the lip corners' lift (franck-dev's spread of it, p95 - p5 against
    /// dlib's: 0.74 with no correction, 0.59 with every point's, 0.76 without these two),
    /// for 0.0001 of the eye distance of mean error (docs/finding.md).
    ///
    /// The first, coarsest stage moves the mouth's points alone (48-67 but 51 and 57): a
    /// wider patch sees a laugh's whole mouth, which the two finer stages then refine
    /// (franck-dev's inner lips' opening 0.81 -> 0.86 of dlib's spread, since 29 Nov). For
    /// every point it read as much but cost 25 kB of weights where the page's first load has
    /// 13 kB to spare; for the mouth's 18 it costs 9 kB.
    fn default() -> Self {
        let points: Vec<u8> = (17..68).filter(|&p| p != 51 && p != 57).collect();
        let mouth = points.iter().copied().filter(|&p| p >= 48).collect();
        LearnOptions {
            scales: vec![0.1, 0.06, 0.04],
            perturb: 4,
            ridge: 0.01,
            points,
            seed: 0x9e37_79b9_7f4a_7c15,
            mirror: true,
            stage_points: vec![Some(mouth)],
        }
    }
}

impl LearnOptions {
    /// The points stage `k` moves ([`LearnOptions::stage_points`], else
    /// [`LearnOptions::points`]).
    pub fn points_of(&self, k: usize) -> &[u8] {
        match self.stage_points.get(k) {
            Some(Some(p)) => p,
            _ => &self.points,
        }
    }
}

/// A xorshift generator of uniform and normal numbers (reproducible learning).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn normal(&mut self) -> f32 {
        let (a, b) = (self.uniform().max(1e-7), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f32::consts::TAU * b).cos()
    }
}

/// `points` moved as a whole (shift and scale by `0.03`, a turn of `0.03` radians, normally
/// distributed) and each point by normal noise of `0.02` of the face's RMS radius.
fn perturbed(points: &[f32], rng: &mut Rng) -> Option<Vec<f32>> {
    let (c, r, _, _) = face_frame(points)?;
    let (tx, ty) = (rng.normal() * 0.03 * r, rng.normal() * 0.03 * r);
    let sc = 1.0 + rng.normal() * 0.03;
    let th = rng.normal() * 0.03;
    let (co, si) = (th.cos(), th.sin());
    let mut p = points.to_vec();
    for q in p.chunks_exact_mut(2) {
        let (x, y) = (q[0] - c[0], q[1] - c[1]);
        q[0] = c[0] + sc * (co * x - si * y) + tx + rng.normal() * 0.02 * r;
        q[1] = c[1] + sc * (si * x + co * y) + ty + rng.normal() * 0.02 * r;
    }
    Some(p)
}

impl LocalCorrection {
    /// Learns a correction from `samples` (docs/finding.md, "The local correction"): the
    /// training starts are each sample's found points and [`LearnOptions::perturb`] perturbed
    /// copies; each stage solves, per point, the ridge regression from the point's descriptor
    /// (and a constant) to dlib's point's offset in the face frame, then moves every start by
    /// its prediction (with the weights as the file stores them, float16) for the next stage.
    pub fn learn(samples: &[LearnSample<'_>], options: &LearnOptions) -> Result<LocalCorrection> {
        let bad = |m: String| Error::Weights(format!("local correction: {m}"));
        for (k, &scale) in options.scales.iter().enumerate() {
            check_stage(scale, options.points_of(k)).map_err(bad)?;
        }
        if !(1..=MAX_STAGES).contains(&options.scales.len()) {
            return Err(bad(format!(
                "{} stages (1..={MAX_STAGES} allowed)",
                options.scales.len()
            )));
        }
        let mut rng = Rng(options.seed);
        let mut starts: Vec<(usize, Vec<f32>)> = Vec::new();
        for (k, s) in samples.iter().enumerate() {
            if s.found.len() != 136 || s.truth.len() != 136 || face_frame(s.found).is_none() {
                continue;
            }
            starts.push((k, s.found.to_vec()));
            for _ in 0..options.perturb {
                if let Some(p) = perturbed(s.found, &mut rng) {
                    starts.push((k, p));
                }
            }
        }
        if starts.is_empty() {
            return Err(bad("no usable samples".into()));
        }
        let mut stages = Vec::new();
        let mut scratch = LocalScratch::default();
        for (k, &scale) in options.scales.iter().enumerate() {
            let points = options.points_of(k);
            let weights = solve_stage(samples, &starts, scale, points, options.ridge)?;
            // The weights as stored (float16), so the next stage learns from what ships.
            let stage = Stage::stored(scale, points.to_vec(), &weights).map_err(bad)?;
            for (k, p) in starts.iter_mut() {
                stage.step(&samples[*k].image, p, &mut scratch);
            }
            stages.push(stage);
        }
        Ok(LocalCorrection::from_stages(stages))
    }
}

impl LocalCorrection {
    /// Learns a correction from landmarked images as the shipped one is learned
    /// (`examples/finder_data.rs local`): `finder` (its local correction off meanwhile)
    /// finds each image's most confident face, and, with [`LearnOptions::mirror`], the mirror
    /// image's too (dlib's points mirrored); images with no face or with points of another
    /// length than 136 are skipped; then [`learn`](Self::learn). Returns the correction and
    /// the number of samples it learned from.
    pub fn learn_from_images(
        finder: &mut FaceFinder,
        images: &[(ImageRef<'_>, &[f32])],
        options: &LearnOptions,
    ) -> Result<(LocalCorrection, usize)> {
        let was = finder.local_correction();
        finder.set_local_correction(false);
        // The mirror images (with the index of the image each mirrors), and per look the image
        // it was found in, the points found and dlib's.
        let mut mirrors: Vec<(usize, Vec<u8>)> = Vec::new();
        let mut looks: Vec<Look> = Vec::new();
        let mut fail = None;
        for (k, (image, truth)) in images.iter().enumerate() {
            if truth.len() != 136 {
                continue;
            }
            if let Some(face) = finder.find(image).into_iter().next() {
                looks.push(Look {
                    source: Source::Image(k),
                    found: face.landmarks,
                    truth: truth.to_vec(),
                });
            }
            if options.mirror {
                let mut data = Vec::new();
                image.mirror_into(&mut data);
                match ImageRef::new(image.width(), image.height(), &data) {
                    Ok(view) => {
                        if let Some(face) = finder.find(&view).into_iter().next() {
                            let mut t = vec![0.0; 136];
                            mirror_points(truth, image.width() as f32, &mut t);
                            looks.push(Look {
                                source: Source::Mirror(mirrors.len()),
                                found: face.landmarks,
                                truth: t,
                            });
                        }
                    }
                    Err(e) => fail = Some(e),
                }
                mirrors.push((k, data));
            }
        }
        finder.set_local_correction(was);
        if let Some(e) = fail {
            return Err(e);
        }
        let mut samples = Vec::with_capacity(looks.len());
        for Look {
            source,
            found,
            truth,
        } in &looks
        {
            let image = match *source {
                Source::Image(k) => images[k].0,
                Source::Mirror(m) => {
                    let (k, data) = &mirrors[m];
                    ImageRef::new(images[*k].0.width(), images[*k].0.height(), data)?
                }
            };
            samples.push(LearnSample {
                image,
                found,
                truth,
            });
        }
        let n = samples.len();
        Ok((LocalCorrection::learn(&samples, options)?, n))
    }
}

/// Where [`LocalCorrection::learn_from_images`] found a face: in image `k`, or in mirror
/// image `m`.
enum Source {
    Image(usize),
    Mirror(usize),
}

/// A face found for learning: where, the finder's points and dlib's.
struct Look {
    source: Source,
    found: Vec<f32>,
    truth: Vec<f32>,
}

/// One stage's weights: per point of `points`, `(DIM + 1) x 2` values (x and y interleaved
/// per feature, the constant last), each point's ridge regression weighted by `ridge` per start.
fn solve_stage(
    samples: &[LearnSample<'_>],
    starts: &[(usize, Vec<f32>)],
    scale: f32,
    points: &[u8],
    ridge: f64,
) -> Result<Vec<f32>> {
    let d = DIM + 1;
    let np = points.len();
    let mut xtx = vec![DMatrix::<f64>::zeros(d, d); np];
    let mut xty = vec![DMatrix::<f64>::zeros(d, 2); np];
    let mut patch = Vec::new();
    let mut f = vec![0f32; DIM];
    let mut x = DVector::<f64>::zeros(d);
    let mut n = 0usize;
    for (k, pts) in starts {
        let s = &samples[*k];
        let (Some((_, r, c, sn)), Some(t)) = (face_frame(pts), face_offsets(pts, s.truth)) else {
            continue;
        };
        n += 1;
        for (q, &i) in points.iter().enumerate() {
            let i = i as usize;
            local_descriptor(
                &s.image,
                pts[2 * i],
                pts[2 * i + 1],
                r * scale,
                c,
                sn,
                &mut patch,
                &mut f,
            );
            for (xj, fj) in x.iter_mut().zip(&f) {
                *xj = *fj as f64;
            }
            x[DIM] = 1.0;
            xtx[q].ger(1.0, &x, &x, 1.0);
            for c in 0..2 {
                let y = t[2 * i + c] as f64;
                for j in 0..d {
                    xty[q][(j, c)] += x[j] * y;
                }
            }
        }
    }
    let mut out = Vec::with_capacity(np * d * 2);
    for (a, b) in xtx.into_iter().zip(&xty) {
        let mut a = a;
        for j in 0..DIM {
            a[(j, j)] += ridge * n as f64;
        }
        let sol = a
            .cholesky()
            .ok_or_else(|| Error::Weights("local correction: a singular regression".into()))?
            .solve(b);
        for j in 0..d {
            out.push(sol[(j, 0)] as f32);
            out.push(sol[(j, 1)] as f32);
        }
    }
    Ok(out)
}

//! The generic expression prior: how far many people's faces move from their neutral face, as
//! a Gaussian over shape displacements in the canonical reference frame.
//!
//! Learned ([`ExpressionPrior::learn`]) from the London set's 60 neutral -> smiling pairs and
//! GRID's ten speakers' speech (each frame against the speaker's mean), both shipped with the
//! crate as landmarks (`data/london/`, `data/grid/`, CC BY 4.0), by
//! `cargo run --release --example expression_prior`; the file it writes
//! (`data/weights/expression_prior.fmep`) is embedded and learned again byte for byte by a test.
//! The expressive method bounds the whole transferred displacement by its Mahalanobis distance
//! under this prior, instead of clamping each of a speech-trained target's modes.

use std::sync::OnceLock;

use crate::error::{Error, Result};
use crate::landmarks::MIRROR_68;
use crate::similarity::Similarity;

/// Magic of the prior file.
const MAGIC: &[u8; 4] = b"FMEP";
/// Version of the prior file (2: the modes as `f16`, half the bytes of version 1's `f32`; the
/// page's first load is counted to the byte).
const VERSION: u32 = 2;
/// Most modes a prior keeps.
pub const MAX_PRIOR_MODES: usize = 24;
/// Share of the displacements' second moment the kept modes explain.
const KEPT_SHARE: f64 = 0.98;

pub use crate::landmarks::STABLE_POINTS;

/// Neutral and expressed shapes of people, a pair each (68 points, image coordinates).
pub type ShapePairs = Vec<(Vec<f32>, Vec<f32>)>;
/// Shapes of speakers, a list each (68 points, image coordinates).
pub type SpeakerShapes = Vec<Vec<Vec<f32>>>;

/// A zero-mean Gaussian over expression displacements (`2n` coordinates, 68 points, canonical
/// model coordinates).
///
/// Represents: `k` orthonormal modes with their variances, an isotropic variance for the rest of
/// the space, and `limit`, the largest of the training displacements' distances.
/// Ensures (when learned or read): finite values, variances positive and descending.
#[derive(Clone, Debug, PartialEq)]
pub struct ExpressionPrior {
    dim: usize,
    modes: Vec<f32>,
    variances: Vec<f32>,
    residual_variance: f32,
    limit: f32,
}

/// The displacement of `expressed` from `neutral` (two shapes of one person, `2n` image
/// coordinates each) in the model coordinates of `base`: each shape is aligned onto `base` by
/// the similarity of its [`STABLE_POINTS`], so the head's own motion between the two is gone.
/// Requires 68-point shapes.
pub fn expression_displacement(
    neutral: &[f32],
    expressed: &[f32],
    base: &[f32],
) -> Result<Vec<f32>> {
    if neutral.len() != 136 || expressed.len() != 136 || base.len() != 136 {
        return Err(Error::Landmarks(
            "an expression displacement needs 68-point shapes".into(),
        ));
    }
    let mut out = vec![0f32; 136];
    for (shape, sign) in [(expressed, 1.0f32), (neutral, -1.0)] {
        let sim = Similarity::align_points(shape, base, &STABLE_POINTS);
        if !sim.is_valid() {
            return Err(Error::Landmarks(
                "degenerate landmarks for an expression displacement".into(),
            ));
        }
        let mut s = shape.to_vec();
        sim.apply_in_place(&mut s);
        out.iter_mut().zip(&s).for_each(|(o, v)| *o += sign * v);
    }
    Ok(out)
}

impl ExpressionPrior {
    /// Learns the prior from displacements (`samples`, each `2n`, 68 points) with a weight each:
    /// the weighted second moment about zero (neutral is the centre), of every sample and its
    /// mirror image, its leading eigenvectors up to 98% of the total (at most
    /// [`MAX_PRIOR_MODES`]), the rest as one isotropic variance. Deterministic.
    pub fn learn(samples: &[Vec<f32>], weights: &[f32]) -> Result<ExpressionPrior> {
        let dim = 136;
        if samples.is_empty() || samples.len() != weights.len() {
            return Err(Error::Params(
                "an expression prior needs samples, one weight each".into(),
            ));
        }
        if samples
            .iter()
            .any(|s| s.len() != dim || s.iter().any(|v| !v.is_finite()))
            || weights.iter().any(|w| !(w.is_finite() && *w >= 0.0))
        {
            return Err(Error::Params(
                "expression prior samples must be finite 68-point displacements".into(),
            ));
        }
        let total: f64 = weights.iter().map(|&w| w as f64).sum();
        if total <= 0.0 {
            return Err(Error::Params("expression prior weights sum to zero".into()));
        }
        let mut c = nalgebra::DMatrix::<f64>::zeros(dim, dim);
        let mut m = vec![0f64; dim];
        for (s, &w) in samples.iter().zip(weights) {
            for mirror in [false, true] {
                for i in 0..68 {
                    let (j, sx) = if mirror {
                        (MIRROR_68[i], -1.0)
                    } else {
                        (i, 1.0)
                    };
                    m[2 * j] = sx * s[2 * i] as f64;
                    m[2 * j + 1] = s[2 * i + 1] as f64;
                }
                let w = w as f64 / (2.0 * total);
                for a in 0..dim {
                    let wa = w * m[a];
                    if wa != 0.0 {
                        for b in 0..dim {
                            c[(a, b)] += wa * m[b];
                        }
                    }
                }
            }
        }
        let eig = nalgebra::SymmetricEigen::new(c);
        let mut order: Vec<usize> = (0..dim).collect();
        order.sort_by(|&a, &b| {
            eig.eigenvalues[b]
                .total_cmp(&eig.eigenvalues[a])
                .then(a.cmp(&b))
        });
        let trace: f64 = eig.eigenvalues.iter().map(|v| v.max(0.0)).sum();
        let mut kept = 0.0;
        let (mut modes, mut variances) = (Vec::new(), Vec::new());
        for &i in &order {
            let v = eig.eigenvalues[i];
            if kept >= KEPT_SHARE * trace || variances.len() == MAX_PRIOR_MODES || v <= 0.0 {
                break;
            }
            kept += v;
            variances.push(v as f32);
            // Sign convention: the largest-magnitude coordinate positive (deterministic output).
            let col = eig.eigenvectors.column(i);
            let big = (0..dim)
                .max_by(|&a, &b| col[a].abs().total_cmp(&col[b].abs()).then(b.cmp(&a)))
                .unwrap_or(0);
            let sign = if col[big] < 0.0 { -1.0 } else { 1.0 };
            modes.extend(col.iter().map(|v| (sign * v) as f32));
        }
        let rest =
            ((trace - kept) / (dim - variances.len()).max(1) as f64).max(1e-4 * trace / dim as f64);
        let mut prior = ExpressionPrior {
            dim,
            modes,
            variances,
            residual_variance: rest as f32,
            limit: 1.0,
        };
        let mut d: Vec<f32> = samples.iter().map(|s| prior.distance(s)).collect();
        d.sort_by(f32::total_cmp);
        prior.limit = d[d.len() - 1].max(1e-3);
        Ok(prior)
    }

    /// The prior shipped with the crate (see the module docs).
    pub fn builtin() -> &'static ExpressionPrior {
        static PRIOR: OnceLock<ExpressionPrior> = OnceLock::new();
        PRIOR.get_or_init(|| {
            ExpressionPrior::from_bytes(include_bytes!("../../data/weights/expression_prior.fmep"))
                .expect("the embedded expression prior is valid (tested)")
        })
    }

    /// The Mahalanobis distance of a displacement `d` (`2n`) under the prior:
    /// `sqrt(sum_j (e_j^2 / gamma_j) + |d - E e|^2 / (m sigma_r^2))` with `e = E^T d` and `m`
    /// the dimensions the modes leave (the rest counted as one coordinate). Allocates nothing;
    /// a displacement of another length has distance 0.
    pub fn distance(&self, d: &[f32]) -> f32 {
        if d.len() != self.dim {
            return 0.0;
        }
        let norm2: f64 = d.iter().map(|&v| (v as f64) * (v as f64)).sum();
        let (mut inside, mut explained) = (0f64, 0f64);
        for (mode, &g) in self.modes.chunks_exact(self.dim).zip(&self.variances) {
            let e: f64 = mode.iter().zip(d).map(|(&a, &b)| a as f64 * b as f64).sum();
            inside += e * e / g as f64;
            explained += e * e;
        }
        // The rest of the space as one coordinate: its energy over what the prior expects of it
        // in all its dimensions (landmarking noise and identity spread there, not expression).
        let dims = (self.dim - self.variances.len()).max(1) as f64;
        let rest = (norm2 - explained).max(0.0) / (self.residual_variance as f64 * dims);
        (inside + rest).sqrt() as f32
    }

    /// The largest of the training displacements' [`ExpressionPrior::distance`]: the strongest
    /// expression the prior has seen.
    pub fn limit(&self) -> f32 {
        self.limit
    }

    /// The number of modes kept.
    pub fn n_modes(&self) -> usize {
        self.variances.len()
    }

    /// The prior as the bytes of its `FMEP` file: magic, version, dimension, modes (`u32`),
    /// residual variance, limit, variances (`f32`), then the modes (`f16`: unit vectors, whose
    /// components keep about three significant digits), all little-endian. What
    /// [`ExpressionPrior::from_bytes`] reads back has its modes rounded so.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(24 + 4 * self.variances.len() + 2 * self.modes.len());
        out.extend_from_slice(MAGIC);
        for v in [VERSION, self.dim as u32, self.variances.len() as u32] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [self.residual_variance, self.limit]
            .iter()
            .chain(&self.variances)
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for &v in &self.modes {
            out.extend_from_slice(&half::f16::from_f32(v).to_le_bytes());
        }
        out
    }

    /// Reads an `FMEP` file, checking magic, version, dimension (136), mode count
    /// (at most [`MAX_PRIOR_MODES`]), length and that every value is finite and every variance
    /// positive: [`Error::Params`] naming what is wrong otherwise.
    pub fn from_bytes(bytes: &[u8]) -> Result<ExpressionPrior> {
        let bad = |why: &str| Error::Params(format!("expression prior file: {why}"));
        if bytes.len() < 16 || &bytes[..4] != MAGIC {
            return Err(bad("not an FMEP file"));
        }
        let word =
            |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
        if word(4) != VERSION {
            return Err(bad(&format!(
                "version {} (this library reads {VERSION})",
                word(4)
            )));
        }
        let (dim, k) = (word(8) as usize, word(12) as usize);
        if dim != 136 || k > MAX_PRIOR_MODES {
            return Err(bad(&format!("dimension {dim} with {k} modes")));
        }
        let head = 16 + 4 * (2 + k);
        let want = head + 2 * k * dim;
        if bytes.len() != want {
            return Err(bad(&format!("{} bytes, {want} expected", bytes.len())));
        }
        let f: Vec<f32> = bytes[16..head]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let modes: Vec<f32> = bytes[head..]
            .chunks_exact(2)
            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect();
        if f.iter().chain(&modes).any(|v| !v.is_finite()) || f.iter().any(|v| *v <= 0.0) {
            return Err(bad("a value is not finite, or a variance not positive"));
        }
        Ok(ExpressionPrior {
            dim,
            residual_variance: f[0],
            limit: f[1],
            variances: f[2..].to_vec(),
            modes,
        })
    }
}

/// The shipped prior's recipe (see the module docs): the London set's neutral -> smiling
/// displacements (`london`, pairs of 68-point shapes in image coordinates), half the weight,
/// shared equally; every GRID frame's displacement from its speaker's mean aligned shape
/// (`speakers`, each a list of shapes), the other half, shared equally between speakers and
/// then between their frames. All in the model coordinates of `base` (the canonical frame's
/// vertices).
pub fn learn_prior(
    london: &[(Vec<f32>, Vec<f32>)],
    speakers: &[Vec<Vec<f32>>],
    base: &[f32],
) -> Result<ExpressionPrior> {
    let (mut samples, mut weights) = (Vec::new(), Vec::new());
    for (neutral, smile) in london {
        samples.push(expression_displacement(neutral, smile, base)?);
        weights.push(0.5 / london.len() as f32);
    }
    let speakers: Vec<&Vec<Vec<f32>>> = speakers.iter().filter(|s| !s.is_empty()).collect();
    for frames in &speakers {
        // The speaker's neutral: the mean of their frames aligned onto the base.
        let aligned: Vec<Vec<f32>> = frames
            .iter()
            .map(|f| expression_displacement(base, f, base))
            .collect::<Result<_>>()?;
        let mut mean = vec![0f32; base.len()];
        for a in &aligned {
            mean.iter_mut()
                .zip(a)
                .for_each(|(m, v)| *m += v / aligned.len() as f32);
        }
        for a in aligned {
            samples.push(a.iter().zip(&mean).map(|(v, m)| v - m).collect());
            weights.push(0.5 / (speakers.len() * frames.len()) as f32);
        }
    }
    ExpressionPrior::learn(&samples, &weights)
}

//! The mutation fuzzing engine behind `examples/fuzz.rs` (long runs) and
//! `tests/integration/fuzz.rs` (a short deterministic run in the test suite). Stable Rust, no
//! dependency: the tests' xorshift64* generator and synthetic training set (this crate's `Rng`
//! and `synthetic`), byte-level mutations (flips, interesting numbers, splices, truncation,
//! extension) and structure-aware ones (header fields and array values of valid
//! `.fmm` models with the checksum repaired, numeric tokens of landmark files and parameter
//! JSON replaced by interesting numbers).
//!
//! Targets: the model loader (and, for every accepted model, `image_shape`, `project`,
//! rendering, cloning, tracking), the `.pts` and `.asf` parsers, and the parameter JSON (then
//! the same downstream operations on a valid model). Each execution must
//! - not panic,
//! - give only finite numbers in every `Ok` output,
//! - stay within the memory budget of `facemimic::bounds` (measured by the counting global
//!   allocator the including crate installs: [`CountingAlloc`]).
//!
//! Inputs whose outcome class was not seen before are "interesting" and may be saved as a
//! corpus; failures are returned with the input that caused them.

use facemimic::fit::FaceTracker;
use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::BTreeSet;
use std::sync::atomic::{AtomicU64, Ordering};

use facemimic::clone::{CloneOptions, Cloner, Method};
use facemimic::fit::{FitOptions, Tracker};
use facemimic::format::{read_model, write_model};
use facemimic::landmarks::{parse_asf, parse_pts, write_pts};
use facemimic::{
    BuildOptions, Builder, DrawOptions, FaceDrawer, FrameChoice, Image, Model, Params, Similarity,
    TrainingImage,
};

use crate::synthetic;
pub use crate::Rng;

// ------------------------------------------------------------------------------------------
// Counting allocator.

/// A global allocator that counts live bytes and their peak (install it with
/// `#[global_allocator]` in the crate that includes this file).
pub struct CountingAlloc;

static LIVE: AtomicU64 = AtomicU64::new(0);
static PEAK: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now =
                LIVE.fetch_add(layout.size() as u64, Ordering::Relaxed) + layout.size() as u64;
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size() as u64, Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                let d = (new_size - layout.size()) as u64;
                let now = LIVE.fetch_add(d, Ordering::Relaxed) + d;
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub((layout.size() - new_size) as u64, Ordering::Relaxed);
            }
        }
        p
    }
}

/// Runs `f` and returns its result with the peak of bytes allocated above the live bytes at
/// the start (single-threaded use).
fn measured<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let r = f();
    (r, PEAK.load(Ordering::Relaxed).saturating_sub(base))
}

/// Interesting floats: non-finite, extremes, limits' neighbours, signed zero, subnormals.
const FLOATS: [f32; 24] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    f32::MIN,
    f32::MIN_POSITIVE,
    1e-45,
    -0.0,
    0.0,
    1.0,
    -1.0,
    0.5,
    2.0,
    3e38,
    1e30,
    -1e30,
    1e15,
    1e7,
    1e6,
    1.000_001e6,
    1e4,
    1e-4,
    4096.0,
    -4097.0,
];

/// Interesting integers (header fields).
pub const INTS: [u32; 16] = [
    0,
    1,
    2,
    3,
    4,
    67,
    68,
    255,
    256,
    257,
    1024,
    2048,
    8192,
    0x7fff_ffff,
    0x8000_0000,
    u32::MAX,
];

fn float(rng: &mut Rng) -> f32 {
    if rng.chance(4) {
        rng.sym() * 10f32.powi(rng.below(80) as i32 - 40)
    } else {
        FLOATS[rng.below(FLOATS.len())]
    }
}

// ------------------------------------------------------------------------------------------
// Seeds.

/// `count` synthetic face-like training images with `n` landmarks on 64x64 images.
pub fn training_set(n: usize, count: usize, seed: u64) -> Vec<TrainingImage> {
    synthetic::training_set(n, count, seed, 64, "t")
}

/// A model small on disk whose tracker would need far more memory than its file's budget:
/// 128 landmarks on a large frame, then 256 orthonormal shape modes (the 0.8 MB model whose
/// tracker precomputation once took 81 MB).
#[allow(dead_code)] // the hostile-input tests use it; the fuzz runner does not
pub fn over_budget_model() -> Model {
    let images = training_set(128, 4, 11);
    let m = Builder::new(BuildOptions {
        name: "many-modes".into(),
        face_width: 240.0,
        frame: FrameChoice::Own,
        max_appearance_modes: 0,
        ..BuildOptions::default()
    })
    .build(&images, None)
    .unwrap();
    let d = m.shape().base.len();
    let k = 256;
    let mut parts = m.into_parts();
    parts.shape.modes = vec![0.0; k * d];
    for i in 0..k {
        parts.shape.modes[i * d + i] = 1.0;
    }
    parts.shape.variances = vec![1.0; k];
    Model::new(parts).unwrap()
}

/// The seed inputs: small valid models, landmark files and parameter JSON.
pub struct Seeds {
    /// Valid models (the first is used for the parameter and landmark targets).
    pub models: Vec<Model>,
    /// Their `.fmm` bytes.
    pub model_bytes: Vec<Vec<u8>>,
    /// Valid `.pts` texts.
    pub pts: Vec<String>,
    /// Valid `.asf` texts.
    pub asf: Vec<String>,
    /// Valid parameter JSON for `models[0]`.
    pub params: Vec<String>,
    /// A test image for `project` and tracking.
    pub image: Image,
}

impl Seeds {
    /// Builds the seeds (deterministic).
    pub fn new() -> Seeds {
        let opts = |name: &str, shape: usize, app: usize| BuildOptions {
            name: name.into(),
            face_width: if shape == 0 { 16.0 } else { 36.0 },
            frame: FrameChoice::Own,
            max_shape_modes: shape,
            max_appearance_modes: app,
            ..BuildOptions::default()
        };
        let a = Builder::new(opts("a", 4, 3))
            .build(&training_set(12, 6, 7), None)
            .expect("seed model a");
        let b = Builder::new(opts("b", 3, 2))
            .build(&training_set(12, 6, 99), Some(&a))
            .expect("seed model b");
        let c = Builder::new(opts("c", 0, 0))
            .build(&training_set(5, 4, 3), None)
            .expect("seed model c");
        let models = vec![a, b, c];
        let model_bytes = models.iter().map(write_model).collect();
        let m = &models[0];
        let mut shape = vec![0.0; m.landmarks() * 2];
        m.image_shape(&m.base_params(), &mut shape)
            .expect("seed shape");
        let pts = vec![write_pts(&shape)];
        let asf = {
            let mut s = format!("# seed\n{}\n", shape.len() / 2);
            for (i, p) in shape.chunks_exact(2).enumerate() {
                s.push_str(&format!("0 0 {} {} {i} 0 0\n", p[0] / 64.0, p[1] / 64.0));
            }
            vec![s]
        };
        let mut p = m.base_params();
        p.shape.iter_mut().for_each(|v| *v = 1.5);
        p.appearance.iter_mut().for_each(|v| *v = -0.5);
        let params = vec![
            serde_json::to_string(&m.base_params()).unwrap(),
            serde_json::to_string(&p).unwrap(),
        ];
        Seeds {
            models,
            model_bytes,
            pts,
            asf,
            params,
            image: synthetic::texture(64, 0.7, 0.0, [32.0, 32.0]),
        }
    }
}

impl Default for Seeds {
    fn default() -> Self {
        Seeds::new()
    }
}

// ------------------------------------------------------------------------------------------
// Mutations.

const HEADER_LEN: usize = facemimic::format::HEADER_LEN;

fn set_u32(b: &mut [u8], off: usize, v: u32) {
    if off + 4 <= b.len() {
        b[off..off + 4].copy_from_slice(&v.to_le_bytes());
    }
}

/// Rewrites the stored file length and the trailing CRC so that they are not what rejects the
/// file (structure-aware mutations reach the validation behind them).
pub fn repair(b: &mut [u8]) {
    if b.len() >= HEADER_LEN + 4 {
        let len = b.len() as u64;
        let off = facemimic::format::offsets::FILE_LENGTH;
        b[off..off + 8].copy_from_slice(&len.to_le_bytes());
        let body = b.len() - 4;
        let c = facemimic::format::crc32(&b[..body]);
        b[body..].copy_from_slice(&c.to_le_bytes());
    }
}

/// Mutates model bytes: one to four stacked mutations, then (usually) the checksum repaired.
pub fn mutate_model(rng: &mut Rng, seeds: &Seeds) -> Vec<u8> {
    let mut b = seeds.model_bytes[rng.below(seeds.model_bytes.len())].clone();
    let structural = !rng.chance(5);
    for _ in 0..1 + rng.below(4) {
        let len = b.len();
        match rng.below(9) {
            // Bit flip.
            0 => {
                let i = rng.below(len);
                b[i] ^= 1 << rng.below(8);
            }
            // Header field set to an interesting integer.
            1 => {
                let off = 8 + 4 * rng.below((HEADER_LEN - 8) / 4);
                set_u32(&mut b, off, INTS[rng.below(INTS.len())]);
            }
            // Header float (origin, pose) or any f32 in the arrays set to an interesting value.
            2 | 3 => {
                let off = if rng.chance(2) {
                    [
                        facemimic::format::offsets::ORIGIN_X,
                        facemimic::format::offsets::ORIGIN_Y,
                        facemimic::format::offsets::POSE,
                        facemimic::format::offsets::POSE + 4,
                        facemimic::format::offsets::POSE + 8,
                        facemimic::format::offsets::POSE + 12,
                    ][rng.below(6)]
                } else {
                    HEADER_LEN + 4 * rng.below((len.saturating_sub(HEADER_LEN + 4)) / 4)
                };
                set_u32(&mut b, off, float(rng).to_bits());
            }
            // Scale a run of f32 values (keeps orthonormality broken or not, values big).
            4 => {
                let start = HEADER_LEN + 4 * rng.below((len.saturating_sub(HEADER_LEN + 4)) / 4);
                let k = float(rng);
                for off in (start..len.saturating_sub(4))
                    .step_by(4)
                    .take(1 + rng.below(64))
                {
                    let v = f32::from_le_bytes(b[off..off + 4].try_into().unwrap());
                    set_u32(&mut b, off, (v * k).to_bits());
                }
            }
            // Truncate.
            5 => b.truncate(rng.below(len + 1)),
            // Extend with junk.
            6 => {
                for _ in 0..1 + rng.below(64) {
                    b.push(rng.next_u64() as u8);
                }
            }
            // Splice with another seed.
            7 => {
                let other = &seeds.model_bytes[rng.below(seeds.model_bytes.len())];
                let at = rng.below(len.min(other.len()));
                let n = rng.below(other.len() - at);
                if at + n <= b.len() {
                    b[at..at + n].copy_from_slice(&other[at..at + n]);
                }
            }
            // Random byte.
            _ => {
                let i = rng.below(len);
                b[i] = rng.next_u64() as u8;
            }
        }
        if b.is_empty() {
            break;
        }
    }
    if structural {
        repair(&mut b);
    }
    b
}

/// Mutates a text (landmark file or JSON): numeric tokens replaced by interesting numbers,
/// characters flipped, lines duplicated or dropped, splices.
pub fn mutate_text(rng: &mut Rng, seed: &str) -> String {
    let mut s: Vec<u8> = seed.as_bytes().to_vec();
    for _ in 0..1 + rng.below(3) {
        match rng.below(6) {
            0 | 1 => {
                // Replace the k-th numeric token.
                let text = String::from_utf8_lossy(&s).into_owned();
                let starts: Vec<usize> = text
                    .char_indices()
                    .filter(|&(i, c)| {
                        (c.is_ascii_digit() || c == '-')
                            && (i == 0 || !text.as_bytes()[i - 1].is_ascii_alphanumeric())
                    })
                    .map(|(i, _)| i)
                    .collect();
                if let Some(&st) = starts.get(rng.below(starts.len())) {
                    let end = text[st..]
                        .find(|c: char| {
                            !(c.is_ascii_alphanumeric() || c == '.' || c == '-' || c == '+')
                        })
                        .map_or(text.len(), |e| st + e);
                    let v = float(rng);
                    let rep = match rng.below(4) {
                        0 => format!("{}", INTS[rng.below(INTS.len())]),
                        1 => format!("{v:e}"),
                        2 => ["NaN", "inf", "-inf", "1e99999", "0x10", ""][rng.below(6)].into(),
                        _ => format!("{v}"),
                    };
                    s = format!("{}{}{}", &text[..st], rep, &text[end..]).into_bytes();
                }
            }
            2 => {
                if !s.is_empty() {
                    let i = rng.below(s.len());
                    s[i] = b" \n{}:,.-0123456789e\"[]nN"[rng.below(24)];
                }
            }
            3 => {
                // Duplicate or drop a line.
                let text = String::from_utf8_lossy(&s).into_owned();
                let mut lines: Vec<&str> = text.lines().collect();
                if !lines.is_empty() {
                    let i = rng.below(lines.len());
                    if rng.chance(2) {
                        lines.insert(i, lines[i]);
                    } else {
                        lines.remove(i);
                    }
                }
                s = lines.join("\n").into_bytes();
            }
            4 => {
                let n = rng.below(s.len() + 1);
                s.truncate(n);
            }
            _ => {
                // Splice: repeat a chunk.
                if !s.is_empty() {
                    let a = rng.below(s.len());
                    let n = rng.below(s.len() - a).min(256);
                    let chunk = s[a..a + n].to_vec();
                    let at = rng.below(s.len());
                    s.splice(at..at, chunk);
                }
            }
        }
    }
    String::from_utf8_lossy(&s).into_owned()
}

// ------------------------------------------------------------------------------------------
// Checks.

/// One broken promise, with the input that broke it.
#[derive(Debug, Clone)]
pub struct Failure {
    /// Which target ("model", "pts", "asf", "params").
    pub target: &'static str,
    /// What went wrong.
    pub what: String,
    /// The input.
    pub input: Vec<u8>,
}

fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn params_finite(p: &Params) -> bool {
    finite(&p.shape) && finite(&p.appearance) && finite(&[p.pose.a, p.pose.b, p.pose.tx, p.pose.ty])
}

/// The memory budget of a model load: `LOAD_BYTES_FACTOR x file bytes + LOAD_ALLOWANCE`.
pub fn load_budget(file_bytes: usize) -> u64 {
    facemimic::bounds::LOAD_BYTES_FACTOR * file_bytes as u64 + facemimic::bounds::LOAD_ALLOWANCE
}

/// Downstream operations on an accepted model; `Err(description)` on a broken promise.
fn exercise(m: &Model, rng: &mut Rng, seeds: &Seeds, track: bool) -> Result<(), String> {
    let n2 = m.landmarks() * 2;
    let mut shape = vec![0.0; n2];
    let base = m.base_params();
    let params = random_params(m, &base, rng);
    for p in [&base, &params] {
        if m.image_shape(p, &mut shape).is_ok() && !finite(&shape) {
            return Err(format!("image_shape gave non-finite landmarks for {p:?}"));
        }
    }
    // Render into a small canvas.
    let mut pixmap = facemimic::tiny_skia::Pixmap::new(48, 40).unwrap();
    if let Ok(mut r) = FaceDrawer::new(m.frame(), DrawOptions::default()) {
        let _ = r.render(m, &params, &Similarity::IDENTITY, &mut pixmap.as_mut());
        let _ = r.render(m, &base, &Similarity::IDENTITY, &mut pixmap.as_mut());
    }
    // Project the test image at the base instance's landmarks.
    if m.image_shape(&base, &mut shape).is_ok() {
        let view = seeds.image.view().map_err(|e| e.to_string())?;
        if let Ok(p) = m.project(&view, &shape) {
            if !params_finite(&p) {
                return Err(format!("project gave non-finite parameters {p:?}"));
            }
        }
    }
    exercise_clone(m, rng, [&base, &params])?;
    // The constraint itself with hostile k and sigmas.
    let mut v: Vec<f32> = (0..4).map(|_| float(rng)).collect();
    let sig: Vec<f32> = (0..4).map(|_| float(rng)).collect();
    facemimic::clone::constrain(&mut v, &sig, float(rng));
    if !finite(&v) {
        return Err(format!("constrain gave {v:?}"));
    }
    if track {
        exercise_track(m, seeds, &base, &mut shape)?;
    }
    Ok(())
}

/// Parameters for [`exercise`]: `base` with random shape and appearance parameters (the
/// interesting floats, or up to 3 sigmas) and, one time in four, an interesting pose.
fn random_params(m: &Model, base: &Params, rng: &mut Rng) -> Params {
    let mut params = base.clone();
    let sig = m.shape().sigmas();
    for (p, s) in params.shape.iter_mut().zip(&sig) {
        *p = if rng.chance(3) {
            float(rng)
        } else {
            rng.sym() * 3.0 * s
        };
    }
    let asig = m.appearance().sigmas();
    for (p, s) in params.appearance.iter_mut().zip(&asig) {
        *p = if rng.chance(3) {
            float(rng)
        } else {
            rng.sym() * 3.0 * s
        };
    }
    if rng.chance(4) {
        params.pose = Similarity {
            a: float(rng),
            b: float(rng),
            tx: float(rng),
            ty: float(rng),
        };
    }
    params
}

/// Clone options for [`exercise`]: a random method, and random (often interesting) gains,
/// clamp, pose following, region gains and style.
fn random_clone_options(rng: &mut Rng) -> CloneOptions {
    CloneOptions {
        method: Method::ALL[rng.below(Method::ALL.len())],
        gain: if rng.chance(2) { float(rng) } else { 1.0 },
        shape_gains: (0..rng.below(3)).map(|_| float(rng)).collect(),
        appearance_gains: Vec::new(),
        clamp: match rng.below(3) {
            0 => None,
            1 => Some(float(rng)),
            _ => Some(3.0),
        },
        follow_pose: rng.chance(2),
        regions: facemimic::clone::RegionGains {
            mouth: if rng.chance(2) { float(rng) } else { 1.0 },
            eyes: if rng.chance(2) { float(rng) } else { 1.0 },
            brows: 1.0,
        },
        style: if rng.chance(2) { float(rng) } else { 1.0 },
    }
}

/// [`exercise`]: clones the model onto itself from each of `params` with random options; the
/// outputs of an accepted frame must be finite.
fn exercise_clone(m: &Model, rng: &mut Rng, params: [&Params; 2]) -> Result<(), String> {
    if let Ok(mut c) = Cloner::new(m.clone()) {
        if c.add_target(m.clone()).is_ok() {
            let opts = random_clone_options(rng);
            for p in params {
                if c.clone_frame(p, &opts).is_ok()
                    && !(finite(c.target_shape(0))
                        && finite(c.target_appearance(0))
                        && params_finite(c.target_params(0)))
                {
                    return Err(format!("clone_frame gave non-finite output for {opts:?}"));
                }
            }
        }
    }
    Ok(())
}

/// [`exercise`]: tracks the test image from the base instance's landmarks (`shape` is
/// scratch); an accepted result must be finite.
fn exercise_track(
    m: &Model,
    seeds: &Seeds,
    base: &Params,
    shape: &mut [f32],
) -> Result<(), String> {
    if let Ok(mut t) = Tracker::new(m, FitOptions::default()) {
        if m.image_shape(base, shape).is_ok() && t.start_from_landmarks(shape).is_ok() {
            let view = seeds.image.view().map_err(|e| e.to_string())?;
            if let Ok(r) = t.track(&view, facemimic::fit::DEFAULT_TIME_STEP) {
                if !(finite(&r.landmarks) && params_finite(&r.params) && r.error.is_finite()) {
                    return Err("track gave a non-finite result".into());
                }
            }
        }
    }
    Ok(())
}

/// The class of an outcome (for "interesting" inputs): the error message with its numbers
/// removed, or "ok".
fn class<E: std::fmt::Display>(target: &str, r: &Result<(), E>) -> String {
    match r {
        Ok(()) => format!("{target}: ok"),
        Err(e) => {
            let s: String = e
                .to_string()
                .chars()
                .map(|c| if c.is_ascii_digit() { '#' } else { c })
                .collect();
            let mut out = String::with_capacity(s.len());
            for c in s.chars() {
                if !(c == '#' && out.ends_with('#')) {
                    out.push(c);
                }
            }
            // Coarse: up to the first quoted token (which echoes the input) and 60 characters.
            let cut = out.split(['\'', '`']).next().unwrap_or("");
            format!("{target}: {}", cut.chars().take(60).collect::<String>())
        }
    }
}

/// Statistics of a run.
#[derive(Debug, Default)]
pub struct Stats {
    /// Executions.
    pub execs: u64,
    /// Models accepted by the loader (after mutation).
    pub accepted_models: u64,
    /// Distinct outcome classes seen.
    pub classes: BTreeSet<String>,
    /// Largest load allocation as a fraction of its budget.
    pub worst_load_ratio: f64,
}

/// The fuzzer: seeds, generator, statistics.
pub struct Fuzzer {
    pub seeds: Seeds,
    pub rng: Rng,
    pub stats: Stats,
}

impl Fuzzer {
    /// A fuzzer with the given generator seed.
    pub fn new(seed: u64) -> Fuzzer {
        Fuzzer {
            seeds: Seeds::new(),
            rng: Rng::new(seed),
            stats: Stats::default(),
        }
    }

    /// One execution on a generated input; returns the new outcome class (if any) with its
    /// input, or the failure.
    pub fn step(&mut self) -> Result<Option<(String, Vec<u8>)>, Failure> {
        self.stats.execs += 1;
        let pick = self.rng.below(10);
        let (target, input): (&'static str, Vec<u8>) = match pick {
            0..=5 => ("model", mutate_model(&mut self.rng, &self.seeds)),
            6 => (
                "pts",
                mutate_text(&mut self.rng, &self.seeds.pts[0]).into_bytes(),
            ),
            7 => (
                "asf",
                mutate_text(&mut self.rng, &self.seeds.asf[0]).into_bytes(),
            ),
            _ => {
                let s = &self.seeds.params[self.rng.below(self.seeds.params.len())];
                ("params", mutate_text(&mut self.rng, s).into_bytes())
            }
        };
        let track = self.rng.chance(16);
        let class = self.run(target, &input, track)?;
        if self.stats.classes.insert(class.clone()) {
            Ok(Some((class, input)))
        } else {
            Ok(None)
        }
    }

    /// Runs one input against one target ("model", "pts", "asf", "params"), checking every
    /// promise; returns the outcome class.
    pub fn run(
        &mut self,
        target: &'static str,
        input: &[u8],
        track: bool,
    ) -> Result<String, Failure> {
        let fail = |what: String| Failure {
            target,
            what,
            input: input.to_vec(),
        };
        let seeds = &self.seeds;
        let rng = &mut self.rng;
        let stats = &mut self.stats;
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(
            || -> Result<String, String> {
                match target {
                    "model" => run_model(input, rng, seeds, stats, track),
                    "pts" | "asf" => run_landmarks(target, input, seeds),
                    _ => run_params(target, input, seeds),
                }
            },
        ));
        match outcome {
            Ok(Ok(c)) => Ok(c),
            Ok(Err(what)) => Err(fail(what)),
            Err(p) => {
                let msg = p
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| p.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                Err(fail(format!("panic: {msg}")))
            }
        }
    }
}

/// [`Fuzzer::run`] on a model file: the load within its memory budget, then, when accepted,
/// [`exercise`] within the model's budget. Returns the outcome class.
fn run_model(
    input: &[u8],
    rng: &mut Rng,
    seeds: &Seeds,
    stats: &mut Stats,
    track: bool,
) -> Result<String, String> {
    let target = "model";
    let (r, peak) = measured(|| read_model(input));
    let budget = load_budget(input.len());
    stats.worst_load_ratio = stats.worst_load_ratio.max(peak as f64 / budget as f64);
    if peak > budget {
        return Err(format!(
            "loading {} bytes allocated {peak} bytes, budget {budget}",
            input.len()
        ));
    }
    let c = class(target, &r.as_ref().map(|_| ()));
    if let Ok(m) = r {
        stats.accepted_models += 1;
        let budget = facemimic::bounds::model_budget(input.len() as u64);
        let (r, peak) = measured(|| exercise(&m, rng, seeds, track));
        r?;
        if peak > budget {
            return Err(format!(
                "operations on a {}-byte model allocated {peak} bytes, budget {budget}",
                input.len()
            ));
        }
    }
    Ok(c)
}

/// [`Fuzzer::run`] on a landmark file (`target` "pts" or "asf"): parsed landmarks must be
/// finite, and are projected when they fit the first seed model. Returns the outcome class.
fn run_landmarks(target: &'static str, input: &[u8], seeds: &Seeds) -> Result<String, String> {
    let text = String::from_utf8_lossy(input);
    let r = if target == "pts" {
        parse_pts(&text)
    } else {
        parse_asf(&text, 640, 480)
    };
    if let Ok(v) = &r {
        if !finite(v) {
            return Err(format!("{target} parser gave non-finite {v:?}"));
        }
        // Downstream: project the parsed landmarks.
        let m = &seeds.models[0];
        if v.len() == m.landmarks() * 2 {
            let view = seeds.image.view().map_err(|e| e.to_string())?;
            if let Ok(p) = m.project(&view, v) {
                if !params_finite(&p) {
                    return Err(format!("project gave non-finite {p:?}"));
                }
            }
        }
    }
    Ok(class(target, &r.map(|_| ())))
}

/// [`Fuzzer::run`] on parameters (JSON; `target` "params"): accepted ones are posed, rendered and cloned, with
/// finite results. Returns the outcome class.
fn run_params(target: &'static str, input: &[u8], seeds: &Seeds) -> Result<String, String> {
    let text = String::from_utf8_lossy(input);
    let r: Result<Params, _> = serde_json::from_str(&text);
    let m = &seeds.models[0];
    let r = r
        .map_err(|e| facemimic::Error::Params(e.to_string()))
        .and_then(|p| m.check_params(&p).map(|()| p));
    if let Ok(p) = &r {
        let mut shape = vec![0.0; m.landmarks() * 2];
        if m.image_shape(p, &mut shape).is_ok() && !finite(&shape) {
            return Err("image_shape gave non-finite landmarks".into());
        }
        let mut pixmap = facemimic::tiny_skia::Pixmap::new(32, 32).unwrap();
        let mut ren =
            FaceDrawer::new(m.frame(), DrawOptions::default()).map_err(|e| e.to_string())?;
        let _ = ren.render(m, p, &Similarity::IDENTITY, &mut pixmap.as_mut());
        let mut c = Cloner::new(m.clone()).map_err(|e| e.to_string())?;
        c.add_target(seeds.models[1].clone())
            .map_err(|e| e.to_string())?;
        let opts = CloneOptions {
            clamp: None,
            ..CloneOptions::default()
        };
        if c.clone_frame(p, &opts).is_ok()
            && !(finite(c.target_shape(0)) && finite(c.target_appearance(0)))
        {
            return Err("clone_frame gave non-finite output".into());
        }
    }
    Ok(class(target, &r.map(|_| ())))
}

/// The target a corpus file belongs to, from its name's prefix (`model-`, `pts-`, `asf-`,
/// `params-`).
pub fn target_of(name: &str) -> Option<&'static str> {
    ["model", "pts", "asf", "params"]
        .into_iter()
        .find(|t| name.starts_with(&format!("{t}-")))
}

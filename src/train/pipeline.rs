//! The enrolment pipeline: frames, with or without landmarks, to a model. One function,
//! [`enrol`], used alike by the wasm `buildModel` and the CLI's `build`, so both give the same
//! model from the same frames.
//!
//! The stages, in order:
//! 1. **landmarks**: the face finder ([`EnrolFinder`]) places them where a frame has none;
//!    frames without a face scoring at least [`EnrolOptions::min_score`] are skipped (and
//!    reported);
//! 2. **quality**: frames whose face is outside the picture, turned too far, dark, blurred or
//!    covered (a hand, a cup, hair) are rejected with their reason ([`crate::FrameQuality`],
//!    [`crate::occlusion_scores`]; [`EnrolOptions::quality`] says which frames are checked);
//!    A judged frame showing the same picture as the frame before is rejected as frozen (when
//!    half the frames are, the camera froze: an error); judged faces that split into two
//!    people (`train/consistency.rs`) are an error naming the frames of the smaller
//!    group;
//! 3. **select**: when asked, [`crate::select_varied`] keeps that many varied frames, always
//!    keeping the named reference frame;
//! 4. **build** (and **refine**): [`Builder::build_refined`];
//! 5. **backdrop**: the training frame closest to the model's mean, when asked.

use crate::error::{Error, Result};
use crate::image::Image;
use crate::model::Model;
use crate::train::consistency::{identity_split, same_picture};
use crate::train::enrol::EnrolFinder;
use crate::train::expression::{expression_coverage, ExpressionCoverage};
use crate::train::quality::{occlusion_scores, FrameProblem, FrameQuality, MAX_OCCLUSION};
use crate::train::{BuildOptions, BuildProgress, Builder, ReferenceChoice, TrainingImage};

/// Boxes the enrolment finder averages by default (each on the image and its mirror): one. On
/// webcam-dev, seven shifted and scaled boxes made models that tracked no better than one box
/// with its mirror pass, at seven times the cost (docs/experiments/fitting-notebook.md).
pub const ENROL_BOXES: usize = 1;

/// The finder's score a face needs by default: none beyond the finder's own acceptance (its
/// landmark passes must agree; no false faces on the no-face set, docs/finding.md). On
/// webcam-dev, models from every face found tracked better than from faces scoring 0.3 or 0.5.
pub const DEFAULT_MIN_SCORE: f32 = 0.0;

/// Most refinement rounds [`enrol`] accepts.
pub const MAX_REFINE_ROUNDS: usize = 3;

/// One frame offered for enrolment.
#[derive(Clone, Debug)]
pub struct EnrolFrame {
    /// Its name (a file stem, or `frame{i}`): the reference is chosen by it.
    pub name: String,
    /// The picture (RGBA).
    pub image: Image,
    /// Its 68 landmarks (image pixels, interleaved), or `None` for the face finder's.
    pub landmarks: Option<Vec<f32>>,
}

/// How [`enrol`] builds.
#[derive(Clone, Debug)]
pub struct EnrolOptions {
    /// The build's options (name, variances, frame, reference). A named reference
    /// ([`ReferenceChoice::Named`]) must be one of the frames; it survives the selection.
    pub build: BuildOptions,
    /// The finder's score (0..=1) a face needs to be used (default [`DEFAULT_MIN_SCORE`]).
    pub min_score: f32,
    /// Fewest frames with a face the build accepts (at least 2; default 2).
    pub min_frames: usize,
    /// Keep this many varied frames (at least 2); `None` keeps all.
    pub select: Option<usize>,
    /// Rounds of refinement (fit the model to its own frames and rebuild; 0..=3, default 0).
    pub refine_rounds: usize,
    /// Boxes the enrolment finder averages (default [`ENROL_BOXES`]).
    pub boxes: usize,
    /// Give the model a backdrop: the training frame closest to its mean (default true).
    pub backdrop: bool,
    /// Which frames the quality checks judge (default [`QualityScope::Found`]).
    pub quality: QualityScope,
}

/// Which frames [`enrol`]'s quality checks judge (a rejected frame is not built from and is
/// reported with its [`FrameProblem`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QualityScope {
    /// None: every frame with a face is used.
    Off,
    /// The frames whose landmarks the face finder placed (frames given with landmarks, such
    /// as a curated training set, are trusted).
    Found,
    /// Every frame with 68 landmarks (the page's frames come with the finder's landmarks).
    All,
}

/// How a front end samples frames for enrolment (the page's "Create a face" and the CLI's
/// `build --find-faces` from a video): how many it keeps and searches, and how often.
///
/// Represents policy, not limits: [`enrol`] accepts any number of frames within the bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EnrolSampling {
    /// Frames a model is built from (the most varied are selected).
    pub want: usize,
    /// Fewer usable frames than this is an error worth telling the person.
    pub min_frames: usize,
    /// Sampled frames kept in memory (pruned to the most varied beyond it).
    pub max_candidates: usize,
    /// Live sampling: the next frame is taken this long (ms) after a search ends.
    pub sample_ms: u32,
    /// Frames searched in a dropped video, evenly spaced.
    pub video_samples: usize,
}

impl EnrolSampling {
    /// The sampling the page and the CLI use.
    pub const DEFAULT: EnrolSampling = EnrolSampling {
        want: 20,
        min_frames: 8,
        max_candidates: 60,
        sample_ms: 100,
        video_samples: 120,
    };
}

impl Default for EnrolSampling {
    fn default() -> Self {
        EnrolSampling::DEFAULT
    }
}

impl Default for EnrolOptions {
    fn default() -> Self {
        EnrolOptions {
            build: BuildOptions::default(),
            min_score: DEFAULT_MIN_SCORE,
            min_frames: 2,
            select: None,
            refine_rounds: 0,
            boxes: ENROL_BOXES,
            backdrop: true,
            quality: QualityScope::Found,
        }
    }
}

/// Which stage a progress report is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnrolStage {
    /// The face finder has searched `done` of the `total` frames without landmarks.
    Landmarks,
    /// The model build (and refinement) has done `done` of its `total` steps.
    Model,
}

/// A progress report of [`enrol`].
#[derive(Clone, Copy, Debug)]
pub struct EnrolProgress<'a> {
    /// The stage.
    pub stage: EnrolStage,
    /// Steps done.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
    /// Indices of the frames skipped so far (no face found).
    pub skipped: &'a [usize],
    /// The frames rejected so far by the quality checks, each with its reason.
    pub rejected: &'a [(usize, FrameProblem)],
}

/// What [`enrol`] made.
#[derive(Debug)]
pub struct Enrolment {
    /// The model.
    pub model: Model,
    /// The frames it was built from, with their landmarks, in the order given.
    pub images: Vec<TrainingImage>,
    /// Indices (into the frames given) of the frames built from.
    pub used: Vec<usize>,
    /// Indices of the frames skipped (no face found).
    pub skipped: Vec<usize>,
    /// The frames with a face that the quality checks rejected (index, reason), by index.
    pub rejected: Vec<(usize, FrameProblem)>,
    /// The expressions the usable frames (before the selection) show.
    pub coverage: ExpressionCoverage,
}

/// Builds a model from `frames` through the pipeline's stages (see the module). `finder` is
/// used for frames without landmarks (one is made when needed and none is given); `frame_of`
/// is the model whose reference frame to build in (as [`Builder::build`]). `progress` is
/// called after each frame searched and each build step; returning `false` cancels with
/// [`Error::Cancelled`].
///
/// Fails with [`Error::Training`] naming the problem: fewer than two frames, a bad option,
/// fewer usable frames than [`EnrolOptions::min_frames`] (listing the frames without a face and
/// the frames rejected, with their reasons), a named reference that is not among the frames,
/// has no face or was rejected.
pub fn enrol(
    frames: Vec<EnrolFrame>,
    options: &EnrolOptions,
    frame_of: Option<&Model>,
    finder: Option<&mut EnrolFinder>,
    progress: &mut dyn FnMut(EnrolProgress<'_>) -> bool,
) -> Result<Enrolment> {
    check_options(options, frames.len())?;
    let reference = match &options.build.reference {
        ReferenceChoice::Named(name) => {
            Some(frames.iter().position(|f| &f.name == name).ok_or_else(|| {
                Error::Training(format!("the reference '{name}' is not among the frames"))
            })?)
        }
        _ => None,
    };
    let total = frames.len();
    let frozen = frozen_frames(&frames, options);
    if frozen.len() >= 2 && frozen.len() * 2 >= total {
        return Err(Error::Training(format!(
            "the camera seems frozen: frames {} show the same picture as the frame before",
            list_indices(&frozen)
        )));
    }
    let mut placed = place_landmarks(frames, &frozen, options, finder, progress)?;
    reject_occluded(&mut placed, options)?;
    check_one_person(&placed)?;
    let Placed {
        images,
        used,
        skipped,
        rejected,
        ..
    } = placed;
    if let Some(r) = reference {
        if skipped.contains(&r) {
            return Err(Error::Training(format!(
                "the reference, frames[{r}], has no confident face"
            )));
        }
        if let Some((_, why)) = rejected.iter().find(|(i, _)| *i == r) {
            return Err(Error::Training(format!(
                "the reference, frames[{r}], was rejected ({why})"
            )));
        }
    }
    let needed = options.min_frames.max(2);
    if images.len() < needed {
        return Err(Error::Training(format!(
            "a usable face in {} of {total} frames, at least {needed} are needed{}",
            images.len(),
            unusable(&skipped, &rejected)
        )));
    }
    // Measured before the selection, reported after the build: a shape the builder refuses
    // (non-finite points) gets the builder's own message, not the checklist's.
    let coverage = {
        let shapes: Vec<&[f32]> = images
            .iter()
            .map(|t| t.landmarks.as_slice())
            .filter(|l| l.len() == 136)
            .collect();
        expression_coverage(&shapes)
    };
    // The face most at rest among the usable frames, kept through the selection and named to
    // the builder (the varied frames chosen need not include it).
    let mut build = options.build.clone();
    let reference = match build.reference {
        ReferenceChoice::Rest => {
            let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
            let r = crate::train::expression::most_at_rest(&shapes)?;
            build.reference = ReferenceChoice::Named(images[r].name.clone());
            Some(used[r])
        }
        _ => reference,
    };
    let (images, used) = select(images, used, options.select, reference)?;
    let model = Builder::new(build).build_refined(
        &images,
        frame_of,
        options.refine_rounds,
        &mut |p: BuildProgress| {
            progress(EnrolProgress {
                stage: EnrolStage::Model,
                done: p.done,
                total: p.total,
                skipped: &skipped,
                rejected: &rejected,
            })
        },
    )?;
    let coverage = coverage?;
    let model = if options.backdrop {
        crate::train::photo::with_default_backdrop(model, &images, None)?
    } else {
        model
    };
    Ok(Enrolment {
        model,
        images,
        used,
        skipped,
        rejected,
        coverage,
    })
}

/// Repeats of one picture in a row (after its first) that make a frozen camera: a live
/// camera repeats a frame now and then (28 of webcam-dev's 120 frames sampled every 5th repeat
/// the one before, at most 2 in a row), a frozen one for seconds.
pub const FROZEN_RUN: usize = 4;

/// The judged frames (see [`QualityScope`]) in runs of at least [`FROZEN_RUN`] frames showing
/// the same picture as the frame before.
fn frozen_frames(frames: &[EnrolFrame], options: &EnrolOptions) -> Vec<usize> {
    let judged = |f: &EnrolFrame| match options.quality {
        QualityScope::Off => false,
        QualityScope::Found => f.landmarks.is_none(),
        QualityScope::All => true,
    };
    let repeat: Vec<bool> = (0..frames.len())
        .map(|i| {
            i > 0
                && judged(&frames[i])
                && matches!(
                    (frames[i - 1].image.view(), frames[i].image.view()),
                    (Ok(a), Ok(b)) if same_picture(&a, &b)
                )
        })
        .collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < repeat.len() {
        let run = repeat[i..].iter().take_while(|&&r| r).count();
        if run >= FROZEN_RUN {
            out.extend(i..i + run);
        }
        i += run.max(1);
    }
    out
}

/// Fails when the judged faces look like two people, naming the smaller group's frames.
fn check_one_person(p: &Placed) -> Result<()> {
    if !p.judged.iter().any(|&j| j) || p.images.iter().any(|t| t.landmarks.len() != 136) {
        return Ok(());
    }
    let faces: Vec<(crate::image::ImageRef, &[f32])> = p
        .images
        .iter()
        .map(|t| Ok((t.image.view()?, t.landmarks.as_slice())))
        .collect::<Result<_>>()?;
    match identity_split(&faces)? {
        None => Ok(()),
        Some(group) => {
            let frames: Vec<usize> = group.iter().map(|&k| p.used[k]).collect();
            Err(Error::Training(format!(
                "the frames show two different people: frames {} differ from the others; \
                 enrol one person at a time",
                list_indices(&frames)
            )))
        }
    }
}

/// "; no confident face in frames 1, 4; rejected: frames 2, 3 occluded, 7 turned" (empty when
/// nothing was left out).
fn unusable(skipped: &[usize], rejected: &[(usize, FrameProblem)]) -> String {
    let mut s = String::new();
    if !skipped.is_empty() {
        s += &format!("; no confident face in frames {}", list_indices(skipped));
    }
    if !rejected.is_empty() {
        let mut by: Vec<(FrameProblem, Vec<usize>)> = Vec::new();
        for &(i, p) in rejected {
            match by.iter_mut().find(|(q, _)| *q == p) {
                Some((_, v)) => v.push(i),
                None => by.push((p, vec![i])),
            }
        }
        let parts: Vec<String> = by
            .iter()
            .map(|(p, v)| format!("{} {p}", list_indices(v)))
            .collect();
        s += &format!("; rejected: frames {}", parts.join("; "));
    }
    s
}

fn check_options(o: &EnrolOptions, frames: usize) -> Result<()> {
    if frames < 2 {
        return Err(Error::Training(format!(
            "{frames} frame(s); at least 2 are needed (15-20 varied ones recommended)"
        )));
    }
    if !(0.0..=1.0).contains(&o.min_score) {
        return Err(Error::Training("the minimum score must be in 0..=1".into()));
    }
    if o.min_frames < 2 {
        return Err(Error::Training(
            "the minimum number of frames must be at least 2".into(),
        ));
    }
    if o.select.is_some_and(|n| n < 2) {
        return Err(Error::Training(
            "selecting fewer than 2 frames leaves nothing to build from".into(),
        ));
    }
    if o.refine_rounds > MAX_REFINE_ROUNDS {
        return Err(Error::Training(format!(
            "at most {MAX_REFINE_ROUNDS} rounds of refinement"
        )));
    }
    Ok(())
}

/// The frames as training images, with the finder's landmarks where none were given: the
/// images kept, their indices among the frames, the indices of the frames without a face, the
/// frames rejected by the per-frame checks (with their reasons), and for each image kept
/// whether the quality checks judge it.
struct Placed {
    images: Vec<TrainingImage>,
    used: Vec<usize>,
    skipped: Vec<usize>,
    rejected: Vec<(usize, FrameProblem)>,
    judged: Vec<bool>,
}

fn place_landmarks(
    frames: Vec<EnrolFrame>,
    frozen: &[usize],
    options: &EnrolOptions,
    finder: Option<&mut EnrolFinder>,
    progress: &mut dyn FnMut(EnrolProgress<'_>) -> bool,
) -> Result<Placed> {
    let to_find = frames
        .iter()
        .enumerate()
        .filter(|(i, f)| f.landmarks.is_none() && !frozen.contains(i))
        .count();
    // A finder of our own only when frames need one and none is given.
    let mut own = None;
    let mut finder = finder;
    if finder.is_none() && to_find > 0 {
        finder = Some(own.insert(EnrolFinder::new(options.boxes)?));
    }
    let mut p = Placed {
        images: Vec::new(),
        used: Vec::new(),
        skipped: Vec::new(),
        rejected: Vec::new(),
        judged: Vec::new(),
    };
    let mut searched = 0;
    for (i, frame) in frames.into_iter().enumerate() {
        if frozen.contains(&i) {
            p.rejected.push((i, FrameProblem::Frozen));
            continue;
        }
        let (landmarks, spread) = match frame.landmarks {
            Some(l) => (Some(l), None),
            None => {
                let Some(f) = finder.as_deref_mut() else {
                    return Err(Error::Training(
                        "no face finder for frames without landmarks".into(),
                    ));
                };
                let found = frame
                    .image
                    .view()
                    .and_then(|view| f.find(&view, options.min_score))
                    .map_err(|e| e.with_context(&format!("frames[{i}]")))?;
                searched += 1;
                match found {
                    Some(face) => (Some(face.landmarks), Some(face.spread)),
                    None => {
                        p.skipped.push(i);
                        (None, None)
                    }
                }
            }
        };
        if let Some(landmarks) = landmarks {
            let judged = match options.quality {
                QualityScope::Off => false,
                QualityScope::Found => spread.is_some(),
                QualityScope::All => true,
            } && landmarks.len() == 136;
            let problem = if judged {
                FrameQuality::measure(&frame.image.view()?, &landmarks, spread)?.problem()
            } else {
                None
            };
            match problem {
                Some(why) => p.rejected.push((i, why)),
                None => {
                    p.images.push(TrainingImage {
                        name: frame.name,
                        image: frame.image,
                        landmarks,
                    });
                    p.used.push(i);
                    p.judged.push(judged);
                }
            }
        }
        if spread.is_some() || p.skipped.last() == Some(&i) {
            let report = EnrolProgress {
                stage: EnrolStage::Landmarks,
                done: searched,
                total: to_find,
                skipped: &p.skipped,
                rejected: &p.rejected,
            };
            if !progress(report) {
                return Err(Error::Cancelled);
            }
        }
    }
    Ok(p)
}

/// Rejects (as [`FrameProblem::Occluded`]) the judged images whose face differs from the
/// others' in one region ([`occlusion_scores`] over [`MAX_OCCLUSION`]); the others' faces are
/// the reference whether judged or not.
fn reject_occluded(p: &mut Placed, options: &EnrolOptions) -> Result<()> {
    if options.quality == QualityScope::Off || !p.judged.iter().any(|&j| j) {
        return Ok(());
    }
    let faces: Vec<(crate::image::ImageRef, &[f32])> = p
        .images
        .iter()
        .filter(|t| t.landmarks.len() == 136)
        .map(|t| Ok((t.image.view()?, t.landmarks.as_slice())))
        .collect::<Result<_>>()?;
    if faces.len() != p.images.len() {
        return Ok(());
    }
    let scores = occlusion_scores(&faces)?;
    drop(faces);
    let out: Vec<bool> = scores
        .iter()
        .zip(&p.judged)
        .map(|(&s, &j)| j && s > MAX_OCCLUSION)
        .collect();
    for (k, _) in out.iter().enumerate().filter(|(_, &o)| o) {
        p.rejected.push((p.used[k], FrameProblem::Occluded));
    }
    p.rejected.sort_unstable_by_key(|r| r.0);
    let mut keep = out.iter().map(|o| !o);
    p.images.retain(|_| keep.next().unwrap_or(true));
    let mut keep = out.iter().map(|o| !o);
    p.used.retain(|_| keep.next().unwrap_or(true));
    let mut keep = out.iter().map(|o| !o);
    p.judged.retain(|_| keep.next().unwrap_or(true));
    Ok(())
}

/// `n` varied images (all when `n` is `None` or not fewer), keeping the frame `reference`;
/// in the order given.
fn select(
    images: Vec<TrainingImage>,
    used: Vec<usize>,
    n: Option<usize>,
    reference: Option<usize>,
) -> Result<(Vec<TrainingImage>, Vec<usize>)> {
    let Some(n) = n.filter(|&n| n < images.len()) else {
        return Ok((images, used));
    };
    let shapes: Vec<&[f32]> = images.iter().map(|t| t.landmarks.as_slice()).collect();
    let mut keep = crate::train::select::select_varied(&shapes, n)?;
    if let Some(r) = reference {
        let k = used.iter().position(|&i| i == r).unwrap_or(0);
        if !keep.contains(&k) {
            keep.pop();
            keep.push(k);
        }
    }
    keep.sort_unstable();
    let mut all: Vec<Option<TrainingImage>> = images.into_iter().map(Some).collect();
    let kept_used = keep.iter().map(|&k| used[k]).collect();
    Ok((
        keep.iter().filter_map(|&k| all[k].take()).collect(),
        kept_used,
    ))
}

/// "0, 3, 7" (at most 12, then "and N more").
fn list_indices(v: &[usize]) -> String {
    let mut s: Vec<String> = v.iter().take(12).map(|i| i.to_string()).collect();
    if v.len() > 12 {
        s.push(format!("and {} more", v.len() - 12));
    }
    s.join(", ")
}

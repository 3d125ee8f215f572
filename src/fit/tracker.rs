//! Tracking a face through a sequence: each frame starts from the previous result; a lost
//! face is detected, and the tracker re-initialises from the last good result or, when it has
//! a [`FaceSource`] (a face finder), from the face found nearest the last position.

use crate::error::{check_len, Error, Result};
use crate::image::ImageRef;
use crate::model::Model;
use crate::similarity::Similarity;

use super::{FitOptions, FitResult, Fitter};

/// A fit whose image contrast under the mesh is below this fraction of the template's (or
/// above its inverse) is a lost face: see [`Fitter::contrast`].
pub const MIN_CONTRAST: f32 = 0.2;

/// Where the tracker finds a face to start from or to come back to: the landmarks of the faces
/// visible in an image (image coordinates, `2n` values each, in the model's landmark layout),
/// most confident first; none when no face is visible. A closure
/// `FnMut(&ImageRef) -> Result<Vec<Vec<f32>>>` is one.
pub trait FaceSource {
    /// The faces visible in `image`.
    fn faces(&mut self, image: &ImageRef<'_>) -> Result<Vec<Vec<f32>>>;
}

impl<F> FaceSource for F
where
    F: FnMut(&ImageRef<'_>) -> Result<Vec<Vec<f32>>>,
{
    fn faces(&mut self, image: &ImageRef<'_>) -> Result<Vec<Vec<f32>>> {
        self(image)
    }
}

/// The face finder is the face source of a 68-landmark model: its faces' landmarks, most
/// confident first.
impl FaceSource for crate::find::FaceFinder {
    fn faces(&mut self, image: &ImageRef<'_>) -> Result<Vec<Vec<f32>>> {
        Ok(self.find(image).into_iter().map(|f| f.landmarks).collect())
    }
}

/// Follows one face through video frames with a [`Fitter`].
///
/// Start a sequence with [`Tracker::start_from_landmarks`] or [`Tracker::start_from_box`], then
/// call [`Tracker::track`] once per frame. A fit is judged lost when its error exceeds
/// [`FitOptions::max_error`], the shape parameters' RMS in standard deviations
/// (`sqrt(mean (p_i / sigma_i)^2)`) exceeds [`FitOptions::max_sigmas`], the scale jumps by more than [`FitOptions::max_scale_jump`] or the rotation by
/// more than 0.5 rad from the last good fit, the image contrast under the mesh is implausible
/// ([`MIN_CONTRAST`]), or the fit failed numerically. The tracker then
/// retries once from the last good result with more appearance-aware iterations; if that
/// fails too and the tracker has a [`FaceSource`] ([`Tracker::set_face_source`]), it asks the
/// source for the faces in the frame and fits from the one nearest the last good position
/// (a cold fit, judged by the same checks except the jump from the last fit). If that fails
/// too, the frame is lost: its result has `lost = true` and carries the last good fit (not a
/// face on this frame); without a source the next frame starts from the last good fit again,
/// with one it asks the source again on every frame until a face is found and fits
/// (`reacquired = true` on that frame). [`Tracker::start_auto`] starts a sequence that way,
/// from no landmarks at all.
pub struct Tracker {
    fitter: Fitter,
    /// Where the next fit starts (landmarks, image coordinates).
    start: Vec<f32>,
    /// True once a sequence has been started.
    started: bool,
    /// True when the next fit starts from a rough guess (a box) and should work harder.
    cold: bool,
    last_good: Option<FitResult>,
    last: Option<FitResult>,
    lost_count: u32,
    resets: u32,
    frames: u32,
    /// Where faces are found to start from or to come back to.
    source: Option<Box<dyn FaceSource>>,
    /// True while the next frame must be acquired from the source (auto start, or lost).
    searching: bool,
    reacquisitions: u32,
    /// Whether the previous frame was lost.
    was_lost: bool,
    /// Running mean of the good fits' errors (0 before the first).
    typical_error: f32,
    /// Size of the frame being tracked.
    frame_size: (f32, f32),
}

impl Tracker {
    /// A tracker for `model` (does the fitter's precomputation).
    pub fn new(model: &Model, options: FitOptions) -> Result<Tracker> {
        let fitter = Fitter::new(model, options)?;
        let n2 = fitter.landmarks() * 2;
        Ok(Tracker {
            fitter,
            start: vec![0.0; n2],
            started: false,
            cold: false,
            last_good: None,
            last: None,
            lost_count: 0,
            resets: 0,
            frames: 0,
            source: None,
            searching: false,
            reacquisitions: 0,
            was_lost: false,
            typical_error: 0.0,
            frame_size: (0.0, 0.0),
        })
    }

    /// The fitter (for its sizes and options).
    pub fn fitter(&self) -> &Fitter {
        &self.fitter
    }

    /// Starts a new sequence from landmarks on the next frame (image coordinates, `2n`).
    pub fn start_from_landmarks(&mut self, landmarks: &[f32]) -> Result<()> {
        check_len("landmarks", landmarks, self.start.len())?;
        crate::bounds::check_landmarks(landmarks)?;
        let pose = Similarity::align(&self.fitter.geom.s0, landmarks);
        if !(pose.is_valid() && pose.scale() > 1e-4) {
            return Err(Error::Params(
                "landmarks are degenerate (all points coincide)".into(),
            ));
        }
        self.start.copy_from_slice(landmarks);
        self.begin(false);
        Ok(())
    }

    /// Starts a new sequence from a face box (image coordinates: left, top, width, height):
    /// the base shape is scaled to the box's width and centred in it.
    pub fn start_from_box(&mut self, x: f32, y: f32, w: f32, h: f32) -> Result<()> {
        crate::bounds::check_param_values("box", &[x, y, w, h])?;
        if !(w >= 4.0 && h >= 4.0) {
            return Err(Error::Params(format!(
                "box {w}x{h} is too small (at least 4x4)"
            )));
        }
        let s0 = &self.fitter.geom.s0;
        let (mut minx, mut miny, mut maxx, mut maxy) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for p in s0.chunks_exact(2) {
            minx = minx.min(p[0]);
            maxx = maxx.max(p[0]);
            miny = miny.min(p[1]);
            maxy = maxy.max(p[1]);
        }
        let scale = (w / (maxx - minx).max(1e-6)).min(h / (maxy - miny).max(1e-6));
        let (cx, cy) = (0.5 * (minx + maxx), 0.5 * (miny + maxy));
        let pose = Similarity {
            a: scale,
            b: 0.0,
            tx: x + 0.5 * w - scale * cx,
            ty: y + 0.5 * h - scale * cy,
        };
        pose.apply(s0, &mut self.start);
        self.begin(true);
        Ok(())
    }

    fn begin(&mut self, cold: bool) {
        self.started = true;
        self.cold = cold;
        self.searching = false;
        self.was_lost = false;
        self.typical_error = 0.0;
        self.last_good = None;
        self.last = None;
    }

    /// Gives the tracker a source of faces (a face finder): it is asked when a face is lost
    /// and by [`Tracker::start_auto`]. Replaces any previous source.
    pub fn set_face_source(&mut self, source: Box<dyn FaceSource>) {
        self.source = Some(source);
    }

    /// Whether the tracker has a face source.
    pub fn has_face_source(&self) -> bool {
        self.source.is_some()
    }

    /// Starts a new sequence with no landmarks: each frame asks the face source until a face
    /// is found and fits; until then frames are reported lost. Fails with [`Error::Params`]
    /// without a source ([`Tracker::set_face_source`]).
    pub fn start_auto(&mut self) -> Result<()> {
        if self.source.is_none() {
            return Err(Error::Params(
                "the tracker has no face source to start from: set one first".into(),
            ));
        }
        self.begin(false);
        self.searching = true;
        Ok(())
    }

    /// Asks the source for the faces in `frame` and fits from the one nearest the last good
    /// position (or the most confident one). Returns whether the fit is plausible (then it is
    /// the fitter's result).
    fn acquire(&mut self, frame: &ImageRef<'_>) -> Result<bool> {
        let Some(source) = self.source.as_mut() else {
            return Ok(false);
        };
        let faces = source.faces(frame)?;
        for f in &faces {
            check_len("found face landmarks", f, self.start.len())?;
        }
        let centre = |s: &[f32]| {
            let n = (s.len() / 2).max(1) as f32;
            (
                s.iter().step_by(2).sum::<f32>() / n,
                s.iter().skip(1).step_by(2).sum::<f32>() / n,
            )
        };
        let near = self.last_good.as_ref().map(|g| centre(&g.landmarks));
        let best = faces
            .iter()
            .filter(|f| f.iter().all(|v| v.is_finite()))
            .min_by(|a, b| {
                let d = |s: &[f32]| match near {
                    Some((x, y)) => {
                        let (cx, cy) = centre(s);
                        (cx - x).powi(2) + (cy - y).powi(2)
                    }
                    None => 0.0,
                };
                d(a).total_cmp(&d(b))
            });
        let Some(face) = best else {
            return Ok(false);
        };
        let opts = self.fitter.options();
        let cold_iters = (opts.max_iters.max(10) * 3, opts.refine_iters.max(3) * 3);
        let starts = opts.coarse_starts;
        match self.fitter.fit_with(frame, face, Some(cold_iters), starts) {
            Ok(_) => Ok(self.plausible(self.fitter.result(), false)),
            // A degenerate found face is no face.
            Err(Error::Params(_)) => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// Fits the next frame, starting from the previous result (or the sequence's start).
    ///
    /// Fails with [`Error::Params`] if no sequence was started. The result's `lost` flag says
    /// whether the face was lost on this frame (then the result is the last good fit).
    pub fn track(&mut self, frame: &ImageRef<'_>) -> Result<&FitResult> {
        if !self.started {
            return Err(Error::Params(
                "the tracker has no start: call start_from_landmarks or start_from_box".into(),
            ));
        }
        self.frames += 1;
        self.frame_size = (frame.width() as f32, frame.height() as f32);
        let mut reacquired = false;
        let ok = if self.searching {
            reacquired = self.acquire(frame)?;
            reacquired
        } else {
            let opts = self.fitter.options().clone();
            let cold_iters = (opts.max_iters.max(10) * 3, opts.refine_iters.max(3) * 3);
            let first = if self.cold { Some(cold_iters) } else { None };
            let start = std::mem::take(&mut self.start);
            let starts = if first.is_some() {
                opts.coarse_starts
            } else {
                opts.tracking_starts
            };
            let r = self
                .fitter
                .fit_with(frame, &start, first, starts)
                .map(|_| ());
            self.start = start;
            r?;
            let mut ok = self.plausible(self.fitter.result(), true);
            if !ok && self.last_good.is_some() {
                self.resets += 1;
                // Retry from the last good fit, working harder (more appearance-aware steps).
                let from = self
                    .last_good
                    .as_ref()
                    .map(|g| g.landmarks.clone())
                    .unwrap_or_default();
                self.fitter
                    .fit_with(frame, &from, Some(cold_iters), opts.coarse_starts)?;
                ok = self.plausible(self.fitter.result(), true);
            }
            if !ok && self.source.is_some() {
                reacquired = self.acquire(frame)?;
                ok = reacquired;
            }
            ok
        };
        let result = if ok {
            self.cold = false;
            self.searching = false;
            let mut r = self.fitter.result().clone();
            // A face found again after lost frames (or the first face of an auto start).
            r.reacquired = reacquired && (self.was_lost || self.last_good.is_none());
            if r.reacquired {
                self.reacquisitions += 1;
            }
            // A slow running mean, restarted by a (re-)acquisition.
            self.typical_error = if self.typical_error > 0.0 && !r.reacquired {
                0.95 * self.typical_error + 0.05 * r.error
            } else {
                r.error
            };
            self.last_good = Some(r.clone());
            self.start.copy_from_slice(&r.landmarks);
            r
        } else {
            self.lost_count += 1;
            self.searching = self.source.is_some();
            match &self.last_good {
                Some(g) => {
                    self.start.copy_from_slice(&g.landmarks);
                    let mut r = g.clone();
                    r.lost = true;
                    r.converged = false;
                    r.reacquired = false;
                    r
                }
                None => {
                    // Nothing good yet (a bad box, or no face found): report the attempt.
                    let mut r = self.fitter.result().clone();
                    r.lost = true;
                    r.reacquired = false;
                    r
                }
            }
        };
        self.was_lost = result.lost;
        self.last = Some(result);
        Ok(self.last.as_ref().expect("just set"))
    }

    /// Whether a fit is plausible (see the type's documentation); `jump` also checks the
    /// change of scale and rotation from the last good fit.
    fn plausible(&self, r: &FitResult, jump: bool) -> bool {
        let o = self.fitter.options();
        if !r.error.is_finite() || r.error > o.max_error {
            return false;
        }
        if !r.landmarks.iter().all(|v| v.is_finite()) || !r.params.pose.is_valid() {
            return false;
        }
        let (w, h) = self.frame_size;
        let n = (r.landmarks.len() / 2).max(1) as f32;
        let inside = r
            .landmarks
            .chunks_exact(2)
            .filter(|p| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w - 1.0 && p[1] <= h - 1.0)
            .count() as f32;
        if inside < o.min_inside * n {
            return false;
        }
        if jump
            && o.max_error_ratio > 0.0
            && self.typical_error > 0.0
            && r.error > o.max_error_ratio * self.typical_error
        {
            return false;
        }
        let c = self.fitter.contrast();
        if !(MIN_CONTRAST..=1.0 / MIN_CONTRAST).contains(&c) {
            return false;
        }
        let sig = self.fitter.shape_sigmas();
        let m = sig.len().max(1) as f32;
        let z2: f32 = r
            .params
            .shape
            .iter()
            .zip(sig)
            .map(|(p, s)| (p / s.max(1e-12)).powi(2))
            .sum();
        if !((z2 / m).sqrt() <= o.max_sigmas) {
            return false;
        }
        if let Some(g) = self.last_good.as_ref().filter(|_| jump) {
            let (s0, s1) = (g.params.pose.scale(), r.params.pose.scale());
            if !((s1 - s0).abs() <= o.max_scale_jump * s0) {
                return false;
            }
            let dr = (r.params.pose.rotation() - g.params.pose.rotation()).abs();
            let dr = dr.min(2.0 * std::f32::consts::PI - dr);
            if dr > 0.5 {
                return false;
            }
        }
        true
    }

    /// The last frame's result.
    pub fn last(&self) -> Option<&FitResult> {
        self.last.as_ref()
    }

    /// The last fit judged good.
    pub fn last_good(&self) -> Option<&FitResult> {
        self.last_good.as_ref()
    }

    /// Frames reported lost (`lost = true`: even the retry from the last good fit failed).
    pub fn lost_count(&self) -> u32 {
        self.lost_count
    }

    /// Re-initialisations: frames whose fit was judged implausible, so that the tracker
    /// re-initialised from the last good result and fitted again.
    pub fn resets(&self) -> u32 {
        self.resets
    }

    /// Faces acquired from the face source: the first face of an auto start and every face
    /// found again after lost frames.
    pub fn reacquisitions(&self) -> u32 {
        self.reacquisitions
    }

    /// Frames tracked since the tracker was made.
    pub fn frames(&self) -> u32 {
        self.frames
    }
}

impl std::fmt::Debug for Tracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracker")
            .field("fitter", &self.fitter)
            .finish_non_exhaustive()
    }
}

//! `facemimic fit`: track a model through a sequence of frames, write a CSV track.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use facemimic::fit::{
    FaceTracker, FitOptions, FitResult, FollowOptions, Follower, TrackStatus, Tracker, TrackerKind,
};
use facemimic::{io, Error, Image, Model, Result, Similarity};

/// How the source face is followed (`--follow`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Follow {
    /// Fit the model's AAM to each frame: for a model of the person in the frames (their own,
    /// built from their frames or enrolled), the closest match.
    Aam,
    /// The person-independent path, for anyone with a model that is not theirs (a bundled
    /// person's): the face finder's landmarks on every frame, smoothed, read as expression
    /// relative to the person's own running neutral shape and mapped onto the model's shape
    /// modes; the appearance stays at the model's mean. In the CSV, `error` is then the
    /// disagreement of the frame's two landmark passes (eye distances), `iterations` the
    /// landmark passes run near the last face, `converged` true on a face.
    Landmarks,
}

#[derive(clap::Args)]
pub struct Args {
    /// The model to fit (.fmm).
    #[arg(long, value_name = "M.fmm")]
    model: PathBuf,
    /// Landmarks (.pts or .asf) of the face in the first frame: the tracking starts there.
    /// `auto`: start from the face finder's face (68-landmark models), and find the face
    /// again with it whenever it is lost. Needed with `--follow aam`; with `--follow
    /// landmarks` optional (the finder starts; landmarks given choose the face).
    #[arg(long, value_name = "INIT.pts|auto")]
    init: Option<PathBuf>,
    /// `aam` (default): fit the model, for a person's own model. `landmarks`: follow anyone
    /// with a model that is not theirs (see docs/fitting.md, "Following anyone").
    #[arg(long, value_enum, default_value_t = Follow::Aam)]
    follow: Follow,
    /// Frames per second of the sequence: the time step of the pose anchor (the CSV's
    /// `placed_*` columns) and, with `--follow landmarks`, of the smoothing.
    #[arg(long, value_name = "FPS", default_value_t = 25.0)]
    fps: f32,
    /// Most project-out iterations per level and frame.
    #[arg(long, value_name = "N")]
    max_iters: Option<u32>,
    /// Appearance-aware refinement iterations per frame.
    #[arg(long, value_name = "N")]
    refine_iters: Option<u32>,
    /// Where to write the track (CSV).
    #[arg(long, value_name = "TRACK.csv")]
    out: PathBuf,
    /// Where to write each frame's status (CSV `frame,status,reasons`): "tracking", "unsure"
    /// (the tracker's confidence checks doubt the fit: collapsed, folded, slid off the
    /// finder's face, an unlikely shape, a residual or pose jump; reasons separated by `;`)
    /// or "lost".
    #[arg(long, value_name = "STATUS.csv")]
    status_out: Option<PathBuf>,
    /// The frames (PNG or JPEG), fitted in the order given.
    #[arg(value_name = "FRAME", required = true)]
    frames: Vec<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let model = io::read_model_file(&a.model)?;
    let mut options = FitOptions::default();
    if let Some(n) = a.max_iters {
        if !(1..=1000).contains(&n) {
            return Err(Error::Params(format!("--max-iters {n} not in 1..=1000")));
        }
        options.max_iters = n;
    }
    if let Some(n) = a.refine_iters {
        options.refine_iters = n;
    }
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 1000.0) {
        return Err(Error::Params(format!("--fps {} not in (0, 1000]", a.fps)));
    }
    // Decode everything first: the timing covers fitting only.
    let images = a
        .frames
        .iter()
        .map(|p| io::read_image(p))
        .collect::<Result<Vec<_>>>()?;
    // One loop for either kind of tracker. Frames go in at their size: the AAM tracker chooses
    // the fit scale for the face's size (large faces are fitted in a smaller copy of the frame,
    // at about the size the model was built at) and both report in the frame's pixels, as they
    // do for the page and the npm package.
    let mut tracker: Box<dyn FaceTracker> = match a.follow {
        Follow::Aam => Box::new(Tracker::new(&model, options)?),
        Follow::Landmarks => Box::new(Follower::new(&model, FollowOptions::default())?),
    };
    start(&a, &model, &images[0], tracker.as_mut())?;
    let dt = 1.0 / a.fps;
    let mut results = Vec::with_capacity(images.len());
    let t0 = Instant::now();
    for (img, path) in images.iter().zip(&a.frames) {
        let context = |e: Error| e.with_context(&path.display().to_string());
        let r = tracker.track(&img.view()?, dt).map_err(context)?;
        results.push((r.clone(), tracker.sequence().placed()));
    }
    let secs = t0.elapsed().as_secs_f64();
    write_csv(&a, &model, &results)?;
    if let Some(path) = &a.status_out {
        write_status(path, &a.frames, &results)?;
    }
    crate::print_line(&summary(&a, tracker.as_ref(), &results, secs))
}

/// Starts `tracker` on the first frame: the AAM from `--init` landmarks or, with `auto`, from
/// the face finder's face (68-landmark models; it finds the face again whenever it is lost);
/// the landmark follower from its own finder, offered the `--init` face when one is given.
fn start(a: &Args, model: &Model, first: &Image, tracker: &mut dyn FaceTracker) -> Result<()> {
    let init = a.init.as_ref().filter(|p| p.as_os_str() != "auto");
    match (tracker.kind(), init) {
        (TrackerKind::Aam, None) if a.init.is_none() => Err(Error::Params(
            "--init INIT.pts|auto is needed to fit the AAM (or follow anyone with --follow \
             landmarks)"
                .into(),
        )),
        (TrackerKind::Aam, None) if model.landmarks() != 68 => Err(Error::Params(format!(
            "--init auto needs a 68-landmark model (the face finder's layout); this one has {}",
            model.landmarks()
        ))),
        (TrackerKind::Aam, None) => tracker.start_auto(),
        (kind, Some(path)) => {
            let points = io::read_landmarks(path, first.width, first.height)?;
            let context = |e: Error| e.with_context(&path.display().to_string());
            match kind {
                TrackerKind::Aam => tracker.start_from_landmarks(&points).map_err(context),
                TrackerKind::Landmarks => tracker.offer_faces(vec![points]).map_err(context),
            }
        }
        (TrackerKind::Landmarks, None) => Ok(()),
    }
}

/// The line `fit` prints: frames, speed and the tracker's counters.
fn summary(
    a: &Args,
    tracker: &dyn FaceTracker,
    results: &[(FitResult, Similarity)],
    secs: f64,
) -> String {
    let frames = results.len();
    let (rate, ms) = (
        frames as f64 / secs.max(1e-9),
        1e3 * secs / frames.max(1) as f64,
    );
    let seq = tracker.sequence();
    let unsure = results
        .iter()
        .filter(|r| r.0.status == TrackStatus::Unsure)
        .count();
    if tracker.kind() == TrackerKind::Landmarks {
        return format!(
            "facemimic fit: {frames} frames followed by landmarks, {rate:.1} frames/s ({ms:.3} ms \
             per frame), {} lost, {} acquisitions -> {}",
            seq.lost_count(),
            seq.reacquisitions(),
            a.out.display()
        );
    }
    let iters = results.iter().map(|r| r.0.iterations as f64).sum::<f64>() / frames.max(1) as f64;
    let converged = results.iter().filter(|r| r.0.converged).count();
    let (rechecks, kept) = tracker.rechecks();
    format!(
        "facemimic fit: {frames} frames, {converged} converged, mean {iters:.2} iterations, \
         {rate:.1} fits/s ({ms:.3} ms per fit), {} re-initialisations, {unsure} unsure, {} lost, \
         {} re-acquisitions, {rechecks} second opinions ({kept} kept), fit scale {:.3} -> {}",
        tracker.resets(),
        seq.lost_count(),
        seq.reacquisitions(),
        tracker.scale(),
        a.out.display()
    )
}

/// Writes the track CSV: one row per frame (name, lost, converged, iterations, error, the
/// landmarks, the pose, `p`, `lambda`, and the placement: the pose re-centred on the model's
/// mean pose about the sequence's anchor, [`facemimic::fit::Sequence::placed`]).
fn write_csv(a: &Args, model: &Model, results: &[(FitResult, Similarity)]) -> Result<()> {
    let n = model.landmarks();
    let mut csv = String::from("frame,lost,converged,iterations,error");
    for i in 0..n {
        let _ = write!(csv, ",x{i},y{i}");
    }
    csv.push_str(",scale,rotation,tx,ty");
    for i in 0..model.shape().n_modes() {
        let _ = write!(csv, ",p{i}");
    }
    for i in 0..model.appearance().n_modes() {
        let _ = write!(csv, ",lambda{i}");
    }
    csv.push_str(",placed_scale,placed_rotation,placed_tx,placed_ty\n");
    for ((r, placed), path) in results.iter().zip(&a.frames) {
        let name = path
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let name = if name.contains([',', '"', '\n']) {
            format!("\"{}\"", name.replace('"', "\"\""))
        } else {
            name
        };
        let _ = write!(
            csv,
            "{name},{},{},{},{}",
            r.lost, r.converged, r.iterations, r.error
        );
        for v in &r.landmarks {
            let _ = write!(csv, ",{v}");
        }
        let pose = r.params.pose;
        let _ = write!(
            csv,
            ",{},{},{},{}",
            pose.scale(),
            pose.rotation(),
            pose.tx,
            pose.ty
        );
        for v in r.params.shape.iter().chain(&r.params.appearance) {
            let _ = write!(csv, ",{v}");
        }
        let _ = writeln!(
            csv,
            ",{},{},{},{}",
            placed.scale(),
            placed.rotation(),
            placed.tx,
            placed.ty
        );
    }
    std::fs::write(&a.out, csv).map_err(|e| Error::Io(format!("{}: {e}", a.out.display())))
}

/// Writes each frame's status (`frame,status,reasons`; reasons separated by `;`).
fn write_status(
    path: &std::path::Path,
    frames: &[PathBuf],
    results: &[(FitResult, Similarity)],
) -> Result<()> {
    let mut csv = String::from("frame,status,reasons\n");
    for ((r, _), p) in results.iter().zip(frames) {
        let name = p
            .file_name()
            .map(|s| s.to_string_lossy().replace([',', '"', '\n'], "_"))
            .unwrap_or_default();
        let reasons: Vec<&str> = r.reasons.names().collect();
        let _ = writeln!(csv, "{name},{},{}", r.status, reasons.join(";"));
    }
    std::fs::write(path, csv).map_err(|e| Error::Io(format!("{}: {e}", path.display())))
}

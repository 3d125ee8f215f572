//! `facemimic fit`: track a model through a sequence of frames, write a CSV track.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use facemimic::fit::{FitOptions, Tracker};
use facemimic::{io, Error, FaceFinder, Result};

#[derive(clap::Args)]
pub struct Args {
    /// The model to fit (.fmm).
    #[arg(long, value_name = "M.fmm")]
    model: PathBuf,
    /// Landmarks (.pts or .asf) of the face in the first frame: the tracking starts there.
    /// `auto`: start from the face finder's face (68-landmark models), and find the face
    /// again with it whenever it is lost.
    #[arg(long, value_name = "INIT.pts|auto")]
    init: PathBuf,
    /// Most project-out iterations per level and frame.
    #[arg(long, value_name = "N")]
    max_iters: Option<u32>,
    /// Appearance-aware refinement iterations per frame.
    #[arg(long, value_name = "N")]
    refine_iters: Option<u32>,
    /// Where to write the track (CSV).
    #[arg(long, value_name = "TRACK.csv")]
    out: PathBuf,
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
    // Decode everything first: the timing covers fitting only.
    let images = a
        .frames
        .iter()
        .map(|p| io::read_image(p))
        .collect::<Result<Vec<_>>>()?;
    let first = &images[0];
    let mut tracker = Tracker::new(&model, options)?;
    if a.init.as_os_str() == "auto" {
        if model.landmarks() != 68 {
            return Err(Error::Params(format!(
                "--init auto needs a 68-landmark model (the face finder's layout); this one has {}",
                model.landmarks()
            )));
        }
        tracker.set_face_source(Box::new(FaceFinder::new()?));
        tracker.start_auto()?;
    } else {
        let init = io::read_landmarks(&a.init, first.width, first.height)?;
        tracker
            .start_from_landmarks(&init)
            .map_err(|e| e.with_context(&a.init.display().to_string()))?;
    }

    let mut results = Vec::with_capacity(images.len());
    let t0 = Instant::now();
    for (img, path) in images.iter().zip(&a.frames) {
        let r = tracker
            .track(&img.view()?)
            .map_err(|e| e.with_context(&path.display().to_string()))?;
        results.push(r.clone());
    }
    let secs = t0.elapsed().as_secs_f64();

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
    csv.push('\n');
    for (r, path) in results.iter().zip(&a.frames) {
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
        csv.push('\n');
    }
    std::fs::write(&a.out, csv).map_err(|e| Error::Io(format!("{}: {e}", a.out.display())))?;

    let frames = results.len();
    let iters = results.iter().map(|r| r.iterations as f64).sum::<f64>() / frames.max(1) as f64;
    let converged = results.iter().filter(|r| r.converged).count();
    crate::print_line(&format!(
        "facemimic fit: {frames} frames, {converged} converged, mean {iters:.2} iterations, \
         {:.1} fits/s ({:.3} ms per fit), {} re-initialisations, {} lost, {} re-acquisitions -> {}",
        frames as f64 / secs.max(1e-9),
        1e3 * secs / frames.max(1) as f64,
        tracker.resets(),
        tracker.lost_count(),
        tracker.reacquisitions(),
        a.out.display()
    ))
}

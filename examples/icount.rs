//! A fixed amount of work for counting instructions, the load-independent way to compare the
//! speed of two commits on a shared machine (valgrind's callgrind counts the instructions a run
//! executes; a timing moves with whatever else the machine runs). `scripts/icount.sh BEFORE
//! [AFTER]` builds this example at both commits and prints the instructions per iteration.
//!
//! `cargo run --release --example icount -- WORK N`, WORK one of:
//! - `clone`: `Cloner::clone_frame`, spk07 -> spk02 (map + residual), frame 17 of spk07's unseen
//!   GRID clip;
//! - `render`: the renderer's (tiny-skia) upload and piecewise-affine warp of that target onto
//!   360x288; `scanline`: the same with the scanline rasteriser;
//! - `track`: spk07's model tracking its unseen GRID clip (75 frames, looped), per frame;
//! - `find`: `FaceFinder::find` on frame 4 of that clip centred on a black 640x480 frame.
//!
//! Models from the committed GRID frames (`data/grid/*/train20.txt`).
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::clone::{CloneOptions, Cloner, Method};
    use facemimic::fit::FaceTracker;
    use facemimic::fit::{FitOptions, Tracker};
    use facemimic::{
        io, Builder, FaceFinder, Image, Model, Renderer, Scanline, Similarity, TrainingImage,
    };
    use std::hint::black_box;
    use std::path::{Path, PathBuf};

    fn grid(rel: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data/grid")
            .join(rel)
    }

    /// The model of a GRID clip's 20 training frames, in `frame_of`'s frame.
    fn model(folder: &str, frame_of: Option<&Model>) -> Model {
        let list = io::read_list(&grid(folder).join("train20.txt")).expect("GRID training list");
        let images: Vec<TrainingImage> = list
            .iter()
            .map(|p| io::read_training_image(p).expect("GRID frame"))
            .collect();
        Builder::default()
            .build(&images, frame_of)
            .expect("GRID model")
    }

    /// The frames of spk07's unseen GRID clip (none in its training list).
    fn clip() -> Vec<TrainingImage> {
        let mut paths: Vec<PathBuf> =
            io::annotated_images(&grid("spk07_id2_vcd_swwp2s")).expect("clip");
        paths.sort();
        paths
            .iter()
            .map(|p| io::read_training_image(p).expect("clip frame"))
            .collect()
    }

    /// `what`, `n` times, after its set-up.
    fn run(what: &str, n: usize) -> Result<f64, String> {
        let mut sink = 0.0f64;
        match what {
            "clone" | "render" | "scanline" => {
                let source = model("spk07_pwij3p", None);
                let target = model("spk02_brbk7n", Some(&source));
                let frame = &clip()[17];
                let params = source
                    .project(&frame.image.view().expect("view"), &frame.landmarks)
                    .expect("projection");
                let mut cloner = Cloner::new(source).expect("cloner");
                cloner.add_target(target.clone()).expect("target");
                let options = CloneOptions {
                    method: Method::MapResidual,
                    ..CloneOptions::default()
                };
                cloner.clone_frame(&params, &options).expect("clone");
                if what == "clone" {
                    for _ in 0..n {
                        cloner
                            .clone_frame(black_box(&params), &options)
                            .expect("clone");
                    }
                    sink += cloner.target_shape(0)[0] as f64;
                } else {
                    let frame = target.frame().clone();
                    let mut pixmap = facemimic::tiny_skia::Pixmap::new(360, 288).expect("pixmap");
                    // The same two calls on either rasteriser (two types at older commits).
                    macro_rules! upload_and_warp {
                        ($r:expr) => {
                            for _ in 0..n {
                                $r.upload(&frame, cloner.target_appearance(0))
                                    .expect("upload");
                                $r.warp(
                                    &frame,
                                    black_box(cloner.target_shape(0)),
                                    &Similarity::IDENTITY,
                                    &mut pixmap.as_mut(),
                                )
                                .expect("warp");
                            }
                        };
                    }
                    if what == "scanline" {
                        let mut scanline = Scanline::new();
                        upload_and_warp!(scanline);
                    } else {
                        let mut renderer = Renderer::new(&frame).expect("renderer");
                        upload_and_warp!(renderer);
                    }
                    sink += pixmap.data().iter().map(|&b| b as f64).sum::<f64>();
                }
            }
            "track" => {
                let source = model("spk07_pwij3p", None);
                let frames = clip();
                let mut tracker = Tracker::new(&source, FitOptions::default()).expect("tracker");
                tracker
                    .start_from_landmarks(&frames[0].landmarks)
                    .expect("start");
                let views: Vec<_> = frames
                    .iter()
                    .map(|f| f.image.view().expect("view"))
                    .collect();
                for i in 0..n {
                    sink += tracker
                        .track(&views[i % views.len()], facemimic::fit::DEFAULT_TIME_STEP)
                        .expect("track")
                        .error as f64;
                }
            }
            "find" => {
                let frame = &clip()[4].image;
                let image = pad_640x480(frame);
                let view = image.view().expect("view");
                let mut finder = FaceFinder::new().expect("finder");
                for _ in 0..n {
                    sink += finder.find(black_box(&view)).len() as f64;
                }
            }
            other => {
                return Err(format!(
                    "icount: unknown work '{other}' (clone, render, scanline, track or find)"
                ))
            }
        }
        Ok(sink)
    }

    /// `src` centred on a black 640x480 frame.
    fn pad_640x480(src: &Image) -> Image {
        let (w, h) = (640u32, 480u32);
        let mut data = vec![0u8; (w * h * 4) as usize];
        data.iter_mut().skip(3).step_by(4).for_each(|a| *a = 255);
        let (ox, oy) = ((w - src.width) / 2, (h - src.height) / 2);
        for y in 0..src.height {
            let s = (y * src.width * 4) as usize;
            let d = (((y + oy) * w + ox) * 4) as usize;
            data[d..d + (src.width * 4) as usize]
                .copy_from_slice(&src.data[s..s + (src.width * 4) as usize]);
        }
        Image {
            width: w,
            height: h,
            data,
        }
    }

    pub(crate) fn main() -> std::process::ExitCode {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let (Some(what), Some(n)) = (
            args.first(),
            args.get(1).and_then(|s| s.parse::<usize>().ok()),
        ) else {
            eprintln!("usage: icount WHAT N   (WHAT: clone, render, track or find)");
            return std::process::ExitCode::from(2);
        };
        match run(what, n) {
            Ok(sink) => {
                println!("{what} x{n}: {sink}");
                std::process::ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("{e}");
                std::process::ExitCode::from(2)
            }
        }
    }
}

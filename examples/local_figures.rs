//! The finder's local correction (`src/find/local.rs`) measured on GRID speakers it was not
//! learned from: the shared GRID frames (../shared/data/grid, 825 frames) split by speaker;
//! the convention offsets learned on every frame of speakers 1-5 (as
//! `examples/calibration_figures.rs` does), the local correction on their committed frames
//! (`data/grid`, as `examples/finder_data.rs local` learns the shipped one), both measured on
//! every frame of speakers 6-10; and the other way round. One look and the precise mode
//! (`FindOptions::mirror`: points averaged over the image and its mirror, the offsets made
//! symmetric). The clips' figures come from `examples/find_eval.rs` (with and without
//! `FIND_NO_LOCAL`).
//!
//!   cargo run --release --example local_figures -- [SCALES]
//!
//! `SCALES` (default `0.06,0.04`, `find::LearnOptions::default()`): the stages' sample steps, to compare cascades.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::find::{
        add_face_offsets, landmark_error, mean_face_offsets, LearnOptions, LearnSample,
        LocalCorrection, LocalScratch,
    };
    use facemimic::io::{annotated_images, read_image, read_landmarks};
    use facemimic::{FaceFinder, Image};
    use std::path::{Path, PathBuf};

    /// A frame: its path, image, the finder's uncalibrated points (one look, then averaged
    /// with the mirror image's) and dlib's points.
    struct Frame {
        path: PathBuf,
        image: Image,
        raw: Vec<f32>,
        raw_mirror: Vec<f32>,
        truth: Vec<f32>,
    }

    fn frames(dir: &Path) -> Vec<Frame> {
        let mut look = FaceFinder::new().unwrap();
        look.set_calibrated(false);
        let mut precise = FaceFinder::new().unwrap();
        precise.set_calibrated(false);
        let mut o = precise.options();
        o.mirror = true;
        precise.set_options(o);
        annotated_images(dir)
            .unwrap()
            .into_iter()
            .filter_map(|p| {
                let image = read_image(&p).unwrap();
                let truth =
                    read_landmarks(&p.with_extension("pts"), image.width, image.height).unwrap();
                let view = image.view().unwrap();
                let raw = look.find(&view).into_iter().next()?.landmarks;
                let raw_mirror = precise.find(&view).into_iter().next()?.landmarks;
                Some(Frame {
                    path: p,
                    image,
                    raw,
                    raw_mirror,
                    truth,
                })
            })
            .collect()
    }

    /// The GRID speaker of a frame (its folder is `sNN...`).
    fn speaker(p: &Path) -> u32 {
        let d = p.parent().unwrap().file_name().unwrap().to_string_lossy();
        d[3..5].parse().unwrap()
    }

    /// Whether the frame is one of the committed ones (`data/grid/<folder>/<name>`).
    fn committed(p: &Path) -> bool {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid");
        let folder = p.parent().unwrap().file_name().unwrap();
        root.join(folder).join(p.file_name().unwrap()).exists()
    }

    /// `offsets` averaged with their mirror image (as calibration_figures does for the
    /// precise mode).
    fn symmetric(offsets: &[f32]) -> Vec<f32> {
        (0..68)
            .flat_map(|i| {
                let j = facemimic::MIRROR_68[i];
                [
                    0.5 * (offsets[2 * i] - offsets[2 * j]),
                    0.5 * (offsets[2 * i + 1] + offsets[2 * j + 1]),
                ]
            })
            .collect()
    }

    fn calibrated(points: &[f32], offsets: &[f32]) -> Vec<f32> {
        let mut p = points.to_vec();
        add_face_offsets(&mut p, offsets);
        p
    }

    pub(crate) fn main() {
        let scales: Vec<f32> = std::env::args()
            .nth(1)
            .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
            .unwrap_or(LearnOptions::default().scales);
        let options = LearnOptions {
            scales,
            ..LearnOptions::default()
        };
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        let grid = frames(&root.join("grid"));
        let mut scratch = LocalScratch::default();
        println!("stages' steps {:?}", options.scales);
        for (train, test) in [((1, 5), (6, 10)), ((6, 10), (1, 5))] {
            let tr: Vec<&Frame> = grid
                .iter()
                .filter(|f| (train.0..=train.1).contains(&speaker(&f.path)))
                .collect();
            let te: Vec<&Frame> = grid
                .iter()
                .filter(|f| (test.0..=test.1).contains(&speaker(&f.path)))
                .collect();
            let o = mean_face_offsets(tr.iter().map(|f| (f.raw.as_slice(), f.truth.as_slice())));
            let learn: Vec<(&Frame, Vec<f32>)> = tr
                .iter()
                .filter(|f| committed(&f.path))
                .map(|f| (*f, calibrated(&f.raw, &o)))
                .collect();
            let samples: Vec<LearnSample> = learn
                .iter()
                .map(|(f, found)| LearnSample {
                    image: f.image.view().unwrap(),
                    found,
                    truth: &f.truth,
                })
                .collect();
            let local = LocalCorrection::learn(&samples, &options).unwrap();
            let sym = symmetric(&o);
            let (mut look, mut look_l, mut prec, mut prec_l) = (0.0, 0.0, 0.0, 0.0);
            for f in &te {
                let view = f.image.view().unwrap();
                let mut p = calibrated(&f.raw, &o);
                look += landmark_error(&p, &f.truth);
                local.apply(&view, &mut p, &mut scratch);
                look_l += landmark_error(&p, &f.truth);
                let mut p = calibrated(&f.raw_mirror, &sym);
                prec += landmark_error(&p, &f.truth);
                local.apply(&view, &mut p, &mut scratch);
                prec_l += landmark_error(&p, &f.truth);
            }
            let n = te.len() as f32;
            println!(
                "grid: learned on speakers {train:?} ({} frames, the correction on {} committed), measured on {test:?} ({} frames): one look {:.4} -> {:.4}, precise {:.4} -> {:.4}",
                tr.len(),
                samples.len(),
                te.len(),
                look / n,
                look_l / n,
                prec / n,
                prec_l / n
            );
        }
    }
}

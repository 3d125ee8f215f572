//! The finder's local correction (`src/find/local.rs`) measured on GRID speakers it was not
//! learned from: the shared GRID frames (../shared/data/grid, 825 frames) split by speaker;
//! the convention offsets learned on every frame of speakers 1-5 (as
//! `examples/calibration_figures.rs` does), the local correction on their committed frames
//! and the London set's committed photos (`data/grid`, `data/london`, as
//! `examples/finder_data.rs local` learns the shipped one), both measured on
//! every frame of speakers 6-10; and the other way round. One look and the precise mode
//! (`FindOptions::mirror`: each look calibrated and corrected in its own image, the mirror
//! image's points mirrored back and averaged; here the mirror image's look starts from its
//! own detection). `LOCAL_NO_MIRROR` set: the correction learns from the images alone, not
//! from their mirror images too. The clips' figures come from `examples/find_eval.rs` (with and without
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
    use facemimic::landmarks::mirror_points;
    use facemimic::{FaceFinder, Image};
    use std::path::{Path, PathBuf};

    /// A frame: its path, the image and its mirror image, the finder's uncalibrated points
    /// (one look) on each, and dlib's points on each.
    struct Frame {
        path: PathBuf,
        image: Image,
        mirror: Image,
        raw: Vec<f32>,
        raw_m: Vec<f32>,
        truth: Vec<f32>,
        truth_m: Vec<f32>,
    }

    fn frames(dir: &Path) -> Vec<Frame> {
        let mut look = FaceFinder::new().unwrap();
        look.set_calibrated(false);
        annotated_images(dir)
            .unwrap()
            .into_iter()
            .filter_map(|p| {
                let image = read_image(&p).unwrap();
                let truth =
                    read_landmarks(&p.with_extension("pts"), image.width, image.height).unwrap();
                let mut data = Vec::new();
                image.view().unwrap().mirror_into(&mut data);
                let mirror = Image {
                    data,
                    ..image.clone()
                };
                let raw = look
                    .find(&image.view().unwrap())
                    .into_iter()
                    .next()?
                    .landmarks;
                let raw_m = look
                    .find(&mirror.view().unwrap())
                    .into_iter()
                    .next()?
                    .landmarks;
                let mut truth_m = vec![0.0; 136];
                mirror_points(&truth, image.width as f32, &mut truth_m);
                Some(Frame {
                    path: p,
                    image,
                    mirror,
                    raw,
                    raw_m,
                    truth,
                    truth_m,
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
            mirror: std::env::var_os("LOCAL_NO_MIRROR").is_none(),
            ..LearnOptions::default()
        };
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        let grid = frames(&root.join("grid"));
        // The London set's committed photos, which the shipped correction learns from too
        // (`find::training_images`); they are no GRID speaker's, so both halves learn from them.
        let london = frames(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/london"));
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
            // The correction learns from the committed frames and (`LearnOptions::mirror`)
            // their mirror images, as `LocalCorrection::learn_from_images` does.
            let mirrored = options.mirror;
            let learn: Vec<(&Image, Vec<f32>, &[f32])> = tr
                .iter()
                .copied()
                .filter(|f| committed(&f.path))
                .chain(&london)
                .flat_map(|f| {
                    let mut v = vec![(&f.image, calibrated(&f.raw, &o), f.truth.as_slice())];
                    if mirrored {
                        v.push((&f.mirror, calibrated(&f.raw_m, &o), f.truth_m.as_slice()));
                    }
                    v
                })
                .collect();
            let samples: Vec<LearnSample> = learn
                .iter()
                .map(|(image, found, truth)| LearnSample {
                    image: image.view().unwrap(),
                    found,
                    truth,
                })
                .collect();
            let local = LocalCorrection::learn(&samples, &options).unwrap();
            let (mut look, mut look_l, mut prec, mut prec_l) = (0.0, 0.0, 0.0, 0.0);
            // The precise mode: each look calibrated (and corrected) in its own image, the
            // mirror's mirrored back, the two averaged.
            let average = |a: &[f32], m: &[f32], width: f32| -> Vec<f32> {
                let mut back = vec![0.0; 136];
                mirror_points(m, width, &mut back);
                a.iter().zip(&back).map(|(x, y)| 0.5 * (x + y)).collect()
            };
            for f in &te {
                let f_width = f.image.width as f32;
                let mut p = calibrated(&f.raw, &o);
                let mut q = calibrated(&f.raw_m, &o);
                look += landmark_error(&p, &f.truth);
                prec += landmark_error(&average(&p, &q, f_width), &f.truth);
                local.apply(&f.image.view().unwrap(), &mut p, &mut scratch);
                local.apply(&f.mirror.view().unwrap(), &mut q, &mut scratch);
                look_l += landmark_error(&p, &f.truth);
                prec_l += landmark_error(&average(&p, &q, f_width), &f.truth);
            }
            let n = te.len() as f32;
            println!(
                "grid: learned on speakers {train:?} ({} frames, the correction on {} committed samples), measured on {test:?} ({} frames): one look {:.4} -> {:.4}, precise {:.4} -> {:.4}",
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

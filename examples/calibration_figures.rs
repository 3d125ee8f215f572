//! The finder's calibration measured where it was not made: on the shared GRID frames
//! (../shared/data/grid, 825 frames) split by speaker, offsets from speakers 1-5 measured on
//! 6-10 and the other way round; the committed table (`find::NET_OFFSETS`) on the other
//! shared clips; and, as issue 20's anchor was calibrated, each set with the offsets of the
//! other three. Prints the figures of docs/finding.md and fails unless the offsets help
//! everywhere: `cargo run --release --example calibration_figures`.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(any(target_arch = "wasm32", test)))]
use native::main;

/// Native only: the example reads files.
#[cfg(not(any(target_arch = "wasm32", test)))]
mod native {
    use facemimic::find::{add_face_offsets, landmark_error, mean_face_offsets, NET_OFFSETS};
    use facemimic::io::{annotated_images, read_image, read_landmarks};
    use facemimic::FaceFinder;
    use std::path::{Path, PathBuf};

    /// A frame: its path, the finder's uncalibrated points of its most confident face and its
    /// dlib points.
    type Pair = (PathBuf, Vec<f32>, Vec<f32>);

    /// The frames of `dir` the finder finds a face in (uncalibrated; with `mirror`, averaged
    /// over the image and its mirror).
    fn raw_pairs(dir: &Path, mirror: bool) -> Vec<Pair> {
        let mut finder = FaceFinder::new().unwrap();
        finder.set_calibrated(false);
        let mut options = finder.options();
        options.mirror = mirror;
        finder.set_options(options);
        annotated_images(dir)
            .unwrap()
            .into_iter()
            .filter_map(|p| {
                let img = read_image(&p).unwrap();
                let truth =
                    read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
                let face = finder.find(&img.view().unwrap()).into_iter().next()?;
                Some((p, face.landmarks, truth))
            })
            .collect()
    }

    /// The mean landmark error of `pairs`, with `table`'s offsets added when given.
    fn error(pairs: &[&Pair], table: Option<&[f32]>) -> f32 {
        let mut sum = 0.0;
        for (_, r, t) in pairs {
            let mut p = r.clone();
            if let Some(o) = table {
                add_face_offsets(&mut p, o);
            }
            sum += landmark_error(&p, t);
        }
        sum / pairs.len() as f32
    }

    /// The GRID speaker of a frame (its folder is `sNN...`).
    fn speaker(p: &Path) -> u32 {
        let d = p
            .parent()
            .unwrap()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .to_string();
        d[3..5].parse().unwrap()
    }

    /// `offsets` (per point, x then y, in the face frame) averaged with their mirror image:
    /// what calibrating each pass in its own image comes to when `FindOptions::mirror`
    /// averages a pass on the image and one on its mirror.
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

    pub(crate) fn main() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
        let grid = raw_pairs(&root.join("grid"), false);
        // With `FindOptions::mirror`: the same frames' uncalibrated points averaged over the
        // image and its mirror, calibrated by the offsets of a half made symmetric.
        let grid_mirror = raw_pairs(&root.join("grid"), true);
        for (train, test) in [((1, 5), (6, 10)), ((6, 10), (1, 5))] {
            let tr: Vec<&Pair> = grid
                .iter()
                .filter(|(p, ..)| (train.0..=train.1).contains(&speaker(p)))
                .collect();
            let te: Vec<&Pair> = grid_mirror
                .iter()
                .filter(|(p, ..)| (test.0..=test.1).contains(&speaker(p)))
                .collect();
            let o = mean_face_offsets(tr.iter().map(|(_, r, t)| (r.as_slice(), t.as_slice())));
            println!(
                "grid, mirror: offsets from speakers {train:?}, measured on {test:?}: {:.4}",
                error(&te, Some(&symmetric(&o)))
            );
        }
        let of = |speakers: (u32, u32)| -> Vec<&Pair> {
            grid.iter()
                .filter(|(p, ..)| (speakers.0..=speakers.1).contains(&speaker(p)))
                .collect()
        };
        for (train, test) in [((1, 5), (6, 10)), ((6, 10), (1, 5))] {
            let tr = of(train);
            let te = of(test);
            let o = mean_face_offsets(tr.iter().map(|(_, r, t)| (r.as_slice(), t.as_slice())));
            let (before, after) = (error(&te, None), error(&te, Some(&o)));
            println!(
                "grid: offsets from speakers {train:?} ({} frames), measured on {test:?} ({} frames): {before:.4} -> {after:.4}",
                tr.len(),
                te.len()
            );
            assert!(after < before);
        }
        let mut sets = vec![("grid", grid.clone())];
        for set in ["franck-dev", "franck-dev2", "webcam-dev"] {
            let pairs = raw_pairs(&root.join(set), false);
            let all: Vec<&Pair> = pairs.iter().collect();
            let (before, after) = (error(&all, None), error(&all, Some(NET_OFFSETS)));
            println!("{set}: {} frames: {before:.4} -> {after:.4}", all.len());
            assert!(after < before);
            sets.push((set, pairs));
        }
        // Issue 20's anchor was calibrated this way: each set measured with the offsets of
        // the other three (every frame of them pooled). Not what ships (its offsets come from
        // the committed GRID frames only); franck-dev and franck-dev2 are the same man.
        for (i, (set, pairs)) in sets.iter().enumerate() {
            let others = sets
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .flat_map(|(_, (_, p))| p.iter());
            let o = mean_face_offsets(others.map(|(_, r, t)| (r.as_slice(), t.as_slice())));
            let all: Vec<&Pair> = pairs.iter().collect();
            println!(
                "{set}, offsets from the other three sets (the anchor's way): {:.4}",
                error(&all, Some(&o))
            );
        }
    }
}

//! `EnrolFinder` on GRID frames (in the repository): a face with landmarks close to dlib's, and
//! the same face, mirrored, on the mirrored image (the averaging with the mirror pass makes the
//! result nearly mirror-symmetric by construction).

use std::path::Path;

use facemimic::{io, EnrolFinder, Image, MIRROR_68};

fn error(a: &[f32], truth: &[f32]) -> f32 {
    facemimic::find::landmark_error(a, truth)
}

fn mirrored(img: &Image) -> Image {
    let w = img.width as usize;
    let mut data = img.data.clone();
    for (row, src) in data
        .chunks_exact_mut(4 * w)
        .zip(img.data.chunks_exact(4 * w))
    {
        for x in 0..w {
            row[4 * (w - 1 - x)..4 * (w - x)].copy_from_slice(&src[4 * x..4 * x + 4]);
        }
    }
    Image {
        data,
        ..img.clone()
    }
}

#[test]
fn enrol_finder_places_grid_faces_and_is_mirror_consistent() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk07_pwij3p");
    let mut finder = EnrolFinder::new(1).unwrap();
    for stem in ["000000", "000030", "000060"] {
        let t = io::read_training_image(&dir.join(format!("{stem}.jpg"))).unwrap();
        let face = finder
            .find(&t.image.view().unwrap(), 0.5)
            .unwrap()
            .expect("a confident face");
        let e = error(&face.landmarks, &t.landmarks);
        assert!(e < 0.06, "{stem}: error {e} against dlib");
        assert!(
            face.spread < 0.03,
            "{stem}: passes disagree by {}",
            face.spread
        );

        let m = mirrored(&t.image);
        let back = finder
            .find(&m.view().unwrap(), 0.5)
            .unwrap()
            .expect("a confident face in the mirror");
        let w = t.image.width as f32;
        let unmirrored: Vec<f32> = (0..68)
            .flat_map(|i| {
                let j = MIRROR_68[i];
                [w - 1.0 - back.landmarks[2 * j], back.landmarks[2 * j + 1]]
            })
            .collect();
        let d = error(&unmirrored, &face.landmarks);
        assert!(d < 0.01, "{stem}: mirrored result differs by {d}");
        println!(
            "{stem}: error {e:.4}, spread {:.4}, mirror difference {d:.4}",
            face.spread
        );
    }
}

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

/// `enrol` about the face at rest (`ReferenceChoice::Rest`): among a GRID clip's 30 landmarked
/// frames, 6 varied ones kept, the model's bases are the frame `most_at_rest` picks among all
/// 30, kept through the selection though farthest-point sampling did not choose it.
#[test]
fn enrolment_about_the_face_at_rest_keeps_that_face() {
    use facemimic::{enrol, BuildOptions, EnrolFrame, EnrolOptions, QualityScope, Reference};
    let dir = facemimic_testkit::repo("data/grid/spk03_lbax4n");
    let frames: Vec<facemimic::TrainingImage> = io::annotated_images(&dir)
        .unwrap()
        .iter()
        .take(30)
        .map(|p| io::read_training_image(p).unwrap())
        .collect();
    let shapes: Vec<&[f32]> = frames.iter().map(|t| t.landmarks.as_slice()).collect();
    let rest = facemimic::most_at_rest(&shapes).unwrap();
    let varied = facemimic::select_varied(&shapes, 6).unwrap();
    let given = frames
        .iter()
        .map(|t| EnrolFrame {
            name: t.name.clone(),
            image: t.image.clone(),
            landmarks: Some(t.landmarks.clone()),
        })
        .collect();
    let options = EnrolOptions {
        build: BuildOptions {
            name: "rest".into(),
            reference: facemimic::ReferenceChoice::Rest,
            ..BuildOptions::default()
        },
        select: Some(6),
        quality: QualityScope::Off,
        ..EnrolOptions::default()
    };
    let e = enrol(given, &options, None, None, &mut |_| true).unwrap();
    eprintln!(
        "  spk03's 30 frames: most at rest {}, varied {varied:?}",
        frames[rest].name
    );
    assert!(
        !varied.contains(&rest),
        "the sampling chose it anyway: {varied:?}"
    );
    assert_eq!(e.used.len(), 6);
    assert!(e.used.contains(&rest), "{:?}", e.used);
    assert_eq!(
        e.model.reference(),
        &Reference::Training(frames[rest].name.clone())
    );
}

//! The face finder on the hard no-face set: title cards, printed text, logos and patterned fabric
//! (`tests/data/no-face/`, drawn by `scripts/no-face-set.py`; the project's own pictures). Each
//! picture is searched as the page and the CLI search a frame (`FaceFinder::find`, default
//! options) and also at half size, where lettering and patterns fall to the sizes of faces the
//! detector sees best. No face may be reported on any of them.

use facemimic_testkit as common;

use facemimic::{io, FaceFinder, Image, ImageRef};

/// Every picture of the set, by file name (sorted, so failures read the same every run).
fn pictures() -> Vec<(String, Image)> {
    common::clip_frames(&common::repo("tests/data/no-face"))
        .iter()
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                io::read_image(p).unwrap(),
            )
        })
        .collect()
}

/// `img` halved by 2x2 box averaging.
fn half(img: &Image) -> Image {
    let (w, h) = (img.width / 2, img.height / 2);
    let mut data = vec![0u8; (w * h * 4) as usize];
    for y in 0..h {
        for x in 0..w {
            for c in 0..4 {
                let at = |dx: u32, dy: u32| {
                    img.data[(((2 * y + dy) * img.width + 2 * x + dx) * 4) as usize + c] as u32
                };
                data[((y * w + x) * 4) as usize + c] =
                    ((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4) as u8;
            }
        }
    }
    Image {
        width: w,
        height: h,
        data,
    }
}

#[test]
fn no_face_on_lettering_logos_or_fabric() {
    let set = pictures();
    assert!(set.len() >= 50, "the set has {} pictures", set.len());
    for kind in ["title-", "text-", "logo-", "fabric-"] {
        assert!(
            set.iter().filter(|(n, _)| n.starts_with(kind)).count() >= 10,
            "too few {kind} pictures"
        );
    }
    let mut finder = FaceFinder::new().unwrap();
    let mut false_faces = Vec::new();
    for (name, img) in &set {
        let small = half(img);
        for (size, view) in [
            ("full", img.view().unwrap()),
            ("half", small.view().unwrap()),
        ] {
            let view: ImageRef<'_> = view;
            for f in finder.find(&view) {
                false_faces.push(format!(
                    "{name} at {size} size: score {:.2}, box {:.0},{:.0} {:.0}x{:.0}",
                    f.score, f.bbox.x, f.bbox.y, f.bbox.width, f.bbox.height
                ));
            }
        }
    }
    println!(
        "false faces: {} on {} pictures (full and half size)",
        false_faces.len(),
        set.len()
    );
    for f in &false_faces {
        println!("  {f}");
    }
    assert!(false_faces.is_empty(), "{false_faces:#?}");
}

#![cfg(not(target_arch = "wasm32"))]
//! The face finder on real frames and on images without faces.
//!
//! - Accuracy on the shared clips (`../shared/data`: GRID, franck-dev, franck-dev2, webcam-dev;
//!   every 25th frame here, the whole sets with `cargo run --release --example find_eval`): the
//!   finder's nets were trained by face-api.js on other data, so every frame is unseen. Skips
//!   with a message when `../shared` is absent, fails when `CI` is set.
//! - No face reported on a generated non-face set: crops of the frames' backgrounds (away from
//!   the dlib landmarks), flat, gradient, noise and text-like images.
//! - Bad input: tiny, greyscale, faces partly outside the frame.

use std::path::{Path, PathBuf};

use facemimic::{io, FaceFinder, Image, ImageRef};

fn shared() -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if d.join("webcam-dev").is_dir() {
        Some(d)
    } else {
        assert!(
            std::env::var_os("CI").is_none(),
            "{} is absent and CI is set",
            d.display()
        );
        println!("skipping: {} is absent", d.display());
        None
    }
}

fn frames(dir: &Path) -> Vec<PathBuf> {
    io::annotated_images(dir).unwrap()
}

#[test]
fn finds_every_face_of_the_shared_clips_with_accurate_landmarks() {
    let Some(root) = shared() else { return };
    let mut finder = FaceFinder::new().unwrap();
    for set in ["grid", "franck-dev", "franck-dev2", "webcam-dev"] {
        let all = frames(&root.join(set));
        let (mut n, mut found, mut err) = (0, 0, 0.0f32);
        for p in all.iter().step_by(25) {
            let img = io::read_image(p).unwrap();
            let truth =
                io::read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            let faces = finder.find(&img.view().unwrap());
            n += 1;
            if let Some(e) = faces
                .first()
                .map(|f| facemimic::find::landmark_error(&f.landmarks, &truth))
            {
                if e < 0.25 {
                    found += 1;
                    err += e;
                }
            }
        }
        let err = err / found.max(1) as f32;
        println!("{set}: {found}/{n} frames found, mean error {err:.4}");
        assert!(found as f32 >= 0.995 * n as f32, "{set}: {found}/{n} found");
        assert!(err <= 0.05, "{set}: mean error {err}");
    }
}

/// Deterministic pseudo-random numbers (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 32) as u32
    }
    fn below(&mut self, n: u32) -> u32 {
        self.next() % n.max(1)
    }
}

fn rgba(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> Image {
    let mut data = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        for x in 0..w {
            let [r, g, b] = f(x, y);
            data.extend_from_slice(&[r, g, b, 255]);
        }
    }
    Image {
        width: w,
        height: h,
        data,
    }
}

/// Images without a face: generated ones, plus background crops of the shared frames when
/// present.
fn non_faces() -> Vec<(String, Image)> {
    let mut out = Vec::new();
    let mut rng = Rng(0x9e3779b97f4a7c15);
    for (i, c) in [
        [0u8, 0, 0],
        [255, 255, 255],
        [128, 128, 128],
        [200, 160, 140],
        [30, 60, 200],
    ]
    .iter()
    .enumerate()
    {
        out.push((format!("flat{i}"), rgba(320, 240, |_, _| *c)));
    }
    out.push((
        "gradient".into(),
        rgba(320, 240, |x, y| {
            [(x * 255 / 320) as u8, (y * 255 / 240) as u8, 128]
        }),
    ));
    for i in 0..6 {
        let cell = [1u32, 2, 4, 8, 16, 32][i];
        let w = 320 / cell + 1;
        let vals: Vec<[u8; 3]> = (0..w * (240 / cell + 1))
            .map(|_| {
                let v = rng.next();
                if i % 2 == 0 {
                    [v as u8, v as u8, v as u8]
                } else {
                    [v as u8, (v >> 8) as u8, (v >> 16) as u8]
                }
            })
            .collect();
        out.push((
            format!("noise{cell}"),
            rgba(320, 240, |x, y| vals[((y / cell) * w + x / cell) as usize]),
        ));
    }
    // Text-like: rows of dark glyph-sized strokes on paper.
    for i in 0..6 {
        let size = 6 + 4 * i as u32;
        let mut strokes = Vec::new();
        let mut y = 8;
        while y + size < 240 {
            let mut x = 8;
            while x + size < 320 {
                if rng.below(5) > 0 {
                    strokes.push((x + rng.below(size / 2), y, 1 + rng.below(size / 3), size));
                    strokes.push((x, y + rng.below(size), size, 1 + rng.below(size / 4)));
                }
                x += size + 2;
            }
            y += size + size / 2;
        }
        out.push((
            format!("text{size}"),
            rgba(320, 240, |x, y| {
                if strokes
                    .iter()
                    .any(|&(sx, sy, sw, sh)| x >= sx && x < sx + sw && y >= sy && y < sy + sh)
                {
                    [20, 20, 30]
                } else {
                    [245, 242, 235]
                }
            }),
        ));
    }
    // Background crops of real frames: a strip beside, above or below the face's landmarks.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    for set in ["grid", "franck-dev", "franck-dev2", "webcam-dev"] {
        if !root.join(set).is_dir() {
            continue;
        }
        for p in frames(&root.join(set)).iter().step_by(97) {
            let img = io::read_image(p).unwrap();
            let pts = io::read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            let b = facemimic::BBox::of_points(&pts);
            // Keep well away from the face: 0.6 face-widths of margin.
            let (fx0, fx1) = (
                (b.x - 0.6 * b.width).max(0.0) as u32,
                (b.x + 1.6 * b.width) as u32,
            );
            let (fy0, fy1) = (
                (b.y - 0.8 * b.height).max(0.0) as u32,
                (b.y + 1.6 * b.height) as u32,
            );
            let regions = [
                (0, 0, fx0, img.height),
                (
                    fx1.min(img.width),
                    0,
                    img.width.saturating_sub(fx1),
                    img.height,
                ),
                (0, 0, img.width, fy0),
                (
                    0,
                    fy1.min(img.height),
                    img.width,
                    img.height.saturating_sub(fy1),
                ),
            ];
            for (k, &(x, y, w, h)) in regions.iter().enumerate() {
                if w < 48 || h < 48 {
                    continue;
                }
                let crop = rgba(w, h, |cx, cy| {
                    let i = (((y + cy) * img.width + x + cx) * 4) as usize;
                    [img.data[i], img.data[i + 1], img.data[i + 2]]
                });
                out.push((
                    format!("{set}/{}#{k}", p.file_name().unwrap().to_string_lossy()),
                    crop,
                ));
            }
        }
    }
    out
}

#[test]
fn reports_no_face_on_images_without_one() {
    let set = non_faces();
    let mut finder = FaceFinder::new().unwrap();
    let mut false_faces = Vec::new();
    for (name, img) in &set {
        let faces = finder.find(&img.view().unwrap());
        if !faces.is_empty() {
            false_faces.push(format!("{name} ({:.2})", faces[0].score));
        }
    }
    println!(
        "false faces: {} of {} images: {false_faces:?}",
        false_faces.len(),
        set.len()
    );
    assert!(
        false_faces.len() as f32 <= 0.01 * set.len() as f32,
        "{} of {}: {false_faces:?}",
        false_faces.len(),
        set.len()
    );
}

#[test]
fn odd_images_give_an_empty_result_or_finite_faces() {
    let mut finder = FaceFinder::new().unwrap();
    let frame = io::read_image(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk01_bbaf2n/000004.jpg"),
    )
    .unwrap();
    let grey = rgba(frame.width, frame.height, |x, y| {
        let i = ((y * frame.width + x) * 4) as usize;
        let v =
            ((frame.data[i] as u32 * 3 + frame.data[i + 1] as u32 * 6 + frame.data[i + 2] as u32)
                / 10) as u8;
        [v, v, v]
    });
    // The face cut in half by the image border.
    let half = rgba(frame.width / 2 + 20, frame.height, |x, y| {
        let i = ((y * frame.width + x + frame.width / 2 - 20) * 4) as usize;
        [frame.data[i], frame.data[i + 1], frame.data[i + 2]]
    });
    let tiny = rgba(1, 1, |_, _| [90, 60, 50]);
    let thin = rgba(4000, 2, |x, _| [(x % 256) as u8, 0, 0]);
    let gf = finder.find(&grey.view().unwrap());
    assert_eq!(gf.len(), 1, "the greyscale face");
    for img in [&half, &tiny, &thin, &frame] {
        for f in finder.find(&img.view().unwrap()) {
            assert!(f.landmarks.len() == 136 && f.landmarks.iter().all(|v| v.is_finite()));
            assert!(f.score > 0.0 && f.score <= 1.0);
        }
    }
    assert!(finder.find(&tiny.view().unwrap()).is_empty());
    // A box outside the image: points, finite, or an error; a degenerate box: an error.
    let view: ImageRef = frame.view().unwrap();
    let far = facemimic::BBox {
        x: -500.0,
        y: -500.0,
        width: 100.0,
        height: 100.0,
    };
    if let Ok(p) = finder.landmarks(&view, far) {
        assert!(p.iter().all(|v| v.is_finite()));
    }
    let nan = facemimic::BBox {
        x: f32::NAN,
        y: 0.0,
        width: 100.0,
        height: 100.0,
    };
    assert!(finder.landmarks(&view, nan).is_err());
    let flat = facemimic::BBox {
        x: 0.0,
        y: 0.0,
        width: 0.0,
        height: 100.0,
    };
    assert!(finder.landmarks(&view, flat).is_err());
}

//! The face finder on real frames and on images without faces.
//!
//! - Accuracy on the shared clips (`../shared/data`: GRID, franck-dev, franck-dev2, webcam-dev;
//!   every 25th frame here, the whole sets with `cargo run --release --example find_eval`): the
//!   finder's nets were trained by MediaPipe on other data, so every frame is unseen (its
//!   468 -> 68 table and convention offsets were learned on the committed GRID frames). Skips
//!   with a message when `../shared` is absent, fails when `CI` is set.
//! - No face reported on a generated non-face set: crops of the frames' backgrounds (away from
//!   the dlib landmarks), flat, gradient, noise and text-like images, title cards, logos (a
//!   drawn smiley among them) and fabric.
//! - Bad input: tiny, greyscale, faces partly outside the frame.

use facemimic_testkit as common;

use std::path::{Path, PathBuf};

use common::following::{pearson, spread};
use common::{first_face, Rng};
use facemimic::{io, BBox, FaceFinder, Image, ImageRef};

/// `../shared/data`, the shared clips, when present (see `common::shared_data`).
fn shared() -> Option<PathBuf> {
    common::shared_data("webcam-dev").map(|d| d.parent().unwrap().to_path_buf())
}

fn frames(dir: &Path) -> Vec<PathBuf> {
    io::annotated_images(dir).unwrap()
}

#[test]
fn finds_every_face_of_the_shared_clips_with_accurate_landmarks() {
    let Some(root) = shared() else { return };
    let mut finder = FaceFinder::new().unwrap();
    // Every 25th frame measured 0.0184 / 0.0206 / 0.0246 / 0.0244 (26 Nov, with the local
    // correction; 0.0253 / 0.0271 / 0.0311 / 0.0269 before it); issue 20's bar is 0.030.
    assert_finds_shared_faces(&root, "", 0.03, |img| first_face(&mut finder, img));
}

/// `FindOptions::mirror` on every 25th frame of the shared sets: every face found, on no set
/// more than 0.001 further from dlib's points than one look, and closer on the held-out clips
/// on average (GRID's committed frames, a part of its frames, taught the local correction its
/// own look; docs/finding.md, "Precise": on every frame 0.0194 / 0.0202 / 0.0251 / 0.0237
/// against 0.0194 / 0.0206 / 0.0250 / 0.0248 with one look).
#[test]
fn mirror_averaging_finds_every_face_and_no_further_from_dlib() {
    let Some(root) = shared() else { return };
    let mut plain = FaceFinder::new().unwrap();
    let mut finder = FaceFinder::new().unwrap();
    let mut options = finder.options();
    options.mirror = true;
    finder.set_options(options);
    let fast = every_25th_frame(&root, |img| first_face(&mut plain, img));
    let precise = every_25th_frame(&root, |img| first_face(&mut finder, img));
    let (mut clips, mut clips_fast) = (0.0, 0.0);
    for ((set, n, found, err), (_, _, _, fast_err)) in precise.into_iter().zip(fast) {
        println!(
            "mirror {set}: {found}/{n} frames found, mean error {err:.4} (one look {fast_err:.4})"
        );
        assert!(found as f32 >= 0.995 * n as f32, "{set}: {found}/{n} found");
        assert!(
            err <= fast_err + 0.001,
            "{set}: {err} with the mirror, {fast_err} without"
        );
        if set != "grid" {
            clips += err;
            clips_fast += fast_err;
        }
    }
    assert!(
        clips < clips_fast,
        "the clips with the mirror: {clips} in all, {clips_fast} without"
    );
}

/// A laugh's lip corners keep their lift: on every 5th frame of the franck clips (he laughs;
/// the finder learned nothing from him), the spread (p95 - p5) of the points' lip-corner lift
/// (`fit::mouth_shape`) is at least 0.68 of dlib's and correlates with it at 0.95 or more, and
/// the mouth's width keeps 0.75 of its spread. Measured 0.75 / 0.75 (r 0.958 / 0.974), widths
/// 0.78 / 0.79; when the local correction also moved the outer lips' middles (51, 57: learned
/// from GRID's speech, it drew a laugh's lips towards speech) franck-dev's lift kept 0.59
/// (r 0.948) and the test failed (docs/finding.md, "A laugh's lip corners").
#[test]
fn a_laughs_lip_corners_keep_their_lift() {
    let Some(root) = shared() else { return };
    let mut finder = FaceFinder::new().unwrap();
    for set in ["franck-dev", "franck-dev2"] {
        let (mut ours, mut dlib) = (Vec::new(), Vec::new());
        for p in frames(&root.join(set)).iter().step_by(5) {
            let img = io::read_image(p).unwrap();
            let truth =
                io::read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            let found = first_face(&mut finder, &img).and_then(|l| facemimic::fit::mouth_shape(&l));
            if let (Some(a), Some(b)) = (found, facemimic::fit::mouth_shape(&truth)) {
                ours.push(a);
                dlib.push(b);
            }
        }
        assert!(ours.len() >= 190, "{set}: {} frames found", ours.len());
        let feature = |v: &[[f32; 2]], k: usize| v.iter().map(|m| m[k]).collect::<Vec<f32>>();
        let (lift, dlib_lift) = (feature(&ours, 1), feature(&dlib, 1));
        let (width, dlib_width) = (feature(&ours, 0), feature(&dlib, 0));
        let kept = spread(lift.clone()) / spread(dlib_lift.clone());
        let r = pearson(&lift, &dlib_lift);
        let width_kept = spread(width) / spread(dlib_width);
        println!("{set}: lift spread {kept:.2} of dlib's, r {r:.3}; width spread {width_kept:.2}");
        assert!(kept >= 0.68, "{set}: the lift keeps {kept} of its spread");
        assert!(r >= 0.95, "{set}: the lift correlates with dlib's at {r}");
        assert!(
            width_kept >= 0.75,
            "{set}: the width keeps {width_kept} of its spread"
        );
    }
}

/// With `FindOptions::mirror` a face and its mirror image give mirrored points: the mean is
/// over the same two looks (the image and its mirror), so what is left is where each look
/// starts (the detector's box on each image).
#[test]
fn mirror_averaging_is_symmetric() {
    let img = io::read_image(&common::repo("data/grid/spk03_lbax4n/000000.jpg")).unwrap();
    let (w, h) = (img.width as usize, img.height as usize);
    let mut flipped = vec![0u8; w * h * 4];
    for y in 0..h {
        for x in 0..w {
            let (s, d) = ((y * w + x) * 4, (y * w + w - 1 - x) * 4);
            flipped[d..d + 4].copy_from_slice(&img.data[s..s + 4]);
        }
    }
    let flipped = ImageRef::new(img.width, img.height, &flipped).unwrap();
    // How far the mirror image's points, mirrored back, are from the image's.
    let asymmetry = |finder: &mut FaceFinder| {
        let a = finder.find(&img.view().unwrap()).remove(0).landmarks;
        let b = finder.find(&flipped).remove(0).landmarks;
        let mut back = vec![0.0; 136];
        facemimic::landmarks::mirror_points(&b, w as f32, &mut back);
        facemimic::find::landmark_error(&back, &a)
    };
    let mut finder = FaceFinder::new().unwrap();
    let mut options = finder.options();
    options.mirror = true;
    finder.set_options(options);
    let e = asymmetry(&mut finder);
    assert!(
        e < 0.005,
        "the mirror image's points, mirrored back, are {e} away"
    );
    // One look is not symmetric in the same way (the net's left-right biases).
    let e1 = asymmetry(&mut FaceFinder::new().unwrap());
    println!("mirror image, mirrored back: {e:.4} with the mirror average, {e1:.4} with one look");
    assert!(e < e1, "{e} with the mirror average, {e1} without");
}

/// Asserts that `first_face` finds the face of at least 99.5% of the frames of each shared set
/// (`every_25th_frame`), within `max_error` on average; prints the figures after `label`.
fn assert_finds_shared_faces(
    root: &Path,
    label: &str,
    max_error: f32,
    first_face: impl FnMut(&Image) -> Option<Vec<f32>>,
) {
    for (set, n, found, err) in every_25th_frame(root, first_face) {
        println!("{label}{set}: {found}/{n} frames found, mean error {err:.4}");
        assert!(found as f32 >= 0.995 * n as f32, "{set}: {found}/{n} found");
        assert!(err <= max_error, "{set}: mean error {err}");
    }
}

/// Every 25th frame of each shared set, each on its own: `(set, frames, found, mean error of
/// the found)`. A frame is found when the first face's landmarks (`first_face`) lie within 0.25
/// of the outer-eye-corner distance of the dlib landmarks, on average.
fn every_25th_frame(
    root: &Path,
    mut first_face: impl FnMut(&Image) -> Option<Vec<f32>>,
) -> Vec<(&'static str, usize, usize, f32)> {
    let mut out = Vec::new();
    for set in ["grid", "franck-dev", "franck-dev2", "webcam-dev"] {
        let (mut n, mut found, mut err) = (0, 0, 0.0f32);
        for p in frames(&root.join(set)).iter().step_by(25) {
            let img = io::read_image(p).unwrap();
            let truth =
                io::read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            n += 1;
            if let Some(e) = first_face(&img)
                .map(|landmarks| facemimic::find::landmark_error(&landmarks, &truth))
            {
                if e < 0.25 {
                    found += 1;
                    err += e;
                }
            }
        }
        out.push((set, n, found, err / found.max(1) as f32));
    }
    out
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

/// A 5x7 bitmap font for the letters of the title cards (rows top to bottom, bit 4 leftmost).
const FONT: [(char, [u8; 7]); 16] = [
    ('A', [0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11]),
    ('C', [0x0e, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0e]),
    ('D', [0x1e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1e]),
    ('E', [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f]),
    ('F', [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x10]),
    ('H', [0x11, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11]),
    ('I', [0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e]),
    ('M', [0x11, 0x1b, 0x15, 0x15, 0x11, 0x11, 0x11]),
    ('N', [0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0x11]),
    ('O', [0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e]),
    ('P', [0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10]),
    ('R', [0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11]),
    ('S', [0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e]),
    ('T', [0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04]),
    ('V', [0x11, 0x11, 0x11, 0x11, 0x11, 0x0a, 0x04]),
    ('8', [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e]),
];

/// Whether pixel `(x, y)` is inked by `text` drawn from `(x0, y0)` with `scale`-pixel dots
/// (letters 6 dots apart, lines 9 apart; `|` breaks the line).
fn inked(text: &str, x0: i64, y0: i64, scale: i64, x: i64, y: i64) -> bool {
    let (dx, dy) = ((x - x0).div_euclid(scale), (y - y0).div_euclid(scale));
    if dx < 0 || dy < 0 {
        return false;
    }
    let (line, row) = (dy / 9, dy % 9);
    let (col, bit) = (dx / 6, dx % 6);
    if row >= 7 || bit >= 5 {
        return false;
    }
    let Some(l) = text.split('|').nth(line as usize) else {
        return false;
    };
    let Some(ch) = l.chars().nth(col as usize) else {
        return false;
    };
    FONT.iter()
        .find(|(c, _)| *c == ch)
        .is_some_and(|(_, rows)| rows[row as usize] >> (4 - bit) & 1 == 1)
}

/// Title cards (big and small lettering, light on dark and dark on light, some with a frame),
/// printed text, logos (rings, eyes-and-mouth-like marks, stars) and patterned fabric
/// (tartan, polka dots, houndstooth, stripes): drawn here, nothing downloaded.
fn title_cards_logos_and_fabric() -> Vec<(String, Image)> {
    let mut out = title_cards();
    out.extend(logos());
    out.extend(fabrics());
    out
}

/// A `w`x`h` image in two colours: `ink` where `on(x, y)`, `paper` elsewhere.
fn two_tone(w: u32, h: u32, ink: [u8; 3], paper: [u8; 3], on: impl Fn(u32, u32) -> bool) -> Image {
    rgba(w, h, |x, y| if on(x, y) { ink } else { paper })
}

/// Title cards (framed or not, at two sizes) and a printed page.
fn title_cards() -> Vec<(String, Image)> {
    let mut out = Vec::new();
    let cards = [
        ("THE END", 12, [240u8, 235, 220], [10u8, 10, 10]),
        ("FACEMIMIC", 7, [250, 250, 250], [20, 20, 60]),
        ("CHAPTER|ONE", 9, [230, 200, 120], [40, 10, 10]),
        ("MOVIE|NIGHT|8 PM", 5, [20, 20, 20], [245, 240, 230]),
        ("OO OO|OOO", 10, [255, 255, 255], [0, 0, 0]),
        ("SHOOT|PROMO|VIDEO|INTRO", 3, [220, 220, 220], [30, 30, 30]),
    ];
    for (i, (text, scale, ink, paper)) in cards.into_iter().enumerate() {
        for (w, h) in [(640u32, 360u32), (320, 240)] {
            let scale = scale * w as i64 / 640;
            let framed = i % 2 == 1;
            let card = two_tone(w, h, ink, paper, |x, y| {
                let edge = x < 12 || y < 12 || x >= w - 12 || y >= h - 12;
                inked(text, 30, 40, scale.max(1), x as i64, y as i64)
                    || (framed && edge && !(x < 6 || y < 6 || x >= w - 6 || y >= h - 6))
            });
            out.push((format!("card{i}-{w}"), card));
        }
    }
    // Printed text: a page of small lettering.
    let words = "THE FACE OF THE MOON|IS NOT A FACE|MORE SHOTS|IN THE CARDS|DO NOT MOVE";
    let page = two_tone(480, 360, [30, 30, 35], [248, 246, 240], |x, y| {
        inked(words, 10, 10, 2, x as i64, (y % 120) as i64)
    });
    out.push(("page".into(), page));
    out
}

/// Logos: two dots over an arc (a smiley), rings, a target, a star.
fn logos() -> Vec<(String, Image)> {
    // A 320x240 logo, `on` in coordinates centred on the image, 80 px a unit.
    let logo = |name: &str, on: &dyn Fn(f32, f32) -> bool, fg: [u8; 3], bg: [u8; 3]| {
        let image = two_tone(320, 240, fg, bg, |x, y| {
            on((x as f32 - 160.0) / 80.0, (y as f32 - 120.0) / 80.0)
        });
        (name.to_string(), image)
    };
    let r = |u: f32, v: f32| (u * u + v * v).sqrt();
    let smiley = |u, v| {
        let d = r(u, v);
        (0.9..1.0).contains(&d)
            || r(u + 0.35, v + 0.3) < 0.12
            || r(u - 0.35, v + 0.3) < 0.12
            || (v > 0.1 && (0.5..0.6).contains(&d))
    };
    let centres = [
        (-0.7, -0.2),
        (0.0, -0.2),
        (0.7, -0.2),
        (-0.35, 0.2),
        (0.35, 0.2),
    ];
    let olympic = |u, v| {
        centres
            .iter()
            .any(|&(a, b)| (0.3..0.36).contains(&r(u - a, v - b)))
    };
    let star = |u: f32, v: f32| r(u, v) < 0.5 + 0.4 * (5.0 * v.atan2(u)).cos();
    vec![
        logo("smiley", &smiley, [20, 20, 20], [250, 210, 40]),
        logo(
            "rings",
            &|u, v| (r(u, v) * 5.0) as i32 % 2 == 0,
            [200, 30, 30],
            [240, 240, 240],
        ),
        logo("olympic", &olympic, [10, 60, 160], [255, 255, 255]),
        logo("star", &star, [250, 200, 0], [20, 30, 90]),
    ]
}

/// Fabric: tartan, polka dots, houndstooth, stripes.
fn fabrics() -> Vec<(String, Image)> {
    let tartan = rgba(320, 240, |x, y| {
        let (a, b) = ((x / 6) % 8, (y / 6) % 8);
        [
            if a < 3 || b < 3 { 150 } else { 30 },
            if a == 5 || b == 5 { 160 } else { 50 },
            if (a + b) % 4 == 0 { 40 } else { 90 },
        ]
    });
    let polka = two_tone(320, 240, [250, 250, 250], [180, 20, 60], |x, y| {
        let (u, v) = ((x % 40) as f32 - 20.0, (y % 40) as f32 - 20.0);
        u * u + v * v < 64.0
    });
    let houndstooth = two_tone(320, 240, [25, 25, 25], [235, 230, 220], |x, y| {
        let (a, b) = ((x / 4) % 4, (y / 4) % 4);
        (a < 2 && b < 2) || (a >= 2 && b >= 2) || (a + b == 3 && a % 2 == 0)
    });
    let stripes = two_tone(320, 240, [30, 50, 120], [230, 220, 200], |x, y| {
        ((x + y) / 10) % 2 == 0
    });
    vec![
        ("tartan".into(), tartan),
        ("polka".into(), polka),
        ("houndstooth".into(), houndstooth),
        ("stripes".into(), stripes),
    ]
}

/// Images without a face: generated ones, plus background crops of the shared frames when
/// present.
fn non_faces() -> Vec<(String, Image)> {
    let mut out = Vec::new();
    let mut rng = Rng::new(0x9e3779b97f4a7c15);
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
                let v = (rng.next_u64() >> 32) as u32;
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
                let mut below = |n: u32| rng.below(n as usize) as u32;
                if below(5) > 0 {
                    strokes.push((x + below(size / 2), y, 1 + below(size / 3), size));
                    strokes.push((x, y + below(size), size, 1 + below(size / 4)));
                }
                x += size + 2;
            }
            y += size + size / 2;
        }
        let text = two_tone(320, 240, [20, 20, 30], [245, 242, 235], |x, y| {
            strokes
                .iter()
                .any(|&(sx, sy, sw, sh)| x >= sx && x < sx + sw && y >= sy && y < sy + sh)
        });
        out.push((format!("text{size}"), text));
    }
    out.extend(title_cards_logos_and_fabric());
    out.extend(background_crops());
    out
}

/// Background crops of the shared frames (every 97th, when present): a strip beside, above or
/// below the face's landmarks.
fn background_crops() -> Vec<(String, Image)> {
    let mut out = Vec::new();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    for set in ["grid", "franck-dev", "franck-dev2", "webcam-dev"] {
        if !root.join(set).is_dir() {
            continue;
        }
        for p in frames(&root.join(set)).iter().step_by(97) {
            let img = io::read_image(p).unwrap();
            let pts = io::read_landmarks(&p.with_extension("pts"), img.width, img.height).unwrap();
            let b = BBox::of_points(&pts);
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
    // Issue 20: no false face at all (the smiley, which the mesh scores 0.70, is left out as a
    // drawing: its vertices lie on flat colour).
    assert!(
        false_faces.is_empty(),
        "{} of {}: {false_faces:?}",
        false_faces.len(),
        set.len()
    );
}

/// A box far outside the odd images' frame: a finder gives finite points or an error.
const FAR_BOX: BBox = BBox {
    x: -500.0,
    y: -500.0,
    width: 100.0,
    height: 100.0,
};

/// Boxes a finder refuses: a NaN corner, no width.
const BAD_BOXES: [BBox; 2] = [
    BBox {
        x: f32::NAN,
        y: 0.0,
        width: 100.0,
        height: 100.0,
    },
    BBox {
        x: 0.0,
        y: 0.0,
        width: 0.0,
        height: 100.0,
    },
];

/// The odd images the finders are given: a GRID frame with one face
/// (`data/grid/spk01_bbaf2n/000004`), the frame in grey (`grey` of its red, green and blue),
/// its face cut in half by the image border, a 1x1 image and a 4000x2 one.
fn odd_images(grey: impl Fn([u8; 3]) -> u8) -> [Image; 5] {
    let frame = io::read_image(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("data/grid/spk01_bbaf2n/000004.jpg"),
    )
    .unwrap();
    let (w, h) = (frame.width, frame.height);
    let at = |x: u32, y: u32| {
        let i = ((y * w + x) * 4) as usize;
        [frame.data[i], frame.data[i + 1], frame.data[i + 2]]
    };
    let grey = rgba(w, h, |x, y| [grey(at(x, y)); 3]);
    let half = rgba(w / 2 + 20, h, |x, y| at(x + w / 2 - 20, y));
    let tiny = rgba(1, 1, |_, _| [90, 60, 50]);
    let thin = rgba(4000, 2, |x, _| [(x % 256) as u8, 0, 0]);
    [frame, grey, half, tiny, thin]
}

#[test]
fn odd_images_give_an_empty_result_or_finite_faces() {
    let mut finder = FaceFinder::new().unwrap();
    let [frame, grey, half, tiny, thin] =
        odd_images(|[r, g, b]| ((r as u32 * 3 + g as u32 * 6 + b as u32) / 10) as u8);
    let gf = finder.find(&grey.view().unwrap());
    assert_eq!(gf.len(), 1, "the greyscale face");
    let [_, grey2, ..] = odd_images(|[r, g, b]| r / 3 + g / 2 + b / 6);
    assert_eq!(finder.find(&grey2.view().unwrap()).len(), 1, "another grey");
    assert_eq!(
        finder.find(&frame.view().unwrap()).len(),
        1,
        "the colour face"
    );
    let empty = Image {
        width: 0,
        height: 0,
        data: Vec::new(),
    };
    if let Ok(v) = empty.view() {
        assert!(finder.find(&v).is_empty());
    }
    for img in [&half, &tiny, &thin, &frame] {
        for f in finder.find(&img.view().unwrap()) {
            assert!(f.landmarks.len() == 136 && f.landmarks.iter().all(|v| v.is_finite()));
            assert!(f.score > 0.0 && f.score <= 1.0);
        }
    }
    assert!(finder.find(&tiny.view().unwrap()).is_empty());
    // A box outside the image: points, finite, or an error; a degenerate box: an error.
    let view: ImageRef = frame.view().unwrap();
    if let Ok(p) = finder.landmarks(&view, FAR_BOX) {
        assert!(p.iter().all(|v| v.is_finite()));
    }
    for bad in BAD_BOXES {
        assert!(finder.landmarks(&view, bad).is_err());
    }
    // The face's own box gives its points again.
    let face = finder.find(&view).remove(0);
    let again = finder.landmarks(&view, face.bbox).unwrap();
    assert!(facemimic::find::landmark_error(&again, &face.landmarks) < 0.05);
    // Following: nothing to follow before a face is given, then the same face's points with a
    // confident score; a failed call leaves nothing to follow.
    let mut fresh = FaceFinder::new().unwrap();
    let mut out = vec![0.0f32; 136];
    assert!(
        fresh.follow_into(&view, &mut out).is_err(),
        "nothing to follow"
    );
    fresh
        .scored_landmarks_into(&view, face.bbox, &mut out)
        .unwrap();
    let score = fresh.follow_into(&view, &mut out).unwrap();
    assert!(score >= 0.5, "followed face score {score}");
    assert!(facemimic::find::landmark_error(&out, &face.landmarks) < 0.05);
    assert!(fresh.follow_into(&view, &mut out[..10]).is_err());
    assert!(fresh
        .scored_landmarks_into(&view, BAD_BOXES[0], &mut out)
        .is_err());
    assert!(
        fresh.follow_into(&view, &mut out).is_err(),
        "after a failed call"
    );
}

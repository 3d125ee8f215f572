//! Golden images, one reference PNG per case in `tests/golden/` (in the manner of tiny-skia's
//! `tests/integration`): every case renders deterministically and is compared with its PNG.
//!
//! The models are built from the GRID frames in the repository, in the canonical frame: spk07
//! (the source, `data/grid/spk07_pwij3p/train20.txt`) and spk02 (a target,
//! `data/grid/spk02_brbk7n/train20.txt`).
//! - `spk07_instance.png`: spk07 at a fixed instance (shape mode 1 at +1.5 sigma, mode 2 at
//!   -1 sigma, appearance mode 1 at +1 sigma), posed at the model's mean training pose and
//!   scaled 1.5x about the face centre onto a 200x220 canvas, tiny-skia rasteriser;
//! - `spk07_instance_scanline.png`: the same with the scanline rasteriser;
//! - `spk07_instance_mesh.png`: the same as the first with the mesh overlay;
//! - `clone_substitute.png`, `clone_map.png`, `clone_map_residual.png`: spk07's unseen frame
//!   `spk07_id2_vcd_swwp2s/000024` (projected with its landmarks) cloned onto spk02 by each
//!   method (default options otherwise), drawn at spk02's canvas view on 200x220.
//!
//! - `composite_map.png`, `composite_map_follow.png`: the same frame cloned onto spk02 by
//!   `map`, composited into spk02's default backdrop (its training frame closest to the mean)
//!   at the backdrop's size (360x288), without and with follow-pose; for follow-pose the
//!   source's pose is additionally rolled by 8 degrees and moved 12 px right about the face
//!   centre, so that the head's motion in the picture is plain;
//! - `composite_letterboxed.png`: the same frame cloned onto spk02 by `map` with follow-pose,
//!   the source's head rolled by 10 degrees and moved 30 px down about its face centre,
//!   composited into spk02's backdrop letterboxed into a taller 288x360 canvas: the bands above
//!   and below the picture stay the background (the mesh under the chin reaches past the
//!   picture's bottom edge);
//! - `composite_strong_gain1.png`, `composite_strong_gain2.png`: the same frame cloned onto
//!   spk02 by `map` with follow-pose at gains 1 and 2, the source's head rolled by 20 degrees
//!   and scaled by 1.25 about its face centre, composited into spk02's backdrop at its size:
//!   the hair and the top of the head keep their proportions (no cone), nothing folds, and the
//!   picture's edges stay straight (no notch);
//! - `composite_photo.png`: the same frame cloned onto a one-photo target (spk03's first
//!   training frame, `data/grid/spk03_lbax4n/train20.txt`), composited into the photo.
//! - `expressive_laugh_grid.png`, `expressive_laugh_photo.png`: a laugh with teeth (the London
//!   set's person 096, a model of their neutral and smiling photos with the neutral as its
//!   reference, `data/london/`) cloned by the expressive method onto spk02 (composited into its
//!   backdrop) and onto a one-photo target of person 068's neutral photo (composited into the
//!   photo): a dark-skinned man's laugh on a light-skinned woman and man, in their own colours.
//!
//! Tolerance: a pixel differs when a channel is off by more than 3 levels (float rounding in
//! PCA or rasterisation on another CPU may move a value by one or two); at most 0.5% of the
//! pixels may differ. Regenerate (after an intended change only) with
//! `FACEMIMIC_BLESS=1 cargo test --release --test integration golden::`, and look at the images.

use facemimic_testkit as common;

use std::path::{Path, PathBuf};

use common::pixels::{pixel_diff, PixelDiff};
use facemimic::clone::{CloneOptions, Cloner, Method};
use facemimic::tiny_skia::{Color, Pixmap};
use facemimic::{
    canvas_view, io, photo_model, picture_view, Compositor, DrawOptions, FaceDrawer, Model, Params,
    Rasterizer, Similarity,
};

const TOLERANCE: i32 = 3;
const MAX_DIFFERING_SHARE: f64 = 0.005;
const SIZE: (u32, u32) = (200, 220);
const BACKGROUND: [u8; 4] = [32, 32, 36, 255];
/// The canvas of the letterboxed composite: taller than the 360x288 backdrop.
const LETTERBOXED: (u32, u32) = (288, 360);

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn golden_path(name: &str) -> PathBuf {
    root().join("tests/golden").join(format!("{name}.png"))
}

fn spk07() -> &'static Model {
    common::list_model("data/grid/spk07_pwij3p/train20.txt", "spk07", false)
}

fn spk02() -> &'static Model {
    common::list_model("data/grid/spk02_brbk7n/train20.txt", "spk02", false)
}

/// spk02 with its default backdrop (the training frame closest to the model's mean).
fn spk02_backdrop() -> &'static Model {
    common::list_model("data/grid/spk02_brbk7n/train20.txt", "spk02", true)
}

/// A one-photo target: spk03's first training frame.
fn spk03_photo() -> Model {
    let list = io::read_list(&root().join("data/grid/spk03_lbax4n/train20.txt")).unwrap();
    let t = io::read_training_image(&list[0]).unwrap();
    photo_model(
        "spk03-photo",
        &t.image.view().unwrap(),
        &t.landmarks,
        facemimic::canonical_frame(),
    )
    .unwrap()
}

fn canvas() -> Pixmap {
    let mut pixmap = Pixmap::new(SIZE.0, SIZE.1).unwrap();
    let [r, g, b, a] = BACKGROUND;
    pixmap.fill(Color::from_rgba8(r, g, b, a));
    pixmap
}

/// The fixed spk07 instance and its view: the face centre (the pose's translation) to the
/// canvas centre, magnified 1.5x.
fn instance() -> (Params, Similarity) {
    let model = spk07();
    assert!(model.shape().n_modes() >= 2 && model.appearance().n_modes() >= 1);
    let mut params = model.base_params();
    let (ss, sa) = (model.shape().sigmas(), model.appearance().sigmas());
    params.shape[0] = 1.5 * ss[0];
    params.shape[1] = -ss[1];
    params.appearance[0] = sa[0];
    let k = 1.5;
    let (cx, cy) = (params.pose.tx, params.pose.ty);
    let view = Similarity {
        a: k,
        b: 0.0,
        tx: SIZE.0 as f32 / 2.0 - k * cx,
        ty: SIZE.1 as f32 / 2.0 - k * cy,
    };
    (params, view)
}

/// The spk07 instance drawn with `options` (straight RGBA8).
fn draw_instance(options: DrawOptions) -> Vec<u8> {
    let model = spk07();
    let (params, view) = instance();
    let mut pixmap = canvas();
    let mut drawer = FaceDrawer::new(model.frame(), options).unwrap();
    drawer
        .render(model, &params, &view, &mut pixmap.as_mut())
        .unwrap();
    facemimic::demultiply(&pixmap)
}

/// spk07's unseen frame 24, projected with its landmarks.
fn source_params() -> Params {
    let frame = root().join("data/grid/spk07_id2_vcd_swwp2s/000024.jpg");
    let t = io::read_training_image(&frame).unwrap();
    spk07()
        .project(&t.image.view().unwrap(), &t.landmarks)
        .unwrap()
}

/// spk07's unseen frame 24 composited into `target`'s backdrop at its size, cloned by
/// `map` (substitution for a photo target); with `follow`, the source's pose rolled by 8
/// degrees and moved 12 px right about its face centre, and followed (straight RGBA8, and the
/// size).
fn draw_composite(target: &Model, follow: bool) -> (Vec<u8>, (u32, u32)) {
    let mut params = source_params();
    if follow {
        params.pose = moved(&params.pose, 8.0, (12.0, 0.0));
    }
    let cloner = cloned(target, &params, follow);
    composite(target, &cloner, picture_size(target))
}

/// `pose` rolled by `roll` degrees about its face centre and moved by `(dx, dy)` pixels.
fn moved(pose: &Similarity, roll: f32, (dx, dy): (f32, f32)) -> Similarity {
    moved_scaled(pose, roll, 1.0, (dx, dy))
}

/// `pose` rolled by `roll` degrees and scaled by `scale` about its face centre, and moved by
/// `(dx, dy)` pixels.
fn moved_scaled(pose: &Similarity, roll: f32, scale: f32, (dx, dy): (f32, f32)) -> Similarity {
    let (cx, cy) = (pose.tx, pose.ty);
    let turn = Similarity::from_parts(scale, roll.to_radians(), 0.0, 0.0);
    let (mx, my) = turn.apply_point(cx, cy);
    let about = Similarity {
        tx: cx - mx + dx,
        ty: cy - my + dy,
        ..turn
    };
    about.compose(pose)
}

/// A cloner of spk07 onto `target` that cloned `params` by `map` (with or without
/// follow-pose).
fn cloned(target: &Model, params: &Params, follow: bool) -> Cloner {
    cloned_with_gain(target, params, follow, 1.0)
}

/// [`cloned`] at `gain`.
fn cloned_with_gain(target: &Model, params: &Params, follow: bool, gain: f32) -> Cloner {
    let source = spk07();
    let mut cloner = Cloner::new(source.clone()).unwrap();
    cloner.add_target(target.clone()).unwrap();
    let options = CloneOptions {
        method: Method::Map,
        follow_pose: follow,
        gain,
        ..CloneOptions::default()
    };
    cloner.clone_frame(params, &options).unwrap();
    cloner
}

/// spk07's unseen frame 24 cloned onto spk02 by `map` at `gain` with follow-pose, the source's
/// head rolled by 20 degrees and scaled by 1.25 about its face centre (a strong pose: the
/// backdrop's hair and the picture's edges must follow without a cone, a fold or a notch),
/// composited into spk02's backdrop at its size (straight RGBA8, and the size).
fn draw_strong_pose(gain: f32) -> (Vec<u8>, (u32, u32)) {
    let mut params = source_params();
    params.pose = moved_scaled(&params.pose, 20.0, 1.25, (0.0, 0.0));
    let target = spk02_backdrop();
    let cloner = cloned_with_gain(target, &params, true, gain);
    composite(target, &cloner, picture_size(target))
}

/// spk07's unseen frame 24 cloned onto spk02 by `map` with follow-pose, the source's head
/// rolled by 10 degrees and moved 30 px down about its face centre, composited into spk02's
/// backdrop letterboxed into a 288x360 canvas (straight RGBA8, and the size).
fn draw_letterboxed() -> (Vec<u8>, (u32, u32)) {
    let mut params = source_params();
    params.pose = moved(&params.pose, 10.0, (0.0, 30.0));
    let target = spk02_backdrop();
    composite(target, &cloned(target, &params, true), LETTERBOXED)
}

/// The size of `target`'s picture (its backdrop).
fn picture_size(target: &Model) -> (u32, u32) {
    let b = target.backdrop().unwrap();
    (b.width(), b.height())
}

/// The cloner's first target composited into its picture, letterboxed into a canvas of
/// `(w, h)` over the background (straight RGBA8, and the size).
fn composite(target: &Model, cloner: &Cloner, (w, h): (u32, u32)) -> (Vec<u8>, (u32, u32)) {
    let mut compositor = Compositor::new(target, DrawOptions::default()).unwrap();
    let (bw, bh) = compositor.size();
    let mut pixmap = Pixmap::new(w, h).unwrap();
    let [r, g, b, a] = BACKGROUND;
    pixmap.fill(Color::from_rgba8(r, g, b, a));
    compositor
        .draw(
            target,
            cloner.target_appearance(0),
            cloner.target_shape(0),
            &picture_view(bw, bh, w, h),
            &mut pixmap.as_mut(),
        )
        .unwrap();
    (facemimic::demultiply(&pixmap), (w, h))
}

/// spk07's unseen frame 24 cloned onto spk02 with `method` (straight RGBA8).
fn draw_clone(method: Method) -> Vec<u8> {
    let source = spk07();
    let params = source_params();
    let target = spk02();
    let mut cloner = Cloner::new(source.clone()).unwrap();
    cloner.add_target(target.clone()).unwrap();
    let options = CloneOptions {
        method,
        ..CloneOptions::default()
    };
    cloner.clone_frame(&params, &options).unwrap();
    let view = canvas_view(target, SIZE.0, SIZE.1);
    let mut pixmap = canvas();
    let mut drawer = FaceDrawer::new(target.frame(), DrawOptions::default()).unwrap();
    drawer
        .draw(
            target.frame(),
            cloner.target_appearance(0),
            cloner.target_shape(0),
            &view,
            &mut pixmap.as_mut(),
        )
        .unwrap();
    facemimic::demultiply(&pixmap)
}

/// The London set's person 096 as a source: a model of their two photos with the neutral as
/// its reference, and the smile's parameters in it.
fn london_096() -> (Model, Params) {
    let photo = |kind: &str| {
        let mut t =
            io::read_training_image(&root().join(format!("data/london/{kind}/096.jpg"))).unwrap();
        t.name = kind.to_string();
        t
    };
    let (neutral, smile) = (photo("neutral"), photo("smiling"));
    let model = facemimic::Builder::new(facemimic::BuildOptions {
        name: "london-096".into(),
        reference: facemimic::ReferenceChoice::Named("neutral".into()),
        ..facemimic::BuildOptions::default()
    })
    .build(&[neutral, smile.clone()], None)
    .unwrap();
    let params = model
        .project(&smile.image.view().unwrap(), &smile.landmarks)
        .unwrap();
    (model, params)
}

/// 096's laugh cloned onto `target` by the expressive method, composited into its picture
/// (straight RGBA8, and the size).
fn draw_expressive(target: &Model) -> (Vec<u8>, (u32, u32)) {
    let (source, params) = london_096();
    let mut cloner = Cloner::new(source).unwrap();
    cloner.add_target(target.clone()).unwrap();
    let options = CloneOptions {
        method: Method::Expressive,
        ..CloneOptions::default()
    };
    cloner.clone_frame(&params, &options).unwrap();
    composite(target, &cloner, picture_size(target))
}

/// Compares `got` with the golden image `name` (or writes it with `FACEMIMIC_BLESS=1`).
fn check(name: &str, got: &[u8]) {
    check_sized(name, got, SIZE);
}

/// [`check`] for an image of another size.
fn check_sized(name: &str, got: &[u8], size: (u32, u32)) {
    assert_eq!(
        got.len(),
        (size.0 * size.1 * 4) as usize,
        "{name}: buffer size"
    );
    let path = golden_path(name);
    if std::env::var_os("FACEMIMIC_BLESS").is_some_and(|v| v == "1") {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        io::write_png(&path, size.0, size.1, got).unwrap();
        println!("wrote {}", path.display());
        return;
    }
    let golden = io::read_image(&path).unwrap_or_else(|e| {
        panic!("{e}: no golden image; create it with FACEMIMIC_BLESS=1 and look at it")
    });
    assert_eq!(
        (golden.width, golden.height),
        size,
        "{name}: golden image size"
    );
    let PixelDiff {
        pixels: total,
        differing,
        worst,
    } = pixel_diff(got, &golden.data, 4, TOLERANCE);
    let background = got.chunks_exact(4).filter(|p| *p == BACKGROUND).count();
    let share = differing as f64 / total as f64;
    println!(
        "{name}: {differing} of {total} pixels differ by more than {TOLERANCE} (worst {worst})"
    );
    assert!(
        share <= MAX_DIFFERING_SHARE,
        "{name}: {differing} pixels ({:.2}%) differ by more than {TOLERANCE} levels (worst {worst})",
        share * 100.0
    );
    // The face covers a good part of the canvas (a blank or tiny render is not a match by
    // accident of a blank golden image).
    assert!(
        background < total * 3 / 4,
        "{name}: the render is mostly background ({background} of {total})"
    );
}

#[test]
fn render_matches_golden_image() {
    check("spk07_instance", &draw_instance(DrawOptions::default()));
}

#[test]
fn scanline_render_matches_golden_image() {
    let got = draw_instance(DrawOptions {
        rasterizer: Rasterizer::Scanline,
        mesh: false,
    });
    check("spk07_instance_scanline", &got);
}

#[test]
fn mesh_overlay_matches_golden_image() {
    let got = draw_instance(DrawOptions {
        rasterizer: Rasterizer::TinySkia,
        mesh: true,
    });
    assert_ne!(got, draw_instance(DrawOptions::default()), "no mesh drawn");
    check("spk07_instance_mesh", &got);
}

#[test]
fn substitute_clone_matches_golden_image() {
    check("clone_substitute", &draw_clone(Method::Substitute));
}

#[test]
fn map_clone_matches_golden_image() {
    check("clone_map", &draw_clone(Method::Map));
}

#[test]
fn map_residual_clone_matches_golden_image() {
    check("clone_map_residual", &draw_clone(Method::MapResidual));
}

#[test]
fn composite_matches_golden_image() {
    let (got, size) = draw_composite(spk02_backdrop(), false);
    check_sized("composite_map", &got, size);
}

#[test]
fn composite_with_follow_pose_matches_golden_image() {
    let (still, size) = draw_composite(spk02_backdrop(), false);
    let (got, _) = draw_composite(spk02_backdrop(), true);
    assert_ne!(got, still, "the head did not move");
    check_sized("composite_map_follow", &got, size);
}

#[test]
fn letterboxed_composite_matches_golden_image() {
    let (got, size) = draw_letterboxed();
    // The bands above and below the picture (rows 0-64 and 295-359: the picture's 230.4 rows
    // start at 64.8) are the background, untouched.
    let band = |y: u32| got[(4 * y * size.0) as usize..(4 * (y + 1) * size.0) as usize].to_vec();
    for y in (0..64).chain(296..size.1) {
        assert!(
            band(y).chunks_exact(4).all(|p| p == BACKGROUND),
            "row {y} of the band was drawn on"
        );
    }
    check_sized("composite_letterboxed", &got, size);
}

#[test]
fn strong_pose_composites_match_golden_images() {
    check_sized_pair("composite_strong_gain1", draw_strong_pose(1.0));
    check_sized_pair("composite_strong_gain2", draw_strong_pose(2.0));
}

fn check_sized_pair(name: &str, (got, size): (Vec<u8>, (u32, u32))) {
    check_sized(name, &got, size);
}

#[test]
fn photo_target_composite_matches_golden_image() {
    let (got, size) = draw_composite(&spk03_photo(), false);
    check_sized("composite_photo", &got, size);
}

#[test]
fn expressive_laugh_on_a_grid_target_matches_golden_image() {
    let (got, size) = draw_expressive(spk02_backdrop());
    check_sized("expressive_laugh_grid", &got, size);
}

#[test]
fn expressive_laugh_on_a_photo_target_matches_golden_image() {
    let t = io::read_training_image(&root().join("data/london/neutral/068.jpg")).unwrap();
    let photo = photo_model(
        "london-068-photo",
        &t.image.view().unwrap(),
        &t.landmarks,
        facemimic::canonical_frame(),
    )
    .unwrap();
    let (got, size) = draw_expressive(&photo);
    check_sized("expressive_laugh_photo", &got, size);
}

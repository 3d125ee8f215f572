//! Rendering: a face (an appearance on the reference frame) warped piecewise-affinely onto a
//! shape, into a tiny-skia pixmap.
//!
//! - [`FaceDrawer`] is what callers use: it owns the chosen backend, the mesh overlay and the
//!   scratch buffers, and draws a face with one call.
//! - `texture.rs`: [`Warp`], what both backends share (the upload and warp calls); a backend
//!   is its [`Store`] of the texture and rasteriser of the triangles.
//! - `skia.rs`: [`Renderer`], one tiny-skia pattern fill per triangle (the default backend).
//! - `scanline.rs`: [`Scanline`], a fixed-point scanline warp into the same pixmap (opt-in).
//! - `overlay.rs`: [`MeshOverlay`], the triangle mesh stroked over a face.
//! - `view.rs`: where a face goes in a canvas ([`fit_view`], [`base_box`], [`canvas_view`]).

use glam::{Affine2, Mat2, Vec2};
use tiny_skia::{Pixmap, PixmapMut, PixmapRef};

use crate::error::{check_len, Result};
use crate::model::frame::ReferenceFrame;
use crate::model::{Model, Params};
use crate::similarity::Similarity;

mod composite;
mod overlay;
mod scanline;
mod skia;
mod texture;
mod view;

pub use composite::{hull_loop, mean_value_weights, Compositor};
pub use overlay::MeshOverlay;
pub use scanline::Scanline;
pub use skia::Renderer;
pub use texture::Store;
pub(crate) use view::PixelRect;
pub use view::{base_box, canvas_view, fit_view, picture_view};

/// Which rasteriser warps the triangles of a piecewise-affine warp into a tiny-skia pixmap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Rasterizer {
    /// [`Renderer`] (`Warp::warp` with a `SkiaStore`): one tiny-skia pattern fill per
    /// triangle (the default).
    #[default]
    TinySkia,
    /// [`Scanline`] (`Warp::warp` with a `ScanlineStore`): a faster fixed-point
    /// rasteriser that writes into the same tiny-skia pixmap; results agree within ~1.5
    /// levels.
    Scanline,
}

/// How [`FaceDrawer`] draws: the rasteriser and whether the mesh is stroked over the face.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DrawOptions {
    /// The triangle rasteriser (default tiny-skia).
    pub rasterizer: Rasterizer,
    /// Stroke the triangle mesh over the face (default off).
    pub mesh: bool,
}

/// Draws faces of the models on one reference frame into tiny-skia pixmaps: the chosen
/// backend ([`Rasterizer`]), the mesh overlay and every scratch buffer in one value.
///
/// A face is drawn in two steps, [`FaceDrawer::upload`] (the appearance becomes the texture)
/// and [`FaceDrawer::warp`] (the texture is warped onto a shape, then the mesh is stroked when
/// asked), or in one ([`FaceDrawer::draw`], [`FaceDrawer::render`]). Create once per frame and
/// reuse: after the first face, drawing allocates nothing.
///
/// Contract: the warp paints exactly the pixels whose centres fall inside the warped mesh;
/// pixels outside are left untouched (except under the mesh overlay's strokes).
#[derive(Debug)]
pub struct FaceDrawer {
    options: DrawOptions,
    skia: Renderer,
    scanline: Scanline,
    overlay: MeshOverlay,
    instance: Instance,
}

impl FaceDrawer {
    /// A drawer for faces on `frame`, drawing with `options`.
    pub fn new(frame: &ReferenceFrame, options: DrawOptions) -> Result<FaceDrawer> {
        Ok(FaceDrawer {
            options,
            skia: Renderer::new(frame)?,
            scanline: Scanline::new(),
            overlay: MeshOverlay::new(),
            instance: Instance::new(frame),
        })
    }

    /// The drawing options.
    pub fn options(&self) -> DrawOptions {
        self.options
    }

    /// Changes the drawing options (an upload made with another rasteriser must be redone).
    pub fn set_options(&mut self, options: DrawOptions) {
        self.options = options;
    }

    /// Writes an appearance vector (`3N`, RGB in `0..=1`) into the chosen backend's texture,
    /// with the padding ring copied from the nearest inside pixels.
    pub fn upload(&mut self, frame: &ReferenceFrame, appearance: &[f32]) -> Result<()> {
        match self.options.rasterizer {
            Rasterizer::TinySkia => self.skia.upload(frame, appearance),
            Rasterizer::Scanline => self.scanline.upload(frame, appearance),
        }
    }

    /// [`FaceDrawer::upload`] with a coverage per frame pixel (`N` values in `0..=1`): the warp
    /// then blends the face over what is under it (used by [`Compositor`]'s feathered edge).
    pub fn upload_with_alpha(
        &mut self,
        frame: &ReferenceFrame,
        appearance: &[f32],
        alpha: &[f32],
    ) -> Result<()> {
        match self.options.rasterizer {
            Rasterizer::TinySkia => self.skia.upload_with_alpha(frame, appearance, Some(alpha)),
            Rasterizer::Scanline => self
                .scanline
                .upload_with_alpha(frame, appearance, Some(alpha)),
        }
    }

    /// Warps the uploaded texture onto `image_shape` (image coordinates, pixel centres on
    /// integers) mapped through `view` (image to target pixels) into `target`, then strokes
    /// the mesh when the options ask for it.
    pub fn warp(
        &mut self,
        frame: &ReferenceFrame,
        image_shape: &[f32],
        view: &Similarity,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        let whole = PixelRect::whole(target.width(), target.height());
        self.warp_in(frame, image_shape, view, whole, target)
    }

    /// [`FaceDrawer::warp`] painting only inside `clip` (the face and the mesh's strokes; the
    /// [`Compositor`]'s picture within a letterboxed canvas).
    pub(crate) fn warp_in(
        &mut self,
        frame: &ReferenceFrame,
        image_shape: &[f32],
        view: &Similarity,
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        match self.options.rasterizer {
            Rasterizer::TinySkia => self.skia.warp_in(frame, image_shape, view, clip, target)?,
            Rasterizer::Scanline => {
                self.scanline
                    .warp_in(frame, image_shape, view, clip, target)?
            }
        }
        if self.options.mesh {
            self.overlay.draw(frame, image_shape, view, clip, target);
        }
        Ok(())
    }

    /// [`FaceDrawer::upload`] then [`FaceDrawer::warp`].
    pub fn draw(
        &mut self,
        frame: &ReferenceFrame,
        appearance: &[f32],
        image_shape: &[f32],
        view: &Similarity,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        self.upload(frame, appearance)?;
        self.warp(frame, image_shape, view, target)
    }

    /// Draws a model instance: synthesises its posed shape (Eq. 1) and its appearance (Eq. 2)
    /// into the drawer's scratch, then draws them through `view`.
    pub fn render(
        &mut self,
        model: &Model,
        params: &Params,
        view: &Similarity,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        model.check_params(params)?;
        let instance = Instance::synthesise(&mut self.instance, model, params)?;
        let r = self.draw(
            model.frame(),
            &instance.appearance,
            &instance.shape,
            view,
            target,
        );
        self.instance = instance;
        r
    }
}

/// The scratch of one model instance: its appearance (Eq. 2, `3N` values) and its posed shape
/// (Eq. 1, image coordinates), sized for a frame once.
#[derive(Debug, Default)]
struct Instance {
    appearance: Vec<f32>,
    shape: Vec<f32>,
}

impl Instance {
    fn new(frame: &ReferenceFrame) -> Instance {
        Instance {
            appearance: vec![0.0; frame.n_pixels() * 3],
            shape: vec![0.0; frame.vertices().len()],
        }
    }

    /// Takes the scratch out of `slot` (so its owner can draw with it; the caller puts it
    /// back) and synthesises `params`' instance of `model` into it. Fails when the scratch was
    /// sized for another frame.
    fn synthesise(slot: &mut Instance, model: &Model, params: &Params) -> Result<Instance> {
        check_len(
            "appearance scratch",
            &slot.appearance,
            model.appearance().len(),
        )?;
        check_len("shape scratch", &slot.shape, model.shape().base.len())?;
        let mut instance = std::mem::take(slot);
        instance_into(model, params, &mut instance.appearance, &mut instance.shape);
        Ok(instance)
    }
}

/// Synthesises the appearance (Eq. 2) and the posed shape (Eq. 1, image coordinates) of
/// `params`. Requires checked parameters and buffers of the model's lengths.
fn instance_into(model: &Model, params: &Params, appearance: &mut [f32], shape: &mut [f32]) {
    model
        .appearance()
        .instance_unchecked(&params.appearance, appearance);
    model.shape().instance_unchecked(&params.shape, shape);
    params.pose.apply_in_place(shape);
}

/// Checks an upload: an appearance of `3N` finite values and, when given, `N` coverages.
fn check_upload(frame: &ReferenceFrame, appearance: &[f32], alpha: Option<&[f32]>) -> Result<()> {
    check_len("appearance", appearance, frame.n_pixels() * 3)?;
    crate::error::check_finite("appearance", appearance)?;
    if let Some(a) = alpha {
        check_len("alpha", a, frame.n_pixels())?;
    }
    Ok(())
}

/// The premultiplied RGBA8 texel of one frame pixel of an appearance (RGB in `0..=1`) at
/// coverage `a` (`0..=1`). Both backends' textures are written from it.
#[inline(always)]
fn texel(rgb: &[f32], a: f32) -> [u8; 4] {
    let to_u8 = |v: f32| (v * 255.0 + 0.5).clamp(0.0, 255.0) as u8;
    [
        to_u8(rgb[0] * a),
        to_u8(rgb[1] * a),
        to_u8(rgb[2] * a),
        to_u8(a),
    ]
}

/// Calls `put(index in the frame's grid, texel)` for every frame pixel of an appearance (`3N`,
/// RGB in `0..=1`) with an optional coverage per pixel (`None` = opaque): both backends write
/// their textures through it. Inlined with `put`, it is the loop written out (an iterator of
/// texels had made the upload half as slow again).
#[inline(always)]
fn for_each_texel(
    frame: &ReferenceFrame,
    appearance: &[f32],
    alpha: Option<&[f32]>,
    mut put: impl FnMut(usize, [u8; 4]),
) {
    let w = frame.width() as usize;
    for (i, (px, rgb)) in frame
        .pixels()
        .iter()
        .zip(appearance.chunks_exact(3))
        .enumerate()
    {
        let a = alpha.map_or(1.0, |a| a[i].clamp(0.0, 1.0));
        put(px.y as usize * w + px.x as usize, texel(rgb, a));
    }
}

/// The padding ring of a frame's texture: `(grid index to write, grid index to copy from)`,
/// so bilinear reads at the mesh border see the nearest inside pixel, not background.
fn padding_copies(frame: &ReferenceFrame) -> impl Iterator<Item = (usize, usize)> + '_ {
    let w = frame.width() as usize;
    let pixels = frame.pixels();
    frame.padding().iter().filter_map(move |&(k, src)| {
        pixels
            .get(src as usize)
            .map(|px| (k as usize, px.y as usize * w + px.x as usize))
    })
}

/// The affine map taking triangle `src` onto triangle `dst` (`None` when `src` is degenerate).
pub fn triangle_affine(src: [Vec2; 3], dst: [Vec2; 3]) -> Option<Affine2> {
    let s = Mat2::from_cols(src[1] - src[0], src[2] - src[0]);
    let det = s.determinant();
    if !(det.abs() > 1e-12) {
        return None;
    }
    let d = Mat2::from_cols(dst[1] - dst[0], dst[2] - dst[0]);
    let m = d * s.inverse();
    let t = dst[0] - m * src[0];
    Some(Affine2::from_mat2_translation(m, t))
}

/// The pixmap's pixels as straight (non-premultiplied) RGBA8, as PNG files and `ImageData` use.
pub fn demultiply(pixmap: &Pixmap) -> Vec<u8> {
    let mut out = Vec::with_capacity(pixmap.data().len());
    demultiply_into(pixmap.as_ref(), &mut out);
    out
}

/// A drawing's pixels as straight RGBA8 (as PNG files and `ImageData` take): the pixmap's own
/// bytes when its background was `opaque` (an opaque background stays opaque under opaque
/// fills and source-over strokes, so the premultiplied pixels are already straight), else
/// [`demultiply_into`] `scratch`. Allocates nothing once `scratch` is large enough.
pub fn straight_rgba<'a>(
    pixmap: PixmapRef<'a>,
    opaque: bool,
    scratch: &'a mut Vec<u8>,
) -> &'a [u8] {
    if opaque {
        pixmap.data()
    } else {
        demultiply_into(pixmap, scratch);
        scratch
    }
}

/// [`demultiply`] into a reusable buffer (cleared first; no allocation once it is large enough).
pub fn demultiply_into(pixmap: PixmapRef<'_>, out: &mut Vec<u8>) {
    out.clear();
    for p in pixmap.pixels() {
        let c = p.demultiply();
        out.extend_from_slice(&[c.red(), c.green(), c.blue(), c.alpha()]);
    }
}

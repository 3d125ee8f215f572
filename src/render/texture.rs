//! What the two warp backends share: a face texture on a reference frame, written from an
//! appearance and warped onto a shape through a view. [`Warp`] holds the calls and the
//! destination points; a [`Store`] (tiny-skia's [`SkiaStore`] or the scanline's
//! [`ScanlineStore`]) holds the texels and rasterises the triangles.

use glam::Vec2;
use tiny_skia::PixmapMut;

use super::PixelRect;
use crate::error::{check_finite, check_len, Result};
use crate::model::frame::ReferenceFrame;
use crate::similarity::Similarity;

/// One backend's texture storage and triangle rasteriser: [`super::SkiaStore`] or
/// [`super::ScanlineStore`]. Implemented by this crate only; use it through [`Warp`].
pub trait Store {
    /// Fails unless the store can take (upload) or draw (warp) a face on `frame`; called
    /// before anything else is checked.
    fn check_frame(&self, frame: &ReferenceFrame) -> Result<()>;

    /// Writes a checked appearance (`3N`, RGB in `0..=1`) with its optional coverage per pixel
    /// into the texture, with the padding ring copied from the nearest inside pixels.
    fn write(&mut self, frame: &ReferenceFrame, appearance: &[f32], alpha: Option<&[f32]>);

    /// Fails unless the store can warp its texture onto `dst` (the mesh's vertices in target
    /// pixels, finite): it has one for `frame`, and the points are within what its
    /// rasteriser holds.
    fn check_points(&self, frame: &ReferenceFrame, dst: &[Vec2]) -> Result<()>;

    /// Warps the texture from the frame's base mesh onto `dst` (checked by
    /// [`Store::check_points`]) into `target`, painting only the pixels of `clip` (within the
    /// target). Allocates nothing.
    fn warp(
        &mut self,
        frame: &ReferenceFrame,
        dst: &[Vec2],
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    );
}

/// A face texture on one reference frame in a backend's [`Store`], and the scratch of its
/// warp: [`super::Renderer`] (tiny-skia) and [`super::Scanline`] are its two kinds. Create once
/// and reuse: after the first frame, uploading and warping allocate nothing of their own.
///
/// Contract: [`Warp::warp`] paints exactly the pixels whose centres fall inside the warped
/// mesh (shared edges are painted once, so there are no cracks and no double-painted seams);
/// pixels outside are left untouched.
#[derive(Default)]
pub struct Warp<S> {
    pub(super) store: S,
    /// The destination points in target pixels (warp's scratch).
    dst: Vec<Vec2>,
}

impl<S: std::fmt::Debug> std::fmt::Debug for Warp<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Warp")
            .field("store", &self.store)
            .finish_non_exhaustive()
    }
}

impl<S: Store> Warp<S> {
    pub(super) fn with_store(store: S, vertices: usize) -> Warp<S> {
        Warp {
            store,
            dst: Vec::with_capacity(vertices),
        }
    }

    /// Writes an appearance vector (`3N`, RGB in `0..=1`) into the texture, with the padding
    /// ring copied from the nearest inside pixels.
    pub fn upload(&mut self, frame: &ReferenceFrame, appearance: &[f32]) -> Result<()> {
        self.upload_with_alpha(frame, appearance, None)
    }

    /// [`Warp::upload`] with a coverage per frame pixel (`N` values in `0..=1`; `None` =
    /// opaque): the warp then blends the face over what is under it (premultiplied
    /// source-over).
    pub fn upload_with_alpha(
        &mut self,
        frame: &ReferenceFrame,
        appearance: &[f32],
        alpha: Option<&[f32]>,
    ) -> Result<()> {
        self.store.check_frame(frame)?;
        super::check_upload(frame, appearance, alpha)?;
        self.store.write(frame, appearance, alpha);
        Ok(())
    }

    /// Warps the uploaded texture from the frame's base mesh onto `image_shape` (image
    /// coordinates, pixel centres on integers) mapped through `view` (image to target pixels),
    /// into `target`.
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

    /// [`Warp::warp`] painting only the pixels of `clip`.
    pub(crate) fn warp_in(
        &mut self,
        frame: &ReferenceFrame,
        image_shape: &[f32],
        view: &Similarity,
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        self.store.check_frame(frame)?;
        check_len("shape", image_shape, frame.vertices().len())?;
        check_finite("shape", image_shape)?;
        self.dst.clear();
        for p in image_shape.chunks_exact(2) {
            let (x, y) = view.apply_point(p[0], p[1]);
            self.dst.push(Vec2::new(x, y));
        }
        self.store.check_points(frame, &self.dst)?;
        self.store.warp(frame, &self.dst, clip, target);
        Ok(())
    }
}

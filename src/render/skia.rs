//! The tiny-skia backend: the piecewise-affine warp of an appearance from the reference frame
//! onto a shape, one pattern-shaded triangle fill per mesh triangle.

use crate::summary::summary;
use glam::Vec2;
use tiny_skia::{
    FillRule, FilterQuality, Paint, PathBuilder, Pattern, Pixmap, PixmapMut, SpreadMode, Transform,
};

use super::texture::{Store, Warp};
use super::triangle_affine;
use crate::error::{Error, Result};
use crate::model::frame::ReferenceFrame;

/// The tiny-skia backend of [`super::FaceDrawer`] for one reference frame: the appearance
/// texture and a recycled path. Create once per model (or per frame shape) and reuse: after
/// the first call, it allocates nothing of its own per frame. To draw a model instance, use
/// [`super::FaceDrawer::render`].
///
/// Contract: `Warp::warp` paints exactly the pixels whose centres fall inside the warped
/// mesh (non-anti-aliased fills share edges exactly, so there are no cracks and no
/// double-painted seams); pixels outside are left untouched.
pub type Renderer = Warp<SkiaStore>;

/// [`Renderer`]'s [`Store`]: the frame texture as a tiny-skia pixmap (premultiplied RGBA,
/// transparent outside the mesh and its padding ring), warped by one pattern-shaded,
/// non-anti-aliased triangle fill per mesh triangle.
pub struct SkiaStore {
    texture: Pixmap,
    frame_fingerprint: u64,
    path: Option<PathBuilder>,
}

impl std::fmt::Debug for SkiaStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        summary(
            f,
            "SkiaStore",
            &[
                ("texture", &(self.texture.width(), self.texture.height())),
                ("frame_fingerprint", &self.frame_fingerprint),
            ],
        )
    }
}

impl Warp<SkiaStore> {
    /// A renderer for models on `frame`.
    pub fn new(frame: &ReferenceFrame) -> Result<Renderer> {
        let texture = Pixmap::new(frame.width(), frame.height())
            .ok_or_else(|| Error::Image("frame too large for a pixmap".into()))?;
        let store = SkiaStore {
            texture,
            frame_fingerprint: frame.fingerprint(),
            path: Some(PathBuilder::with_capacity(4, 4)),
        };
        Ok(Warp::with_store(store, frame.vertices().len() / 2))
    }

    /// The texture of the last appearance drawn (frame-sized, premultiplied RGBA; transparent
    /// outside the mesh and its padding ring). Useful to show the shape-normalised appearance.
    pub fn texture(&self) -> &Pixmap {
        &self.store.texture
    }
}

impl Store for SkiaStore {
    fn check_frame(&self, frame: &ReferenceFrame) -> Result<()> {
        if frame.fingerprint() != self.frame_fingerprint {
            return Err(Error::Incompatible(
                "renderer was made for another reference frame".into(),
            ));
        }
        Ok(())
    }

    fn write(&mut self, frame: &ReferenceFrame, appearance: &[f32], alpha: Option<&[f32]>) {
        let data = self.texture.data_mut();
        super::for_each_texel(frame, appearance, alpha, |k, t| {
            let k = 4 * k;
            data[k] = t[0];
            data[k + 1] = t[1];
            data[k + 2] = t[2];
            data[k + 3] = t[3];
        });
        for (d, s) in super::padding_copies(frame) {
            data.copy_within(4 * s..4 * s + 4, 4 * d);
        }
    }

    /// Any points: tiny-skia clips what falls outside the target.
    fn check_points(&self, _frame: &ReferenceFrame, _dst: &[Vec2]) -> Result<()> {
        Ok(())
    }

    fn warp(&mut self, frame: &ReferenceFrame, dst: &[Vec2], target: &mut PixmapMut<'_>) {
        let [ox, oy] = frame.origin();
        // Destination points in target pixels, source points in texture pixels.
        let v = frame.vertices();
        let src = |i: usize| Vec2::new(v[2 * i] + ox, v[2 * i + 1] + oy);
        warp_mesh(
            self.texture.as_ref(),
            src,
            |i| dst[i],
            frame.triangles(),
            &mut self.path,
            target,
        );
    }
}

/// The piecewise-affine warp of a texture by a triangle mesh, one pattern-shaded,
/// non-anti-aliased tiny-skia fill per triangle: triangle `t` of `triangles` is painted where
/// `dst` places it (target pixels, centres on integers) with the texture read where `src` places
/// it (texture pixels, centres on integers). Adjacent triangles share edges exactly; pixels
/// outside the mesh are untouched. `path` is a recycled path builder.
pub(crate) fn warp_mesh(
    texture: tiny_skia::PixmapRef<'_>,
    src: impl Fn(usize) -> Vec2,
    dst: impl Fn(usize) -> Vec2,
    triangles: &[[u32; 3]],
    path: &mut Option<PathBuilder>,
    target: &mut PixmapMut<'_>,
) {
    let half = Vec2::splat(0.5);
    for t in triangles {
        let s = t.map(|i| src(i as usize) + half);
        let d = t.map(|i| dst(i as usize) + half);
        let Some(m) = triangle_affine(s, d) else {
            continue;
        };
        let tr = Transform::from_row(
            m.matrix2.x_axis.x,
            m.matrix2.x_axis.y,
            m.matrix2.y_axis.x,
            m.matrix2.y_axis.y,
            m.translation.x,
            m.translation.y,
        );
        let mut pb = path.take().unwrap_or_default();
        pb.move_to(d[0].x, d[0].y);
        pb.line_to(d[1].x, d[1].y);
        pb.line_to(d[2].x, d[2].y);
        pb.close();
        let Some(p) = pb.finish() else {
            *path = Some(PathBuilder::new());
            continue;
        };
        let paint = Paint {
            shader: Pattern::new(texture, SpreadMode::Pad, FilterQuality::Bilinear, 1.0, tr),
            anti_alias: false,
            ..Paint::default()
        };
        target.fill_path(&p, &paint, FillRule::Winding, Transform::identity(), None);
        *path = Some(p.clear());
    }
}

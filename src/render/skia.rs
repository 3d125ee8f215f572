//! The tiny-skia backend: the piecewise-affine warp of an appearance from the reference frame
//! onto a shape, one pattern-shaded triangle fill per mesh triangle.

use crate::summary::summary;
use glam::Vec2;
use tiny_skia::{
    FillRule, FilterQuality, Paint, PathBuilder, Pattern, Pixmap, PixmapMut, SpreadMode, Transform,
};

use super::texture::{Store, Warp};
use super::{triangle_affine, PixelRect};
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

    fn warp(
        &mut self,
        frame: &ReferenceFrame,
        dst: &[Vec2],
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    ) {
        let [ox, oy] = frame.origin();
        // Destination points in target pixels, source points in texture pixels.
        let v = frame.vertices();
        let src = |i: usize| Vec2::new(v[2 * i] + ox, v[2 * i + 1] + oy);
        warp_mesh(
            self.texture.as_ref(),
            src,
            |i| dst[i],
            frame.triangles(),
            clip,
            &mut self.path,
            target,
        );
    }
}

/// The piecewise-affine warp of a texture by a triangle mesh, one pattern-shaded,
/// non-anti-aliased tiny-skia fill per triangle: triangle `t` of `triangles` is painted where
/// `dst` places it (target pixels, centres on integers) with the texture read where `src` places
/// it (texture pixels, centres on integers). Adjacent triangles share edges exactly; pixels
/// outside the mesh are untouched, and so are those outside `clip`: a triangle across a side of
/// `clip` inside the target is cut to it ([`Clipped`]; tiny-skia clips at the target's own
/// edges), one wholly outside is skipped. `path` is a recycled path builder.
pub(crate) fn warp_mesh(
    texture: tiny_skia::PixmapRef<'_>,
    src: impl Fn(usize) -> Vec2,
    dst: impl Fn(usize) -> Vec2,
    triangles: &[[u32; 3]],
    clip: PixelRect,
    path: &mut Option<PathBuilder>,
    target: &mut PixmapMut<'_>,
) {
    if clip.is_empty() {
        return;
    }
    let cuts = clip.cuts(target.width(), target.height());
    let half = Vec2::splat(0.5);
    let mut clipped = Clipped::new();
    for t in triangles {
        let s = t.map(|i| src(i as usize) + half);
        let d = t.map(|i| dst(i as usize) + half);
        let Some(m) = triangle_affine(s, d) else {
            continue;
        };
        let Some(corners) = clipped.cut(&d, cuts) else {
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
        pb.move_to(corners[0].x, corners[0].y);
        for c in &corners[1..] {
            pb.line_to(c.x, c.y);
        }
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

/// A triangle cut to a clip rectangle (Sutherland-Hodgman), in a fixed buffer: a triangle cut
/// by four half-planes has at most seven corners. Every cut point of an edge is computed from
/// the edge's two ends in one canonical order, so triangles sharing an edge cut it at the same
/// points and still share their edges exactly.
struct Clipped {
    corners: [Vec2; 8],
    scratch: [Vec2; 8],
    n: usize,
}

impl Clipped {
    fn new() -> Clipped {
        Clipped {
            corners: [Vec2::ZERO; 8],
            scratch: [Vec2::ZERO; 8],
            n: 0,
        }
    }

    /// Triangle `d` (pixel edges, pixel `i` spanning `[i, i + 1]`) within `cuts`
    /// (`[left, top, right, bottom]`, infinite where nothing is cut): the triangle itself
    /// when it is wholly inside, `None` when wholly outside, else the polygon cut to it.
    fn cut(&mut self, d: &[Vec2; 3], cuts: [f32; 4]) -> Option<&[Vec2]> {
        let lo = d[0].min(d[1]).min(d[2]);
        let hi = d[0].max(d[1]).max(d[2]);
        let [left, top, right, bottom] = cuts;
        if hi.x <= left || hi.y <= top || lo.x >= right || lo.y >= bottom {
            return None;
        }
        self.corners[..3].copy_from_slice(d);
        self.n = 3;
        // (axis, bound, keep the side above the bound) for each side the triangle crosses.
        for (axis, bound, above) in [
            (0, left, true),
            (1, top, true),
            (0, right, false),
            (1, bottom, false),
        ] {
            let crosses = if above {
                lo[axis] < bound
            } else {
                hi[axis] > bound
            };
            if crosses {
                self.half_plane(axis, bound, above);
            }
        }
        (self.n >= 3).then_some(&self.corners[..self.n])
    }

    /// Keeps the part of the polygon on one side of the line `p[axis] = bound`.
    fn half_plane(&mut self, axis: usize, bound: f32, above: bool) {
        let inside = |p: Vec2| {
            if above {
                p[axis] >= bound
            } else {
                p[axis] <= bound
            }
        };
        let mut m = 0;
        for k in 0..self.n {
            let (a, b) = (self.corners[k], self.corners[(k + 1) % self.n]);
            if inside(a) {
                self.scratch[m] = a;
                m += 1;
            }
            if inside(a) != inside(b) {
                self.scratch[m] = cross(a, b, axis, bound);
                m += 1;
            }
        }
        self.corners[..m].copy_from_slice(&self.scratch[..m]);
        self.n = m;
    }
}

/// Where the segment `ab` crosses the line `p[axis] = bound`, computed from its ends in one
/// order whichever way round it is given.
fn cross(a: Vec2, b: Vec2, axis: usize, bound: f32) -> Vec2 {
    let (p, q) = if (a[axis], a[1 - axis]) <= (b[axis], b[1 - axis]) {
        (a, b)
    } else {
        (b, a)
    };
    let t = (bound - p[axis]) / (q[axis] - p[axis]);
    let mut r = p + (q - p) * t;
    r[axis] = bound;
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use wasm_bindgen_test::wasm_bindgen_test;

    /// A jittered 7x7 grid mesh over (and past) a 64x64 target: destination points, source
    /// points in a 16x16 texture, triangles.
    fn jittered_grid() -> (Vec<Vec2>, Vec<Vec2>, Vec<[u32; 3]>) {
        let mut seed = 0x2545_f491u32;
        let mut jitter = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed % 1000) as f32 / 1000.0 * 6.0 - 3.0
        };
        let n = 7;
        let (mut dst, mut src) = (Vec::new(), Vec::new());
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (-12.0 + 14.7 * i as f32, -9.0 + 14.1 * j as f32);
                dst.push(Vec2::new(x + jitter(), y + jitter()));
                src.push(Vec2::new(2.0 * i as f32 + 0.3, 2.0 * j as f32 + 0.6));
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let (k, n) = ((j * n + i) as u32, n as u32);
                triangles.push([k, k + 1, k + n + 1]);
                triangles.push([k, k + n + 1, k + n]);
            }
        }
        (dst, src, triangles)
    }

    /// The grid's mesh with a translucent texture (so a pixel painted twice would show), warped
    /// whole and cut to `clip` by both rasterisers: the cut one is the whole one inside `clip`,
    /// byte for byte, and untouched outside it.
    #[wasm_bindgen_test(unsupported = test)]
    fn a_clipped_warp_is_the_warp_inside_the_clip() {
        let (dst, src, triangles) = jittered_grid();
        let mut texture = Pixmap::new(16, 16).unwrap();
        for (k, p) in texture.data_mut().chunks_exact_mut(4).enumerate() {
            let v = (k * 37 % 128) as u8;
            p.copy_from_slice(&[v, 127 - v, 64, 128]);
        }
        let words: Vec<u32> = texture
            .data()
            .chunks_exact(4)
            .map(|p| u32::from_le_bytes([p[0], p[1], p[2], p[3]]))
            .collect();
        let warp = |clip: PixelRect, scanline: bool| {
            let mut out = Pixmap::new(64, 64).unwrap();
            let mut path = None;
            if scanline {
                let s = |i: usize| src[i];
                let tris = &triangles;
                super::super::scanline::warp_mesh(
                    &words,
                    (16, 16),
                    s,
                    &dst,
                    tris,
                    clip,
                    &mut out.as_mut(),
                );
            } else {
                let (s, d) = (|i: usize| src[i], |i: usize| dst[i]);
                warp_mesh(
                    texture.as_ref(),
                    s,
                    d,
                    &triangles,
                    clip,
                    &mut path,
                    &mut out.as_mut(),
                );
            }
            out
        };
        for scanline in [false, true] {
            let whole = warp(PixelRect::whole(64, 64), scanline);
            assert!(
                whole.data().chunks_exact(4).all(|p| p[3] == 128),
                "one paint per pixel"
            );
            for (x0, y0, x1, y1) in [
                (0, 0, 64, 64),
                (5, 0, 64, 64),
                (0, 9, 64, 50),
                (3, 7, 61, 58),
                (30, 31, 31, 33),
                (20, 20, 20, 40),
            ] {
                let clip = PixelRect { x0, y0, x1, y1 };
                let cut = warp(clip, scanline);
                for y in 0..64 {
                    for x in 0..64 {
                        let k = 4 * (y * 64 + x) as usize;
                        let inside = x >= x0 && x < x1 && y >= y0 && y < y1;
                        let want = if inside {
                            &whole.data()[k..k + 4]
                        } else {
                            &[0u8; 4][..]
                        };
                        assert_eq!(
                            &cut.data()[k..k + 4],
                            want,
                            "scanline {scanline}: ({x}, {y}) in {clip:?}"
                        );
                    }
                }
            }
        }
    }
}

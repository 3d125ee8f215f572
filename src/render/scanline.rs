//! The per-frame triangle warp, scanline edition: the same piecewise-affine warp as
//! [`super::Renderer`]'s (bilinear texture lookups, pixel centres inside the warped mesh
//! painted, shared edges painted exactly once), written straight into the same tiny-skia
//! pixmap with 8-bit fixed-point bilinear filtering. tiny-skia's pattern fill runs its
//! high-precision f32 pipeline with source-over blending for every pixel, several times the
//! cost of this path; results agree within ~1.5 levels. [`super::Rasterizer`] picks one of the
//! two; [`super::Rasterizer::TinySkia`] (`Renderer::warp`) is the default everywhere.
//!
//! Coverage rule: a pixel whose centre `(i, j)` (integers) lies in a triangle is painted by
//! it, with half-open spans in `x` and `y` (top-left rule); every edge is evaluated from its
//! endpoints in a canonical order, so two triangles sharing an edge compute the same
//! intersections and split the pixels along it exactly, leaving no cracks and painting no
//! pixel twice.

use tiny_skia::PixmapMut;

use super::texture::{Store, Warp};
use super::{triangle_affine, PixelRect};
use crate::error::Result;
use crate::model::frame::ReferenceFrame;
use glam::Vec2;

/// The scanline backend of [`super::FaceDrawer`]: the same calls as [`super::Renderer`], the
/// frame texture kept as packed RGBA8 words (`ScanlineStore`). Create once and reuse: after
/// the first frame on a reference frame, uploading and warping allocate nothing.
pub type Scanline = Warp<ScanlineStore>;

/// [`Scanline`]'s [`Store`]: the frame texture as packed RGBA8 words (the same content as
/// [`super::Renderer`]'s pixmap: the appearance on the mesh pixels, the padding ring copied
/// from the nearest inside pixels, transparent elsewhere), sized by the first upload on a
/// reference frame, and the fixed-point scanline warp.
#[derive(Debug, Default)]
pub struct ScanlineStore {
    texture: Vec<u32>,
    width: u32,
    height: u32,
    fingerprint: Option<u64>,
}

impl Warp<ScanlineStore> {
    /// Empty state (the texture is sized by the first [`Warp::upload`]).
    pub fn new() -> Scanline {
        Scanline::default()
    }
}

impl Store for ScanlineStore {
    /// Any frame: an upload sizes the texture for its frame, a warp checks it has one.
    fn check_frame(&self, _frame: &ReferenceFrame) -> Result<()> {
        Ok(())
    }

    fn write(&mut self, frame: &ReferenceFrame, appearance: &[f32], alpha: Option<&[f32]>) {
        if self.fingerprint != Some(frame.fingerprint()) {
            self.width = frame.width();
            self.height = frame.height();
            self.texture = vec![0; self.width as usize * self.height as usize];
            self.fingerprint = Some(frame.fingerprint());
        }
        let tex = &mut self.texture;
        super::for_each_texel(frame, appearance, alpha, |k, texel| {
            if let Some(t) = tex.get_mut(k) {
                *t = u32::from_le_bytes(texel);
            }
        });
        for (d, s) in super::padding_copies(frame) {
            let value = tex.get(s).copied().unwrap_or(0);
            if let Some(t) = tex.get_mut(d) {
                *t = value;
            }
        }
    }

    fn check_points(&self, frame: &ReferenceFrame, dst: &[Vec2]) -> Result<()> {
        if self.fingerprint != Some(frame.fingerprint()) {
            return Err(crate::error::Error::Incompatible(
                "no texture uploaded for this reference frame".into(),
            ));
        }
        // Keep every coordinate well inside what the fixed-point and integer maths can hold.
        let limit = 1.0e6;
        if dst
            .iter()
            .any(|p| !(p.x.abs() < limit && p.y.abs() < limit))
        {
            return Err(crate::error::Error::Params(
                "the shape is placed too far outside the canvas".into(),
            ));
        }
        Ok(())
    }

    fn warp(
        &mut self,
        frame: &ReferenceFrame,
        dst: &[Vec2],
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    ) {
        let (tw, th) = (self.width as i32, self.height as i32);
        let [ox, oy] = frame.origin();
        let v = frame.vertices();
        let src = |i: usize| {
            Vec2::new(
                v.get(2 * i).copied().unwrap_or(0.0) + ox,
                v.get(2 * i + 1).copied().unwrap_or(0.0) + oy,
            )
        };
        let triangles = frame.triangles();
        warp_mesh(&self.texture, (tw, th), src, dst, triangles, clip, target);
    }
}

/// `a + (b - a) * w / 256` on two 8-bit lanes packed in `0x00ff00ff`, rounded.
#[cfg_attr(
    all(target_arch = "wasm32", target_feature = "simd128"),
    allow(dead_code)
)]
#[inline(always)]
fn lerp_lanes(a: u32, b: u32, w: u32) -> u32 {
    ((a * (256 - w) + b * w + 0x0080_0080) >> 8) & 0x00ff_00ff
}

/// Bilinear blend of four RGBA8 texels (`w` weights in `0..=255`), with wasm's 128-bit SIMD:
/// the same arithmetic as the scalar version lane by lane (`(a (256 - w) + b w + 128) >> 8`,
/// horizontal then vertical), so both give the same bytes; the four texels' channels are
/// blended at once (2.3x fewer instructions in the warp's inner loop).
#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
#[inline(always)]
fn bilerp(p00: u32, p10: u32, p01: u32, p11: u32, wx: u32, wy: u32) -> u32 {
    use core::arch::wasm32::*;
    let v = u32x4(p00, p01, p10, p11);
    // [p00, p01] and [p10, p11] as 16-bit lanes: one horizontal blend for both rows.
    let left = u16x8_extend_low_u8x16(v);
    let right = u16x8_extend_high_u8x16(v);
    // (a * (256 - w) + b * w + 128) >> 8 in every 16-bit lane.
    let lerp = |a: v128, b: v128, w: u32| {
        u16x8_shr(
            u16x8_add(
                u16x8_add(
                    u16x8_mul(a, u16x8_splat((256 - w) as u16)),
                    u16x8_mul(b, u16x8_splat(w as u16)),
                ),
                u16x8_splat(128),
            ),
            8,
        )
    };
    let rows = lerp(left, right, wx);
    // [top, bottom] -> [bottom, top]: the vertical blend of the two rows.
    let swapped = i16x8_shuffle::<4, 5, 6, 7, 0, 1, 2, 3>(rows, rows);
    let out = lerp(rows, swapped, wy);
    u32x4_extract_lane::<0>(u8x16_narrow_i16x8(out, out))
}

/// Bilinear blend of four RGBA8 texels (`w` weights in `0..=255`).
#[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
#[inline(always)]
fn bilerp(p00: u32, p10: u32, p01: u32, p11: u32, wx: u32, wy: u32) -> u32 {
    bilerp_scalar(p00, p10, p01, p11, wx, wy)
}

/// The scalar bilinear blend: two 8-bit lanes at a time in a `u32`.
#[cfg_attr(
    all(target_arch = "wasm32", target_feature = "simd128"),
    allow(dead_code)
)]
#[inline(always)]
fn bilerp_scalar(p00: u32, p10: u32, p01: u32, p11: u32, wx: u32, wy: u32) -> u32 {
    const M: u32 = 0x00ff_00ff;
    let top_rb = lerp_lanes(p00 & M, p10 & M, wx);
    let top_ag = lerp_lanes((p00 >> 8) & M, (p10 >> 8) & M, wx);
    let bot_rb = lerp_lanes(p01 & M, p11 & M, wx);
    let bot_ag = lerp_lanes((p01 >> 8) & M, (p11 >> 8) & M, wx);
    lerp_lanes(top_rb, bot_rb, wy) | (lerp_lanes(top_ag, bot_ag, wy) << 8)
}

/// Writes texel `c` (premultiplied RGBA8) into the target pixel `px`: stored when opaque,
/// blended source-over when translucent, skipped when transparent.
#[inline(always)]
fn put(px: &mut [u8], c: u32) {
    let a = c >> 24;
    if a == 255 {
        px.copy_from_slice(&c.to_le_bytes());
    } else if a != 0 {
        let under = u32::from_le_bytes([px[0], px[1], px[2], px[3]]);
        px.copy_from_slice(&source_over(c, under).to_le_bytes());
    }
}

/// Premultiplied source-over of `src` onto `dst` (both RGBA8 little-endian).
#[inline]
fn source_over(src: u32, dst: u32) -> u32 {
    let inv = 255 - (src >> 24);
    let mut out = 0u32;
    for shift in [0u32, 8, 16, 24] {
        let s = (src >> shift) & 0xff;
        let d = (dst >> shift) & 0xff;
        let v = s + (d * inv + 127) / 255;
        out |= v.min(255) << shift;
    }
    out
}

/// The x where edge `(p, q)` crosses row `y`, evaluated from the endpoints in canonical order
/// (by `y`, then `x`) so that every triangle sharing the edge gets the same value.
#[inline(always)]
fn edge_x(p: Vec2, q: Vec2, y: f32) -> f32 {
    let (a, b) = if (p.y, p.x) <= (q.y, q.x) {
        (p, q)
    } else {
        (q, p)
    };
    a.x + (y - a.y) * ((b.x - a.x) / (b.y - a.y))
}

/// Fixed-point scale of texture coordinates (16.16).
const ONE: f32 = 65536.0;

/// The fixed-point scanline warp of a packed RGBA8 texture (`tw x th` premultiplied words) by a
/// triangle mesh: triangle `t` is painted where `dst` places it (target pixels, centres on
/// integers), reading the texture bilinearly where `src` places it (texels, centres on
/// integers); premultiplied source-over where the texture is not opaque. Only the pixels of
/// `clip` are painted (the rows and spans are cut to it, at no cost); pixels outside the mesh
/// or the clip are untouched. Allocates nothing.
pub(crate) fn warp_mesh(
    tex: &[u32],
    (tw, th): (i32, i32),
    src: impl Fn(usize) -> Vec2,
    dst: &[Vec2],
    triangles: &[[u32; 3]],
    clip: PixelRect,
    target: &mut PixmapMut<'_>,
) {
    let cw = target.width() as i32;
    let whole = PixelRect::whole(target.width(), target.height());
    let (cx0, cy0) = (clip.x0.max(whole.x0), clip.y0.max(whole.y0));
    let (cx1, cy1) = (clip.x1.min(whole.x1), clip.y1.min(whole.y1));
    let out = target.data_mut();
    let texture = Texture {
        words: tex,
        tw,
        th,
        umax: ((tw - 1) << 16) as f32,
        vmax: ((th - 1) << 16) as f32,
    };
    let (umax, vmax) = (texture.umax, texture.vmax);
    for t in triangles {
        let d = t.map(|i| dst.get(i as usize).copied().unwrap_or(Vec2::ZERO));
        let s = t.map(|i| src(i as usize));
        // Target pixel -> texture coordinates (texel centres on integers).
        let Some(m) = triangle_affine(d, s) else {
            continue;
        };
        let (ymin, ymax) = (
            d[0].y.min(d[1].y).min(d[2].y),
            d[0].y.max(d[1].y).max(d[2].y),
        );
        let j0 = (ymin.ceil() as i32).max(cy0);
        let j1 = (ymax.ceil() as i32).min(cy1); // exclusive
        let edges = [(d[0], d[1]), (d[1], d[2]), (d[2], d[0])];
        let (du, dv) = (
            (m.matrix2.x_axis.x * ONE) as i32,
            (m.matrix2.x_axis.y * ONE) as i32,
        );
        for j in j0..j1 {
            let y = j as f32;
            let Some((xl, xr)) = row_crossing(&edges, y) else {
                continue;
            };
            let i0 = (xl.ceil() as i32).max(cx0);
            let i1 = (xr.ceil() as i32).min(cx1); // exclusive
            if i0 >= i1 {
                continue;
            }
            let x0 = i0 as f32;
            let u0 = m.matrix2.x_axis.x * x0 + m.matrix2.y_axis.x * y + m.translation.x;
            let v0 = m.matrix2.x_axis.y * x0 + m.matrix2.y_axis.y * y + m.translation.y;
            let u = (u0 * ONE).clamp(-umax, 2.0 * umax) as i32;
            let w = (v0 * ONE).clamp(-vmax, 2.0 * vmax) as i32;
            let row = (j * cw) as usize;
            let Some(span) = out.get_mut((row + i0 as usize) * 4..(row + i1 as usize) * 4) else {
                continue;
            };
            texture.paint_span(span, (u, w), (du, dv));
        }
    }
}

/// Where row `y` crosses a triangle given by its `edges`: `(left, right)` from the two edges
/// whose half-open y-range `[top, bottom)` holds the row, `None` when fewer than two do.
#[inline(always)]
fn row_crossing(edges: &[(Vec2, Vec2); 3], y: f32) -> Option<(f32, f32)> {
    let mut xs = [0f32; 2];
    let mut n = 0;
    for &(p, q) in edges {
        let (top, bottom) = if p.y <= q.y { (p.y, q.y) } else { (q.y, p.y) };
        if top <= y && y < bottom && n < 2 {
            xs[n] = edge_x(p, q, y);
            n += 1;
        }
    }
    if n < 2 {
        return None;
    }
    Some(if xs[0] <= xs[1] {
        (xs[0], xs[1])
    } else {
        (xs[1], xs[0])
    })
}

/// The texture [`warp_mesh`] reads: `tw x th` packed premultiplied RGBA8 words, and the
/// largest 16.16 coordinates of a texel centre (`umax`, `vmax`).
struct Texture<'a> {
    words: &'a [u32],
    tw: i32,
    th: i32,
    umax: f32,
    vmax: f32,
}

impl Texture<'_> {
    /// Paints one span of target pixels (RGBA8 bytes), reading the texture bilinearly from the
    /// 16.16 coordinates `(u, w)` on, stepping `(du, dv)` per pixel.
    #[inline(always)]
    fn paint_span(&self, span: &mut [u8], (u, w): (i32, i32), (du, dv): (i32, i32)) {
        // Fast path: the whole span samples inside the texture (the lookups affine along
        // it, so its ends decide), every 2x2 neighbourhood exists: no clamping, no edge
        // cases.
        let n = (span.len() / 4) as i64;
        let (ue, ve) = (
            u as i64 + du as i64 * (n - 1),
            w as i64 + dv as i64 * (n - 1),
        );
        let inside = |a: i64, b: i64, max: f32| a.min(b) >= 0 && (a.max(b) as f32) < max;
        if inside(u as i64, ue, self.umax) && inside(w as i64, ve, self.vmax) {
            self.paint_inside(span, (u, w), (du, dv));
        } else {
            self.paint_clamped(span, (u, w), (du, dv));
        }
    }

    /// [`Texture::paint_span`] where every lookup and its 2x2 neighbourhood lie inside the
    /// texture.
    #[inline(always)]
    fn paint_inside(&self, span: &mut [u8], (mut u, mut w): (i32, i32), (du, dv): (i32, i32)) {
        let tex = self.words;
        let stride = self.tw as usize;
        for px in span.chunks_exact_mut(4) {
            let (xi, yi) = ((u >> 16) as usize, (w >> 16) as usize);
            let (wx, wy) = (((u >> 8) & 0xff) as u32, ((w >> 8) & 0xff) as u32);
            let k = yi * stride + xi;
            let (top, bottom) = (&tex[k..k + 2], &tex[k + stride..k + stride + 2]);
            let c = bilerp(top[0], top[1], bottom[0], bottom[1], wx, wy);
            put(px, c);
            u = u.wrapping_add(du);
            w = w.wrapping_add(dv);
        }
    }

    /// [`Texture::paint_span`] anywhere: lookups clamped to the texture, neighbourhoods to its
    /// last column and row.
    #[inline(always)]
    fn paint_clamped(&self, span: &mut [u8], (mut u, mut w): (i32, i32), (du, dv): (i32, i32)) {
        let (tex, tw, th) = (self.words, self.tw, self.th);
        for px in span.chunks_exact_mut(4) {
            let uc = u.clamp(0, self.umax as i32);
            let vc = w.clamp(0, self.vmax as i32);
            let (xi, yi) = ((uc >> 16) as usize, (vc >> 16) as usize);
            let (wx, wy) = (((uc >> 8) & 0xff) as u32, ((vc >> 8) & 0xff) as u32);
            let k = yi * tw as usize + xi;
            let dx = usize::from((xi as i32) < tw - 1);
            let dy = if (yi as i32) < th - 1 { tw as usize } else { 0 };
            let c = match (
                tex.get(k),
                tex.get(k + dx),
                tex.get(k + dy),
                tex.get(k + dy + dx),
            ) {
                (Some(&a), Some(&b), Some(&c), Some(&d)) => bilerp(a, b, c, d, wx, wy),
                _ => 0,
            };
            put(px, c);
            u = u.wrapping_add(du);
            w = w.wrapping_add(dv);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{DrawOptions, FaceDrawer, Rasterizer};
    use crate::similarity::Similarity;
    use tiny_skia::{Color, Pixmap};
    use wasm_bindgen_test::wasm_bindgen_test;

    #[wasm_bindgen_test(unsupported = test)]
    fn bilerp_corners_and_middle() {
        let (a, b) = (0x10_20_30_40u32, 0xf0_e0_d0_c0u32);
        assert_eq!(bilerp(a, b, a, b, 0, 0), a);
        assert_eq!(bilerp(a, a, b, b, 0, 256), b);
        let m = bilerp(a, b, a, b, 128, 0);
        assert_eq!(m, 0x80_80_80_80);
    }

    /// The SIMD blend (wasm) gives the scalar blend's bytes: the same arithmetic lane by lane.
    #[wasm_bindgen_test(unsupported = test)]
    fn bilerp_is_the_scalar_blend() {
        let mut x = 0x1234_5678u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        for _ in 0..20000 {
            let p = [next(), next(), next(), next()];
            let (wx, wy) = (next() & 0xff, next() & 0xff);
            assert_eq!(
                bilerp(p[0], p[1], p[2], p[3], wx, wy),
                bilerp_scalar(p[0], p[1], p[2], p[3], wx, wy),
                "{p:x?} {wx} {wy}"
            );
        }
    }

    #[wasm_bindgen_test(unsupported = test)]
    fn source_over_opaque_and_clear() {
        assert_eq!(source_over(0xff_01_02_03, 0xff_ff_ff_ff), 0xff_01_02_03);
        assert_eq!(source_over(0, 0xff_10_20_30), 0xff_10_20_30);
    }

    #[wasm_bindgen_test(unsupported = test)]
    fn tiny_skia_is_the_default() {
        assert_eq!(Rasterizer::default(), Rasterizer::TinySkia);
    }

    /// A face-sized mesh: two rings of 12 points and a centre (model coordinates).
    fn mesh() -> ReferenceFrame {
        let mut base = vec![0.0f32, 0.0];
        for (r, phase) in [(70.0f32, 0.0f32), (35.0, 0.26)] {
            for k in 0..12 {
                let a = phase + k as f32 * std::f32::consts::TAU / 12.0;
                base.extend_from_slice(&[r * a.cos(), 1.2 * r * a.sin()]);
            }
        }
        ReferenceFrame::from_base(&base).unwrap()
    }

    /// Draws a smooth, textured appearance on a deformed, posed copy of the mesh with `r`
    /// over an opaque magenta background.
    fn draw(r: Rasterizer, frame: &ReferenceFrame, view: &Similarity) -> Pixmap {
        let appearance: Vec<f32> = frame
            .pixels()
            .iter()
            .flat_map(|p| {
                let (x, y) = (p.x as f32, p.y as f32);
                [
                    0.5 + 0.4 * (x * 0.11).sin(),
                    y / frame.height() as f32,
                    0.5 + 0.3 * ((x + y) * 0.07).cos(),
                ]
            })
            .collect();
        let mut shape = frame.vertices().to_vec();
        for (k, v) in shape.iter_mut().enumerate() {
            *v += 4.0 * (k as f32 * 1.7).sin();
        }
        let mut pixmap = Pixmap::new(260, 300).unwrap();
        pixmap.fill(Color::from_rgba8(255, 0, 255, 255));
        let options = DrawOptions {
            rasterizer: r,
            mesh: false,
        };
        let mut drawer = FaceDrawer::new(frame, options).unwrap();
        drawer
            .draw(frame, &appearance, &shape, view, &mut pixmap.as_mut())
            .unwrap();
        pixmap
    }

    /// The two rasterisers paint the same pixels (to within the pixel-centre rounding on the
    /// mesh boundary) with colours that agree within ~1.5 levels on average.
    #[wasm_bindgen_test(unsupported = test)]
    fn scanline_agrees_with_tiny_skia() {
        let frame = mesh();
        for view in [
            Similarity::from_parts(1.13, 0.21, 131.3, 148.6),
            Similarity::from_parts(0.67, -2.9, 120.5, 160.0),
        ] {
            let a = draw(Rasterizer::Scanline, &frame, &view);
            let b = draw(Rasterizer::TinySkia, &frame, &view);
            let (mut both, mut either, mut diff) = (0usize, 0usize, 0f64);
            for (x, y) in a.data().chunks_exact(4).zip(b.data().chunks_exact(4)) {
                let (fa, fb) = (x[..3] != [255, 0, 255], y[..3] != [255, 0, 255]);
                either += usize::from(fa || fb);
                if fa && fb {
                    both += 1;
                    diff += (0..3)
                        .map(|c| (x[c] as f64 - y[c] as f64).abs())
                        .sum::<f64>()
                        / 3.0;
                }
            }
            assert!(both > 5_000, "only {both} face pixels drawn");
            let mismatch = (either - both) as f64 / either as f64;
            assert!(
                mismatch < 0.01,
                "coverage differs on {:.3}%",
                100.0 * mismatch
            );
            let mean = diff / both as f64;
            assert!(mean < 1.5, "colours differ by {mean:.2} levels on average");
        }
    }

    #[wasm_bindgen_test(unsupported = test)]
    fn bad_input_is_an_error() {
        let frame = mesh();
        let mut pixmap = Pixmap::new(64, 64).unwrap();
        let mut scanline = Scanline::new();
        let shape = frame.vertices().to_vec();
        let view = Similarity::IDENTITY;
        // Nothing uploaded yet.
        assert!(scanline
            .warp(&frame, &shape, &view, &mut pixmap.as_mut())
            .is_err());
        assert!(scanline.upload(&frame, &[0.5; 3]).is_err());
        scanline
            .upload(&frame, &vec![0.5; frame.n_pixels() * 3])
            .unwrap();
        assert!(scanline
            .warp(&frame, &shape[2..], &view, &mut pixmap.as_mut())
            .is_err());
        let mut nan = shape.clone();
        nan[3] = f32::NAN;
        assert!(scanline
            .warp(&frame, &nan, &view, &mut pixmap.as_mut())
            .is_err());
        let far: Vec<f32> = shape.iter().map(|v| v + 1.0e7).collect();
        assert!(scanline
            .warp(&frame, &far, &view, &mut pixmap.as_mut())
            .is_err());
        // Off-canvas but finite: nothing drawn, no error.
        let off: Vec<f32> = shape.iter().map(|v| v - 5000.0).collect();
        scanline
            .warp(&frame, &off, &view, &mut pixmap.as_mut())
            .unwrap();
        assert!(pixmap.data().iter().all(|&b| b == 0));
    }
}

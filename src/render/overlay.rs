//! The mesh overlay: the reference frame's triangle edges stroked over a drawn face.

use tiny_skia::{Paint, PathBuilder, PixmapMut, Stroke, Transform};

use super::PixelRect;
use crate::model::frame::ReferenceFrame;
use crate::similarity::Similarity;

/// How far from a hairline its anti-aliased stroke can touch pixels, in pixels: a pixel is
/// touched when its centre is within a pixel of the line.
const STROKE_REACH: f32 = 1.0;

/// The part of the segment `pq` inside `[left, top, right, bottom]` (Liang-Barsky), `None`
/// when none is. Infinite bounds cut nothing: the segment comes back as it is.
fn clip_segment(
    p: (f32, f32),
    q: (f32, f32),
    [left, top, right, bottom]: [f32; 4],
) -> Option<((f32, f32), (f32, f32))> {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    // Each side as `(-d, p - bound)` for a lower bound, `(d, bound - p)` for an upper one:
    // inside where `t * den <= num`.
    for (den, num) in [
        (-dx, p.0 - left),
        (-dy, p.1 - top),
        (dx, right - p.0),
        (dy, bottom - p.1),
    ] {
        if num == f32::INFINITY {
            continue;
        }
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let t = num / den;
            if den < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f32| (p.0 + t * dx, p.1 + t * dy);
    let a = if t0 > 0.0 { at(t0) } else { p };
    let b = if t1 < 1.0 { at(t1) } else { q };
    Some((a, b))
}

/// Unique undirected edges of a frame's triangles, sorted.
pub fn mesh_edges(frame: &ReferenceFrame) -> Vec<[u32; 2]> {
    let mut e: Vec<[u32; 2]> = frame
        .triangles()
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| if a < b { [a, b] } else { [b, a] })
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Reusable state for drawing the mesh overlay: the frame's edges (recomputed only when the
/// frame changes) and a recycled path. After the first draw on a frame it allocates nothing.
#[derive(Debug, Default)]
pub struct MeshOverlay {
    edges: Vec<[u32; 2]>,
    fingerprint: Option<u64>,
    path: Option<PathBuilder>,
}

impl MeshOverlay {
    /// An empty overlay (the edges are found on the first draw).
    pub fn new() -> MeshOverlay {
        MeshOverlay::default()
    }

    /// Strokes the mesh edges of `frame` at `image_shape` (image coordinates, pixel centres on
    /// integers) through `view` (image to target pixels): thin, semi-transparent white
    /// hairlines, touching only the pixels of `clip` (where a side of `clip` cuts into the
    /// target, the edges stop [`STROKE_REACH`] short of it). Edges with a missing or
    /// non-finite end point are skipped.
    pub fn draw(
        &mut self,
        frame: &ReferenceFrame,
        image_shape: &[f32],
        view: &Similarity,
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    ) {
        if clip.is_empty() {
            return;
        }
        let [left, top, right, bottom] = clip.cuts(target.width(), target.height());
        let inner = [
            left + STROKE_REACH,
            top + STROKE_REACH,
            right - STROKE_REACH,
            bottom - STROKE_REACH,
        ];
        if self.fingerprint != Some(frame.fingerprint()) {
            self.edges = mesh_edges(frame);
            self.fingerprint = Some(frame.fingerprint());
        }
        let mut pb = self.path.take().unwrap_or_default();
        let pt = |i: u32| -> Option<(f32, f32)> {
            let x = *image_shape.get(2 * i as usize)?;
            let y = *image_shape.get(2 * i as usize + 1)?;
            let (u, v) = view.apply_point(x, y);
            (u.is_finite() && v.is_finite()).then_some((u + 0.5, v + 0.5))
        };
        for &[a, b] in &self.edges {
            if let Some((p, q)) = pt(a)
                .zip(pt(b))
                .and_then(|(p, q)| clip_segment(p, q, inner))
            {
                pb.move_to(p.0, p.1);
                pb.line_to(q.0, q.1);
            }
        }
        let Some(path) = pb.finish() else {
            self.path = Some(PathBuilder::new());
            return;
        };
        let mut paint = Paint::default();
        paint.set_color_rgba8(255, 255, 255, 110);
        paint.anti_alias = true;
        // Width 1 takes tiny-skia's hairline path: no stroked-path allocation.
        let stroke = Stroke {
            width: 1.0,
            ..Stroke::default()
        };
        target.stroke_path(&path, &paint, &stroke, Transform::identity(), None);
        self.path = Some(path.clear());
    }
}

//! The mesh overlay: the reference frame's triangle edges stroked over a drawn face.

use tiny_skia::{Paint, PathBuilder, PixmapMut, Stroke, Transform};

use crate::model::frame::ReferenceFrame;
use crate::similarity::Similarity;

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
    /// hairlines. Edges with a missing or non-finite end point are skipped.
    pub fn draw(
        &mut self,
        frame: &ReferenceFrame,
        image_shape: &[f32],
        view: &Similarity,
        target: &mut PixmapMut<'_>,
    ) {
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
            if let (Some(p), Some(q)) = (pt(a), pt(b)) {
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

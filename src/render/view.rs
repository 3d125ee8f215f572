//! The view layout: where a face goes in a canvas (the same for the page, the npm package and
//! the CLI).

use crate::model::Model;
use crate::similarity::Similarity;

/// Share of the smaller canvas side that the face's bounding box takes.
pub const FACE_FILL: f32 = 0.85;

/// The bounding box `[min x, min y, max x, max y]` of a model's base shape placed at its home
/// pose ([`Model::home_pose`]: on its backdrop, or at its mean training pose), in image
/// coordinates. Allocation-free.
pub fn base_box(model: &Model) -> [f32; 4] {
    let pose = model.home_pose();
    let b = crate::geometry::BBox::of_pairs(
        model
            .shape()
            .base
            .chunks_exact(2)
            .map(|p| pose.apply_point(p[0], p[1])),
    );
    [b.x, b.y, b.right(), b.bottom()]
}

/// The view (backdrop pixels -> canvas pixels) that shows a whole `width x height` picture
/// centred in a `w x h` canvas, as large as fits (letterboxed).
pub fn picture_view(width: u32, height: u32, w: u32, h: u32) -> Similarity {
    let s = (w as f32 / width.max(1) as f32).min(h as f32 / height.max(1) as f32);
    let s = if s.is_finite() && s > 0.0 { s } else { 1.0 };
    // Centres on integers: the picture's centre (width - 1) / 2 goes to the canvas's.
    Similarity {
        a: s,
        b: 0.0,
        tx: 0.5 * (w as f32 - 1.0) - s * 0.5 * (width as f32 - 1.0),
        ty: 0.5 * (h as f32 - 1.0) - s * 0.5 * (height as f32 - 1.0),
    }
}

/// The view (image coordinates -> canvas pixels) that centres the box in a `w x h` canvas with
/// its larger side at `FACE_FILL` (85%) of the smaller canvas side. Stable for a box and size.
pub fn fit_view(bbox: [f32; 4], w: u32, h: u32) -> Similarity {
    let bw = (bbox[2] - bbox[0]).max(1e-3);
    let bh = (bbox[3] - bbox[1]).max(1e-3);
    let side = w.min(h) as f32;
    let s = FACE_FILL * side / bw.max(bh);
    let s = if s.is_finite() && s > 0.0 { s } else { 1.0 };
    let (cx, cy) = (0.5 * (bbox[0] + bbox[2]), 0.5 * (bbox[1] + bbox[3]));
    // Pixel centres are on integers, so the canvas centre is at (w - 1) / 2.
    Similarity {
        a: s,
        b: 0.0,
        tx: 0.5 * (w as f32 - 1.0) - s * cx,
        ty: 0.5 * (h as f32 - 1.0) - s * cy,
    }
}

/// The view with which `model` is drawn into a `width x height` canvas: its base shape at its
/// mean pose, bounding box centred, the box's larger side at `FACE_FILL` (85%) of the smaller
/// canvas side. Stable for a model and a canvas size.
pub fn canvas_view(model: &Model, width: u32, height: u32) -> Similarity {
    fit_view(base_box(model), width, height)
}

/// A rectangle of target pixels, columns `x0..x1` by rows `y0..y1` (pixel indices, ends
/// exclusive): where a warp may paint ([`crate::Compositor`]: the picture's pixels).
/// (Named by the backends' [`super::Store`]; not re-exported.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// The first column.
    pub x0: i32,
    /// The first row.
    pub y0: i32,
    /// One past the last column.
    pub x1: i32,
    /// One past the last row.
    pub y1: i32,
}

impl PixelRect {
    /// The whole of a `w x h` target.
    pub fn whole(w: u32, h: u32) -> PixelRect {
        let side = |v: u32| v.min(i32::MAX as u32) as i32;
        PixelRect {
            x0: 0,
            y0: 0,
            x1: side(w),
            y1: side(h),
        }
    }

    /// The pixels of a `w x h` target whose centres lie in the picture of a `width x height`
    /// bitmap drawn through `view` (its pixel squares, centres on integers, mapped to target
    /// pixels): the letterboxed picture of [`picture_view`] exactly (any view without rotation),
    /// the box around it for a rotated view. Half-open as the rasterisers are: a centre on the
    /// picture's left or top edge is in, one on its right or bottom edge out. Allocation-free.
    pub fn picture(view: &Similarity, (width, height): (u32, u32), (w, h): (u32, u32)) -> Self {
        let (r, b) = (width as f32 - 0.5, height as f32 - 0.5);
        let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for (u, v) in [(-0.5, -0.5), (r, -0.5), (-0.5, b), (r, b)] {
            let (x, y) = view.apply_point(u, v);
            (x0, x1) = (x0.min(x), x1.max(x));
            (y0, y1) = (y0.min(y), y1.max(y));
        }
        let whole = PixelRect::whole(w, h);
        // The first pixel centre at or after `v`, within `0..=hi` (NaN goes to 0).
        let cell = |v: f32, hi: i32| v.ceil().max(0.0).min(hi as f32) as i32;
        PixelRect {
            x0: cell(x0, whole.x1),
            y0: cell(y0, whole.y1),
            x1: cell(x1, whole.x1),
            y1: cell(y1, whole.y1),
        }
    }

    /// Whether no pixel is in the rectangle.
    pub fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }

    /// The rectangle's sides `[left, top, right, bottom]` in pixel edges (pixel `i` spans
    /// `[i, i + 1]`) where they cut into a `w x h` target, infinite where the rectangle reaches
    /// the target's own edge (what the target clips already is not cut again, so drawing with
    /// the whole target's rectangle is drawing without one).
    pub fn cuts(&self, w: u32, h: u32) -> [f32; 4] {
        let whole = PixelRect::whole(w, h);
        let side = |v: i32, edge: i32, open: f32| if v == edge { open } else { v as f32 };
        [
            side(self.x0, whole.x0, f32::NEG_INFINITY),
            side(self.y0, whole.y0, f32::NEG_INFINITY),
            side(self.x1, whole.x1, f32::INFINITY),
            side(self.y1, whole.y1, f32::INFINITY),
        ]
    }
}

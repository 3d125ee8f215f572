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

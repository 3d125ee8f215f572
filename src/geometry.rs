//! Small geometry shared by every floor of the crate: the axis-aligned box of a point set.

/// An axis-aligned box in image pixels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BBox {
    /// Left edge.
    pub x: f32,
    /// Top edge.
    pub y: f32,
    /// Width.
    pub width: f32,
    /// Height.
    pub height: f32,
}

impl BBox {
    /// Intersection over union with `other` (0 when either is empty).
    pub fn iou(&self, other: &BBox) -> f32 {
        let ix = (self.x + self.width).min(other.x + other.width) - self.x.max(other.x);
        let iy = (self.y + self.height).min(other.y + other.height) - self.y.max(other.y);
        if !(ix > 0.0 && iy > 0.0) {
            return 0.0;
        }
        let inter = ix * iy;
        inter / (self.width * self.height + other.width * other.height - inter)
    }

    /// The bounding box of interleaved points `x0, y0, x1, y1, ...` (the crate's one: every
    /// box of a point set is this). Empty input gives a box at `f32::MAX` with negative size.
    pub fn of_points(points: &[f32]) -> BBox {
        BBox::of_pairs(points.chunks_exact(2).map(|p| (p[0], p[1])))
    }

    /// The bounding box of `(x, y)` pairs (for points transformed on the fly).
    pub fn of_pairs(points: impl IntoIterator<Item = (f32, f32)>) -> BBox {
        let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for (x, y) in points {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        BBox {
            x: x0,
            y: y0,
            width: x1 - x0,
            height: y1 - y0,
        }
    }

    /// The right edge, `x + width`.
    pub fn right(&self) -> f32 {
        self.x + self.width
    }

    /// The bottom edge, `y + height`.
    pub fn bottom(&self) -> f32 {
        self.y + self.height
    }
}

/// Whether a region (a box, a rotated square) is usable: its `position` numbers and its
/// `sides` all finite, and every side at least `min_side`.
pub(crate) fn is_usable_region(position: &[f32], sides: &[f32], min_side: f32) -> bool {
    position.iter().chain(sides).all(|v| v.is_finite()) && sides.iter().all(|&s| s >= min_side)
}

/// The distance from `p` to the outline of the polygon of points `range` of shape `s`.
pub(crate) fn distance_to_polygon(p: [f32; 2], s: &[f32], range: std::ops::Range<usize>) -> f32 {
    let mut best = f32::MAX;
    let mut j = range.end - 1;
    for i in range {
        let (a, b) = ([s[2 * j], s[2 * j + 1]], [s[2 * i], s[2 * i + 1]]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let t = if len2 > 0.0 {
            (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (qx, qy) = (a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
        best = best.min((qx * qx + qy * qy).sqrt());
        j = i;
    }
    best
}

/// True when `p` is inside the polygon of points `range` of shape `s` (even-odd rule).
pub(crate) fn inside_polygon(p: [f32; 2], s: &[f32], range: std::ops::Range<usize>) -> bool {
    let mut inside = false;
    let mut j = range.end - 1;
    for i in range {
        let (a, b) = ([s[2 * i], s[2 * i + 1]], [s[2 * j], s[2 * j + 1]]);
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]
        {
            inside = !inside;
        }
        j = i;
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use wasm_bindgen_test::wasm_bindgen_test;

    #[wasm_bindgen_test(unsupported = test)]
    fn box_of_points_and_iou() {
        let b = BBox::of_points(&[1.0, 5.0, 4.0, 2.0, 3.0, 9.0]);
        assert_eq!(
            b,
            BBox {
                x: 1.0,
                y: 2.0,
                width: 3.0,
                height: 7.0
            }
        );
        assert_eq!((b.right(), b.bottom()), (4.0, 9.0));
        assert_eq!(BBox::of_pairs([(1.0, 5.0), (4.0, 2.0), (3.0, 9.0)]), b);
        assert_eq!(b.iou(&b), 1.0);
        let far = BBox { x: 10.0, ..b };
        assert_eq!(b.iou(&far), 0.0);
    }
}

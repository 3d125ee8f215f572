//! Compositing a rendered face into its model's backdrop (the picture it belongs in): the head
//! of the backdrop moves with the face while the room stays still, the face's colours are
//! matched to the backdrop along its border by a smooth offset field, and its edge is feathered.
//!
//! - [`ExtendedMesh`]: the face mesh extended by two rings of points around the head. The inner
//!   ring moves rigidly with the head (forehead, hair, ears, neck), the outer ring stays where it
//!   is in the backdrop; the band between them absorbs the motion. The whole is warped
//!   piecewise-affinely, so pixels outside the outer ring are the backdrop as it is.
//! - [`mean_value_weights`]: mean-value coordinates of a point with respect to a polygon
//!   (Floater 2003), the interpolant of Farbman et al., "Coordinates for instant image cloning"
//!   (SIGGRAPH 2009): the membrane that carries the border's colour differences inside.
//! - [`Compositor`]: per model precomputation (rings, triangles, the border pixels, the
//!   mean-value weights of every mesh vertex, the feather) and the per-frame composite.

use glam::Vec2;
use tiny_skia::{Pixmap, PixmapMut, PixmapPaint, Transform};

use super::{scanline, skia, DrawOptions, FaceDrawer, PixelRect, Rasterizer};
use crate::error::{check_finite, check_len, Error, Result};
use crate::model::frame::ReferenceFrame;
use crate::model::{Model, Params};
use crate::similarity::Similarity;

// The constants below were chosen by the webcam-dev and franck-dev2 self-reenactment measures
// (tests/integration/composite_measure.rs and composite.rs, docs/compositing.md), within the
// tearing bounds of tests/integration/composite.rs.

/// Distance of the inner ring (moving rigidly with the head) outside the face's hull, in eye
/// distances, at the sides and below; above the brows it is pushed further by [`RING_UP`] to
/// take the forehead and the hair along whole.
const RING_INNER: f32 = 0.45;
/// Extra distance of the inner ring above the brows, in eye distances: the top of the inner
/// ring lies an eye distance above the brows, over the hair of a GRID backdrop, so the hair
/// moves with the head instead of being drawn out between the rings into a cone.
const RING_UP: f32 = 0.55;
/// Width of the fall-off outside the inner ring, in eye distances: the head's motion fades
/// smoothly (smoothstep) to none over it, on [`FALL_LOOPS`] loops; the last loop stays where
/// it is and beyond it the picture is untouched (1.15 eye distances from the face at the sides
/// and below, 1.7 above). Chosen by the webcam-dev room measure: 1 eye distance moved the room
/// (-0.86 dB), 0.8 was at the edge of the 0.5 dB aim (-0.49), 0.7 -0.26; narrower damps
/// strong poses more (the strong-pose golden's share of its pose: 1 -> 0.82, 0.7 -> 0.60).
const FALL_OFF: f32 = 0.7;
/// Loops of the fall-off (the last one fixed).
const FALL_LOOPS: usize = 4;
/// Depth inside the picture's edges, in eye distances, over which the motion away from the
/// nearest edges fades to none: no point on an edge moves inwards off it, so the warp never
/// pulls what lies beyond the picture into it (the clamped reads that bent the edge into a
/// notch); along an edge and outwards (what it shows leaves the picture) points move freely.
const EDGE_FADE: f32 = 0.3;
/// The most a triangle of the warp outside the face may grow in area; follow-pose is damped
/// (the head's motion scaled back towards the backdrop's pose) until none grows more.
const MAX_STRETCH: f32 = 2.0;
/// The least area a triangle of the warp outside the face may keep (a small margin before a
/// fold: the issue limits folds, not squashing; the 1/4 this was first damped the strong
/// poses to a few degrees of roll); damped likewise.
const MAX_SQUASH: f32 = 0.02;
/// Bisection steps of the damping (the applied share of the pose change within 1/256).
const DAMP_STEPS: usize = 8;
/// Width of the feathered edge of the face, in eye distances of the reference frame.
const FEATHER: f32 = 0.07;
/// Depth, in eye distances of the reference frame, over which the colour offset fades from
/// the border (where it matches the backdrop exactly) to none: the inside of the face keeps
/// the model's own colours. Measured: the full membrane (Farbman's) costs 1.6 dB on the face
/// when the backdrop was lit differently from the frame; this fade 0.5 dB.
const OFFSET_FADE: f32 = 0.22;

/// The boundary of a triangle mesh as one closed loop of vertex indices (the edges used by
/// exactly one triangle, chained), counter-clockwise in image axes (y down). Fails when the
/// boundary is not one simple loop.
pub fn hull_loop(triangles: &[[u32; 3]], vertices: &[f32]) -> Result<Vec<u32>> {
    use std::collections::HashMap;
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    for (&(a, b), &c) in &count {
        if c == 1 {
            next.entry(a).or_default().push(b);
            next.entry(b).or_default().push(a);
        }
    }
    let bad = || Error::Training("the mesh boundary is not one simple loop".into());
    if next.is_empty() || next.values().any(|v| v.len() != 2) {
        return Err(bad());
    }
    let start = *next.keys().min().ok_or_else(bad)?;
    let mut lp = vec![start];
    let mut prev = start;
    let mut cur = next[&start][0];
    while cur != start {
        lp.push(cur);
        let n = &next[&cur];
        let nxt = if n[0] == prev { n[1] } else { n[0] };
        prev = cur;
        cur = nxt;
        if lp.len() > next.len() {
            return Err(bad());
        }
    }
    if lp.len() != next.len() {
        return Err(bad());
    }
    // Orientation: make the signed area positive (counter-clockwise with y down = clockwise on
    // screen; any fixed choice will do, it only has to be consistent).
    let p = |i: u32| Vec2::new(vertices[2 * i as usize], vertices[2 * i as usize + 1]);
    let area: f32 = (0..lp.len())
        .map(|k| p(lp[k]).perp_dot(p(lp[(k + 1) % lp.len()])))
        .sum();
    if area < 0.0 {
        lp.reverse();
    }
    Ok(lp)
}

/// The eye distance of a shape: between the outer eye corners (points 37 and 46, 1-based) for
/// 68 points, otherwise a size of the same order (half the square root of the hull's area).
fn eye_distance(points: &[f32], hull: &[u32]) -> f32 {
    if let Some([dx, dy]) = crate::landmarks::eye_line(points) {
        let d = Vec2::new(dx, dy).length();
        if d > 0.0 {
            return d;
        }
    }
    let p = |i: u32| Vec2::new(points[2 * i as usize], points[2 * i as usize + 1]);
    let area: f32 = (0..hull.len())
        .map(|k| p(hull[k]).perp_dot(p(hull[(k + 1) % hull.len()])))
        .sum::<f32>()
        .abs()
        / 2.0;
    area.sqrt() / 2.0
}

/// The direction "up" of a 68-point face (from the mouth towards the brows, perpendicular to
/// the eye line), or `-y` for other layouts.
fn face_up(points: &[f32]) -> Vec2 {
    if let Some([dx, dy]) = crate::landmarks::eye_line(points) {
        let eyes = Vec2::new(dx, dy);
        if eyes.length() > 0.0 {
            // Perpendicular to the eye line, pointing up in the image (y down).
            let up = Vec2::new(eyes.y, -eyes.x).normalize();
            return if up.y <= 0.0 { up } else { -up };
        }
    }
    Vec2::new(0.0, -1.0)
}

/// The face mesh extended by loops around the head, in the backdrop.
///
/// Represents: `n` landmarks, then `1 + FALL_LOOPS` loops of `r` points each (one point per
/// vertex of the face mesh's boundary loop, outwards along the boundary's normal there, cut
/// at the picture's edges): the inner ring, then the fall-off's loops, the last one fixed.
/// Each loop point has a weight: the share of the head's motion it takes (1 on the inner
/// ring, falling smoothly to 0 on the last loop; loops cut at the picture's edge take the
/// weight of where they were cut, so points cut onto one move as one), and per axis a share
/// the picture's edges leave its motion away from them (0 on an edge). Triangles:
/// the face's own (the reference frame's, over the landmarks) plus annuli of quads split in
/// two between consecutive loops, less those of no area in the backdrop (at the picture's
/// edges).
/// Ensures: [`ExtendedMesh::place`] never folds an annulus triangle, nor grows one by more than
/// [`MAX_STRETCH`] or shrinks it below [`MAX_SQUASH`] in area, when the head's motion can be
/// damped to a placement that keeps them (the backdrop's pose and, at the worst, the
/// backdrop's landmarks); no point on the picture's edges moves inwards off it.
#[derive(Clone, Debug)]
pub struct ExtendedMesh {
    points: Vec<f32>,
    triangles: Vec<[u32; 3]>,
    n: usize,
    ring: usize,
    /// Index of the annuli's first triangle (the face's own come first).
    annuli: usize,
    /// The boundary loop's landmarks (the spokes' roots).
    hull: Vec<u32>,
    /// Per loop point, where it lies across the fall-off (0 on the inner ring, 1 on the last
    /// loop).
    falls: Vec<f32>,
    /// Per loop point, the shares of the motion across and down the picture's edges leave it
    /// (1 away from them; none square to an edge on it).
    edges: Vec<Vec2>,
    /// The picture's extent (`-0.5` to `size - 0.5`: no point is placed beyond it).
    size: Vec2,
    /// Per annulus triangle, its signed area in the backdrop.
    areas: Vec<f32>,
    /// The centre of the backdrop's landmarks (the damping's pivot).
    centre: Vec2,
}

/// The largest `t <= want` at which `p + t dir` is still in the picture `[-0.5, w - 0.5] x
/// [-0.5, h - 0.5]` (`p` inside it).
fn inside_along(p: Vec2, dir: Vec2, want: f32, (w, h): (f32, f32)) -> f32 {
    let mut t = want;
    for (x, d, hi) in [(p.x, dir.x, w - 0.5), (p.y, dir.y, h - 0.5)] {
        if d > 1e-6 {
            t = t.min((hi - x) / d);
        } else if d < -1e-6 {
            t = t.min((-0.5 - x) / d);
        }
    }
    t.max(0.0)
}

/// The shares of motion across (x) and down (y) a point `q` takes near the picture's edges:
/// none square to an edge on it, rising (smoothstep) to all at `depth` pixels inside. Along an
/// edge a point may slide (what it reads stays inside the picture); at a corner it cannot.
fn edge_share(q: Vec2, (w, h): (f32, f32), depth: f32) -> Vec2 {
    let depth = depth.max(1e-6);
    let x = (q.x + 0.5).min(w - 0.5 - q.x);
    let y = (q.y + 0.5).min(h - 0.5 - q.y);
    Vec2::new(smoothstep(x / depth), smoothstep(y / depth))
}

fn smoothstep(s: f32) -> f32 {
    let s = s.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

fn signed_area(pts: &[f32], t: &[u32; 3]) -> f32 {
    let p = |i: u32| Vec2::new(pts[2 * i as usize], pts[2 * i as usize + 1]);
    (p(t[1]) - p(t[0])).perp_dot(p(t[2]) - p(t[0]))
}

/// Per vertex of the hull loop, the unit direction outwards along the boundary's normal (the
/// bisector of its two edges' normals): spokes square to the loops keep every annulus
/// triangle the right way round when the head rolls (radial spokes from the centre met an
/// elongated face's jaw at a slant, and a 15-degree roll folded them).
fn spokes(landmarks: &[f32], hull: &[u32], centre: Vec2) -> Vec<Vec2> {
    let p = |i: u32| Vec2::new(landmarks[2 * i as usize], landmarks[2 * i as usize + 1]);
    let r = hull.len();
    (0..r)
        .map(|k| {
            let i = hull[k];
            let n1 = (p(i) - p(hull[(k + r - 1) % r])).perp().normalize_or_zero();
            let n2 = (p(hull[(k + 1) % r]) - p(i)).perp().normalize_or_zero();
            let mut dir = (n1 + n2).normalize_or_zero();
            if dir.dot(p(i) - centre) < 0.0 {
                dir = -dir;
            }
            if dir == Vec2::ZERO {
                dir = (p(i) - centre).normalize_or_zero();
            }
            dir
        })
        .collect()
}

impl ExtendedMesh {
    /// Extends `frame`'s mesh placed on `landmarks` (the backdrop's, in a picture of `size`)
    /// by the inner ring and the fall-off's loops.
    pub fn new(
        frame: &ReferenceFrame,
        landmarks: &[f32],
        size: (u32, u32),
    ) -> Result<ExtendedMesh> {
        check_len("backdrop landmarks", landmarks, frame.vertices().len())?;
        check_finite("backdrop landmarks", landmarks)?;
        let hull = hull_loop(frame.triangles(), frame.vertices())?;
        let d = eye_distance(landmarks, &hull);
        if !(d > 0.0) {
            return Err(Error::Landmarks(
                "the backdrop's landmarks have no extent".into(),
            ));
        }
        let picture = (size.0 as f32, size.1 as f32);
        let p = |i: u32| Vec2::new(landmarks[2 * i as usize], landmarks[2 * i as usize + 1]);
        let centre = hull.iter().map(|&i| p(i)).sum::<Vec2>() / hull.len() as f32;
        let up = face_up(landmarks);
        let (n, r) = (landmarks.len() / 2, hull.len());
        let dirs = spokes(landmarks, &hull, centre);
        let mut points = landmarks.to_vec();
        let mut falls = Vec::with_capacity((FALL_LOOPS + 1) * r);
        let mut edges = Vec::with_capacity((FALL_LOOPS + 1) * r);
        for j in 0..=FALL_LOOPS {
            let fall = j as f32 / FALL_LOOPS as f32;
            for (k, &i) in hull.iter().enumerate() {
                let dir = dirs[k];
                let out = d * (RING_INNER + RING_UP * dir.dot(up).max(0.0) + FALL_OFF * fall);
                // Inside the picture's edges, but never inside the landmark itself (a face at
                // the edge: its loops sit on the landmark, fixed).
                let q = p(i).clamp(Vec2::splat(-0.5), Vec2::new(picture.0, picture.1) - 0.5);
                let t = inside_along(q, dir, out, picture);
                let q = q + dir * t;
                points.extend_from_slice(&[q.x, q.y]);
                // Where the point lies across the fall-off once cut at the edge: the loops
                // cut onto one point move as one (their triangles of no area stay so).
                let start = out - d * FALL_OFF * fall;
                let cut = ((t - start) / (d * FALL_OFF)).clamp(0.0, fall);
                falls.push(if t < out { cut } else { fall });
                edges.push(edge_share(q, picture, d * EDGE_FADE));
            }
        }
        let mut triangles = frame.triangles().to_vec();
        let annuli = triangles.len();
        let ring = |j: usize, k: usize| (n + j * r + k % r) as u32;
        for k in 0..r {
            let (h0, h1) = (hull[k], hull[(k + 1) % r]);
            let quads = std::iter::once([h0, h1, ring(0, k + 1), ring(0, k)]).chain(
                (0..FALL_LOOPS).map(|j| {
                    [
                        ring(j, k),
                        ring(j, k + 1),
                        ring(j + 1, k + 1),
                        ring(j + 1, k),
                    ]
                }),
            );
            for [a, b, c, e] in quads {
                for t in [[a, b, c], [a, c, e]] {
                    // Triangles of no area (cut flat at the picture's edge) draw nothing.
                    if signed_area(&points, &t).abs() > 0.5 {
                        triangles.push(t);
                    }
                }
            }
        }
        let areas = triangles[annuli..]
            .iter()
            .map(|t| signed_area(&points, t))
            .collect();
        Ok(ExtendedMesh {
            points,
            triangles,
            n,
            ring: r,
            annuli,
            hull,
            falls,
            edges,
            size: Vec2::new(picture.0, picture.1),
            areas,
            centre,
        })
    }

    /// All points in the backdrop (landmarks, inner ring, the fall-off's loops), interleaved.
    pub fn points(&self) -> &[f32] {
        &self.points
    }

    /// The triangles (the face's, then the annuli's).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Where the points go when the face is at `image_shape`, the head's motion damped where
    /// the backdrop cannot show it. The head's motion is the similarity `H` that best takes the
    /// backdrop's landmarks onto `image_shape`; applied whole, the landmarks go to
    /// `image_shape` and every loop point `q` to `q + w (H(q) - q + e)`, `e` its spoke's
    /// landmark's motion beyond `H` (the expression: a dropped jaw takes the neck along) and
    /// `w` its weight, `1 - smoothstep(f / b)` (times, per axis, its edge share when the motion
    /// is away from its nearest edges), `f` where it lies across
    /// the fall-off and `b` the narrowest fall-off (at least a quarter of it) that keeps every
    /// triangle: a small motion moves the room no further out than it must. When even the
    /// whole fall-off folds, grows or shrinks a triangle past the limits, the motion is scaled
    /// back (translation, rotation and the logarithm of the scale, about the face's centre, by
    /// the largest share in `[0, 1]` that keeps every triangle) and the landmarks with it: the
    /// face is drawn where its head can go. When even the backdrop's pose tears (the expression
    /// does: a jaw dropped at gain 2 towards the picture's edge), the expression is scaled back
    /// likewise, the landmarks drawn towards the backdrop's. All found by bisection. Writes
    /// `out` (same length
    /// as [`ExtendedMesh::points`]; its first `2n` values are the face's landmarks as drawn)
    /// and returns the share of the motion applied (1: all of it).
    pub fn place(&self, image_shape: &[f32], out: &mut [f32]) -> f32 {
        self.place_within(image_shape, true, out)
    }

    /// [`ExtendedMesh::place`], or with `limit` false the head's whole motion over the widest
    /// fall-off whenever the narrowest would tear (the picture may then fold or stretch: the
    /// face lands where the head is; returns 1).
    pub fn place_within(&self, image_shape: &[f32], limit: bool, out: &mut [f32]) -> f32 {
        let n2 = 2 * self.n;
        let head = Similarity::align(&self.points[..n2], image_shape);
        let narrow = 1.0 / FALL_LOOPS as f32;
        self.place_share(image_shape, &head, 1.0, narrow, out);
        if self.untorn(out) {
            return 1.0;
        }
        self.place_share(image_shape, &head, 1.0, 1.0, out);
        if !limit {
            return 1.0;
        }
        if self.untorn(out) {
            let width = self.bisect(
                narrow,
                1.0,
                |b, out| {
                    self.place_share(image_shape, &head, 1.0, b, out);
                    self.untorn(out)
                },
                out,
            );
            self.place_share(image_shape, &head, 1.0, width, out);
            return 1.0;
        }
        self.place_share(image_shape, &head, 0.0, 1.0, out);
        if !self.untorn(out) {
            // Even the backdrop's pose tears: the expression itself (a jaw dropped at gain 2
            // past the picture's fixed edge) does. Damp it too (the landmarks drawn towards
            // the backdrop's; at none, nothing moves).
            let expr = self.bisect(
                1.0,
                0.0,
                |e, out| {
                    self.place_expr(image_shape, &head, 0.0, 1.0, e, out);
                    self.untorn(out)
                },
                out,
            );
            self.place_expr(image_shape, &head, 0.0, 1.0, expr, out);
            return 0.0;
        }
        let share = self.bisect(
            1.0,
            0.0,
            |s, out| {
                self.place_share(image_shape, &head, s, 1.0, out);
                self.untorn(out)
            },
            out,
        );
        self.place_share(image_shape, &head, share, 1.0, out);
        share
    }

    /// The value between `bad` (failing `good`) and `ok` (passing it, or the fallback) closest
    /// to `bad` that passes, within `1 / 2^DAMP_STEPS` of their distance.
    fn bisect(
        &self,
        bad: f32,
        ok: f32,
        mut good: impl FnMut(f32, &mut [f32]) -> bool,
        out: &mut [f32],
    ) -> f32 {
        let (mut bad, mut ok) = (bad, ok);
        for _ in 0..DAMP_STEPS {
            let mid = 0.5 * (bad + ok);
            if good(mid, out) {
                ok = mid;
            } else {
                bad = mid;
            }
        }
        ok
    }

    /// [`ExtendedMesh::place`] with `share` of the head's motion `head` applied and the
    /// fall-off `width` wide (a share of [`FALL_OFF`]).
    fn place_share(
        &self,
        image_shape: &[f32],
        head: &Similarity,
        share: f32,
        width: f32,
        out: &mut [f32],
    ) {
        self.place_expr(image_shape, head, share, width, 1.0, out);
    }

    /// [`ExtendedMesh::place_share`] with `expr` of the expression applied: the landmarks
    /// drawn from the backdrop's (0) to `image_shape`'s (1), both moved by the damped head.
    fn place_expr(
        &self,
        image_shape: &[f32],
        head: &Similarity,
        share: f32,
        width: f32,
        expr: f32,
        out: &mut [f32],
    ) {
        let n2 = 2 * self.n;
        let c = self.centre;
        let (hx, hy) = head.apply_point(c.x, c.y);
        let damped =
            Similarity::from_parts(head.scale().powf(share), head.rotation() * share, 0.0, 0.0);
        let (dx, dy) = damped.apply_point(c.x, c.y);
        let moved = c + (Vec2::new(hx, hy) - c) * share;
        let damped = Similarity {
            tx: damped.tx + moved.x - dx,
            ty: damped.ty + moved.y - dy,
            ..damped
        };
        // The landmarks: `damped o head^-1` on `image_shape` (exactly `image_shape` whole).
        let back = head.inverse().map(|h| damped.compose(&h));
        for ((o, s), b0) in out[..n2]
            .chunks_exact_mut(2)
            .zip(image_shape.chunks_exact(2))
            .zip(self.points[..n2].chunks_exact(2))
        {
            let (mut x, mut y) = match (share >= 1.0, back) {
                (false, Some(b)) => b.apply_point(s[0], s[1]),
                _ => (s[0], s[1]),
            };
            if expr < 1.0 {
                let (bx, by) = damped.apply_point(b0[0], b0[1]);
                x = bx + expr * (x - bx);
                y = by + expr * (y - by);
            }
            o[0] = x;
            o[1] = y;
        }
        let r = self.ring;
        let (face, loops) = out.split_at_mut(n2);
        for (m, (o, q)) in loops
            .chunks_exact_mut(2)
            .zip(self.points[n2..].chunks_exact(2))
            .enumerate()
        {
            let fall = 1.0 - smoothstep(self.falls[m] / width);
            if fall == 0.0 {
                o.copy_from_slice(q);
                continue;
            }
            let h = 2 * self.hull[m % r] as usize;
            let (lx, ly) = damped.apply_point(self.points[h], self.points[h + 1]);
            let (hx, hy) = damped.apply_point(q[0], q[1]);
            let q = Vec2::new(q[0], q[1]);
            let motion = fall * Vec2::new(hx - q.x + face[h] - lx, hy - q.y + face[h + 1] - ly);
            // Towards its nearest edges a point moves freely (what it shows leaves the
            // picture); away from them only as far as their shares let it (nothing from
            // beyond the picture comes in).
            let outwards = (q * 2.0 - self.size).signum();
            let share = Vec2::select(
                (motion * outwards).cmpgt(Vec2::ZERO),
                Vec2::ONE,
                self.edges[m],
            );
            let moved = q + share * motion;
            o[0] = moved.x;
            o[1] = moved.y;
        }
    }

    /// Whether every annulus triangle of `placed` keeps its orientation and its area within
    /// [`MAX_SQUASH`] and [`MAX_STRETCH`] of the backdrop's.
    fn untorn(&self, placed: &[f32]) -> bool {
        self.triangles[self.annuli..]
            .iter()
            .zip(&self.areas)
            .all(|(t, &a0)| {
                let ratio = signed_area(placed, t) / a0;
                (MAX_SQUASH..=MAX_STRETCH).contains(&ratio)
            })
    }

    /// How many of the annuli's triangles are folded (orientation reversed or collapsed)
    /// at `placed` (a [`ExtendedMesh::place`] output) compared with the backdrop.
    pub fn folded(&self, placed: &[f32]) -> usize {
        self.triangles[self.annuli..]
            .iter()
            .zip(&self.areas)
            .filter(|(t, &a0)| {
                let a1 = signed_area(placed, t);
                !(a0 * a1 > 0.0) || a1.abs() < 1e-3 * a0.abs()
            })
            .count()
    }
}

/// Mean-value coordinates of `x` with respect to the closed polygon `poly` (Floater, "Mean
/// value coordinates", 2003): `w_k = (tan(a_{k-1}/2) + tan(a_k/2)) / |q_k - x|`, normalised,
/// where `a_k` is the angle at `x` between `q_k` and `q_{k+1}`. They reproduce linear
/// functions and constants exactly, and interpolate the polygon's values smoothly inside: the
/// membrane of Farbman et al., "Coordinates for instant image cloning" (2009). A point on a
/// vertex gets that vertex alone. Writes `out` (`poly.len()`).
pub fn mean_value_weights(x: Vec2, poly: &[Vec2], out: &mut [f32]) {
    let k = poly.len();
    out.iter_mut().for_each(|w| *w = 0.0);
    if k == 0 {
        return;
    }
    // tan(a/2) = sin a / (1 + cos a) = (e_k x e_k1) / (r_k r_k1 + e_k . e_k1).
    let e = |i: usize| poly[i % k] - x;
    for i in 0..k {
        if e(i).length() < 1e-6 {
            out[i] = 1.0;
            return;
        }
    }
    let tan_half = |i: usize| {
        let (a, b) = (e(i), e(i + 1));
        let den = a.length() * b.length() + a.dot(b);
        if den.abs() < 1e-12 {
            0.0
        } else {
            a.perp_dot(b) / den
        }
    };
    let mut sum = 0.0f64;
    for i in 0..k {
        let w = (tan_half(i + k - 1) + tan_half(i)) / e(i).length();
        out[i] = w;
        sum += w as f64;
    }
    if sum.abs() > 1e-12 {
        let inv = (1.0 / sum) as f32;
        out.iter_mut().for_each(|w| *w *= inv);
    }
}

/// Composites one model's faces into its backdrop.
///
/// Represents: for one model with a backdrop, the backdrop as textures, its `ExtendedMesh`,
/// the frame's border pixels (in order around the face) with the backdrop's colours there, the
/// mean-value weights of every frame vertex with respect to that border, the feathered edge
/// (a coverage per frame pixel) and the scratch of one frame.
/// Requires: the model it was made for ([`Compositor::draw`] checks the frame and landmark
/// counts). Ensures: a frame allocates nothing once the cache of the static backdrop is made for
/// the canvas; nothing is drawn outside the picture (the target's pixels whose centres the
/// picture covers through the view, `PixelRect::picture`: around a letterboxed picture the
/// caller's background stays exactly as painted); pixels outside the outer ring are the
/// backdrop's (through the view); the face's colour offset is the mean-value interpolation of
/// the border differences, so a constant difference is removed exactly.
#[derive(Debug)]
pub struct Compositor {
    fingerprint: u64,
    size: (u32, u32),
    backdrop: Pixmap,
    words: Vec<u32>,
    mesh: ExtendedMesh,
    /// Frame pixel indices of the border, ordered around the face.
    border: Vec<u32>,
    /// The backdrop's colours at the border pixels (3 per pixel), sampled once.
    border_backdrop: Vec<f32>,
    /// Mean-value weights: one row of `border.len()` per frame vertex.
    weights: Vec<f32>,
    /// Coverage of each frame pixel (the feathered edge).
    alpha: Vec<f32>,
    /// Share of the colour offset each frame pixel takes (1 at the border).
    decay: Vec<f32>,
    drawer: FaceDrawer,
    /// Static backdrop under the last view: (view, width, height, pixels).
    cache: Option<(Similarity, u32, u32, Pixmap)>,
    /// The extended mesh placed for the last frame (the face's landmarks as drawn first).
    placed: Vec<f32>,
    /// The share of the head's motion the last frame applied.
    damping: f32,
    /// Whether follow-pose is damped where the backdrop would tear (the default).
    keep_whole: bool,
    dst: Vec<Vec2>,
    diff: Vec<f32>,
    smooth: Vec<f32>,
    offsets: Vec<f32>,
    rgb: Vec<f32>,
    instance: super::Instance,
    path: Option<tiny_skia::PathBuilder>,
    /// Per face triangle, whether the face covers it opaquely (every pixel in it is at least
    /// twice the feather's width inside the border): the head warp skips it.
    opaque: Vec<bool>,
    /// The triangles of the head warp of the current frame.
    draw_list: Vec<[u32; 3]>,
}

impl Compositor {
    /// The compositor of `model`'s faces, drawing with `options`. Fails with
    /// [`Error::Params`] when the model has no backdrop.
    pub fn new(model: &Model, options: DrawOptions) -> Result<Compositor> {
        let b = model.backdrop().ok_or_else(|| {
            Error::Params(format!(
                "model '{}' has no backdrop to composite into",
                model.name()
            ))
        })?;
        let frame = model.frame();
        let (w, h) = (b.width(), b.height());
        let mesh = ExtendedMesh::new(frame, b.landmarks(), (w, h))?;
        let mut backdrop =
            Pixmap::new(w, h).ok_or_else(|| Error::Image(format!("backdrop {w}x{h} too large")))?;
        backdrop.data_mut().copy_from_slice(b.rgba());
        let words = b
            .rgba()
            .chunks_exact(4)
            .map(|p| u32::from_le_bytes([p[0], p[1], p[2], 255]))
            .collect();

        let border = border_pixels(frame);
        let image = b.image();
        let tris = frame.triangles();
        let lm = b.landmarks();
        let mut border_backdrop = Vec::with_capacity(3 * border.len());
        for &k in &border {
            let px = frame.pixels()[k as usize];
            let t = tris[px.triangle as usize];
            let (mut x, mut y) = (0.0, 0.0);
            for j in 0..3 {
                x += px.bary[j] * lm[2 * t[j] as usize];
                y += px.bary[j] * lm[2 * t[j] as usize + 1];
            }
            border_backdrop.extend_from_slice(&image.sample_rgb(x, y));
        }
        let [ox, oy] = frame.origin();
        let poly: Vec<Vec2> = border
            .iter()
            .map(|&k| {
                let px = frame.pixels()[k as usize];
                Vec2::new(px.x as f32 - ox, px.y as f32 - oy)
            })
            .collect();
        let v = frame.vertices();
        let nv = v.len() / 2;
        let mut weights = vec![0.0; nv * border.len()];
        for (i, row) in weights.chunks_exact_mut(border.len().max(1)).enumerate() {
            mean_value_weights(Vec2::new(v[2 * i], v[2 * i + 1]), &poly, row);
        }
        let alpha = feather(frame, FEATHER)?;
        let mut opaque = vec![true; tris.len()];
        for (px, a) in frame.pixels().iter().zip(feather(frame, 2.0 * FEATHER)?) {
            if a < 1.0 {
                opaque[px.triangle as usize] = false;
            }
        }
        let decay = feather(frame, OFFSET_FADE)?
            .into_iter()
            .map(|a| 1.0 - a)
            .collect();
        let n_px = frame.n_pixels();
        let mesh_triangles = mesh.triangles().len();
        Ok(Compositor {
            fingerprint: frame.fingerprint(),
            size: (w, h),
            backdrop,
            words,
            placed: vec![0.0; mesh.points().len()],
            damping: 1.0,
            keep_whole: true,
            dst: Vec::with_capacity(mesh.points().len() / 2),
            mesh,
            diff: vec![0.0; 3 * border.len()],
            smooth: vec![0.0; 3 * border.len()],
            border,
            border_backdrop,
            weights,
            alpha,
            decay,
            drawer: FaceDrawer::new(frame, options)?,
            cache: None,
            offsets: vec![0.0; 3 * nv],
            rgb: vec![0.0; 3 * n_px],
            instance: super::Instance::new(frame),
            path: Some(tiny_skia::PathBuilder::new()),
            opaque,
            draw_list: Vec::with_capacity(mesh_triangles),
        })
    }

    /// The backdrop's size `(width, height)`: the size of a composite at the identity view.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The extended mesh (for tests and tools).
    pub fn mesh(&self) -> &ExtendedMesh {
        &self.mesh
    }

    /// Places the extended mesh for a face at `image_shape` (its landmarks in the backdrop's
    /// pixels) as [`Compositor::draw`] does (`ExtendedMesh::place`: the head's motion damped
    /// where the backdrop cannot show it), and returns the placed points, the face's landmarks
    /// as drawn first (for tests and tools).
    pub fn place_head(&mut self, image_shape: &[f32]) -> &[f32] {
        self.damping = self
            .mesh
            .place_within(image_shape, self.keep_whole, &mut self.placed);
        &self.placed
    }

    /// The share of the head's motion the last frame applied (1: all of it; less where
    /// follow-pose was damped so that the backdrop's warp neither folds nor stretches).
    pub fn pose_share(&self) -> f32 {
        self.damping
    }

    /// Whether the picture is kept whole (the default): follow-pose is damped where the
    /// backdrop's warp would fold or stretch past 2x, so a large head motion shows in part
    /// ([`Compositor::pose_share`]). Off, the head's whole motion is applied over the widest
    /// fall-off: the face lands where the head is, and the picture around it may fold or
    /// stretch (measured in docs/compositing.md, "Pictures that never tear").
    pub fn set_keep_whole(&mut self, keep_whole: bool) {
        self.keep_whole = keep_whole;
    }

    /// See [`Compositor::set_keep_whole`].
    pub fn keeps_whole(&self) -> bool {
        self.keep_whole
    }

    /// The drawing options.
    pub fn options(&self) -> DrawOptions {
        self.drawer.options()
    }

    /// Changes the drawing options.
    pub fn set_options(&mut self, options: DrawOptions) {
        self.drawer.set_options(options);
    }

    /// Composites a model instance: synthesises its shape (Eq. 1, posed by `params.pose` in
    /// the backdrop's pixels) and appearance (Eq. 2), then [`Compositor::draw`]s them.
    pub fn render(
        &mut self,
        model: &Model,
        params: &Params,
        view: &Similarity,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        model.check_params(params)?;
        self.check_model(model)?;
        let instance = super::Instance::synthesise(&mut self.instance, model, params)?;
        let r = self.draw(model, &instance.appearance, &instance.shape, view, target);
        self.instance = instance;
        r
    }

    fn check_model(&self, model: &Model) -> Result<()> {
        if model.frame().fingerprint() != self.fingerprint || model.landmarks() != self.mesh.n {
            return Err(Error::Incompatible(format!(
                "compositor was made for another model than '{}'",
                model.name()
            )));
        }
        Ok(())
    }

    /// Composites a face given by its appearance (`3N`, frame pixels) and its landmarks in the
    /// backdrop's pixels (`image_shape`), through `view` (backdrop pixels to target pixels),
    /// into `target`: the static backdrop, the head warped by the extended mesh, then the face,
    /// colour-matched and feathered, the last two within the picture's pixels (the box around
    /// it for a rotated view).
    pub fn draw(
        &mut self,
        model: &Model,
        appearance: &[f32],
        image_shape: &[f32],
        view: &Similarity,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        self.check_model(model)?;
        let frame = model.frame();
        check_len("appearance", appearance, 3 * frame.n_pixels())?;
        check_len("shape", image_shape, frame.vertices().len())?;
        check_finite("shape", image_shape)?;
        check_finite("appearance", appearance)?;
        if !view.is_valid() {
            return Err(Error::Params("the view is not a valid similarity".into()));
        }
        self.paint_static(view, target);
        // The head and the face are drawn within the picture only: around a letterboxed
        // picture the caller's background stays as it was painted (the mesh under the chin and
        // a face near the edge reach beyond the picture, where the warp would smear its edge).
        let clip = PixelRect::picture(view, self.size, (target.width(), target.height()));
        self.warp_head(image_shape, view, clip, target)?;
        self.colour_match(frame, appearance);
        let rgb = std::mem::take(&mut self.rgb);
        // The face where the head went (follow-pose damped where the backdrop cannot show it).
        let shape = &self.placed[..image_shape.len()];
        let r = self
            .drawer
            .upload_with_alpha(frame, &rgb, &self.alpha)
            .and_then(|_| self.drawer.warp_in(frame, shape, view, clip, target));
        self.rgb = rgb;
        r
    }

    /// The backdrop as it is, through `view`, into `target` (from a cache made once per view and
    /// canvas size, over what `target` held then: the caller's background shows around a
    /// letterboxed picture).
    fn paint_static(&mut self, view: &Similarity, target: &mut PixmapMut<'_>) {
        let (w, h) = (target.width(), target.height());
        let fresh =
            matches!(&self.cache, Some((v, cw, ch, _)) if v == view && *cw == w && *ch == h);
        if !fresh {
            let mut p = match Pixmap::new(w, h) {
                Some(p) => p,
                None => return,
            };
            let identity = *view == Similarity::IDENTITY && (w, h) == self.size;
            if identity {
                p.data_mut().copy_from_slice(self.backdrop.data());
            } else {
                // What the caller painted (a background) shows around a letterboxed picture.
                p.data_mut().copy_from_slice(target.data_mut());
                let tr = centred(view);
                let paint = PixmapPaint {
                    quality: tiny_skia::FilterQuality::Bilinear,
                    ..PixmapPaint::default()
                };
                p.draw_pixmap(0, 0, self.backdrop.as_ref(), &paint, tr, None);
            }
            self.cache = Some((*view, w, h, p));
        }
        if let Some((_, _, _, p)) = &self.cache {
            target.data_mut().copy_from_slice(p.data());
        }
    }

    /// Warps the backdrop's head region by the extended mesh placed at `image_shape`: every
    /// triangle but those the face covers opaquely and those whose corners did not move (their
    /// warp is the identity: the static picture already shows them; the outer annulus while
    /// the head moves little).
    fn warp_head(
        &mut self,
        image_shape: &[f32],
        view: &Similarity,
        clip: PixelRect,
        target: &mut PixmapMut<'_>,
    ) -> Result<()> {
        self.damping = self
            .mesh
            .place_within(image_shape, self.keep_whole, &mut self.placed);
        self.dst.clear();
        for p in self.placed.chunks_exact(2) {
            let (x, y) = view.apply_point(p[0], p[1]);
            if !(x.abs() < 1e6 && y.abs() < 1e6) {
                return Err(Error::Params(
                    "the face is placed too far outside the canvas".into(),
                ));
            }
            self.dst.push(Vec2::new(x, y));
        }
        let pts = &self.mesh.points;
        let placed = &self.placed;
        let still = |i: u32| {
            let i = 2 * i as usize;
            pts[i] == placed[i] && pts[i + 1] == placed[i + 1]
        };
        self.draw_list.clear();
        for (j, t) in self.mesh.triangles.iter().enumerate() {
            let covered = self.opaque.get(j).copied().unwrap_or(false);
            if !covered && !t.iter().all(|&i| still(i)) {
                self.draw_list.push(*t);
            }
        }
        let src = |i: usize| Vec2::new(pts[2 * i], pts[2 * i + 1]);
        let (bw, bh) = (self.size.0 as i32, self.size.1 as i32);
        match self.drawer.options().rasterizer {
            Rasterizer::Scanline => scanline::warp_mesh(
                &self.words,
                (bw, bh),
                src,
                &self.dst,
                &self.draw_list,
                clip,
                target,
            ),
            Rasterizer::TinySkia => {
                let dst = &self.dst;
                skia::warp_mesh(
                    self.backdrop.as_ref(),
                    src,
                    |i| dst[i],
                    &self.draw_list,
                    clip,
                    &mut self.path,
                    target,
                )
            }
        }
        Ok(())
    }

    /// The face's colours matched to the backdrop: the differences along the border (backdrop
    /// minus face), smoothed along it, carried to every frame vertex by the mean-value weights
    /// and across each triangle by the frame's barycentrics, added to `appearance` into
    /// `self.rgb`.
    fn colour_match(&mut self, frame: &ReferenceFrame, appearance: &[f32]) {
        let k = self.border.len();
        if k == 0 {
            self.rgb.copy_from_slice(appearance);
            return;
        }
        for (j, &px) in self.border.iter().enumerate() {
            for c in 0..3 {
                self.diff[3 * j + c] =
                    self.border_backdrop[3 * j + c] - appearance[3 * px as usize + c];
            }
        }
        // A [1 4 6 4 1] / 16 smoothing along the (closed) border: one noisy pixel does not
        // decide a vertex's offset.
        const TAPS: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
        for j in 0..k {
            for c in 0..3 {
                let mut s = 0.0;
                for (t, w) in TAPS.iter().enumerate() {
                    let i = (j + k + t - 2) % k;
                    s += w * self.diff[3 * i + c];
                }
                self.smooth[3 * j + c] = s;
            }
        }
        for (o, row) in self
            .offsets
            .chunks_exact_mut(3)
            .zip(self.weights.chunks_exact(k))
        {
            let mut acc = [0f32; 3];
            for (w, d) in row.iter().zip(self.smooth.chunks_exact(3)) {
                acc[0] += w * d[0];
                acc[1] += w * d[1];
                acc[2] += w * d[2];
            }
            o.copy_from_slice(&acc);
        }
        let tris = frame.triangles();
        for (((px, a), out), &share) in frame
            .pixels()
            .iter()
            .zip(appearance.chunks_exact(3))
            .zip(self.rgb.chunks_exact_mut(3))
            .zip(&self.decay)
        {
            let t = tris[px.triangle as usize];
            for c in 0..3 {
                let off = px.bary[0] * self.offsets[3 * t[0] as usize + c]
                    + px.bary[1] * self.offsets[3 * t[1] as usize + c]
                    + px.bary[2] * self.offsets[3 * t[2] as usize + c];
                out[c] = (a[c] + share * off).clamp(0.0, 1.0);
            }
        }
    }

    /// The colour offset of the last frame at every frame vertex (3 per vertex), for tests.
    pub fn vertex_offsets(&self) -> &[f32] {
        &self.offsets
    }

    /// The colour-matched appearance of the last frame (`3N`), for tests.
    pub fn matched_appearance(&self) -> &[f32] {
        &self.rgb
    }
}

/// The tiny-skia transform drawing a bitmap whose pixel centres are on integers through `view`
/// (whose coordinates also put centres on integers): `x + 0.5 = view(u - 0.5 + 0.5) + 0.5`.
fn centred(view: &Similarity) -> Transform {
    Transform::from_row(view.a, view.b, -view.b, view.a, view.tx, view.ty)
        .pre_translate(-0.5, -0.5)
        .post_translate(0.5, 0.5)
}

/// The frame pixels on the mesh's border (a 4-neighbour outside the mesh), ordered by angle
/// around their centroid.
fn border_pixels(frame: &ReferenceFrame) -> Vec<u32> {
    let (w, h) = (frame.width() as i64, frame.height() as i64);
    let mut inside = vec![false; (w * h) as usize];
    for px in frame.pixels() {
        inside[(px.y as i64 * w + px.x as i64) as usize] = true;
    }
    let is_in = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h && inside[(y * w + x) as usize];
    let mut border: Vec<u32> = frame
        .pixels()
        .iter()
        .enumerate()
        .filter(|(_, px)| {
            let (x, y) = (px.x as i64, px.y as i64);
            !(is_in(x - 1, y) && is_in(x + 1, y) && is_in(x, y - 1) && is_in(x, y + 1))
        })
        .map(|(i, _)| i as u32)
        .collect();
    let pts = frame.pixels();
    let n = border.len().max(1) as f32;
    let c = border.iter().fold(Vec2::ZERO, |acc, &i| {
        acc + Vec2::new(pts[i as usize].x as f32, pts[i as usize].y as f32)
    }) / n;
    border.sort_by(|&a, &b| {
        let ang = |i: u32| {
            let p = pts[i as usize];
            (p.y as f32 - c.y).atan2(p.x as f32 - c.x)
        };
        ang(a).total_cmp(&ang(b))
    });
    border
}

/// A ramp from the mesh's boundary inwards: each frame pixel's value rises from 0 at the
/// boundary to 1 at `eyes` eye distances inside it (smoothstep). With [`FEATHER`], the coverage
/// of the feathered edge; with [`OFFSET_FADE`], one minus the colour offset's share.
fn feather(frame: &ReferenceFrame, eyes: f32) -> Result<Vec<f32>> {
    let v = frame.vertices();
    let hull = hull_loop(frame.triangles(), v)?;
    let width = (eyes * eye_distance(v, &hull)).max(1.0);
    let [ox, oy] = frame.origin();
    let p = |i: u32| Vec2::new(v[2 * i as usize], v[2 * i as usize + 1]);
    Ok(frame
        .pixels()
        .iter()
        .map(|px| {
            let x = Vec2::new(px.x as f32 - ox, px.y as f32 - oy);
            let mut d = f32::MAX;
            for k in 0..hull.len() {
                let (a, b) = (p(hull[k]), p(hull[(k + 1) % hull.len()]));
                let ab = b - a;
                let t = ((x - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
                d = d.min((a + ab * t - x).length());
            }
            let s = (d / width).clamp(0.0, 1.0);
            s * s * (3.0 - 2.0 * s)
        })
        .collect())
}

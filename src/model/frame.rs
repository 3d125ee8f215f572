//! The reference frame: base mesh, pixel grid and per-pixel barycentrics.

use crate::error::{Error, Result};

/// Margin, in frame pixels, kept around the base mesh (room for the render padding ring).
pub const FRAME_MARGIN: f32 = 3.0;

/// One pixel of the reference frame that lies inside the base mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FramePixel {
    /// Column in the frame grid.
    pub x: u16,
    /// Row in the frame grid.
    pub y: u16,
    /// Index of the triangle that contains the pixel centre.
    pub triangle: u32,
    /// Barycentric coordinates of the pixel centre in that triangle (sum to 1).
    pub bary: [f32; 3],
}

/// The reference frame in which appearance lives: the paper's "pixels x inside the base mesh s0".
///
/// Represents: a triangulated base mesh (vertices in model coordinates), a `width x height`
/// pixel grid whose pixel `(c, r)` has its centre at model coordinates `(c - origin.x,
/// r - origin.y)`, and for every grid pixel inside the mesh its triangle and barycentric
/// coordinates, precomputed once. Pixels are listed row-major; appearance vectors hold one RGB
/// triple per listed pixel in that order.
///
/// Ensures: every pixel centre inside the mesh appears once; the fingerprint changes whenever
/// anything that decides the pixels changes, so two models whose appearance vectors live on the
/// same pixels (a requirement of cloning) have equal fingerprints.
#[derive(Clone, Debug)]
pub struct ReferenceFrame {
    width: u32,
    height: u32,
    origin: [f32; 2],
    vertices: Vec<f32>,
    triangles: Vec<[u32; 3]>,
    pixels: Vec<FramePixel>,
    /// Pixels just outside the mesh (up to two pixels away) and the inside pixel whose colour
    /// they take: padding so that bilinear filtering at the mesh border never reads background.
    padding: Vec<(u32, u32)>,
    fingerprint: u64,
}

impl PartialEq for ReferenceFrame {
    fn eq(&self, other: &Self) -> bool {
        self.fingerprint == other.fingerprint
            && self.width == other.width
            && self.height == other.height
            && self.origin == other.origin
            && self.vertices == other.vertices
            && self.triangles == other.triangles
    }
}

/// Largest frame side the library accepts (also a model-file limit).
pub const MAX_FRAME_SIDE: u32 = 2048;

/// Triangulates a base shape (model coordinates) with a Delaunay triangulation, dropping
/// near-degenerate slivers on the hull (area below 0.5% of the mean triangle area).
pub fn triangulate(base: &[f32]) -> Result<Vec<[u32; 3]>> {
    let pts: Vec<delaunator::Point> = base
        .chunks_exact(2)
        .map(|p| delaunator::Point {
            x: p[0] as f64,
            y: p[1] as f64,
        })
        .collect();
    let t = delaunator::triangulate(&pts);
    if t.triangles.is_empty() {
        return Err(Error::Training(
            "the base shape cannot be triangulated (collinear points?)".into(),
        ));
    }
    let tris: Vec<[u32; 3]> = t
        .triangles
        .chunks_exact(3)
        .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
        .collect();
    let area = |t: &[u32; 3]| tri_area(base, t).abs();
    let mean_area = tris.iter().map(area).sum::<f32>() / tris.len() as f32;
    Ok(tris
        .into_iter()
        .filter(|t| area(t) > 0.005 * mean_area)
        .collect())
}

fn tri_area(v: &[f32], t: &[u32; 3]) -> f32 {
    let p = |i: u32| (v[2 * i as usize], v[2 * i as usize + 1]);
    let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
    0.5 * ((b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1))
}

/// Rasterises the mesh (shifted by `origin`) onto the `width x height` grid: per grid cell,
/// the first non-degenerate triangle whose closure holds the cell's centre (`u32::MAX` for
/// none) and the centre's barycentric coordinates in it.
fn rasterise(
    vertices: &[f32],
    triangles: &[[u32; 3]],
    width: u32,
    height: u32,
    origin: [f32; 2],
) -> (Vec<u32>, Vec<[f32; 3]>) {
    let mut owner = vec![u32::MAX; (width * height) as usize];
    let mut bary = vec![[0f32; 3]; (width * height) as usize];
    for (ti, t) in triangles.iter().enumerate() {
        let p = |i: u32| {
            (
                vertices[2 * i as usize] + origin[0],
                vertices[2 * i as usize + 1] + origin[1],
            )
        };
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        let det = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
        if det.abs() < 1e-9 {
            continue;
        }
        let x0 = a.0.min(b.0).min(c.0).floor().max(0.0) as u32;
        let x1 = (a.0.max(b.0).max(c.0).ceil() as u32).min(width - 1);
        let y0 = a.1.min(b.1).min(c.1).floor().max(0.0) as u32;
        let y1 = (a.1.max(b.1).max(c.1).ceil() as u32).min(height - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f32, y as f32);
                let l1 = ((px - a.0) * (c.1 - a.1) - (c.0 - a.0) * (py - a.1)) / det;
                let l2 = ((b.0 - a.0) * (py - a.1) - (px - a.0) * (b.1 - a.1)) / det;
                let l0 = 1.0 - l1 - l2;
                let eps = -1e-4;
                let k = (y * width + x) as usize;
                if l0 >= eps && l1 >= eps && l2 >= eps && owner[k] == u32::MAX {
                    owner[k] = ti as u32;
                    bary[k] = [l0, l1, l2];
                }
            }
        }
    }
    (owner, bary)
}

/// The frame pixels of a rasterised grid ([`rasterise`]) in row-major order, and the grid's
/// index into them (`u32::MAX` outside the mesh).
fn collect_pixels(
    owner: &[u32],
    bary: &[[f32; 3]],
    width: u32,
    height: u32,
) -> (Vec<FramePixel>, Vec<u32>) {
    let mut pixels = Vec::new();
    let mut index = vec![u32::MAX; (width * height) as usize];
    for y in 0..height {
        for x in 0..width {
            let k = (y * width + x) as usize;
            if owner[k] != u32::MAX {
                index[k] = pixels.len() as u32;
                pixels.push(FramePixel {
                    x: x as u16,
                    y: y as u16,
                    triangle: owner[k],
                    bary: bary[k],
                });
            }
        }
    }
    (pixels, index)
}

/// Two rings of padding around the frame pixels, each cell taking the colour of an
/// already-covered 8-neighbour: `(grid index, frame pixel to copy)`. Marks the padded cells in
/// `index` as it goes.
fn padding_rings(index: &mut [u32], width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut padding = Vec::new();
    for _ in 0..2 {
        let mut ring = Vec::new();
        for y in 0..height as i64 {
            for x in 0..width as i64 {
                let k = (y * width as i64 + x) as usize;
                if index[k] != u32::MAX {
                    continue;
                }
                'n: for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (nx, ny) = (x + dx, y + dy);
                        if nx < 0 || ny < 0 || nx >= width as i64 || ny >= height as i64 {
                            continue;
                        }
                        let nk = (ny * width as i64 + nx) as usize;
                        if index[nk] != u32::MAX {
                            ring.push((k as u32, index[nk]));
                            break 'n;
                        }
                    }
                }
            }
        }
        for &(k, src) in &ring {
            index[k as usize] = src;
        }
        padding.extend(ring);
    }
    padding
}

impl ReferenceFrame {
    /// Builds the frame for a base shape: triangulates it and sizes the grid to its bounding
    /// box plus a margin of `FRAME_MARGIN` (3) pixels.
    pub fn from_base(base: &[f32]) -> Result<ReferenceFrame> {
        let triangles = triangulate(base)?;
        let b = crate::geometry::BBox::of_points(base);
        let (minx, miny, maxx, maxy) = (b.x, b.y, b.right(), b.bottom());
        let origin = [(FRAME_MARGIN - minx).ceil(), (FRAME_MARGIN - miny).ceil()];
        let width = (maxx + origin[0] + FRAME_MARGIN).ceil() as u32 + 1;
        let height = (maxy + origin[1] + FRAME_MARGIN).ceil() as u32 + 1;
        Self::new(base.to_vec(), triangles, width, height, origin)
    }

    /// Builds a frame from its defining parts, computing the pixels and the fingerprint.
    ///
    /// Requires: finite vertices, triangle indices in range, `1 <= width, height <=
    /// MAX_FRAME_SIDE`. Fails with [`Error::Training`] otherwise or if no pixel is inside.
    pub fn new(
        vertices: Vec<f32>,
        triangles: Vec<[u32; 3]>,
        width: u32,
        height: u32,
        origin: [f32; 2],
    ) -> Result<ReferenceFrame> {
        let bad = |m: String| Err(Error::Training(m));
        if width == 0 || height == 0 || width > MAX_FRAME_SIDE || height > MAX_FRAME_SIDE {
            return bad(format!(
                "frame size {width}x{height} outside 1..={MAX_FRAME_SIDE}"
            ));
        }
        if vertices.len() < 6 || vertices.len() % 2 != 0 || vertices.iter().any(|v| !v.is_finite())
        {
            return bad("frame vertices must be at least 3 finite points".into());
        }
        if !origin[0].is_finite() || !origin[1].is_finite() {
            return bad("frame origin is not finite".into());
        }
        let n = (vertices.len() / 2) as u32;
        if triangles.is_empty() || triangles.iter().flatten().any(|&i| i >= n) {
            return bad("frame triangles are empty or index a missing vertex".into());
        }
        let (owner, bary) = rasterise(&vertices, &triangles, width, height, origin);
        let (pixels, mut index) = collect_pixels(&owner, &bary, width, height);
        if pixels.is_empty() {
            return bad("no frame pixel lies inside the mesh".into());
        }
        let padding = padding_rings(&mut index, width, height);
        let fingerprint = fingerprint(width, height, origin, &vertices, &triangles);
        Ok(ReferenceFrame {
            width,
            height,
            origin,
            vertices,
            triangles,
            pixels,
            padding,
            fingerprint,
        })
    }

    /// Grid width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Grid height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Frame pixel coordinates of the model-coordinate origin.
    pub fn origin(&self) -> [f32; 2] {
        self.origin
    }
    /// The base mesh vertices in model coordinates (interleaved).
    pub fn vertices(&self) -> &[f32] {
        &self.vertices
    }
    /// The base mesh triangles (vertex indices).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
    /// The pixels inside the mesh, row-major.
    pub fn pixels(&self) -> &[FramePixel] {
        &self.pixels
    }
    /// Number of pixels inside the mesh (`N`; appearance vectors have `3N` values).
    pub fn n_pixels(&self) -> usize {
        self.pixels.len()
    }
    /// Padding pixels: `(grid index, index of the inside pixel whose colour it copies)`.
    pub fn padding(&self) -> &[(u32, u32)] {
        &self.padding
    }
    /// A 64-bit FNV-1a hash of everything that decides the pixels.
    pub fn fingerprint(&self) -> u64 {
        self.fingerprint
    }
    /// Number of landmarks (mesh vertices).
    pub fn landmarks(&self) -> usize {
        self.vertices.len() / 2
    }
}

fn fingerprint(width: u32, height: u32, origin: [f32; 2], v: &[f32], t: &[[u32; 3]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&width.to_le_bytes());
    eat(&height.to_le_bytes());
    origin.iter().for_each(|o| eat(&o.to_le_bytes()));
    v.iter().for_each(|x| eat(&x.to_le_bytes()));
    t.iter().flatten().for_each(|i| eat(&i.to_le_bytes()));
    h
}

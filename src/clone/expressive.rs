//! The expressive method: strong expressions arrive on every target, in the target's own
//! proportions and colours.
//!
//! Per frame, once for all targets ([`SourceFrame::prepare`]): the source's gained shape
//! displacement `d = S p`, scaled per region (mouth, eyes, brows), and the source's expression
//! ratio image `rho = Y(A0 + A lambda) / Y(A0)` on luminance (Liu, Shan & Zhang, "Expressive
//! expression mapping with ratio images", SIGGRAPH 2001), powered per region.
//!
//! Per target ([`ExpressiveTarget`]):
//! - **shape** ([`expressive_shape`]): `u = L d`, the displacement fitted to the target's
//!   proportions by deformation transfer ([`super::transfer`]); bounded as a whole by its
//!   Mahalanobis distance under the generic [`ExpressionPrior`]; the part the target's own modes
//!   can show (`p* = S*^T u`, limited to `k + sqrt(q)` in the target's Mahalanobis norm) plus, by `style`,
//!   the residual `u - S* p*` computed AFTER that limit; then lips and eyelids never cross and
//!   no triangle folds.
//! - **appearance** ([`expressive_appearance`]): the target's own face times the ratio image
//!   (so skin tone, beard, make-up and lighting stay the target's); the inner mouth shaded by
//!   the source's mouth and coloured for the target (teeth white-balanced to the target's
//!   picture, the dark parts in its lip tones); closed eyelids in the target's lid skin.

use crate::error::Result;
use crate::geometry::{distance_to_polygon, inside_polygon};
use crate::model::Model;

use super::prior::ExpressionPrior;
use super::transfer::{transfer_displacement, transfer_operator};

/// Luminance of an RGB triple (Rec. 601 weights), the channel the ratio image lives on.
#[inline]
pub fn luma(rgb: &[f32]) -> f32 {
    let [r, g, b] = crate::image::LUMA;
    r * rgb[0] + g * rgb[1] + b * rgb[2]
}

/// The ratio image's offset (appearance units, 0..1): keeps dark pixels' ratios from
/// exploding on noise (about ten grey levels).
pub const RATIO_OFFSET: f32 = 0.04;
/// The ratio image's offset grows with the source's skin by this share of its mean skin
/// luminance (added to [`RATIO_OFFSET`]): dark skin's luminance is small, so its ratios would
/// otherwise swing with every highlight. A luminance change carries at about `Y0 / (Y0 +
/// offset)` of itself (0.85 on mid-tone skin). Chosen with [`RATIO_RANGE`]'s upper end among
/// 0.1-0.6 on the London pairs (every 7th) and franck-dev through his own model
/// (docs/cloning.md): the creases, raised cheeks and lids' shading of a laugh carry. It was
/// 0.6 until 29 Nov, when a ratio could brighten 2.5-fold: the London faces then lost more to
/// another person's highlights than a stronger shading gained.
pub const RATIO_SKIN_SHARE: f32 = 0.1;
/// The ratio image's range: no pixel is darkened by more than the first factor or brightened by
/// more than the second. A smile's shading is mostly shadow (the creases, the raised cheeks'
/// undersides, the lids), its brightening mostly the shine of the person's own skin in their
/// own light; carried up to 2.5-fold (until 29 Nov), a source's highlights became pale patches
/// on a darker target's chin. Chosen among 1.0-2.5 (docs/cloning.md): 1.15 keeps the judge's
/// figure within 0.01 and every London measure improves; none at all (1.0) loses a fifth of it.
pub const RATIO_RANGE: [f32; 2] = [0.4, 1.15];

/// Per-region gains of the expressive method: each multiplies the source's shape displacement
/// of its landmarks and powers its ratio image (1 = as the source does, 0 = none, 2 = twice).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionGains {
    /// The mouth, the lips and the jaw below them.
    pub mouth: f32,
    /// The eyes and eyelids.
    pub eyes: f32,
    /// The brows.
    pub brows: f32,
}

impl Default for RegionGains {
    fn default() -> Self {
        RegionGains {
            mouth: 1.0,
            eyes: 1.0,
            brows: 1.0,
        }
    }
}

impl RegionGains {
    /// The gain of region `r` (0 the rest of the face, which keeps 1).
    fn of(&self, r: u8) -> f32 {
        match r {
            1 => self.mouth,
            2 => self.eyes,
            3 => self.brows,
            _ => 1.0,
        }
    }

    /// True when every gain is 1.
    pub fn is_unit(&self) -> bool {
        *self == RegionGains::default()
    }
}

/// The region of 68-point landmark `i`: 1 mouth (lips, and the jaw from 3 to 13, which opens
/// with it), 2 eyes, 3 brows, 0 the rest.
pub fn region_of(i: usize) -> u8 {
    match i {
        3..=13 | 48..=67 => 1,
        36..=47 => 2,
        17..=26 => 3,
        _ => 0,
    }
}

const INNER_LIPS: [(usize, usize); 3] = [(61, 67), (62, 66), (63, 65)];
const EYELIDS: [[(usize, usize); 2]; 2] = [[(37, 41), (38, 40)], [(43, 47), (44, 46)]];

/// What the method needs of the shared reference frame and the source model, made once per
/// cloner: region memberships, the source's neutral luminance, the masks of the inner mouth
/// and the eyes.
#[derive(Clone, Debug)]
pub struct SourceSide {
    /// 68-point scheme (regions, lips and eyelids exist); otherwise only the transfer and the
    /// ratio image apply.
    scheme68: bool,
    /// Per frame pixel, its weights in regions 1..=3 (barycentric blend of its vertices').
    pixel_regions: Vec<[f32; 3]>,
    /// Source base luminance per frame pixel.
    y0: Vec<f32>,
    /// Mean source skin luminance (pixels outside the eyes and the mouth).
    skin: f32,
    /// Frame pixels inside the inner lips.
    mouth: Vec<u32>,
    /// Each inner-mouth pixel's weight: 1 inside, falling to 0 over [`FEATHER`] pixels at the
    /// lips (a hard edge aliases into a jagged outline).
    mouth_w: Vec<f32>,
    /// Frame pixels of the skin away from the eyes and the mouth.
    skin_pixels: Vec<u32>,
    /// Each skin pixel's column less their mean (frame pixels, as `skin_pixels`).
    skin_x: Vec<f32>,
    /// The skin pixels' mean column.
    skin_x0: f32,
    /// The unit direction in which a turn of the head to the side moves the source's base
    /// shape ([`crate::fit::split_head_yaw`]'s), for 68 points.
    yaw: Option<[f32; 136]>,
    /// Per frame pixel: 1 inside the inner lips, 2 and 3 inside each eye, 0 elsewhere.
    inner: Vec<u8>,
    /// Frame pixels inside each eye.
    eyes: [Vec<u32>; 2],
    /// Each eye pixel's weight, as `mouth_w`.
    eyes_w: [Vec<f32>; 2],
    /// The frame pixels a closing lid covers, per eye: the eye and a margin around it
    /// ([`LID_MARGIN`]), the lid margin's lashes and the sclera's edge on the target's picture
    /// lying just outside the landmarks' outline.
    lids: [Vec<u32>; 2],
    /// Each of those pixels' weight: 1 inside the eye, falling to 0 across the margin.
    lids_w: [Vec<f32>; 2],
    /// The face's downward direction in model coordinates (from the eyes to the mouth).
    down: [f32; 2],
    /// The inter-ocular distance of the source base (model units).
    iod: f32,
    /// The frame grid's width, and per grid cell the frame pixel there (`u32::MAX`: none).
    grid_width: usize,
    grid: Vec<u32>,
    /// The source base's inner-lip gap and eyelid gaps.
    gaps0: [f32; 3],
    /// Each eye pixel's place in the frame (as `eyes`).
    eyes_at: [Vec<[f32; 2]>; 2],
    /// Where each eye's iris lies in the source's base appearance ([`iris_centre`]).
    iris0: [[f32; 2]; 2],
    /// The largest gaze shift carried, in frame pixels ([`MAX_GAZE`] of the eye's width).
    max_gaze: f32,
    /// The frame's origin (a pixel's grid cell is its place plus the origin).
    origin: (f32, f32),
    /// The source base's eye whites' luminance ([`sclera_luma`]).
    sclera: f32,
}

/// The source's side of one frame for the expressive method, shared by every target.
#[derive(Clone, Debug)]
pub struct SourceFrame {
    /// The region-gained shape displacement `d` (`2n`).
    pub d: Vec<f32>,
    /// The source appearance `A0 + A lambda` (`3N`).
    app: Vec<f32>,
    /// The region-gained ratio image (`N`).
    pub ratio: Vec<f32>,
    /// Scratch for smoothing the ratio image (two grids each).
    grid: Vec<f32>,
    tmp: Vec<f32>,
    /// How open the source's mouth is beyond its neutral (0..1).
    open: f32,
    /// How closed each source eye is beyond its neutral (0..1).
    closed: [f32; 2],
    /// The source's gaze: its irises' shift from where they are in its base appearance, in
    /// frame pixels (both eyes' mean), limited to `max_gaze`.
    pub gaze: [f32; 2],
    /// The mean skin luminance of the source's neutral this frame (the model's base, or the
    /// observed person's neutral), exposure-matched to `app`.
    skin: f32,
    /// The luminance of the eye whites of the source's neutral ([`sclera_luma`]), exposure-matched
    /// to `app` as `skin`.
    sclera: f32,
    /// Scratch for [`sclera_luma`] (one value per eye pixel).
    eye_luma: Vec<f32>,
    /// The brightest of the source's open mouth this frame: the 90th percentile of the inner
    /// mouth's luminance in `app` (0 when the mouth is closed).
    teeth: f32,
    /// Scratch for `teeth` (one value per inner-mouth pixel).
    mouth_luma: Vec<f32>,
    /// Scratch: per frame grid column, the factor that takes the light's sideways slope out
    /// of the ratio image ([`level_sideways_light`]).
    columns: Vec<f32>,
}

/// The limits of the lights' ratio taken from the eye whites (the 90th percentile of the
/// luminance inside both eyes, smoothed to one resolution, the target's over the source's
/// neutral's): the source's mouth is drawn at most this much darker and brighter on the target
/// than on the source, and never brighter than brings the source's brightest teeth (the 90th
/// percentile of its inner mouth that frame) to [`KNEE`], so the knee never flattens them.
pub const LIGHT_RATIO: [f32; 2] = [0.67, 1.5];

/// The 90th percentile of `values` (reordered), `None` when empty, not finite or not positive.
fn upper_decile(values: &mut [f32]) -> Option<f32> {
    if values.is_empty() {
        return None;
    }
    let at = (values.len() - 1) * 9 / 10;
    let (_, v, _) = values.select_nth_unstable_by(at, |a, b| a.total_cmp(b));
    Some(*v).filter(|v| v.is_finite() && *v > 0.0)
}

/// Into `out`, one value per eye pixel (both eyes, in `side.eyes`' order): the mean luminance
/// of appearance `app` over the frame pixels in the 5 x 5 grid box about it (the ratio image's
/// box), so the eye whites of two pictures are compared at one resolution (a video's small,
/// blurred eyes read darker at their brightest than a photo's sharp ones; unsmoothed, a London
/// smile's teeth came out a dull blue-grey on spk03). Only the eyes' boxes are read.
fn eye_lumas(side: &SourceSide, app: &[f32], out: &mut Vec<f32>) {
    const R: i64 = 2;
    out.clear();
    let w = side.grid_width as i64;
    let h = side.grid.len() as i64 / w.max(1);
    for at in side.eyes_at.iter().flatten() {
        let (cx, cy) = (
            (at[0] + side.origin.0).round() as i64,
            (at[1] + side.origin.1).round() as i64,
        );
        let (mut sum, mut n) = (0f32, 0f32);
        for y in (cy - R).max(0)..=(cy + R).min(h - 1) {
            for x in (cx - R).max(0)..=(cx + R).min(w - 1) {
                let k = side.grid[(y * w + x) as usize];
                if k != u32::MAX {
                    sum += luma(&app[3 * k as usize..3 * k as usize + 3]);
                    n += 1.0;
                }
            }
        }
        out.push(if n > 0.0 { sum / n } else { 0.0 });
    }
}

/// The luminance of the eyes' whites in appearance `app`: the 90th percentile of
/// [`eye_lumas`] over both eyes (the sclera is the brightest thing there; the iris, the lashes
/// and the lids' shadow are darker). Teeth and eye whites reflect much the same from person to
/// person, whatever their skin, so the ratio of two faces' sclera is the ratio of their
/// lights. `scratch` holds one value per eye pixel; `None` when there is none.
fn sclera_luma(side: &SourceSide, app: &[f32], scratch: &mut Vec<f32>) -> Option<f32> {
    eye_lumas(side, app, scratch);
    upper_decile(scratch)
}

/// Where [`highlight_knee`] starts to bend.
pub const KNEE: f32 = 0.8;

/// Brings values above [`KNEE`] smoothly under 1 (the slope 1 at the knee, approaching 1
/// exponentially): teeth brightened into a brighter light keep their separations instead of
/// clipping into a white blob. Values in `[0, KNEE]` are kept, negative ones are 0.
pub fn highlight_knee(v: f32) -> f32 {
    if v <= KNEE {
        v.max(0.0)
    } else {
        let room = 1.0 - KNEE;
        KNEE + room * (1.0 - (-(v - KNEE) / room).exp())
    }
}

/// [`sclera_luma`] of appearance `app` at the frame's common resolution, and the mean colour
/// (RGB) of the eye pixels at least that bright (the eye whites: the colour of the picture's
/// light on something white), allocating. `(0, None)` without eye pixels.
fn sclera_of(side: &SourceSide, app: &[f32]) -> (f32, Option<[f32; 3]>) {
    let mut lum = Vec::new();
    eye_lumas(side, app, &mut lum);
    let Some(level) = upper_decile(&mut lum.clone()) else {
        return (0.0, None);
    };
    let pixels = side.eyes.iter().flatten().map(|&k| k as usize);
    let whites: Vec<usize> = pixels
        .zip(&lum)
        .filter(|&(_, &l)| l >= level)
        .map(|(k, _)| k)
        .collect();
    let rgb = (!whites.is_empty()).then(|| mean_rgb(app, whites.into_iter(), [1.0; 3]));
    (level, rgb)
}

fn point(s: &[f32], i: usize) -> [f32; 2] {
    [s[2 * i], s[2 * i + 1]]
}

fn eye_centres(s: &[f32]) -> [[f32; 2]; 2] {
    let mut c = [[0f32; 2]; 2];
    for (e, range) in [(0, 36..42), (1, 42..48)] {
        for i in range {
            c[e][0] += s[2 * i] / 6.0;
            c[e][1] += s[2 * i + 1] / 6.0;
        }
    }
    c
}

/// Gaps along `down` of `base + d`: the inner lips (mean of three pairs) and each eye's lids
/// (two pairs each). Allocates nothing.
fn gaps_displaced(base: &[f32], d: &[f32], down: [f32; 2]) -> [f32; 3] {
    let gap = |(a, b): (usize, usize)| {
        let dx = (base[2 * b] + d[2 * b]) - (base[2 * a] + d[2 * a]);
        let dy = (base[2 * b + 1] + d[2 * b + 1]) - (base[2 * a + 1] + d[2 * a + 1]);
        dx * down[0] + dy * down[1]
    };
    [
        INNER_LIPS.iter().map(|&p| gap(p)).sum::<f32>() / 3.0,
        EYELIDS[0].iter().map(|&p| gap(p)).sum::<f32>() / 2.0,
        EYELIDS[1].iter().map(|&p| gap(p)).sum::<f32>() / 2.0,
    ]
}

/// Takes out of the ratio image the slope of the light across the face, from one side to the
/// other: the least-squares slope of `ln rho` along the frame's columns over the skin pixels,
/// divided out of every pixel (then limited to [`RATIO_RANGE`] again). A head turned towards
/// or away from a lamp darkens one cheek and brightens the other; an expression's shading is
/// local and mirrored (a smile raises both cheeks), so it has next to no such slope. A ratio
/// image without a slope (a neutral face's, exactly 1) is kept bit for bit. Allocates nothing
/// (`columns` is the grid's width).
fn level_sideways_light(side: &SourceSide, ratio: &mut [f32], columns: &mut [f32]) {
    let (mut sxy, mut sxx) = (0f64, 0f64);
    for (&k, &x) in side.skin_pixels.iter().zip(&side.skin_x) {
        let l = ratio[k as usize].max(1e-6).ln();
        sxy += (x * l) as f64;
        sxx += (x * x) as f64;
    }
    if sxx <= 0.0 || sxy == 0.0 || !sxy.is_finite() {
        return;
    }
    let b = (sxy / sxx) as f32;
    for (c, v) in columns.iter_mut().enumerate() {
        *v = (-b * (c as f32 - side.skin_x0)).exp();
    }
    for cells in side.grid.chunks_exact(side.grid_width.max(1)) {
        for (&k, &f) in cells.iter().zip(columns.iter()) {
            if k != u32::MAX {
                let r = &mut ratio[k as usize];
                *r = (*r * f).clamp(RATIO_RANGE[0], RATIO_RANGE[1]);
            }
        }
    }
}

/// The width, in frame pixels, over which the inner mouth's and the eyes' own colours blend
/// into their surroundings.
pub const FEATHER: f32 = 1.5;

/// Smooths the ratio image with a 5 x 5 box over the frame's pixels (the mean of the
/// neighbours that are frame pixels), as Liu et al. filter theirs: the expression's shading
/// carries, the noise of the source's appearance does not. A ratio of exactly 1 everywhere
/// stays exactly 1. Running sums over the frame's grid (values and weights, rows then
/// columns), so a pass costs a few operations a grid cell. Allocates nothing (`grid` and `tmp`
/// are two grids long).
fn smooth_ratio(side: &SourceSide, ratio: &mut [f32], grid: &mut [f32], tmp: &mut [f32]) {
    if ratio.iter().all(|&v| v == 1.0) {
        return;
    }
    let cells = side.grid.len();
    let w = side.grid_width.max(1);
    let (v, wt) = grid.split_at_mut(cells);
    for ((cell, vv), ww) in side.grid.iter().zip(v.iter_mut()).zip(wt.iter_mut()) {
        (*vv, *ww) = match *cell {
            u32::MAX => (0.0, 0.0),
            k => (ratio[k as usize], 1.0),
        };
    }
    let (tv, tw) = tmp.split_at_mut(cells);
    box_rows(v, tv, w);
    box_rows(wt, tw, w);
    box_columns(tv, v, w);
    box_columns(tw, wt, w);
    for (cell, (vv, ww)) in side.grid.iter().zip(v.iter().zip(wt.iter())) {
        if *cell != u32::MAX {
            ratio[*cell as usize] = vv / ww;
        }
    }
}

/// Box sums of radius 2 along each row of a `w`-wide grid: `dst` = the sum of `src` over the
/// cells within two steps on the same row (a running sum: one add and one subtract a cell).
fn box_rows(src: &[f32], dst: &mut [f32], w: usize) {
    const R: usize = 2;
    for (s, d) in src.chunks_exact(w).zip(dst.chunks_exact_mut(w)) {
        let mut sum = 0f32;
        for i in 0..w + R {
            if i < w {
                sum += s[i];
            }
            if i > 2 * R {
                sum -= s[i - 2 * R - 1];
            }
            if i >= R {
                d[i - R] = sum;
            }
        }
    }
}

/// Box sums of radius 2 along each column of a `w`-wide grid, a row at a time (each row the
/// previous one's plus the row entering, less the row leaving: whole rows at once, which the
/// compiler vectorises).
fn box_columns(src: &[f32], dst: &mut [f32], w: usize) {
    const R: usize = 2;
    let h = src.len() / w;
    for y in 0..h {
        let (done, rest) = dst.split_at_mut(y * w);
        let row = &mut rest[..w];
        if y == 0 {
            row.fill(0.0);
            for j in 0..=R.min(h - 1) {
                row.iter_mut()
                    .zip(&src[j * w..(j + 1) * w])
                    .for_each(|(d, s)| *d += s);
            }
            continue;
        }
        row.copy_from_slice(&done[(y - 1) * w..]);
        if y + R < h {
            row.iter_mut()
                .zip(&src[(y + R) * w..(y + R + 1) * w])
                .for_each(|(d, s)| *d += s);
        }
        if y > R {
            let out = y - R - 1;
            row.iter_mut()
                .zip(&src[out * w..(out + 1) * w])
                .for_each(|(d, s)| *d -= s);
        }
    }
}

impl SourceSide {
    /// Prepares the method for `source` (its frame is every target's frame).
    pub fn new(source: &Model) -> SourceSide {
        let frame = source.frame();
        let n = frame.landmarks();
        let scheme68 = n == 68;
        let base = &source.shape().base;
        let region = |i: u32| if scheme68 { region_of(i as usize) } else { 0 };
        let tris = frame.triangles();
        let mut pixel_regions = Vec::with_capacity(frame.n_pixels());
        let (mut mouth, mut eyes) = (Vec::new(), [Vec::new(), Vec::new()]);
        let (mut mouth_w, mut eyes_w) = (Vec::new(), [Vec::new(), Vec::new()]);
        let edge = |at: [f32; 2], r: std::ops::Range<usize>| {
            (distance_to_polygon(at, frame.vertices(), r) / FEATHER).min(1.0)
        };
        let a0 = source.appearance().base();
        let y0: Vec<f32> = a0.chunks_exact(3).map(luma).collect();
        let mut skin_pixels = Vec::new();
        let mut inner = vec![0u8; frame.n_pixels()];
        let (mut lids, mut lids_w) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
        let mut eyes_at: [Vec<[f32; 2]>; 2] = [Vec::new(), Vec::new()];
        let margin = if scheme68 {
            let c = eye_centres(frame.vertices());
            LID_MARGIN * (c[1][0] - c[0][0]).hypot(c[1][1] - c[0][1])
        } else {
            0.0
        };
        for (k, px) in frame.pixels().iter().enumerate() {
            let t = tris[px.triangle as usize];
            let mut w = [0f32; 3];
            for (v, b) in t.iter().zip(px.bary) {
                let r = region(*v);
                if r > 0 {
                    w[r as usize - 1] += b;
                }
            }
            pixel_regions.push(w);
            let at = [
                px.x as f32 - frame.origin()[0],
                px.y as f32 - frame.origin()[1],
            ];
            // The appearance lives on the frame's mesh, so its polygons are the frame's.
            let inside =
                |r: std::ops::Range<usize>| scheme68 && inside_polygon(at, frame.vertices(), r);
            for (e, r) in [36..42, 42..48].into_iter().enumerate() {
                if !scheme68 || inside(60..68) {
                    continue;
                }
                let w = if inside(r.clone()) {
                    1.0
                } else {
                    let d = distance_to_polygon(at, frame.vertices(), r) / margin.max(1e-3);
                    let t = (1.0 - d).clamp(0.0, 1.0);
                    t * t * (3.0 - 2.0 * t)
                };
                if w > 0.0 {
                    lids[e].push(k as u32);
                    lids_w[e].push(w);
                }
            }
            if inside(60..68) {
                mouth.push(k as u32);
                mouth_w.push(edge(at, 60..68));
                inner[k] = 1;
            } else if inside(36..42) {
                eyes[0].push(k as u32);
                eyes_at[0].push(at);
                eyes_w[0].push(edge(at, 36..42));
                inner[k] = 2;
            } else if inside(42..48) {
                eyes[1].push(k as u32);
                eyes_at[1].push(at);
                eyes_w[1].push(edge(at, 42..48));
                inner[k] = 3;
            } else if !t.iter().any(|v| (36..=67).contains(v)) || !scheme68 {
                skin_pixels.push(k as u32);
            }
        }
        let (down, iod, gaps0) = if scheme68 {
            let c = eye_centres(base);
            let (ex, ey) = (c[1][0] - c[0][0], c[1][1] - c[0][1]);
            let iod = (ex * ex + ey * ey).sqrt().max(1e-3);
            let down = [-ey / iod, ex / iod];
            (
                down,
                iod,
                gaps_displaced(base, &vec![0.0; base.len()], down),
            )
        } else {
            ([0.0, 1.0], 1.0, [0.0; 3])
        };
        let grid_width = frame.width() as usize;
        let mut grid = vec![u32::MAX; grid_width * frame.height() as usize];
        for (k, px) in frame.pixels().iter().enumerate() {
            grid[px.y as usize * grid_width + px.x as usize] = k as u32;
        }
        let iris0 = [0, 1].map(|e| iris_centre(a0, &eyes[e], &eyes_at[e]).unwrap_or([0.0; 2]));
        let max_gaze = if scheme68 {
            let v = frame.vertices();
            MAX_GAZE * (v[2 * 39] - v[2 * 36]).hypot(v[2 * 39 + 1] - v[2 * 36 + 1])
        } else {
            0.0
        };
        let skin_x0 = if skin_pixels.is_empty() {
            0.0
        } else {
            let sum: f64 = skin_pixels
                .iter()
                .map(|&k| frame.pixels()[k as usize].x as f64)
                .sum();
            (sum / skin_pixels.len() as f64) as f32
        };
        let skin_x = skin_pixels
            .iter()
            .map(|&k| frame.pixels()[k as usize].x as f32 - skin_x0)
            .collect();
        let mut side = SourceSide {
            skin_x,
            skin_x0,
            sclera: 0.0,
            eyes_at,
            iris0,
            max_gaze,
            origin: (frame.origin()[0], frame.origin()[1]),
            grid_width,
            grid,
            scheme68,
            pixel_regions,
            y0,
            skin: luma(&mean_rgb(
                a0,
                skin_pixels.iter().map(|&k| k as usize),
                [0.5; 3],
            )),
            inner,
            mouth,
            mouth_w,
            skin_pixels,
            yaw: if scheme68 {
                crate::fit::turn_directions(base, crate::find::IBUG_DEPTH)[0]
            } else {
                None
            },
            eyes,
            eyes_w,
            lids,
            lids_w,
            down,
            iod,
            gaps0,
        };
        side.sclera = sclera_of(&side, a0).0;
        side
    }

    /// An empty frame buffer for this source.
    pub fn frame_buffer(&self, source: &Model) -> SourceFrame {
        SourceFrame {
            d: vec![0.0; source.shape().base.len()],
            app: vec![0.0; source.appearance().len()],
            ratio: vec![1.0; self.y0.len()],
            grid: vec![0.0; 2 * self.grid.len()],
            tmp: vec![0.0; 2 * self.grid.len()],
            open: 0.0,
            closed: [0.0; 2],
            gaze: [0.0; 2],
            skin: self.skin,
            sclera: self.sclera,
            eye_luma: Vec::with_capacity(self.eyes[0].len() + self.eyes[1].len()),
            teeth: 0.0,
            mouth_luma: Vec::with_capacity(self.mouth.len()),
            columns: vec![1.0; self.grid_width],
        }
    }
}

/// Scales each landmark's displacement in `d` by its region's gain.
fn apply_region_gains(side: &SourceSide, d: &mut [f32], gains: &RegionGains) {
    if side.scheme68 && !gains.is_unit() {
        for (i, xy) in d.chunks_exact_mut(2).enumerate() {
            let g = gains.of(region_of(i));
            xy[0] *= g;
            xy[1] *= g;
        }
    }
}

impl SourceFrame {
    /// The source's side of one frame: `d = G (S p)` (`G` the region gains per landmark), the
    /// appearance `A0 + A lambda`, and the ratio image `rho = ((e Y(A) + c) / (Y(A0) + c))^g`
    /// (`e` the skin's mean luminance at neutral over now: the frame's exposure left out)
    /// (Liu, Shan & Zhang 2001, on luminance; `g` the pixel's blend of region gains), limited
    /// to [`RATIO_RANGE`]. A neutral face (`lambda = 0`) gives `rho = 1` exactly. With
    /// `hold_turn` (the target keeps its own pose: [`super::CloneOptions::follow_pose`] off),
    /// the part of `S p` a turn of the head to the side explains is left out of `d`, and the
    /// light's slope across the face (the least-squares slope of `ln rho` along the frame's
    /// columns) out of `rho`: a turn, and the lamp it turns towards, are pose, not
    /// expression. Allocates nothing.
    pub fn prepare(
        &mut self,
        side: &SourceSide,
        source: &Model,
        p: &[f32],
        lambda: &[f32],
        gains: &RegionGains,
        hold_turn: bool,
    ) {
        self.displacement(side, source, p, gains, hold_turn);
        source
            .appearance()
            .instance_unchecked(lambda, &mut self.app);
        self.expression(side, &source.shape().base, None, gains, 1.0, hold_turn);
    }

    /// [`SourceFrame::prepare`] with the appearance observed in the frame's pixels instead of
    /// synthesised, against the person's own neutral appearance instead of the model's base
    /// (a followed face: [`crate::fit::ObservedAppearance`]), and `d` the observed whole
    /// displacement (`2n`, times `gain` and the region gains) when it has one: its appearance
    /// and neutral are `3N` RGB values on the source's frame pixels (the caller checks every
    /// length); the ratio is raised to the global `gain` too (the synthesis has it in
    /// `lambda`). A frame equal to the neutral gives `rho = 1` exactly. `hold_turn` as for
    /// [`SourceFrame::prepare`] (on `d` only when it is the projection: an observed
    /// displacement comes with the head's turn left out already). Allocates nothing.
    #[allow(clippy::too_many_arguments)]
    pub fn prepare_observed(
        &mut self,
        side: &SourceSide,
        source: &Model,
        p: &[f32],
        observed: crate::fit::Observed<'_>,
        gains: &RegionGains,
        gain: f32,
        hold_turn: bool,
    ) {
        let (neutral, displacement) = (observed.neutral, observed.displacement);
        match displacement {
            Some(d) => {
                self.d.iter_mut().zip(d).for_each(|(o, &v)| *o = gain * v);
                // A target that follows the pose turns its head with the person's.
                if let (false, Some(turn)) = (hold_turn, observed.turn) {
                    self.d
                        .iter_mut()
                        .zip(turn)
                        .for_each(|(o, &v)| *o += gain * v);
                }
                apply_region_gains(side, &mut self.d, gains);
            }
            None => self.displacement(side, source, p, gains, hold_turn),
        }
        self.app.copy_from_slice(observed.appearance);
        self.expression(
            side,
            &source.shape().base,
            Some(neutral),
            gains,
            gain,
            hold_turn,
        );
    }

    /// `d = G (S p)` into `self.d`; with `hold_turn` (68 points), less the part a turn of the
    /// head to the side explains ([`crate::fit::split_head_yaw`] about the source's base, its
    /// direction found once per source).
    fn displacement(
        &mut self,
        side: &SourceSide,
        source: &Model,
        p: &[f32],
        gains: &RegionGains,
        hold_turn: bool,
    ) {
        let shape = source.shape();
        self.d.iter_mut().for_each(|v| *v = 0.0);
        for (&pi, mode) in p.iter().zip(shape.modes.chunks_exact(self.d.len().max(1))) {
            if pi != 0.0 {
                self.d.iter_mut().zip(mode).for_each(|(o, &m)| *o += pi * m);
            }
        }
        if let (true, Some(q)) = (hold_turn, &side.yaw) {
            let c: f32 = self.d.iter().zip(q).map(|(d, q)| d * q).sum();
            if c.is_finite() {
                self.d.iter_mut().zip(q).for_each(|(d, q)| *d -= c * q);
            }
        }
        apply_region_gains(side, &mut self.d, gains);
    }

    /// The ratio image, the mouth's opening, the eyes' closing and the gaze of `self.app`
    /// against `neutral` (the model's base appearance when `None`); with `level`, the light's
    /// slope across the face taken out of the ratio image.
    fn expression(
        &mut self,
        side: &SourceSide,
        base: &[f32],
        neutral: Option<&[f32]>,
        gains: &RegionGains,
        gain: f32,
        level: bool,
    ) {
        let y0 = |k: usize| match neutral {
            Some(n) => luma(&n[3 * k..3 * k + 3]),
            None => side.y0[k],
        };
        // The exposure of the source's frame against its neutral (a light switched on, a camera
        // adapting) is not expression: the ratio is taken against it.
        let (mut ys, mut y0s) = (0f64, 0f64);
        for &k in &side.skin_pixels {
            let k = k as usize;
            ys += luma(&self.app[3 * k..3 * k + 3]) as f64;
            y0s += y0(k) as f64;
        }
        let exposure = if ys > 0.0 && y0s > 0.0 {
            (y0s / ys) as f32
        } else {
            1.0
        };
        // The neutral's skin luminance; the inner mouth compares the frame's with it in the
        // frame's exposure (a model's synthesis has the base's).
        let skin0 = match neutral {
            Some(_) if !side.skin_pixels.is_empty() => (y0s / side.skin_pixels.len() as f64) as f32,
            _ => side.skin,
        };
        self.skin = match neutral {
            Some(_) => skin0 / exposure,
            None => skin0,
        };
        self.sclera = match neutral {
            Some(n) => sclera_luma(side, n, &mut self.eye_luma).unwrap_or(0.0) / exposure,
            None => side.sclera,
        };
        let unit = gains.is_unit() && gain == 1.0;
        // Dark skin's luminance is small, so its ratios would swing with every highlight: the
        // offset grows with the source's skin.
        let offset = RATIO_OFFSET + RATIO_SKIN_SHARE * skin0;
        for (k, ((r, rgb), w)) in self
            .ratio
            .iter_mut()
            .zip(self.app.chunks_exact(3))
            .zip(&side.pixel_regions)
            .enumerate()
        {
            let mut v = (exposure * luma(rgb) + offset) / (y0(k) + offset);
            if !unit && v != 1.0 {
                let g = 1.0
                    + w[0] * (gains.mouth - 1.0)
                    + w[1] * (gains.eyes - 1.0)
                    + w[2] * (gains.brows - 1.0);
                v = v.max(1e-6).powf(g * gain);
            }
            *r = v.clamp(RATIO_RANGE[0], RATIO_RANGE[1]);
        }
        // A lamp to one side of a turned head is pose too (and comes with the turn).
        if level {
            level_sideways_light(side, &mut self.ratio, &mut self.columns);
        }
        // Twice: a 9 x 9 tent, about a tenth of the eye distance.
        smooth_ratio(side, &mut self.ratio, &mut self.grid, &mut self.tmp);
        smooth_ratio(side, &mut self.ratio, &mut self.grid, &mut self.tmp);
        // Inside the eyes the target keeps its own eye (the closure below blends in its lid):
        // a ratio there would paste the source's iris and lashes as a ghost.
        for e in &side.eyes {
            for &k in e {
                self.ratio[k as usize] = 1.0;
            }
        }
        if side.scheme68 {
            let g = gaps_displaced(base, &self.d, side.down);
            self.open =
                ((g[0] - side.gaps0[0] - 0.03 * side.iod) / (0.09 * side.iod)).clamp(0.0, 1.0);
            self.teeth = 0.0;
            if self.open > 0.0 {
                self.mouth_luma.clear();
                let app = &self.app;
                self.mouth_luma.extend(
                    side.mouth
                        .iter()
                        .map(|&k| luma(&app[3 * k as usize..3 * k as usize + 3])),
                );
                self.teeth = upper_decile(&mut self.mouth_luma).unwrap_or(0.0);
            }
            for e in 0..2 {
                let g0 = side.gaps0[e + 1].max(1e-3);
                self.closed[e] = (1.0 - g[e + 1] / g0).clamp(0.0, 1.0);
            }
            // The gaze: both irises' shift (an eye half closed or more says nothing of it).
            let (mut sum, mut n) = ([0f32; 2], 0.0);
            for e in 0..2 {
                if self.closed[e] < 0.5 {
                    let at_rest = match neutral {
                        Some(a) => iris_centre(a, &side.eyes[e], &side.eyes_at[e]),
                        None => Some(side.iris0[e]),
                    };
                    let now = iris_centre(&self.app, &side.eyes[e], &side.eyes_at[e]);
                    if let (Some(c), Some(c0)) = (now, at_rest) {
                        sum[0] += c[0] - c0[0];
                        sum[1] += c[1] - c0[1];
                        n += 1.0;
                    }
                }
            }
            self.gaze = if n > 0.0 {
                let g = [sum[0] / n, sum[1] / n];
                let len = g[0].hypot(g[1]);
                let k = if len > side.max_gaze {
                    side.max_gaze / len
                } else {
                    1.0
                };
                [g[0] * k, g[1] * k]
            } else {
                [0.0; 2]
            };
        }
    }
}

/// The per-target precomputation of the expressive method, and its per-frame scratch.
#[derive(Clone, Debug)]
pub struct ExpressiveTarget {
    /// The deformation-transfer operator from the source's base onto the target's.
    l: Vec<f32>,
    /// The target's picture's white balance (a neutral grey's RGB, luminance 1).
    white: [f32; 3],
    /// The target's lip colour, luminance 1.
    lip: [f32; 3],
    /// Each eye's lid skin colour (RGB).
    lid: [[f32; 3]; 2],
    /// The target base's eye whites' luminance ([`sclera_luma`]).
    sclera: f32,
    /// The signed area of every frame triangle on the target's base.
    area0: Vec<f32>,
    /// The target's shape sigmas.
    sigmas: Vec<f32>,
    /// Scratch: the transferred displacement, the shape, the own part's parameters.
    u: Vec<f32>,
    x: Vec<f32>,
    own: Vec<f32>,
}

/// The signed area of triangle `t` on shape `s`.
fn signed_area(s: &[f32], t: &[u32; 3]) -> f32 {
    let [a, b, c] = t.map(|i| point(s, i as usize));
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
}

/// Mean RGB over `pixels` of an appearance, or `fallback` when there are none.
fn mean_rgb(app: &[f32], pixels: impl Iterator<Item = usize>, fallback: [f32; 3]) -> [f32; 3] {
    let (mut s, mut n) = ([0f64; 3], 0usize);
    for k in pixels {
        for c in 0..3 {
            s[c] += app[3 * k + c] as f64;
        }
        n += 1;
    }
    if n == 0 {
        return fallback;
    }
    s.map(|v| (v / n as f64) as f32)
}

/// `rgb` scaled to luminance 1 (grey when it is black).
fn chroma(rgb: [f32; 3]) -> [f32; 3] {
    let y = luma(&rgb);
    if y > 1e-4 {
        rgb.map(|v| v / y)
    } else {
        [1.0; 3]
    }
}

/// Each eye's lid skin colour on `target`: the per-channel median of the skin just above the
/// eye (between [`LID_BAND`] eye distances from the eye's outline, above its centre), where the
/// upper lid lies when the eye is open. The lid margin itself (lashes, the sclera's edge) and
/// the brow are left out: a mean over every triangle touching the eye took them in, and a
/// closed eye on a dark-skinned target showed a pale almond.
fn lid_colours(side: &SourceSide, target: &Model) -> [[f32; 3]; 2] {
    let mut lid = [[0.5f32; 3]; 2];
    if !side.scheme68 {
        return lid;
    }
    let frame = target.frame();
    let a0 = target.appearance().base();
    let centres = eye_centres(frame.vertices());
    let (ex, ey) = (centres[1][0] - centres[0][0], centres[1][1] - centres[0][1]);
    let iod = (ex * ex + ey * ey).sqrt().max(1e-3);
    let down = [-ey / iod, ex / iod];
    let mut band: Vec<[f32; 3]> = Vec::new();
    for (e, range) in [36..42, 42..48].into_iter().enumerate() {
        band.clear();
        for (k, px) in frame.pixels().iter().enumerate() {
            if side.inner[k] != 0 {
                continue;
            }
            let at = [
                px.x as f32 - frame.origin()[0],
                px.y as f32 - frame.origin()[1],
            ];
            let above = (at[0] - centres[e][0]) * down[0] + (at[1] - centres[e][1]) * down[1] < 0.0;
            let d = distance_to_polygon(at, frame.vertices(), range.clone()) / iod;
            if above && (LID_BAND[0]..=LID_BAND[1]).contains(&d) {
                band.push([a0[3 * k], a0[3 * k + 1], a0[3 * k + 2]]);
            }
        }
        if band.is_empty() {
            continue;
        }
        for c in 0..3 {
            band.sort_unstable_by(|a, b| a[c].total_cmp(&b[c]));
            lid[e][c] = band[band.len() / 2][c];
        }
    }
    lid
}

/// The largest gaze shift carried onto a target, as a share of the eye's width (corner to
/// corner): an iris moved further would leave the eye.
pub const MAX_GAZE: f32 = 0.2;

/// Where the iris lies in one eye of appearance `app` (`3N`): the centroid of the eye's
/// pixels `px` (at `at`) weighted by how much darker than the eye's mean each is, squared (the
/// iris and pupil are the eye's darkest part, the sclera its brightest). `None` when the eye
/// is flat (closed, or no eye pixels).
fn iris_centre(app: &[f32], px: &[u32], at: &[[f32; 2]]) -> Option<[f32; 2]> {
    if px.is_empty() {
        return None;
    }
    let y = |k: u32| luma(&app[3 * k as usize..3 * k as usize + 3]);
    let mean = px.iter().map(|&k| y(k)).sum::<f32>() / px.len() as f32;
    let (mut sx, mut sy, mut sw) = (0f32, 0f32, 0f32);
    for (&k, p) in px.iter().zip(at) {
        let d = (mean - y(k)).max(0.0);
        let w = d * d;
        sx += w * p[0];
        sy += w * p[1];
        sw += w;
    }
    (sw > 1e-6).then(|| [sx / sw, sy / sw])
}

/// The margin around each eye that a closing lid covers too, in eye distances of the frame.
pub const LID_MARGIN: f32 = 0.08;

/// The band above each eye whose skin colours a closed lid, in eye distances from the eye's
/// outline.
pub const LID_BAND: [f32; 2] = [0.06, 0.18];

impl ExpressiveTarget {
    /// Precomputes the method for one source-target pair in one frame.
    pub fn new(side: &SourceSide, source: &Model, target: &Model) -> Result<ExpressiveTarget> {
        let frame = target.frame();
        let base = &target.shape().base;
        let l = transfer_operator(&source.shape().base, base, frame.triangles())?;
        let a0 = target.appearance().base();
        let tris = frame.triangles();
        let pixels = frame.pixels();
        let in_tri = |k: usize, f: &dyn Fn(u32) -> bool| {
            let t = tris[pixels[k].triangle as usize];
            t.iter().any(|&v| f(v))
        };
        let n = pixels.len();
        let lips = (0..n).filter(|&k| {
            side.scheme68 && in_tri(k, &|v| (48..=59).contains(&v)) && side.inner[k] == 0
        });
        let lip = chroma(mean_rgb(a0, lips, [0.6, 0.35, 0.35]));
        let lid = lid_colours(side, target);
        // Teeth: the colour of the target's eye whites (the picture's light on something
        // white) warmed 40% of the way towards the target's skin's hue, so they sit in the
        // picture's warm light (0.2, 0.35, 0.5 tried on London pairs: the mouth's colour error
        // fell with warmth; cooler teeth looked pasted in). A neutral white in place of the eye
        // whites' colour drew a dim video's teeth a dull blue-grey beside its orange skin.
        let skin_rgb = mean_rgb(a0, side.skin_pixels.iter().map(|&k| k as usize), [0.5; 3]);
        let warm = chroma(skin_rgb);
        let (sclera, sclera_rgb) = sclera_of(side, a0);
        let eye_white = sclera_rgb.map(chroma).unwrap_or([1.0; 3]);
        let white = chroma([0, 1, 2].map(|c| 0.6 * eye_white[c] + 0.4 * warm[c]));
        // The mouth's dark parts: the lips' colour, a little paler.
        let lip = chroma([0, 1, 2].map(|c| 0.7 * lip[c] + 0.3 * white[c]));
        Ok(ExpressiveTarget {
            sclera,
            l,
            white,
            lip,
            lid,
            // A sliver's orientation means nothing (a closed mouth's inner lips cross by a
            // hair in many landmarkings): 0 exempts it from the fold check.
            area0: tris
                .iter()
                .map(|t| {
                    if super::transfer::is_sliver(base, t) {
                        0.0
                    } else {
                        signed_area(base, t)
                    }
                })
                .collect(),
            sigmas: target.shape().sigmas(),
            u: vec![0.0; base.len()],
            x: vec![0.0; base.len()],
            own: vec![0.0; target.shape().n_modes()],
        })
    }
}

/// Limits `p` (target parameters) to Mahalanobis norm `k` under the target's sigmas, by
/// scaling the whole vector (so its direction, the kind of expression, is kept). A zero sigma
/// forces its parameter to 0. NaN-safe: a non-finite norm zeroes `p`.
pub fn limit_mahalanobis(p: &mut [f32], sigmas: &[f32], k: f32) {
    let mut m2 = 0f64;
    for (v, s) in p.iter_mut().zip(sigmas) {
        if !(*s > 0.0) {
            *v = 0.0;
        } else {
            m2 += ((*v / s) as f64).powi(2);
        }
    }
    let m = m2.sqrt() as f32;
    if !m.is_finite() {
        p.iter_mut().for_each(|v| *v = 0.0);
    } else if m > k {
        let f = if k > 0.0 { k / m } else { 0.0 };
        p.iter_mut().for_each(|v| *v *= f);
    }
}

/// The residual the target's modes cannot show once limited: `r = u - S* p*` (`S*` row-major
/// `q x 2n`, `p*` after [`limit_mahalanobis`]). Zero when the target can follow `u` (in the
/// span of its modes and within the limit).
pub fn residual_after_limit(u: &[f32], modes: &[f32], p: &[f32], out: &mut [f32]) {
    out.copy_from_slice(u);
    for (&pj, mode) in p.iter().zip(modes.chunks_exact(u.len().max(1))) {
        out.iter_mut().zip(mode).for_each(|(o, &m)| *o -= pj * m);
    }
}

/// Moves the two points of each pair to meet where the first (upper) has passed below the
/// second (lower) along `down`: lips never cross, eyes never invert.
fn uncross(x: &mut [f32], pairs: &[(usize, usize)], down: [f32; 2]) {
    for &(a, b) in pairs {
        let gap = (x[2 * b] - x[2 * a]) * down[0] + (x[2 * b + 1] - x[2 * a + 1]) * down[1];
        if gap < 0.0 {
            for c in 0..2 {
                x[2 * a + c] += 0.5 * gap * down[c];
                x[2 * b + c] -= 0.5 * gap * down[c];
            }
        }
    }
}

/// Options of the expressive shape and appearance, from [`super::CloneOptions`].
#[derive(Clone, Copy, Debug)]
pub struct ExpressiveOptions<'a> {
    /// `Some(k)`: the target's own part within Mahalanobis norm `k + sqrt(q)` (`q` its modes), the whole displacement
    /// within `k` times the prior's strongest expression (a laugh in video, with the head's own
    /// motion, reaches about 2.3 of it at the 99th percentile); `None`: neither limit.
    pub clamp: Option<f32>,
    /// 0 = the target's own range only, 1 = the source's full motion.
    pub style: f32,
    /// The generic prior that bounds the whole displacement.
    pub prior: &'a ExpressionPrior,
}

/// The least share of its own area on the target's base a frame triangle keeps in an
/// expressive shape ([`expressive_shape`] scales the displacement back until every one does).
const FOLD_MARGIN: f32 = 1e-3;

/// The expressive shape (see the module docs) of one frame into `acc` (`2n`, model
/// coordinates, unposed) and the target's own parameters `p*` into `params`:
/// `x = s0* + S* p* + style (u - S* p*)` with `u = L d` bounded by the prior, then the lips and
/// eyelids uncrossed, and the displacement scaled back (bisection) until no triangle folds.
pub fn expressive_shape(
    t: &mut ExpressiveTarget,
    side: &SourceSide,
    frame: &SourceFrame,
    target: &Model,
    o: &ExpressiveOptions<'_>,
    params: &mut [f32],
    acc: &mut [f64],
) {
    let shape = target.shape();
    transfer_displacement(&t.l, &frame.d, &mut t.u);
    if let Some(k) = o.clamp {
        let m = o.prior.distance(&t.u);
        let lim = o.prior.limit() * k;
        if m > lim && m.is_finite() {
            let f = lim / m;
            t.u.iter_mut().for_each(|v| *v *= f);
        }
    }
    for (o_j, mode) in t
        .own
        .iter_mut()
        .zip(shape.modes.chunks_exact(t.u.len().max(1)))
    {
        *o_j = mode.iter().zip(&t.u).map(|(a, b)| a * b).sum();
    }
    if let Some(k) = o.clamp {
        // A training face of q modes lies about sqrt(q) from the mean: the limit is k beyond.
        let radius = k + (t.own.len() as f32).sqrt();
        limit_mahalanobis(&mut t.own, &t.sigmas, radius);
    }
    residual_after_limit(&t.u, &shape.modes, &t.own, &mut t.x);
    // t.x holds the residual; the displacement is own + style * residual.
    for (i, r) in t.x.iter_mut().enumerate() {
        *r = (t.u[i] - *r) + o.style * *r;
    }
    std::mem::swap(&mut t.u, &mut t.x);
    params.copy_from_slice(&t.own);
    let base = &shape.base;
    let tris = target.frame().triangles();
    let place = |scale: f32, x: &mut [f32]| {
        for ((xv, &b), &d) in x.iter_mut().zip(base).zip(t.u.iter()) {
            *xv = b + scale * d;
        }
        if side.scheme68 {
            uncross(x, &INNER_LIPS, side.down);
            uncross(x, &EYELIDS[0], side.down);
            uncross(x, &EYELIDS[1], side.down);
        }
    };
    let folds = |x: &[f32]| {
        tris.iter().zip(&t.area0).any(|(tri, &a0)| {
            // The mouth's interior folds harmlessly as lips meet; crossing is `uncross`'s.
            if side.scheme68 && tri.iter().filter(|&&v| (60..=67).contains(&v)).count() >= 2 {
                return false;
            }
            // Collapsing to a thousandth of its area counts as folding: a triangle left at
            // exactly zero turns over in the rounding of the pose applied after.
            let a = signed_area(x, tri);
            a0 != 0.0 && a * a0.signum() < FOLD_MARGIN * a0.abs()
        })
    };
    let mut x = std::mem::take(&mut t.x);
    place(1.0, &mut x);
    if folds(&x) {
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..24 {
            let mid = 0.5 * (lo + hi);
            place(mid, &mut x);
            if folds(&x) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        place(lo, &mut x);
    }
    acc.iter_mut().zip(&x).for_each(|(a, &v)| *a = v as f64);
    t.x = x;
}

/// Appearance `a0` sampled bilinearly at frame point `(x, y)` (frame coordinates, the
/// origin removed) when all four grid cells around it are pixels of the eye `own` (the
/// `inner` code), else `None`.
fn sample_eye(side: &SourceSide, a0: &[f32], own: u8, x: f32, y: f32) -> Option<[f32; 3]> {
    let (ox, oy) = side.origin;
    let (gx, gy) = (x + ox, y + oy);
    if !(gx >= 0.0 && gy >= 0.0) {
        return None;
    }
    let (x0, y0) = (gx.floor() as usize, gy.floor() as usize);
    let (fx, fy) = (gx - x0 as f32, gy - y0 as f32);
    let w = side.grid_width;
    if x0 + 1 >= w || (y0 + 1) * w + x0 + 1 >= side.grid.len() {
        return None;
    }
    let at = |x: usize, y: usize| {
        let k = side.grid[y * w + x];
        (k != u32::MAX && side.inner[k as usize] == own).then_some(k as usize)
    };
    let (a, b, c, d) = (
        at(x0, y0)?,
        at(x0 + 1, y0)?,
        at(x0, y0 + 1)?,
        at(x0 + 1, y0 + 1)?,
    );
    let mut out = [0f32; 3];
    for (ch, o) in out.iter_mut().enumerate() {
        let top = a0[3 * a + ch] * (1.0 - fx) + a0[3 * b + ch] * fx;
        let bot = a0[3 * c + ch] * (1.0 - fx) + a0[3 * d + ch] * fx;
        *o = top * (1.0 - fy) + bot * fy;
    }
    Some(out)
}

/// The expressive appearance (see the module docs) into `out` (`3N`): the target's base
/// appearance times the ratio image; in the inner mouth, as the mouth opens, the source's
/// mouth shading in the target's colours; in the eyes, as they close, the target's lid skin.
/// With `style < 1`, blended with what `out` holds on entry (the paper's mapped appearance).
pub fn expressive_appearance(
    t: &ExpressiveTarget,
    side: &SourceSide,
    frame: &SourceFrame,
    target: &Model,
    style: f32,
    out: &mut [f32],
) {
    let a0 = target.appearance().base();
    let keep = 1.0 - style;
    let blend = style < 1.0;
    for ((o, a), &r) in out
        .chunks_exact_mut(3)
        .zip(a0.chunks_exact(3))
        .zip(&frame.ratio)
    {
        for c in 0..3 {
            let v = (a[c] * r).clamp(0.0, 1.0);
            o[c] = if blend { keep * o[c] + style * v } else { v };
        }
    }
    if !side.scheme68 {
        return;
    }
    // The gaze: each eye's texture moved by the source's iris shift, sampled from the
    // target's own eye (bilinear over the frame's grid); a sample reaching outside the eye
    // keeps the pixel's own colour, and the shift fades out at the eye's outline.
    let [gx, gy] = frame.gaze;
    if gx != 0.0 || gy != 0.0 {
        for e in 0..2 {
            let own = 2 + e as u8;
            for ((&k, p), &edge) in side.eyes[e]
                .iter()
                .zip(&side.eyes_at[e])
                .zip(&side.eyes_w[e])
            {
                let Some(rgb) = sample_eye(side, a0, own, p[0] - gx, p[1] - gy) else {
                    continue;
                };
                let w = edge * style;
                let k = k as usize;
                for c in 0..3 {
                    out[3 * k + c] += w * (rgb[c] - out[3 * k + c]);
                }
            }
        }
    }
    if frame.open > 0.0 {
        let w0 = frame.open * style;
        // The source's mouth in the target's light: scaled by the ratio of their eye whites.
        let light = if t.sclera > 0.0 && frame.sclera > 0.0 {
            (t.sclera / frame.sclera).clamp(LIGHT_RATIO[0], LIGHT_RATIO[1])
        } else {
            1.0
        };
        // Never so bright that the knee flattens the teeth: the source's brightest teeth land
        // at most at the knee, so their separations stay.
        let light = if frame.teeth > 0.0 {
            light.min(KNEE / frame.teeth)
        } else {
            light
        };
        for (&k, &edge) in side.mouth.iter().zip(&side.mouth_w) {
            let (k, w) = (k as usize, w0 * edge);
            let s = &frame.app[3 * k..3 * k + 3];
            let b = luma(s) / frame.skin.max(0.05);
            let teeth = ((b - 0.6) / 0.5).clamp(0.0, 1.0);
            let teeth = teeth * teeth * (3.0 - 2.0 * teeth);
            let y = light * luma(s);
            for c in 0..3 {
                let chroma = t.lip[c] + teeth * (t.white[c] - t.lip[c]);
                let v = highlight_knee(y * chroma);
                out[3 * k + c] += w * (v - out[3 * k + c]);
            }
        }
    }
    for e in 0..2 {
        let w0 = frame.closed[e] * style;
        if w0 > 0.0 {
            for (&k, &edge) in side.lids[e].iter().zip(&side.lids_w[e]) {
                let (k, w) = (k as usize, w0 * edge);
                for c in 0..3 {
                    let v = (t.lid[e][c] * frame.ratio[k]).clamp(0.0, 1.0);
                    out[3 * k + c] += w * (v - out[3 * k + c]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_highlight_knee_keeps_the_range_smooth_and_ordered() {
        assert_eq!(highlight_knee(-0.5), 0.0);
        assert_eq!(highlight_knee(0.5), 0.5);
        assert_eq!(highlight_knee(KNEE), KNEE);
        let mut last = KNEE;
        for i in 1..=200 {
            let v = highlight_knee(KNEE + i as f32 * 0.01);
            assert!(
                v > last || v == 1.0,
                "not increasing at {i}: {v} after {last}"
            );
            assert!(v <= 1.0);
            last = v;
        }
        // The slope is 1 at the knee: no visible crease where the teeth's highlights start.
        let slope = (highlight_knee(KNEE + 1e-3) - KNEE) / 1e-3;
        assert!((slope - 1.0).abs() < 0.01, "slope {slope}");
        // Separations above the knee survive: 1.0 and 1.2 stay 10 levels of 255 apart.
        assert!(highlight_knee(1.2) - highlight_knee(1.0) > 10.0 / 255.0);
    }

    #[test]
    fn the_sclera_is_the_bright_end_of_the_eyes() {
        // 10 eye pixels with luminances 0.0..0.9: the 90th percentile is the 9th value.
        let mut lum: Vec<f32> = (0..10).rev().map(|i| i as f32 / 10.0).collect();
        let v = upper_decile(&mut lum).unwrap();
        assert!((v - 0.8).abs() < 1e-5, "{v}");
        assert_eq!(upper_decile(&mut []), None);
        assert_eq!(upper_decile(&mut [0.0; 10]), None);
    }

    /// The eye pixels' box means are the ratio image's 5 x 5 box at those pixels (the
    /// whole-grid smoothing), read only about the eyes.
    #[test]
    fn the_eyes_box_means_are_the_frames_smoothing_there() {
        // A one-photo model of a flat grey picture with the canonical face's points in it.
        let frame = crate::canonical_frame();
        let points: Vec<f32> = frame.vertices().iter().map(|c| c + 100.0).collect();
        let px = vec![128u8; 400 * 400 * 4];
        let image = crate::ImageRef::new(400, 400, &px).unwrap();
        let model = crate::photo_model("grey", &image, &points, frame).unwrap();
        let side = SourceSide::new(&model);
        assert!(!side.eyes[0].is_empty());
        let app: Vec<f32> = (0..side.y0.len())
            .flat_map(|k| [((k * 37) % 101) as f32 / 100.0; 3])
            .collect();
        let mut whole: Vec<f32> = app.chunks_exact(3).map(luma).collect();
        let (mut grid, mut tmp) = (
            vec![0.0; 2 * side.grid.len()],
            vec![0.0; 2 * side.grid.len()],
        );
        smooth_ratio(&side, &mut whole, &mut grid, &mut tmp);
        let mut eyes = Vec::new();
        eye_lumas(&side, &app, &mut eyes);
        for (&k, v) in side.eyes.iter().flatten().zip(&eyes) {
            assert!(
                (whole[k as usize] - v).abs() < 1e-4,
                "{} vs {v}",
                whole[k as usize]
            );
        }
    }
}

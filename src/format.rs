//! The `.fmm` model file: a versioned, little-endian binary format (specified in
//! `docs/model-format.md`).
//!
//! [`write_model`] serialises a [`Model`]; [`read_model`] parses and validates one. Reading
//! never panics, checks every header value against the explicit [`LIMITS`], compares the byte
//! length the header implies (computed with checked arithmetic) with the actual length before
//! allocating any array, verifies a CRC-32 of the whole file, and finally rebuilds the
//! reference frame from the stored mesh and checks that it yields the stored pixel count and
//! fingerprint. Every failure is a [`FormatError`] variant naming the problem.

pub use crate::bounds::{Limits, LIMITS};
pub use crate::error::FormatError;

use crate::appearance::AppearanceModel;
use crate::backdrop::Backdrop;
use crate::frame::ReferenceFrame;
use crate::model::{LandmarkScheme, Model, ModelParts, Reference};
use crate::shape::ShapeModel;
use crate::similarity::Similarity;

/// The eight bytes every `.fmm` file starts with: `\x89 F M M \r \n \x1a \n` (the PNG trick:
/// a non-ASCII first byte and line-ending bytes expose text-mode transfers and truncation).
pub const MAGIC: [u8; 8] = [0x89, b'F', b'M', b'M', b'\r', b'\n', 0x1a, b'\n'];

/// The format version this library writes (the newest it reads). Version 3 is version 2 plus
/// optional tagged sections after the appearance (the backdrop, [`SECTION_BACKDROP`]).
pub const FORMAT_VERSION: u32 = 3;

/// Section tag of the backdrop (`"BKDR"` in little-endian bytes): the picture a model's face is
/// composited into, with its landmarks (see `docs/model-format.md`).
pub const SECTION_BACKDROP: u32 = u32::from_le_bytes(*b"BKDR");

/// Most sections a file may hold.
pub const MAX_SECTIONS: usize = 16;

/// The oldest format version this library reads. Readers keep reading older versions: every
/// version from this one to [`FORMAT_VERSION`] loads.
pub const OLDEST_VERSION: u32 = 1;

/// Size in bytes of the fixed header (version 1).
pub const HEADER_LEN: usize = 112;

/// Size in bytes of the trailing checksum.
pub const CHECKSUM_LEN: usize = 4;

/// Scheme tag: any layout with `landmarks` points.
pub const SCHEME_GENERIC: u32 = 0;
/// Scheme tag: the 68-point iBUG layout (requires `landmarks == 68`).
pub const SCHEME_IBUG68: u32 = 1;
/// Reference tag: the bases show the training mean (reference name length must be 0).
pub const REFERENCE_MEAN: u32 = 0;
/// Reference tag: the bases show the named training image.
pub const REFERENCE_TRAINING: u32 = 1;

/// CRC-32 (IEEE 802.3, as zlib's, PNG's and gzip's `crc32`) of `bytes`, the file's checksum.
/// `crc32(b"123456789") == 0xCBF43926`.
pub fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

// ---------------------------------------------------------------------------------------------
// Header offsets (version 1).

const OFF_VERSION: usize = 8;
const OFF_FLAGS: usize = 12;
const OFF_FILE_LENGTH: usize = 16;
const OFF_LANDMARKS: usize = 24;
const OFF_TRIANGLES: usize = 28;
const OFF_FRAME_WIDTH: usize = 32;
const OFF_FRAME_HEIGHT: usize = 36;
const OFF_ORIGIN_X: usize = 40;
const OFF_ORIGIN_Y: usize = 44;
const OFF_PIXELS: usize = 48;
const OFF_CHANNELS: usize = 52;
const OFF_SHAPE_MODES: usize = 56;
const OFF_APPEARANCE_MODES: usize = 60;
const OFF_SCHEME: usize = 64;
const OFF_REFERENCE: usize = 68;
const OFF_NAME_LEN: usize = 72;
const OFF_REFERENCE_NAME_LEN: usize = 76;
const OFF_POSE: usize = 80;
const OFF_IMAGE_WIDTH: usize = 96;
const OFF_IMAGE_HEIGHT: usize = 100;
const OFF_FINGERPRINT: usize = 104;

/// Byte offsets of the header fields (version 1), for tools and tests that patch headers.
pub mod offsets {
    /// `u32` format version.
    pub const VERSION: usize = super::OFF_VERSION;
    /// `u32` reserved flags (0) in version 1.
    pub const FLAGS: usize = super::OFF_FLAGS;
    /// `u32` appearance storage tag in version 2 (the same field as version 1's flags).
    pub const STORAGE: usize = super::OFF_FLAGS;
    /// `u64` total file length in bytes, checksum included.
    pub const FILE_LENGTH: usize = super::OFF_FILE_LENGTH;
    /// `u32` landmarks `n`.
    pub const LANDMARKS: usize = super::OFF_LANDMARKS;
    /// `u32` triangles `t`.
    pub const TRIANGLES: usize = super::OFF_TRIANGLES;
    /// `u32` frame width `W`.
    pub const FRAME_WIDTH: usize = super::OFF_FRAME_WIDTH;
    /// `u32` frame height `H`.
    pub const FRAME_HEIGHT: usize = super::OFF_FRAME_HEIGHT;
    /// `f32` frame origin x.
    pub const ORIGIN_X: usize = super::OFF_ORIGIN_X;
    /// `f32` frame origin y.
    pub const ORIGIN_Y: usize = super::OFF_ORIGIN_Y;
    /// `u32` frame pixels `N`.
    pub const PIXELS: usize = super::OFF_PIXELS;
    /// `u32` channels (3).
    pub const CHANNELS: usize = super::OFF_CHANNELS;
    /// `u32` shape modes `m`.
    pub const SHAPE_MODES: usize = super::OFF_SHAPE_MODES;
    /// `u32` appearance modes `l`.
    pub const APPEARANCE_MODES: usize = super::OFF_APPEARANCE_MODES;
    /// `u32` landmark scheme tag.
    pub const SCHEME: usize = super::OFF_SCHEME;
    /// `u32` reference tag.
    pub const REFERENCE: usize = super::OFF_REFERENCE;
    /// `u32` model name length in bytes.
    pub const NAME_LEN: usize = super::OFF_NAME_LEN;
    /// `u32` reference name length in bytes.
    pub const REFERENCE_NAME_LEN: usize = super::OFF_REFERENCE_NAME_LEN;
    /// `4 x f32` mean pose `a, b, tx, ty`.
    pub const POSE: usize = super::OFF_POSE;
    /// `u32` training image width.
    pub const IMAGE_WIDTH: usize = super::OFF_IMAGE_WIDTH;
    /// `u32` training image height.
    pub const IMAGE_HEIGHT: usize = super::OFF_IMAGE_HEIGHT;
    /// `u64` frame fingerprint.
    pub const FINGERPRINT: usize = super::OFF_FINGERPRINT;
}

/// Rounds `x` up to a multiple of 4.
fn pad4(x: u64) -> u64 {
    (4 - x % 4) % 4
}

// ---------------------------------------------------------------------------------------------
// Writing.

/// Serialises a model into the `.fmm` format (version [`FORMAT_VERSION`]) with the default,
/// compact appearance storage ([`Storage::I8`]); see [`write_model_as`].
pub fn write_model(model: &Model) -> Vec<u8> {
    write_model_as(model, Storage::default())
}

/// Serialises a model into the `.fmm` format (version [`FORMAT_VERSION`]), the appearance base
/// and modes stored as `storage` says.
///
/// Infallible: it writes what the model holds. A model from [`crate::Builder::build`] or
/// [`read_model`] within the [`LIMITS`] reads back equal with [`Storage::F32`]
/// (`read_model(&write_model_as(&m, Storage::F32)) == Ok(m)`), and within the storage's
/// rounding otherwise (a model read from a file of that storage writes back byte for byte); a
/// model that breaks its invariants or the limits is written faithfully and rejected by
/// [`read_model`].
pub fn write_model_as(model: &Model, storage: Storage) -> Vec<u8> {
    let n2 = model.shape().base.len();
    let m = model.shape().variances.len();
    let l = model.appearance().variances.len();
    let frame = &model.frame();
    let name = model.name().as_bytes();
    let (ref_tag, ref_name): (u32, &[u8]) = match &model.reference() {
        Reference::Mean => (REFERENCE_MEAN, &[]),
        Reference::Training(s) => (REFERENCE_TRAINING, s.as_bytes()),
    };
    let names = name.len() + ref_name.len();
    let padding = pad4(names as u64) as usize;
    let floats = model.shape().base.len()
        + model.shape().modes.len()
        + m
        + frame.vertices().len()
        + 3 * frame.triangles().len();
    let appearance = appearance_bytes(
        storage,
        model.appearance().base.len() as u64,
        model.appearance().modes.len() as u64 / model.appearance().base.len().max(1) as u64,
    )
    .unwrap_or(0) as usize;
    let sections = sections_of(model);
    let total =
        HEADER_LEN + names + padding + 4 * floats + appearance + sections.len() + CHECKSUM_LEN;
    let mut out = Vec::with_capacity(total);
    let u32le = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
    let f32le = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
    let as_u32 = |v: usize| u32::try_from(v).unwrap_or(u32::MAX);

    out.extend_from_slice(&MAGIC);
    u32le(&mut out, FORMAT_VERSION);
    u32le(&mut out, storage.tag());
    out.extend_from_slice(&(total as u64).to_le_bytes());
    u32le(&mut out, as_u32(n2 / 2));
    u32le(&mut out, as_u32(frame.triangles().len()));
    u32le(&mut out, frame.width());
    u32le(&mut out, frame.height());
    f32le(&mut out, frame.origin()[0]);
    f32le(&mut out, frame.origin()[1]);
    u32le(&mut out, as_u32(model.appearance().base.len() / 3));
    u32le(&mut out, 3);
    u32le(&mut out, as_u32(m));
    u32le(&mut out, as_u32(l));
    u32le(
        &mut out,
        match model.scheme() {
            LandmarkScheme::Ibug68 => SCHEME_IBUG68,
            LandmarkScheme::Generic(_) => SCHEME_GENERIC,
        },
    );
    u32le(&mut out, ref_tag);
    u32le(&mut out, as_u32(name.len()));
    u32le(&mut out, as_u32(ref_name.len()));
    let p = model.mean_pose();
    for v in [p.a, p.b, p.tx, p.ty] {
        f32le(&mut out, v);
    }
    u32le(&mut out, model.image_size()[0]);
    u32le(&mut out, model.image_size()[1]);
    out.extend_from_slice(&frame.fingerprint().to_le_bytes());
    debug_assert_eq!(out.len(), HEADER_LEN);

    out.extend_from_slice(name);
    out.extend_from_slice(ref_name);
    out.extend(std::iter::repeat_n(0u8, padding));
    let arrays: [&[f32]; 4] = [
        &model.shape().base,
        &model.shape().modes,
        &model.shape().variances,
        frame.vertices(),
    ];
    for a in arrays {
        a.iter().for_each(|&v| f32le(&mut out, v));
    }
    frame
        .triangles()
        .iter()
        .flatten()
        .for_each(|&i| u32le(&mut out, i));
    write_appearance(&mut out, model.appearance(), storage);
    out.extend_from_slice(&sections);
    let crc = crc32(&out);
    u32le(&mut out, crc);
    debug_assert_eq!(out.len(), total);
    out
}

// ---------------------------------------------------------------------------------------------
// Reading.

/// Little-endian reads at fixed offsets of a slice whose length was checked beforehand; a
/// missing byte reads as a truncation error rather than a panic.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], FormatError> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or(FormatError::Truncated {
                needed: self.pos as u64 + n as u64,
                available: self.bytes.len() as u64,
            })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    /// Reads `count` f32 values, rejecting non-finite ones.
    fn f32s(&mut self, count: usize, array: &'static str) -> Result<Vec<f32>, FormatError> {
        let bytes = self.take(count.checked_mul(4).ok_or(FormatError::Truncated {
            needed: u64::MAX,
            available: self.bytes.len() as u64,
        })?)?;
        let mut out = Vec::with_capacity(count);
        for (i, c) in bytes.chunks_exact(4).enumerate() {
            let v = f32::from_le_bytes(le_at(c, 0));
            if !v.is_finite() {
                return Err(FormatError::NonFinite {
                    array,
                    index: i as u64,
                });
            }
            out.push(v);
        }
        Ok(out)
    }
}

/// The `N` bytes at `off` (for `from_le_bytes`). Callers check `b.len() >= HEADER_LEN` (or
/// `off + N`) first.
fn le_at<const N: usize>(b: &[u8], off: usize) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&b[off..off + N]);
    a
}

fn u32_at(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(le_at(b, off))
}

fn f32_at(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes(le_at(b, off))
}

fn u64_at(b: &[u8], off: usize) -> u64 {
    u64::from_le_bytes(le_at(b, off))
}

/// Fails unless `min <= value <= max`.
fn check_range(what: &'static str, value: u32, min: u32, max: u32) -> Result<(), FormatError> {
    if value > max {
        return Err(FormatError::LimitExceeded {
            what,
            value: value as u64,
            limit: max as u64,
        });
    }
    if value < min {
        return Err(FormatError::BelowMinimum {
            what,
            value: value as u64,
            minimum: min as u64,
        });
    }
    Ok(())
}

/// The header of a version-1 or version-2 file, validated against the limits.
struct Header {
    version: u32,
    storage: Storage,
    file_length: u64,
    n: u32,
    t: u32,
    width: u32,
    height: u32,
    origin: [f32; 2],
    pixels: u32,
    m: u32,
    l: u32,
    scheme: u32,
    reference: u32,
    name_len: u32,
    ref_name_len: u32,
    pose: Similarity,
    image_size: [u32; 2],
    fingerprint: u64,
}

impl Header {
    /// Parses and validates the header: magic, version, flags, every dimension against its
    /// limit, the tags, and the consistency of the dimensions.
    fn parse(b: &[u8]) -> Result<Header, FormatError> {
        let avail = b.len() as u64;
        let prefix = b.len().min(MAGIC.len());
        if b[..prefix] != MAGIC[..prefix] {
            return Err(FormatError::BadMagic);
        }
        let mut version = FORMAT_VERSION;
        if b.len() >= OFF_VERSION + 4 {
            version = u32_at(b, OFF_VERSION);
            if !(OLDEST_VERSION..=FORMAT_VERSION).contains(&version) {
                return Err(FormatError::UnsupportedVersion {
                    found: version,
                    supported: FORMAT_VERSION,
                });
            }
        }
        if b.len() < HEADER_LEN {
            return Err(FormatError::Truncated {
                needed: HEADER_LEN as u64,
                available: avail,
            });
        }
        let storage = parse_storage_field(version, u32_at(b, OFF_FLAGS))?;
        let lim = &LIMITS;
        let h = Header {
            version,
            storage,
            file_length: u64_at(b, OFF_FILE_LENGTH),
            n: u32_at(b, OFF_LANDMARKS),
            t: u32_at(b, OFF_TRIANGLES),
            width: u32_at(b, OFF_FRAME_WIDTH),
            height: u32_at(b, OFF_FRAME_HEIGHT),
            origin: [f32_at(b, OFF_ORIGIN_X), f32_at(b, OFF_ORIGIN_Y)],
            pixels: u32_at(b, OFF_PIXELS),
            m: u32_at(b, OFF_SHAPE_MODES),
            l: u32_at(b, OFF_APPEARANCE_MODES),
            scheme: u32_at(b, OFF_SCHEME),
            reference: u32_at(b, OFF_REFERENCE),
            name_len: u32_at(b, OFF_NAME_LEN),
            ref_name_len: u32_at(b, OFF_REFERENCE_NAME_LEN),
            pose: Similarity {
                a: f32_at(b, OFF_POSE),
                b: f32_at(b, OFF_POSE + 4),
                tx: f32_at(b, OFF_POSE + 8),
                ty: f32_at(b, OFF_POSE + 12),
            },
            image_size: [u32_at(b, OFF_IMAGE_WIDTH), u32_at(b, OFF_IMAGE_HEIGHT)],
            fingerprint: u64_at(b, OFF_FINGERPRINT),
        };
        check_range("landmarks", h.n, 3, lim.max_landmarks)?;
        check_range("triangles", h.t, 1, lim.max_triangles)?;
        check_range("frame width", h.width, 1, lim.max_frame_side)?;
        check_range("frame height", h.height, 1, lim.max_frame_side)?;
        if !h.origin[0].is_finite() || !h.origin[1].is_finite() {
            let index = if h.origin[0].is_finite() { 1 } else { 0 };
            return Err(FormatError::NonFinite {
                array: "frame origin",
                index,
            });
        }
        check_range("frame pixels", h.pixels, 1, lim.max_pixels)?;
        let channels = u32_at(b, OFF_CHANNELS);
        if channels != 3 {
            return Err(FormatError::UnsupportedChannels { found: channels });
        }
        check_range("shape modes", h.m, 0, lim.max_shape_modes)?;
        check_range("appearance modes", h.l, 0, lim.max_appearance_modes)?;
        match h.scheme {
            SCHEME_GENERIC => {}
            SCHEME_IBUG68 if h.n == 68 => {}
            SCHEME_IBUG68 => {
                return Err(FormatError::InconsistentDimensions(format!(
                    "the iBUG-68 scheme needs 68 landmarks, the header has {}",
                    h.n
                )))
            }
            tag => return Err(FormatError::BadSchemeTag { tag }),
        }
        match h.reference {
            REFERENCE_MEAN if h.ref_name_len != 0 => {
                return Err(FormatError::InconsistentDimensions(format!(
                    "the reference is the mean but a reference name of {} bytes is given",
                    h.ref_name_len
                )))
            }
            REFERENCE_MEAN | REFERENCE_TRAINING => {}
            tag => return Err(FormatError::BadReferenceTag { tag }),
        }
        check_range("model name length", h.name_len, 0, lim.max_name_bytes)?;
        check_range(
            "reference name length",
            h.ref_name_len,
            0,
            lim.max_reference_name_bytes,
        )?;
        let pose = [h.pose.a, h.pose.b, h.pose.tx, h.pose.ty];
        if let Some(i) = pose.iter().position(|v| !v.is_finite()) {
            return Err(FormatError::NonFinite {
                array: "mean pose",
                index: i as u64,
            });
        }
        check_range("image width", h.image_size[0], 1, lim.max_image_side)?;
        check_range("image height", h.image_size[1], 1, lim.max_image_side)?;

        // Consistency of the dimensions (all products fit in u64: the factors are limited).
        let area = h.width as u64 * h.height as u64;
        if h.pixels as u64 > area {
            return Err(FormatError::InconsistentDimensions(format!(
                "{} frame pixels do not fit a {}x{} grid",
                h.pixels, h.width, h.height
            )));
        }
        let area_limit = lim.area_per_pixel * h.pixels as u64 + lim.area_slack;
        if area > area_limit {
            return Err(FormatError::LimitExceeded {
                what: "frame area (width x height) for the pixel count",
                value: area,
                limit: area_limit,
            });
        }
        if h.m as u64 > 2 * h.n as u64 {
            return Err(FormatError::InconsistentDimensions(format!(
                "{} shape modes for {} shape values (at most one mode per value)",
                h.m,
                2 * h.n
            )));
        }
        if h.l as u64 > 3 * h.pixels as u64 {
            return Err(FormatError::InconsistentDimensions(format!(
                "{} appearance modes for {} appearance values (at most one mode per value)",
                h.l,
                3 * h.pixels as u64
            )));
        }
        Ok(h)
    }

    /// The file length the dimensions imply, with checked arithmetic (`None` on overflow,
    /// which the limits make impossible).
    fn implied_length(&self) -> Option<u64> {
        let (n2, m, t, px3, l) = (
            2 * self.n as u64,
            self.m as u64,
            self.t as u64,
            3 * self.pixels as u64,
            self.l as u64,
        );
        let names = self.name_len as u64 + self.ref_name_len as u64;
        let shape = n2.checked_mul(m)?.checked_add(2 * n2)?.checked_add(m)?;
        let words = shape.checked_add(t.checked_mul(3)?)?;
        (HEADER_LEN as u64)
            .checked_add(names)?
            .checked_add(pad4(names))?
            .checked_add(words.checked_mul(4)?)?
            .checked_add(appearance_bytes(self.storage, px3, l)?)?
            .checked_add(CHECKSUM_LEN as u64)
    }
}

/// Checks `|<a_i, a_j> - delta_ij| <= tol` for every pair of rows (`all_pairs`) or only the
/// norms, in f64.
fn check_orthonormal(
    array: &'static str,
    modes: &[f32],
    dim: usize,
    all_pairs: bool,
) -> Result<(), FormatError> {
    if dim == 0 {
        return Ok(());
    }
    let tol = LIMITS.orthonormal_tolerance as f64;
    let rows: Vec<&[f32]> = modes.chunks_exact(dim).collect();
    for (i, a) in rows.iter().enumerate() {
        let others = if all_pairs { &rows[..=i] } else { &rows[i..=i] };
        let first = if all_pairs { 0 } else { i };
        for (k, b) in others.iter().enumerate() {
            let j = first + k;
            let dot: f64 = a
                .iter()
                .zip(b.iter())
                .map(|(&x, &y)| x as f64 * y as f64)
                .sum();
            let target = if i == j { 1.0 } else { 0.0 };
            if !((dot - target).abs() <= tol) {
                return Err(FormatError::NotOrthonormal {
                    array,
                    i: i as u32,
                    j: j as u32,
                    dot: dot as f32,
                });
            }
        }
    }
    Ok(())
}

fn check_variances(array: &'static str, v: &[f32]) -> Result<(), FormatError> {
    match v.iter().position(|&x| x < 0.0) {
        Some(i) => Err(FormatError::NegativeVariance {
            array,
            index: i as u32,
            value: v[i],
        }),
        None => Ok(()),
    }
}

/// The sum over triangles of their bounding boxes in grid cells, clipped to the grid (an upper
/// bound of the work [`ReferenceFrame::new`] does rasterising the mesh).
fn raster_work(vertices: &[f32], triangles: &[[u32; 3]], origin: [f32; 2], w: u32, h: u32) -> u64 {
    let mut total = 0u64;
    for t in triangles {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &i in t {
            let i = i as usize;
            let (x, y) = match (vertices.get(2 * i), vertices.get(2 * i + 1)) {
                (Some(&x), Some(&y)) => (x as f64 + origin[0] as f64, y as f64 + origin[1] as f64),
                _ => continue,
            };
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        let x0 = x0.floor().max(0.0);
        let y0 = y0.floor().max(0.0);
        let x1 = x1.ceil().min(w as f64 - 1.0);
        let y1 = y1.ceil().min(h as f64 - 1.0);
        if x1 >= x0 && y1 >= y0 {
            total = total.saturating_add(((x1 - x0 + 1.0) * (y1 - y0 + 1.0)) as u64);
        }
    }
    total
}

/// Parses and validates a `.fmm` model file.
///
/// Checks, in this order (the first failure is returned): magic, version, header length,
/// reserved flags, every header value against [`LIMITS`] and the tags, the consistency of the
/// dimensions, the stated file length against the one the dimensions imply, the actual length
/// (truncation, trailing bytes), the CRC-32, the names' UTF-8, the padding, every array
/// (finite values, triangle indices, non-negative variances, orthonormal modes), the
/// rasterisation work, and finally the reference frame rebuilt from the mesh (its pixel count
/// and fingerprint must equal the stored ones).
///
/// Never panics, and allocates nothing before the file's length has been checked against the
/// length its header implies; all allocations are then bounded by a small multiple of the file
/// size (the frame grid by the area limit).
pub fn read_model(bytes: &[u8]) -> Result<Model, FormatError> {
    read_model_info(bytes).map(|(model, _)| model)
}

/// [`read_model`], also returning the file's version and appearance storage.
pub fn read_model_info(bytes: &[u8]) -> Result<(Model, FileInfo), FormatError> {
    let h = Header::parse(bytes)?;
    let implied = h.implied_length().ok_or(FormatError::LimitExceeded {
        what: "implied file length",
        value: u64::MAX,
        limit: u64::MAX - 1,
    })?;
    // Version 3 may hold sections after the appearance: the stated length is then larger than
    // what the dimensions imply, by the sections' bytes (checked when they are parsed).
    let sections_allowed = h.version >= 3;
    if h.file_length != implied && !(sections_allowed && h.file_length > implied) {
        return Err(FormatError::LengthMismatch {
            stated: h.file_length,
            implied,
        });
    }
    let implied = h.file_length;
    let found = bytes.len() as u64;
    if found < implied {
        return Err(FormatError::Truncated {
            needed: implied,
            available: found,
        });
    }
    if found > implied {
        return Err(FormatError::TrailingBytes {
            expected: implied,
            found,
        });
    }
    // From here on every size fits in usize: it is at most bytes.len().
    let body = bytes.len() - CHECKSUM_LEN;
    let stored = u32_at(bytes, body);
    let computed = crc32(&bytes[..body]);
    if stored != computed {
        return Err(FormatError::ChecksumMismatch { stored, computed });
    }

    let mut c = Cursor {
        bytes: &bytes[..body],
        pos: HEADER_LEN,
    };
    let name = std::str::from_utf8(c.take(h.name_len as usize)?)
        .map_err(|_| FormatError::InvalidUtf8 {
            field: "model name",
        })?
        .to_string();
    let ref_name = std::str::from_utf8(c.take(h.ref_name_len as usize)?)
        .map_err(|_| FormatError::InvalidUtf8 {
            field: "reference name",
        })?
        .to_string();
    let padding = pad4(h.name_len as u64 + h.ref_name_len as u64) as usize;
    if c.take(padding)?.iter().any(|&b| b != 0) {
        return Err(FormatError::NonZeroPadding);
    }

    let (n2, m, t, px3, l) = (
        2 * h.n as usize,
        h.m as usize,
        h.t as usize,
        3 * h.pixels as usize,
        h.l as usize,
    );
    let shape_base = c.f32s(n2, "shape base")?;
    let shape_modes = c.f32s(n2 * m, "shape modes")?;
    let shape_variances = c.f32s(m, "shape variances")?;
    let vertices = c.f32s(n2, "frame vertices")?;
    let tri_bytes = c.take(12 * t)?;
    let mut triangles = Vec::with_capacity(t);
    for (k, tri) in tri_bytes.chunks_exact(12).enumerate() {
        let idx = [u32_at(tri, 0), u32_at(tri, 4), u32_at(tri, 8)];
        if let Some(&bad) = idx.iter().find(|&&i| i >= h.n) {
            return Err(FormatError::InvalidTriangleIndex {
                triangle: k as u32,
                index: bad,
                landmarks: h.n,
            });
        }
        triangles.push(idx);
    }
    let appearance = read_appearance(&mut c, h.storage, px3, l)?;
    let sections = read_sections(&mut c, body, h.n)?;
    debug_assert_eq!(c.pos, body);

    check_variances("shape variances", &shape_variances)?;
    check_variances("appearance variances", &appearance.variances)?;
    check_orthonormal("shape modes", &shape_modes, n2, true)?;
    check_orthonormal("appearance modes", &appearance.modes, px3, false)?;

    let work = raster_work(&vertices, &triangles, h.origin, h.width, h.height);
    let work_limit = LIMITS.coverage_per_cell * (h.width as u64 * h.height as u64)
        + LIMITS.coverage_per_triangle * h.t as u64;
    if work > work_limit {
        return Err(FormatError::LimitExceeded {
            what: "sum of triangle bounding boxes (grid cells)",
            value: work,
            limit: work_limit,
        });
    }
    let frame = ReferenceFrame::new(vertices, triangles, h.width, h.height, h.origin)
        .map_err(|e| FormatError::BadFrame(e.to_string()))?;
    if frame.n_pixels() as u64 != h.pixels as u64 {
        return Err(FormatError::PixelCountMismatch {
            header: h.pixels,
            recomputed: frame.n_pixels() as u64,
        });
    }
    if frame.fingerprint() != h.fingerprint {
        return Err(FormatError::FingerprintMismatch {
            stored: h.fingerprint,
            recomputed: frame.fingerprint(),
        });
    }

    let mut info = FileInfo {
        version: h.version,
        storage: h.storage,
        backdrop_bytes: 0,
        backdrop_notice: None,
    };
    let model = Model::new(ModelParts {
        name,
        scheme: if h.scheme == SCHEME_IBUG68 {
            LandmarkScheme::Ibug68
        } else {
            LandmarkScheme::Generic(h.n)
        },
        shape: ShapeModel {
            base: shape_base,
            modes: shape_modes,
            variances: shape_variances,
        },
        appearance,
        frame,
        reference: if h.reference == REFERENCE_TRAINING {
            Reference::Training(ref_name)
        } else {
            Reference::Mean
        },
        mean_pose: h.pose,
        image_size: h.image_size,
    })
    .map_err(|e| FormatError::InconsistentDimensions(e.to_string()))?;
    crate::bounds::check_model_values(&model)?;
    // A backdrop whose picture does not decode or whose landmarks fall outside it is dropped
    // with a notice: the model still renders, face only.
    let model = match sections.backdrop {
        None => model,
        Some(raw) => {
            info.backdrop_bytes = raw.jpeg.len();
            match Backdrop::decode(raw.width, raw.height, raw.landmarks, raw.jpeg)
                .and_then(|b| model.clone().with_backdrop(b))
            {
                Ok(m) => m,
                Err(e) => {
                    info.backdrop_notice = Some(format!(
                        "the backdrop is damaged and was left out (the face renders alone): {e}"
                    ));
                    model
                }
            }
        }
    };
    Ok((model, info))
}

// ---------------------------------------------------------------------------------------------
// Sections (version 3): `u32 tag, u32 length, length bytes, zero padding to 4`, up to the
// checksum. Unknown tags are skipped (a newer writer's optional data).

/// A backdrop section as stored, before its picture is decoded.
struct RawBackdrop {
    width: u32,
    height: u32,
    landmarks: Vec<f32>,
    jpeg: Vec<u8>,
}

/// The sections a file holds.
#[derive(Default)]
struct Sections {
    backdrop: Option<RawBackdrop>,
}

/// The sections' bytes for `model` (empty when it has no backdrop).
fn sections_of(model: &Model) -> Vec<u8> {
    let mut out = Vec::new();
    if let Some(b) = model.backdrop() {
        let mut payload = Vec::with_capacity(16 + 4 * b.landmarks().len() + b.jpeg().len());
        payload.extend_from_slice(&b.width().to_le_bytes());
        payload.extend_from_slice(&b.height().to_le_bytes());
        payload.extend_from_slice(&((b.landmarks().len() / 2) as u32).to_le_bytes());
        b.landmarks()
            .iter()
            .for_each(|v| payload.extend_from_slice(&v.to_le_bytes()));
        payload.extend_from_slice(&(b.jpeg().len() as u32).to_le_bytes());
        payload.extend_from_slice(b.jpeg());
        out.extend_from_slice(&SECTION_BACKDROP.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        out.extend_from_slice(&payload);
        out.extend(std::iter::repeat_n(
            0u8,
            pad4(payload.len() as u64) as usize,
        ));
    }
    out
}

/// Parses the sections from the cursor's position up to `end` (the checksum).
fn read_sections(c: &mut Cursor<'_>, end: usize, landmarks: u32) -> Result<Sections, FormatError> {
    let mut sections = Sections::default();
    let mut count = 0;
    while c.pos < end {
        count += 1;
        if count > MAX_SECTIONS {
            return Err(FormatError::LimitExceeded {
                what: "sections",
                value: count as u64,
                limit: MAX_SECTIONS as u64,
            });
        }
        let head = c.take(8)?;
        let (tag, len) = (u32_at(head, 0), u32_at(head, 4) as usize);
        if len > end - c.pos {
            return Err(FormatError::InconsistentDimensions(format!(
                "a section of {len} bytes runs past the end of the file"
            )));
        }
        let payload = c.take(len)?;
        check_padding(c, len)?;
        if tag != SECTION_BACKDROP {
            continue;
        }
        if sections.backdrop.is_some() {
            return Err(FormatError::InconsistentDimensions(
                "two backdrop sections".into(),
            ));
        }
        sections.backdrop = Some(parse_backdrop(payload, landmarks)?);
    }
    Ok(sections)
}

/// The backdrop section's payload: `u32 width, u32 height, u32 n, 2n f32 landmarks, u32 jpeg
/// length, jpeg bytes`.
fn parse_backdrop(p: &[u8], landmarks: u32) -> Result<RawBackdrop, FormatError> {
    let bad = |m: String| FormatError::InconsistentDimensions(format!("backdrop section: {m}"));
    if p.len() < 12 {
        return Err(bad(format!("{} bytes, too short for its header", p.len())));
    }
    let (width, height, n) = (u32_at(p, 0), u32_at(p, 4), u32_at(p, 8));
    check_range(
        "backdrop width",
        width,
        1,
        crate::backdrop::MAX_BACKDROP_SIDE,
    )?;
    check_range(
        "backdrop height",
        height,
        1,
        crate::backdrop::MAX_BACKDROP_SIDE,
    )?;
    if n != landmarks {
        return Err(bad(format!("{n} landmarks, the model has {landmarks}")));
    }
    let lm_end = 12 + 8 * n as usize;
    if p.len() < lm_end + 4 {
        return Err(bad(format!(
            "{} bytes, too short for {n} landmarks",
            p.len()
        )));
    }
    let values: Vec<f32> = (0..2 * n as usize).map(|i| f32_at(p, 12 + 4 * i)).collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(FormatError::NonFinite {
            array: "backdrop landmarks",
            index: i as u64,
        });
    }
    let jpeg_len = u32_at(p, lm_end) as usize;
    if jpeg_len > crate::backdrop::MAX_BACKDROP_BYTES {
        return Err(FormatError::LimitExceeded {
            what: "backdrop bytes",
            value: jpeg_len as u64,
            limit: crate::backdrop::MAX_BACKDROP_BYTES as u64,
        });
    }
    if p.len() != lm_end + 4 + jpeg_len {
        return Err(bad(format!(
            "{} bytes for a picture of {jpeg_len} bytes and {n} landmarks",
            p.len()
        )));
    }
    Ok(RawBackdrop {
        width,
        height,
        landmarks: values,
        jpeg: p[lm_end + 4..].to_vec(),
    })
}

// ---------------------------------------------------------------------------------------------
// Appearance storage (version 2). Version 1 stores the appearance base and modes as f32, which
// is version 2's `Storage::F32` byte for byte.

/// How a version-2 file stores the appearance base `A0` and modes (everything else is always
/// stored exactly, as `f32` / `u32`). Specified in `docs/model-format.md`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Storage {
    /// Exact: `f32` base and modes (tag 0; the only storage of version 1).
    F32,
    /// IEEE binary16 base and modes (tag 1): half the bytes, relative rounding `2^-11`.
    F16,
    /// Tag 2: the base as `u8` levels `q / 255`, each mode as `i8` values `q * scale_i` with one
    /// `f32` scale per mode; about a quarter of the bytes.
    I8,
    /// The compact default (tag 3): as [`Storage::I8`] with the mode values packed in 6 bits
    /// (about a fifth of the bytes).
    #[default]
    I6,
}

impl Storage {
    /// Every storage, in tag order.
    pub const ALL: [Storage; 4] = [Storage::F32, Storage::F16, Storage::I8, Storage::I6];

    /// The tag stored at header offset 12 in version 2.
    pub fn tag(self) -> u32 {
        match self {
            Storage::F32 => 0,
            Storage::F16 => 1,
            Storage::I8 => 2,
            Storage::I6 => 3,
        }
    }

    /// The storage of a tag.
    pub fn from_tag(tag: u32) -> Option<Storage> {
        Storage::ALL.into_iter().find(|s| s.tag() == tag)
    }

    /// Its name: `f32`, `f16`, `i8` or `i6` (as `facemimic build --precision` takes it).
    pub fn name(self) -> &'static str {
        match self {
            Storage::F32 => "f32",
            Storage::F16 => "f16",
            Storage::I8 => "i8",
            Storage::I6 => "i6",
        }
    }

    /// Bits per stored mode value.
    pub fn mode_bits(self) -> u32 {
        match self {
            Storage::F32 => 32,
            Storage::F16 => 16,
            Storage::I8 => 8,
            Storage::I6 => 6,
        }
    }
}

impl std::fmt::Display for Storage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Storage {
    type Err = String;
    fn from_str(s: &str) -> Result<Storage, String> {
        Storage::ALL
            .into_iter()
            .find(|x| x.name() == s)
            .ok_or_else(|| format!("unknown precision '{s}' (expected f32, f16, i8 or i6)"))
    }
}

/// What a file was, besides the model it holds: see [`read_model_info`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileInfo {
    /// Its format version (1 to 3).
    pub version: u32,
    /// How it stores the appearance ([`Storage::F32`] for version 1).
    pub storage: Storage,
    /// Compressed bytes of its backdrop section's picture (0 when it has none).
    pub backdrop_bytes: usize,
    /// Set when the file's backdrop could not be used (the model was loaded without it): why.
    pub backdrop_notice: Option<String>,
}

/// The header field at offset 12: reserved flags (0) in version 1, the storage tag in version 2.
fn parse_storage_field(version: u32, value: u32) -> Result<Storage, FormatError> {
    if version == 1 {
        return match value {
            0 => Ok(Storage::F32),
            _ => Err(FormatError::ReservedFlags { value }),
        };
    }
    Storage::from_tag(value).ok_or(FormatError::BadStorageTag { tag: value })
}

/// Bytes of the appearance section (base, modes, variances and, for i8, the scales) for `3N =
/// px3` values per vector and `l` modes; `None` on overflow.
fn appearance_bytes(storage: Storage, px3: u64, l: u64) -> Option<u64> {
    let values = px3.checked_mul(l)?.checked_add(px3)?;
    match storage {
        Storage::F32 => values.checked_add(l)?.checked_mul(4),
        Storage::F16 => round4(values.checked_mul(2)?)?.checked_add(4 * l),
        Storage::I8 | Storage::I6 => {
            let bits = px3
                .checked_mul(l)?
                .checked_mul(storage.mode_bits() as u64)?;
            round4(px3.checked_add(bits.checked_add(7)? / 8)?)?.checked_add(8 * l)
        }
    }
}

fn round4(x: u64) -> Option<u64> {
    x.checked_add(3).map(|v| v & !3)
}

/// Decodes an IEEE binary16 value.
fn f16_to_f32(bits: u16) -> f32 {
    half::f16::from_bits(bits).to_f32()
}

/// The scale and `bits`-bit values of one mode: `q = round(v / s0)` with `s0 = max|v| / qmax`,
/// `qmax = 2^(bits-1) - 1`, then the scale `1 / |q|` so that the decoded mode `q * scale` has
/// unit norm like the `f32` one (a model read from such a file encodes back to the same bytes).
fn quantise_mode(mode: &[f32], bits: u32, q: &mut Vec<i8>) -> f32 {
    let qmax = ((1i32 << (bits - 1)) - 1) as f32;
    let peak = mode.iter().fold(0f32, |a, &v| a.max(v.abs()));
    let s0 = if peak > 0.0 && peak.is_finite() {
        peak / qmax
    } else {
        1.0
    };
    let mut norm2 = 0f64;
    for &v in mode {
        let k = (v / s0).round().clamp(-qmax, qmax) as i8;
        norm2 += (k as f64) * (k as f64);
        q.push(k);
    }
    if norm2 > 0.0 {
        (1.0 / norm2.sqrt()) as f32
    } else {
        s0
    }
}

/// Writes the appearance section (layout in `docs/model-format.md`, "Appearance storage").
fn write_appearance(out: &mut Vec<u8>, a: &AppearanceModel, storage: Storage) {
    let f32le = |out: &mut Vec<u8>, v: f32| out.extend_from_slice(&v.to_le_bytes());
    let start = out.len();
    match storage {
        Storage::F32 => {
            for &v in a.base.iter().chain(&a.modes) {
                f32le(out, v);
            }
        }
        Storage::F16 => {
            for &v in a.base.iter().chain(&a.modes) {
                out.extend_from_slice(&half::f16::from_f32(v).to_bits().to_le_bytes());
            }
        }
        Storage::I8 | Storage::I6 => {
            let d = a.base.len();
            let bits = storage.mode_bits();
            let mut q = Vec::with_capacity(a.modes.len());
            let scales: Vec<f32> = if d == 0 {
                Vec::new()
            } else {
                a.modes
                    .chunks_exact(d)
                    .map(|m| quantise_mode(m, bits, &mut q))
                    .collect()
            };
            scales.iter().for_each(|&s| f32le(out, s));
            let base_start = out.len();
            out.extend(
                a.base
                    .iter()
                    .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8),
            );
            pack_bits(&q, bits, out);
            let pad = pad4((out.len() - base_start) as u64) as usize;
            out.extend(std::iter::repeat_n(0u8, pad));
        }
    }
    if storage == Storage::F16 {
        let pad = pad4((out.len() - start) as u64) as usize;
        out.extend(std::iter::repeat_n(0u8, pad));
    }
    a.variances.iter().for_each(|&v| f32le(out, v));
}

/// Reads and validates the appearance section, expanded to `f32`
/// (non-finite values, scales that are not positive and non-zero padding are rejected).
fn read_appearance(
    c: &mut Cursor<'_>,
    storage: Storage,
    px3: usize,
    l: usize,
) -> Result<AppearanceModel, FormatError> {
    let values = px3 * (l + 1);
    let (base, modes) = match storage {
        Storage::F32 => (
            c.f32s(px3, "appearance base")?,
            c.f32s(px3 * l, "appearance modes")?,
        ),
        Storage::F16 => {
            let bytes = c.take(2 * values)?;
            let mut base = Vec::with_capacity(px3);
            let mut modes = Vec::with_capacity(px3 * l);
            for (i, h) in bytes.chunks_exact(2).enumerate() {
                let v = f16_to_f32(u16::from_le_bytes(le_at(h, 0)));
                let (array, index, dst) = if i < px3 {
                    ("appearance base", i, &mut base)
                } else {
                    ("appearance modes", i - px3, &mut modes)
                };
                if !v.is_finite() {
                    return Err(FormatError::NonFinite {
                        array,
                        index: index as u64,
                    });
                }
                dst.push(v);
            }
            check_padding(c, 2 * values)?;
            (base, modes)
        }
        Storage::I8 | Storage::I6 => {
            let bits = storage.mode_bits() as usize;
            let scales = c.f32s(l, "appearance mode scales")?;
            if let Some(i) = scales.iter().position(|&s| s <= 0.0) {
                return Err(FormatError::InvalidScale {
                    array: "appearance mode scales",
                    index: i as u32,
                    value: scales[i],
                });
            }
            let base = c.take(px3)?.iter().map(|&q| q as f32 / 255.0).collect();
            let packed = c.take((px3 * l * bits).div_ceil(8))?;
            let mut modes = Vec::with_capacity(px3 * l);
            let mut values = unpack_bits(packed, bits as u32);
            for &s in &scales {
                modes.extend(values.by_ref().take(px3).map(|k| k as f32 * s));
            }
            check_padding(c, px3 + packed.len())?;
            (base, modes)
        }
    };
    let variances = c.f32s(l, "appearance variances")?;
    Ok(AppearanceModel {
        base,
        modes,
        variances,
    })
}

/// Consumes the zero padding after `len` bytes of 1- or 2-byte values.
fn check_padding(c: &mut Cursor<'_>, len: usize) -> Result<(), FormatError> {
    let pad = pad4(len as u64) as usize;
    if c.take(pad)?.iter().any(|&b| b != 0) {
        return Err(FormatError::NonZeroPadding);
    }
    Ok(())
}

/// Appends `q` as `bits`-bit two's-complement values, packed least significant bit first (value
/// `k` occupies stream bits `[k*bits, (k+1)*bits)`, stream bit `j` being bit `j mod 8` of byte
/// `j / 8`); the last byte's unused high bits are 0. With 8 bits this is plain `i8` bytes.
fn pack_bits(q: &[i8], bits: u32, out: &mut Vec<u8>) {
    let mask = (1u32 << bits) - 1;
    let (mut acc, mut n) = (0u32, 0u32);
    for &k in q {
        acc |= (k as i32 as u32 & mask) << n;
        n += bits;
        while n >= 8 {
            out.push(acc as u8);
            acc >>= 8;
            n -= 8;
        }
    }
    if n > 0 {
        out.push(acc as u8);
    }
}

/// The `bits`-bit two's-complement values packed by [`pack_bits`] (sign-extended).
fn unpack_bits(bytes: &[u8], bits: u32) -> impl Iterator<Item = i32> + '_ {
    let shift = 32 - bits;
    let (mut acc, mut n) = (0u32, 0u32);
    let mut it = bytes.iter();
    std::iter::from_fn(move || {
        while n < bits {
            acc |= (*it.next()? as u32) << n;
            n += 8;
        }
        let v = ((acc << shift) as i32) >> shift;
        acc >>= bits;
        n -= bits;
        Some(v)
    })
}

/// [`write_model_as`], refusing what [`read_model`] would reject: the bytes are read back with
/// the full validation before they are returned, so a file written is always a file read.
pub fn write_model_checked_as(model: &Model, storage: Storage) -> Result<Vec<u8>, FormatError> {
    crate::bounds::check_model_values(model)?;
    let bytes = write_model_as(model, storage);
    read_model(&bytes)?;
    Ok(bytes)
}

/// [`write_model_checked_as`] with the default storage (as [`write_model`]).
pub fn write_model_checked(model: &Model) -> Result<Vec<u8>, FormatError> {
    write_model_checked_as(model, Storage::default())
}

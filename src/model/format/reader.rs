//! Reading a model: the validating reader (header against the limits, lengths before any
//! allocation, checksum, arrays, the rebuilt frame) and the sections of version 3.

use super::*;
use crate::model::backdrop::Backdrop;
use crate::model::frame::ReferenceFrame;
use crate::model::shape::ShapeModel;
use crate::model::{LandmarkScheme, Model, ModelParts, Reference};
use crate::similarity::Similarity;

/// Little-endian reads at fixed offsets of a slice whose length was checked beforehand; a
/// missing byte reads as a truncation error rather than a panic.
pub(super) struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    pub(super) fn take(&mut self, n: usize) -> Result<&'a [u8], FormatError> {
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
    pub(super) fn f32s(
        &mut self,
        count: usize,
        array: &'static str,
    ) -> Result<Vec<f32>, FormatError> {
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
pub(super) fn le_at<const N: usize>(b: &[u8], off: usize) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&b[off..off + N]);
    a
}

pub(super) fn u32_at(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(le_at(b, off))
}

pub(super) fn f32_at(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes(le_at(b, off))
}

pub(super) fn u64_at(b: &[u8], off: usize) -> u64 {
    u64::from_le_bytes(le_at(b, off))
}

/// Fails unless `min <= value <= max`.
pub(super) fn check_range(
    what: &'static str,
    value: u32,
    min: u32,
    max: u32,
) -> Result<(), FormatError> {
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
pub(super) struct Header {
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
        let h = Header::read(b)?;
        h.check_limits(u32_at(b, OFF_CHANNELS))?;
        h.check_consistency()?;
        Ok(h)
    }

    /// Reads the header's fields after checking the magic, the version, the length and the
    /// storage flags.
    fn read(b: &[u8]) -> Result<Header, FormatError> {
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
        Ok(Header {
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
        })
    }

    /// Every dimension against its limit (and `channels`, the file's channel count, against 3),
    /// the finite origin and pose, the tags.
    fn check_limits(&self, channels: u32) -> Result<(), FormatError> {
        let lim = &LIMITS;
        check_range("landmarks", self.n, 3, lim.max_landmarks)?;
        check_range("triangles", self.t, 1, lim.max_triangles)?;
        check_range("frame width", self.width, 1, lim.max_frame_side)?;
        check_range("frame height", self.height, 1, lim.max_frame_side)?;
        if !self.origin[0].is_finite() || !self.origin[1].is_finite() {
            let index = if self.origin[0].is_finite() { 1 } else { 0 };
            return Err(FormatError::NonFinite {
                array: "frame origin",
                index,
            });
        }
        check_range("frame pixels", self.pixels, 1, lim.max_pixels)?;
        if channels != 3 {
            return Err(FormatError::UnsupportedChannels { found: channels });
        }
        check_range("shape modes", self.m, 0, lim.max_shape_modes)?;
        check_range("appearance modes", self.l, 0, lim.max_appearance_modes)?;
        match self.scheme {
            SCHEME_GENERIC => {}
            SCHEME_IBUG68 if self.n == 68 => {}
            SCHEME_IBUG68 => {
                return Err(FormatError::InconsistentDimensions(format!(
                    "the iBUG-68 scheme needs 68 landmarks, the header has {}",
                    self.n
                )))
            }
            tag => return Err(FormatError::BadSchemeTag { tag }),
        }
        match self.reference {
            REFERENCE_MEAN if self.ref_name_len != 0 => {
                return Err(FormatError::InconsistentDimensions(format!(
                    "the reference is the mean but a reference name of {} bytes is given",
                    self.ref_name_len
                )))
            }
            REFERENCE_MEAN | REFERENCE_TRAINING => {}
            tag => return Err(FormatError::BadReferenceTag { tag }),
        }
        check_range("model name length", self.name_len, 0, lim.max_name_bytes)?;
        check_range(
            "reference name length",
            self.ref_name_len,
            0,
            lim.max_reference_name_bytes,
        )?;
        let pose = [self.pose.a, self.pose.b, self.pose.tx, self.pose.ty];
        if let Some(i) = pose.iter().position(|v| !v.is_finite()) {
            return Err(FormatError::NonFinite {
                array: "mean pose",
                index: i as u64,
            });
        }
        check_range("image width", self.image_size[0], 1, lim.max_image_side)?;
        check_range("image height", self.image_size[1], 1, lim.max_image_side)?;
        Ok(())
    }

    /// The consistency of the dimensions (all products fit in u64: the factors are limited).
    fn check_consistency(&self) -> Result<(), FormatError> {
        let lim = &LIMITS;
        let area = self.width as u64 * self.height as u64;
        if self.pixels as u64 > area {
            return Err(FormatError::InconsistentDimensions(format!(
                "{} frame pixels do not fit a {}x{} grid",
                self.pixels, self.width, self.height
            )));
        }
        let area_limit = lim.area_per_pixel * self.pixels as u64 + lim.area_slack;
        if area > area_limit {
            return Err(FormatError::LimitExceeded {
                what: "frame area (width x height) for the pixel count",
                value: area,
                limit: area_limit,
            });
        }
        if self.m as u64 > 2 * self.n as u64 {
            return Err(FormatError::InconsistentDimensions(format!(
                "{} shape modes for {} shape values (at most one mode per value)",
                self.m,
                2 * self.n
            )));
        }
        if self.l as u64 > 3 * self.pixels as u64 {
            return Err(FormatError::InconsistentDimensions(format!(
                "{} appearance modes for {} appearance values (at most one mode per value)",
                self.l,
                3 * self.pixels as u64
            )));
        }
        Ok(())
    }

    /// The arrays' sizes: shape values `2n`, shape modes `m`, triangles `t`, appearance values
    /// `3 x pixels`, appearance modes `l`.
    fn counts(&self) -> [u64; 5] {
        [
            2 * self.n as u64,
            self.m as u64,
            self.t as u64,
            3 * self.pixels as u64,
            self.l as u64,
        ]
    }

    /// The file length the dimensions imply, with checked arithmetic (`None` on overflow,
    /// which the limits make impossible).
    fn implied_length(&self) -> Option<u64> {
        let [n2, m, t, px3, l] = self.counts();
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
pub(super) fn check_orthonormal(
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

pub(super) fn check_variances(array: &'static str, v: &[f32]) -> Result<(), FormatError> {
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
pub(super) fn raster_work(
    vertices: &[f32],
    triangles: &[[u32; 3]],
    origin: [f32; 2],
    w: u32,
    h: u32,
) -> u64 {
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

/// What a model file says of itself in its header and names, read without expanding the
/// model: enough to list kept models (name, sizes, frame, whether it is a photo) at the cost of
/// the header's checks, the length and the CRC-32.
///
/// Requires nothing of `bytes`. Ensures: a file this accepts has a valid header, the length its
/// dimensions imply and an intact checksum; [`read_model`] may still refuse it for what only a
/// full read sees (non-orthonormal modes, a bad frame, values out of range).
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSummary {
    /// The model's name.
    pub name: String,
    /// Its format version (1 to 3).
    pub version: u32,
    /// How it stores the appearance.
    pub storage: Storage,
    /// Number of landmarks.
    pub landmarks: usize,
    /// Number of shape modes.
    pub shape_modes: usize,
    /// Number of appearance modes.
    pub appearance_modes: usize,
    /// Pixels of the reference frame.
    pub frame_pixels: usize,
    /// The reference frame's fingerprint (models clone between each other when equal).
    pub fingerprint: u64,
    /// The image size the model was built at.
    pub image_size: [u32; 2],
    /// True for a photo target (no modes of its own).
    pub is_photo: bool,
    /// The file's length in bytes.
    pub file_bytes: usize,
}

/// The checked header and a cursor over the body (the bytes before the checksum), just past
/// the header: what every read of a model file starts with.
fn open(bytes: &[u8]) -> Result<(Header, Cursor<'_>), FormatError> {
    let h = Header::parse(bytes)?;
    let body = check_length_and_checksum(&h, bytes)?;
    let c = Cursor {
        bytes: &bytes[..body],
        pos: HEADER_LEN,
    };
    Ok((h, c))
}

/// Reads a model file's [`ModelSummary`]: the header and names only (no model is built).
pub fn read_summary(bytes: &[u8]) -> Result<ModelSummary, FormatError> {
    let (h, mut c) = open(bytes)?;
    let (name, _) = read_names(&mut c, &h)?;
    Ok(ModelSummary {
        name,
        version: h.version,
        storage: h.storage,
        landmarks: h.n as usize,
        shape_modes: h.m as usize,
        appearance_modes: h.l as usize,
        frame_pixels: h.pixels as usize,
        fingerprint: h.fingerprint,
        image_size: h.image_size,
        is_photo: h.m == 0 && h.l == 0,
        file_bytes: bytes.len(),
    })
}

/// [`read_model`], also returning the file's version and appearance storage.
pub fn read_model_info(bytes: &[u8]) -> Result<(Model, FileInfo), FormatError> {
    let (h, mut c) = open(bytes)?;
    let body = c.bytes.len();
    let (name, ref_name) = read_names(&mut c, &h)?;
    let [n2, m, t, px3, l] = h.counts().map(|v| v as usize);
    let shape_base = c.f32s(n2, "shape base")?;
    let shape_modes = c.f32s(n2 * m, "shape modes")?;
    let shape_variances = c.f32s(m, "shape variances")?;
    let vertices = c.f32s(n2, "frame vertices")?;
    let triangles = read_triangles(&mut c, &h, t)?;
    let appearance = read_appearance(&mut c, h.storage, px3, l)?;
    let sections = read_sections(&mut c, body, h.n)?;
    debug_assert_eq!(c.pos, body);

    check_variances("shape variances", &shape_variances)?;
    check_variances("appearance variances", appearance.variances())?;
    check_orthonormal("shape modes", &shape_modes, n2, true)?;
    check_orthonormal("appearance modes", &appearance.linear().modes, px3, false)?;
    let frame = checked_frame(&h, vertices, triangles)?;

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
        shape: ShapeModel(crate::model::linear::LinearModel {
            base: shape_base,
            modes: shape_modes,
            variances: shape_variances,
        }),
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
    crate::model::bounds::check_model_values(&model)?;
    let model = with_backdrop(model, sections.backdrop, &mut info);
    Ok((model, info))
}

/// Checks the stated length against the implied one and the actual one, then the CRC-32;
/// returns the length of the body (the bytes before the checksum). From here on every size
/// fits in `usize`: it is at most `bytes.len()`.
fn check_length_and_checksum(h: &Header, bytes: &[u8]) -> Result<usize, FormatError> {
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

    Ok(body)
}

/// The model name and the reference name (UTF-8), and their zero padding.
fn read_names(c: &mut Cursor<'_>, h: &Header) -> Result<(String, String), FormatError> {
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

    Ok((name, ref_name))
}

/// `t` triangles of three landmark indices, each below the landmark count.
fn read_triangles(c: &mut Cursor<'_>, h: &Header, t: usize) -> Result<Vec<[u32; 3]>, FormatError> {
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
    Ok(triangles)
}

/// The reference frame rebuilt from the stored mesh, after bounding the rasterisation work;
/// its pixel count and fingerprint must equal the header's.
fn checked_frame(
    h: &Header,
    vertices: Vec<f32>,
    triangles: Vec<[u32; 3]>,
) -> Result<ReferenceFrame, FormatError> {
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

    Ok(frame)
}

/// `model` with the file's backdrop. A backdrop whose picture does not decode or whose
/// landmarks fall outside it is dropped with a notice in `info`: the model still renders, face
/// only.
fn with_backdrop(model: Model, raw: Option<RawBackdrop>, info: &mut FileInfo) -> Model {
    match raw {
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
    }
}

// ---------------------------------------------------------------------------------------------
// Sections (version 3): `u32 tag, u32 length, length bytes, zero padding to 4`, up to the
// checksum. Unknown tags are skipped (a newer writer's optional data).

/// A backdrop section as stored, before its picture is decoded.
pub(super) struct RawBackdrop {
    width: u32,
    height: u32,
    landmarks: Vec<f32>,
    jpeg: Vec<u8>,
}

/// The sections a file holds.
#[derive(Default)]
pub(super) struct Sections {
    backdrop: Option<RawBackdrop>,
}

/// Parses the sections from the cursor's position up to `end` (the checksum).
pub(super) fn read_sections(
    c: &mut Cursor<'_>,
    end: usize,
    landmarks: u32,
) -> Result<Sections, FormatError> {
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
pub(super) fn parse_backdrop(p: &[u8], landmarks: u32) -> Result<RawBackdrop, FormatError> {
    let bad = |m: String| FormatError::InconsistentDimensions(format!("backdrop section: {m}"));
    if p.len() < 12 {
        return Err(bad(format!("{} bytes, too short for its header", p.len())));
    }
    let (width, height, n) = (u32_at(p, 0), u32_at(p, 4), u32_at(p, 8));
    check_range(
        "backdrop width",
        width,
        1,
        crate::model::backdrop::MAX_BACKDROP_SIDE,
    )?;
    check_range(
        "backdrop height",
        height,
        1,
        crate::model::backdrop::MAX_BACKDROP_SIDE,
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
    if jpeg_len > crate::model::backdrop::MAX_BACKDROP_BYTES {
        return Err(FormatError::LimitExceeded {
            what: "backdrop bytes",
            value: jpeg_len as u64,
            limit: crate::model::backdrop::MAX_BACKDROP_BYTES as u64,
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

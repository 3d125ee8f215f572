//! The file's layout: the magic, versions, tags, the header's field offsets and the checksum.

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

pub(super) const OFF_VERSION: usize = 8;
pub(super) const OFF_FLAGS: usize = 12;
pub(super) const OFF_FILE_LENGTH: usize = 16;
pub(super) const OFF_LANDMARKS: usize = 24;
pub(super) const OFF_TRIANGLES: usize = 28;
pub(super) const OFF_FRAME_WIDTH: usize = 32;
pub(super) const OFF_FRAME_HEIGHT: usize = 36;
pub(super) const OFF_ORIGIN_X: usize = 40;
pub(super) const OFF_ORIGIN_Y: usize = 44;
pub(super) const OFF_PIXELS: usize = 48;
pub(super) const OFF_CHANNELS: usize = 52;
pub(super) const OFF_SHAPE_MODES: usize = 56;
pub(super) const OFF_APPEARANCE_MODES: usize = 60;
pub(super) const OFF_SCHEME: usize = 64;
pub(super) const OFF_REFERENCE: usize = 68;
pub(super) const OFF_NAME_LEN: usize = 72;
pub(super) const OFF_REFERENCE_NAME_LEN: usize = 76;
pub(super) const OFF_POSE: usize = 80;
pub(super) const OFF_IMAGE_WIDTH: usize = 96;
pub(super) const OFF_IMAGE_HEIGHT: usize = 100;
pub(super) const OFF_FINGERPRINT: usize = 104;

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
pub(super) fn pad4(x: u64) -> u64 {
    (4 - x % 4) % 4
}

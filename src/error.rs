//! The one error type of the library.

/// Everything that can go wrong in facemimic, with a message that names the problem.
///
/// Contract: every fallible public function returns this type; no public function panics on
/// bad input (corrupt files, mismatched models, NaN parameters, images without landmarks).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A landmark file could not be parsed, or has the wrong number of points.
    #[error("landmarks: {0}")]
    Landmarks(String),
    /// A model file is corrupt, truncated, of another version, or exceeds a limit.
    #[error("model file: {0}")]
    Format(#[from] FormatError),
    /// A model cannot be built from the given training data.
    #[error("training: {0}")]
    Training(String),
    /// Two models cannot be used together (different landmark scheme or reference frame), or
    /// the parts given to [`crate::Model::new`] do not fit together.
    #[error("incompatible models: {0}")]
    Incompatible(String),
    /// Parameters have the wrong length or are not finite.
    #[error("parameters: {0}")]
    Params(String),
    /// An image has the wrong size or layout.
    #[error("image: {0}")]
    Image(String),
    /// An error about a named file.
    #[error("{file}: {source}")]
    File {
        /// The file's name or path.
        file: String,
        /// What went wrong.
        source: Box<Error>,
    },
    /// Reading or writing a file failed.
    #[error("{0}")]
    Io(String),
    /// The caller cancelled a long operation (a build) before it finished; nothing was made.
    #[error("cancelled")]
    Cancelled,
    /// A face finder's weight file is corrupt or of another layout.
    #[error("face finder weights: {0}")]
    Weights(String),
    /// A computation from finite inputs overflowed; names what overflowed.
    #[error("overflow: {0}")]
    Overflow(String),
    /// An operation would allocate more than its memory budget (see `bounds`).
    #[error("memory budget: {0}")]
    Budget(String),
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::Io(e.to_string())
    }
}

impl Error {
    /// A stable, machine-readable name of the error's kind, for front ends that show or branch
    /// on it (the npm package puts it in every thrown `Error`'s `code`). Never changes for a
    /// kind once released; the message may be reworded.
    ///
    /// | kind | code |
    /// |---|---|
    /// | [`Error::Landmarks`] | `bad-landmarks` |
    /// | [`Error::Format`] | `bad-model` |
    /// | [`Error::Training`] | `training` |
    /// | [`Error::Incompatible`] | `mismatched-models` |
    /// | [`Error::Params`] | `bad-params` |
    /// | [`Error::Image`] | `bad-frame` |
    /// | [`Error::File`] | its source's code |
    /// | [`Error::Io`] | `io` |
    /// | [`Error::Cancelled`] | `cancelled` |
    /// | [`Error::Weights`] | `bad-weights` |
    /// | [`Error::Overflow`] | `overflow` |
    /// | [`Error::Budget`] | `too-large` |
    pub fn code(&self) -> &'static str {
        match self {
            Error::Landmarks(_) => "bad-landmarks",
            Error::Format(_) => "bad-model",
            Error::Training(_) => "training",
            Error::Incompatible(_) => "mismatched-models",
            Error::Params(_) => "bad-params",
            Error::Image(_) => "bad-frame",
            Error::File { source, .. } => source.code(),
            Error::Io(_) => "io",
            Error::Cancelled => "cancelled",
            Error::Weights(_) => "bad-weights",
            Error::Overflow(_) => "overflow",
            Error::Budget(_) => "too-large",
        }
    }

    /// Prefixes the message with where it happened (a file name), keeping the variant for
    /// [`Error::Format`] by turning it into a context-carrying [`Error::File`].
    pub fn with_context(self, context: &str) -> Error {
        Error::File {
            file: context.to_string(),
            source: Box::new(self),
        }
    }
}

/// Why a model file was rejected. Each variant names the problem precisely.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum FormatError {
    /// The file does not start with [`crate::model::format::MAGIC`].
    #[error("not a facemimic model (bad magic bytes)")]
    BadMagic,
    /// The format version is not one this reader understands.
    #[error("format version {found} is not supported (this reader supports versions 1 to {supported}); a newer facemimic may read it")]
    UnsupportedVersion {
        /// Version in the file.
        found: u32,
        /// Newest version this reader supports (it reads every version from 1 to this).
        supported: u32,
    },
    /// The file ends before the header or the data the header describes.
    #[error("truncated: {needed} bytes needed, {available} available")]
    Truncated {
        /// Bytes the header (or the fixed header size) requires.
        needed: u64,
        /// Bytes present.
        available: u64,
    },
    /// Bytes follow the checksum.
    #[error("{} trailing bytes after the model (expected {expected} bytes, found {found})", found.saturating_sub(*expected))]
    TrailingBytes {
        /// Length the header implies.
        expected: u64,
        /// Actual length.
        found: u64,
    },
    /// The file length stored in the header disagrees with the length its dimensions imply.
    #[error("header states a file length of {stated} bytes but its dimensions imply {implied}")]
    LengthMismatch {
        /// The header's `file_length` field.
        stated: u64,
        /// The length computed from the header's dimensions.
        implied: u64,
    },
    /// The reserved flags field is not zero.
    #[error("reserved flags are {value:#x}, expected 0")]
    ReservedFlags {
        /// The flags value.
        value: u32,
    },
    /// The appearance storage tag (version 2) is not one of [`crate::model::format::Storage`]'s.
    #[error("unknown appearance storage tag {tag} (0 = f32, 1 = f16, 2 = i8)")]
    BadStorageTag {
        /// The tag.
        tag: u32,
    },
    /// A quantisation scale (version 2, i8 storage) is not positive.
    #[error("{array}[{index}] is {value}, a scale must be positive")]
    InvalidScale {
        /// Which array.
        array: &'static str,
        /// Index of the first bad value.
        index: u32,
        /// The value.
        value: f32,
    },
    /// A header value exceeds its limit.
    #[error("{what} is {value}, more than the limit {limit}")]
    LimitExceeded {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: u64,
        /// The limit.
        limit: u64,
    },
    /// A header value is below its minimum (e.g. zero landmarks).
    #[error("{what} is {value}, less than the minimum {minimum}")]
    BelowMinimum {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: u64,
        /// The minimum.
        minimum: u64,
    },
    /// The channel count is not 3 (RGB).
    #[error("{found} channels, only 3 (RGB) are supported")]
    UnsupportedChannels {
        /// Channels in the file.
        found: u32,
    },
    /// Unknown landmark scheme tag.
    #[error("unknown landmark scheme tag {tag}")]
    BadSchemeTag {
        /// The tag.
        tag: u32,
    },
    /// Unknown reference tag.
    #[error("unknown reference tag {tag}")]
    BadReferenceTag {
        /// The tag.
        tag: u32,
    },
    /// Header values contradict each other.
    #[error("inconsistent dimensions: {0}")]
    InconsistentDimensions(String),
    /// The CRC-32 of the file does not match the stored one (bit flips, bad transfer).
    #[error("checksum mismatch: stored {stored:08x}, computed {computed:08x} (file corrupt)")]
    ChecksumMismatch {
        /// Checksum in the file.
        stored: u32,
        /// Checksum of the bytes read.
        computed: u32,
    },
    /// A name is not valid UTF-8.
    #[error("the {field} is not valid UTF-8")]
    InvalidUtf8 {
        /// Which name ("model name" or "reference name").
        field: &'static str,
    },
    /// The alignment padding after the names is not zero.
    #[error("padding after the names is not zero")]
    NonZeroPadding,
    /// An array holds NaN or an infinity.
    #[error("{array}[{index}] is not finite")]
    NonFinite {
        /// Which array.
        array: &'static str,
        /// Index of the first bad value.
        index: u64,
    },
    /// A value is finite but outside the range a real model can have (see
    /// [`crate::model::bounds::check_model_values`]).
    #[error("{array}[{index}] is {value}, outside the range {range} a real model can have")]
    OutOfRange {
        /// Which array or quantity.
        array: &'static str,
        /// Index of the first bad value.
        index: u64,
        /// The value.
        value: f32,
        /// The allowed range.
        range: String,
    },
    /// A variance is negative.
    #[error("{array}[{index}] is negative ({value})")]
    NegativeVariance {
        /// Which array.
        array: &'static str,
        /// Index of the mode.
        index: u32,
        /// The value.
        value: f32,
    },
    /// Modes are not orthonormal: `<mode_i, mode_j>` is `dot` (should be 1 when `i == j`,
    /// 0 otherwise).
    #[error("{array} are not orthonormal: <mode {i}, mode {j}> = {dot}")]
    NotOrthonormal {
        /// Which modes ("shape modes" or "appearance modes").
        array: &'static str,
        /// First mode.
        i: u32,
        /// Second mode.
        j: u32,
        /// Their dot product.
        dot: f32,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {index}, but there are only {landmarks} landmarks")]
    InvalidTriangleIndex {
        /// Triangle number.
        triangle: u32,
        /// The bad vertex index.
        index: u32,
        /// Number of landmarks.
        landmarks: u32,
    },
    /// The stored mesh and grid do not make a valid reference frame.
    #[error("bad reference frame: {0}")]
    BadFrame(String),
    /// The frame rebuilt from the mesh has a different pixel count than the header states.
    #[error("header states {header} frame pixels, the mesh yields {recomputed}")]
    PixelCountMismatch {
        /// The header's pixel count.
        header: u32,
        /// The count recomputed from the mesh.
        recomputed: u64,
    },
    /// The frame rebuilt from the mesh has a different fingerprint than the stored one.
    #[error("frame fingerprint mismatch: stored {stored:016x}, recomputed {recomputed:016x}")]
    FingerprintMismatch {
        /// Fingerprint in the file.
        stored: u64,
        /// Fingerprint of the rebuilt frame.
        recomputed: u64,
    },
}

/// Shorthand for `Result<T, facemimic::Error>`.
pub type Result<T> = std::result::Result<T, Error>;

/// Fails with [`Error::Params`] unless every value is finite.
pub(crate) fn check_finite(what: &str, values: &[f32]) -> Result<()> {
    // A branch-free pass over the exponent bits (vectorises; this runs on every rendered
    // face), then the position only when something is wrong.
    const EXP: u32 = 0x7f80_0000;
    let bad = values
        .iter()
        .fold(0u32, |acc, v| acc | u32::from(v.to_bits() & EXP == EXP));
    if bad == 0 {
        return Ok(());
    }
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::Params(format!(
            "{what}[{i}] is not finite ({})",
            values[i]
        ))),
    }
}

/// Fails with [`Error::Params`] unless `values.len() == expected`.
pub(crate) fn check_len(what: &str, values: &[f32], expected: usize) -> Result<()> {
    if values.len() == expected {
        Ok(())
    } else {
        Err(Error::Params(format!(
            "{what} has {} values, the model expects {expected}",
            values.len()
        )))
    }
}

//! The one error type of the library.

use crate::format::FormatError;

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
    /// Prefixes the message with where it happened (a file name), keeping the variant for
    /// [`Error::Format`] by turning it into a context-carrying [`Error::File`].
    pub fn with_context(self, context: &str) -> Error {
        Error::File {
            file: context.to_string(),
            source: Box::new(self),
        }
    }
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

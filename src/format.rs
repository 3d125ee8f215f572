//! The `.fmm` model file (being written: see docs/model-format.md once it lands).

use crate::model::Model;

/// Errors reading a model file.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FormatError {
    /// Not a facemimic model.
    #[error("not a facemimic model (bad magic)")]
    BadMagic,
}

/// Serialises a model.
pub fn write_model(_model: &Model) -> Vec<u8> {
    Vec::new()
}

/// Parses and validates a model.
pub fn read_model(_bytes: &[u8]) -> Result<Model, FormatError> {
    Err(FormatError::BadMagic)
}

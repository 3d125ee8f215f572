//! The `.fmm` model file (placeholder until the format lands).

/// Errors reading a model file.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// Not a facemimic model.
    #[error("not a facemimic model (bad magic)")]
    BadMagic,
}

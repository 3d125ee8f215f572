//! The `.fmm` model file: a versioned, little-endian binary format (specified in
//! `docs/model-format.md`).
//!
//! [`write_model`] serialises a [`Model`](crate::Model); [`read_model`] parses and validates one. Reading
//! never panics, checks every header value against the explicit [`LIMITS`], compares the byte
//! length the header implies (computed with checked arithmetic) with the actual length before
//! allocating any array, verifies a CRC-32 of the whole file, and finally rebuilds the
//! reference frame from the stored mesh and checks that it yields the stored pixel count and
//! fingerprint. Every failure is a [`FormatError`] variant naming the problem.
//!
//! - `layout.rs`: magic, versions, tags and the header's byte offsets ([`offsets`]);
//! - `writer.rs`: [`write_model`] and its variants;
//! - `reader.rs`: [`read_model`], the validating reader;
//! - `codec.rs`: the appearance storage ([`Storage`]) and its bit packing.

pub use crate::error::FormatError;
pub use crate::model::bounds::{Limits, LIMITS};

mod codec;
mod layout;
mod reader;
mod writer;

pub use codec::Storage;
use codec::*;
use layout::*;
pub use layout::{
    crc32, offsets, CHECKSUM_LEN, FORMAT_VERSION, HEADER_LEN, MAGIC, MAX_SECTIONS, OLDEST_VERSION,
    REFERENCE_MEAN, REFERENCE_TRAINING, SCHEME_GENERIC, SCHEME_IBUG68, SECTION_BACKDROP,
};
use reader::*;
pub use reader::{read_model, read_model_info, read_summary, FileInfo, ModelSummary};
pub use writer::{write_model, write_model_as, write_model_checked, write_model_checked_as};

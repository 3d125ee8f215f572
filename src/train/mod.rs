//! Training models: from landmarked images (or frames the face finder landmarks) to a
//! [`crate::Model`].
//!
//! - `builder.rs`: [`Builder`], the paper's model building (Procrustes, PCA of shape and of
//!   shape-normalised appearance, the reference frame), stage by stage.
//! - `canonical.rs`: the canonical reference frame every model is built in by default.
//! - `select.rs`: choosing varied training frames; `refine.rs`: refining landmarks by fitting.
//! - `enrol.rs`: the face finder's landmarks for enrolment ([`crate::EnrolFinder`]).
//! - `pipeline.rs`: the enrolment pipeline ([`crate::enrol`]: find, select, build, refine,
//!   backdrop) that the CLI and the wasm layer both call.
//! - `quality.rs`: which enrolment frames are good enough ([`crate::FrameQuality`]:
//!   occluded, blurred, dark, turned, outside the picture).
//! - `expression.rs`: which expressions the kept frames cover ([`crate::expression_coverage`]),
//!   and which of them is most at rest ([`crate::most_at_rest`], a person's reference face).
//! - `photo.rs`: a target from a single photo.

pub(crate) mod builder;
pub mod canonical;
pub(crate) mod consistency;
pub(crate) mod enrol;
pub(crate) mod expression;
pub(crate) mod photo;
pub(crate) mod pipeline;
pub(crate) mod quality;
pub(crate) mod refine;
pub(crate) mod select;

pub use builder::{
    BuildOptions, BuildProgress, Builder, FrameChoice, ReferenceChoice, TrainingImage,
};

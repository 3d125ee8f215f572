//! # facemimic
//!
//! Real-time facial expression cloning with Active Appearance Models (Theobald, Matthews,
//! Cohn & Boker, "Real-time expression cloning using appearance models", ICMI 2007).
//!
//! This crate is the pure-Rust core (no browser knowledge, no command line): the wasm-bindgen
//! glue (`crates/wasm`, the npm package) and the CLI (`crates/cli`) are thin crates over it. See
//! `ARCHITECTURE.md`.
//!
//! - [`Builder`] builds a person-specific [`Model`] from landmarked images: a Procrustes-aligned
//!   PCA shape model (Eq. 1), a shape-normalised PCA appearance model (Eq. 2) and a triangulated
//!   [`ReferenceFrame`].
//! - [`format`](mod@format) reads and writes the versioned binary model file (`.fmm`).
//! - [`FaceDrawer`] draws a face (an instance warped onto any shape, optionally with its mesh)
//!   into a tiny-skia pixmap with the chosen backend: [`Renderer`] (tiny-skia pattern fills, the
//!   default) or [`Scanline`] ([`Rasterizer::Scanline`], an opt-in faster fixed-point warp);
//!   [`fit_view`] lays a face out in a canvas.
//! - [`Stage`] is the whole pipeline of a front end: a source (parameters, or video through a
//!   [`fit::FaceTracker`]) cloned onto every target and drawn, composited, into
//!   [`Picture`]s it owns, with the compare view and the timings.
//! - [`fit`] tracks a face in video ([`fit::Tracker`]), [`clone`] maps one face's parameters
//!   onto other models ([`clone::Cloner`]), [`find`] finds faces and their landmarks
//!   ([`FaceFinder`]).
//! - [`bounds`] holds the limits every input is checked against and the memory budget;
//!   [`canonical`] the reference frame every model is built in by default; [`numerics`] the
//!   numerical steps (PCA, Procrustes, sampling, synthesis) for tests and research use.
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![warn(missing_debug_implementations)]
// `!(x > y)` is used on purpose: it is true for NaN, which is how bad input is rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over several parallel arrays read better than zipped iterators in the numerics.
#![allow(clippy::needless_range_loop)]

pub mod clone;
mod error;
mod filter;
pub mod find;
pub mod fit;
mod geometry;
mod image;
#[cfg(not(target_arch = "wasm32"))]
pub mod io;
pub mod landmarks;
mod model;
pub mod numerics;
mod pca;
mod render;
mod similarity;
mod stage;
mod summary;
mod train;

pub use error::{Error, FormatError, Result};
pub use find::{Face, FaceFinder, FindOptions};
pub use geometry::BBox;
pub use glam;
pub use image::{Image, ImageRef, MAX_IMAGE_SIDE};
pub use landmarks::MIRROR_68;
pub use model::appearance::AppearanceModel;
pub use model::backdrop::{backdrop_budget, Backdrop, MAX_BACKDROP_BYTES, MAX_BACKDROP_SIDE};
pub use model::frame::{FramePixel, ReferenceFrame, MAX_FRAME_SIDE};
pub use model::linear::LinearModel;
pub use model::shape::ShapeModel;
pub use model::warp::sample_rgb;
pub use model::{bounds, format};
pub use model::{LandmarkScheme, Model, ModelParts, Params, Reference};
pub use render::{
    base_box, canvas_view, demultiply, demultiply_into, fit_view, picture_view, straight_rgba,
    Compositor, DrawOptions, FaceDrawer, Rasterizer, Renderer, Scanline,
};
pub use similarity::{PoseJson, Similarity};
pub use stage::{
    check_picture_size, default_clock, Clock, CompareView, Framing, Picture, PictureOptions, Stage,
    Timings, DEFAULT_BACKGROUND, MAX_PICTURE_PIXELS,
};
pub use tiny_skia;
pub use train::canonical;
pub use train::canonical::{canonical_frame, CANONICAL_FINGERPRINT};
pub use train::consistency::{identity_split, same_picture};
pub use train::enrol::{EnrolFace, EnrolFinder};
pub use train::expression::{expression_coverage, most_at_rest, ExpressionCoverage};
pub use train::photo::{
    closest_to_mean, photo_model, with_default_backdrop, MIN_PHOTO_FACE, PHOTO_FIT_PASSES,
    PHOTO_MAX_SIDE,
};
pub use train::pipeline::{
    enrol, EnrolFrame, EnrolOptions, EnrolProgress, EnrolSampling, EnrolStage, Enrolment,
    QualityScope, DEFAULT_MIN_SCORE, ENROL_BOXES, MAX_REFINE_ROUNDS,
};
pub use train::quality::{occlusion_scores, FrameProblem, FrameQuality};
pub use train::refine::refine_landmarks;
pub use train::select::{coverage, select_varied};
pub use train::{
    BuildOptions, BuildProgress, Builder, FrameChoice, ReferenceChoice, TrainingImage,
};

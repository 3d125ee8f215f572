//! The numerical steps the model is made of, for tests, benchmarks and research use: the
//! builder, the projection and the renderer are built from them, and most users need only the
//! types at the crate root.
//!
//! - [`pca`] (principal components about a centre, snapshot or covariance method) and
//!   [`generalised_procrustes`] (shape alignment with a rotation-invariant gauge) build the
//!   shape model (Eq. 1) and the appearance model (Eq. 2);
//! - [`triangulate`] meshes a base shape (Delaunay);
//! - [`sample_rgb`] samples an image at its landmarks into a reference frame;
//! - [`synthesise`] computes an appearance instance `A0 + sum lambda_i A_i` (Eq. 2);
//! - [`hull_loop`] and [`mean_value_weights`] are the compositor's border and its mean-value
//!   interpolation of the offsets along it.

pub use crate::model::appearance::synthesise;
pub use crate::model::frame::triangulate;
pub use crate::model::shape::generalised_procrustes;
pub use crate::model::warp::sample_rgb;
pub use crate::pca::{pca, Pca};
pub use crate::render::{hull_loop, mean_value_weights};

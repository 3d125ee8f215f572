//! The stage's clock and its timings per frame.

/// A monotonic clock in milliseconds. The stage reads it around each stage of a frame; the
/// default ([`default_clock`]) is `std::time::Instant` natively and a clock that stands still
/// on wasm32 (where `Instant` is missing), so a wasm shell gives its own
/// (`performance.now()`).
pub type Clock = fn() -> f64;

/// Milliseconds per stage of a frame, accumulated since the last [`super::Stage::update`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Timings {
    /// Mapping and target synthesis ([`super::Stage::update`]), plus the compare views'
    /// cloning.
    pub map: f64,
    /// Source synthesis, texture uploads and compositor set-up.
    pub synth: f64,
    /// Clearing and warping into the pictures.
    pub raster: f64,
    /// Copying the pictures out (added by the shell that blits them,
    /// [`super::Stage::add_blit_ms`]).
    pub blit: f64,
}

#[cfg(not(target_arch = "wasm32"))]
/// The default clock: milliseconds since the first call, from `std::time::Instant`.
pub fn default_clock() -> f64 {
    use std::sync::OnceLock;
    use std::time::Instant;
    static START: OnceLock<Instant> = OnceLock::new();
    START.get_or_init(Instant::now).elapsed().as_secs_f64() * 1e3
}

#[cfg(target_arch = "wasm32")]
/// The default clock on wasm32: always 0 (`std::time::Instant` panics there); the shell gives
/// its own with [`super::Stage::set_clock`].
pub fn default_clock() -> f64 {
    0.0
}

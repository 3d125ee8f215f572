//! Benchmarks (core): being written.
fn main() {}

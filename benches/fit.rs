//! Benchmarks (fit): being written.
fn main() {}

//! Benchmarks (clone): being written.
fn main() {}

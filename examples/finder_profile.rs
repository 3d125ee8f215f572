//! The face finder's nets (MediaPipe's) timed on a fixed input: the fastest and the median run
//! over REPS runs (default 20; the finder's fused runs), and each layer kind's time (the sum of
//! its layers' fastest times over REPS runs layer by layer, nothing fused: their sum is more
//! than a fused run). A profile, not a check:
//! `cargo run --release --example finder_profile -- [REPS]`.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    let reps = std::env::args().nth(1).map_or(20, |s| s.parse().unwrap());
    for net in facemimic::find::profile_mesh_nets(reps).unwrap() {
        eprintln!(
            "net {}: {:.2} ms a run (fastest), {:.2} ms (median)",
            net.side,
            net.run * 1e3,
            net.median * 1e3
        );
        let total: f64 = net.layers.iter().map(|(_, t)| t).sum();
        for (kind, t) in net.layers {
            eprintln!("  {kind}: {:.3} ms", t * 1e3);
        }
        eprintln!(
            "  (sum of the layers' fastest, unfused: {:.2} ms)",
            total * 1e3
        );
    }
}

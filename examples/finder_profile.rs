//! MediaPipe's nets (`MeshFinder`) timed layer by layer on a fixed input: the mean time of a
//! run and of each layer kind over REPS runs (default 20). A profile, not a check:
//! `cargo run --release --features mesh-finder --example finder_profile -- [REPS]`.
#![cfg_attr(target_arch = "wasm32", no_main)]

#[cfg(not(target_arch = "wasm32"))]
fn main() {
    let reps = std::env::args().nth(1).map_or(20, |s| s.parse().unwrap());
    for net in facemimic::find::profile_mesh_nets(reps).unwrap() {
        eprintln!("net {}: {:.2} ms a run", net.side, net.run * 1e3);
        for (kind, t) in net.layers {
            eprintln!("  {kind}: {:.3} ms", t * 1e3);
        }
    }
}

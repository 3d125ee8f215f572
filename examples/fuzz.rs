//! The fuzz harness, long runs: `cargo run --release --example fuzz -- [EXECS] [SEED]`.
//!
//! Mutates models, landmark files and parameter JSON (see `crates/testkit/src/fuzz.rs`), checks that
//! nothing panics, every `Ok` output is finite and every model load stays within its memory
//! budget (counting global allocator), prints executions per second, saves each input whose
//! outcome class is new into `fuzz/corpus/` (replayed by `tests/integration/fuzz.rs`), and exits non-zero
//! on the first failure (saved as `fuzz/failures/<target>-<n>`).

use facemimic_testkit::fuzz as engine;

use std::time::Instant;

#[global_allocator]
static ALLOC: engine::CountingAlloc = engine::CountingAlloc;

fn main() {
    let mut args = std::env::args().skip(1);
    let execs: u64 = args
        .next()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    std::panic::set_hook(Box::new(|_| {}));
    let mut f = engine::Fuzzer::new(seed);
    let start = Instant::now();
    let mut last = Instant::now();
    let mut saved = 0;
    for i in 0..execs {
        match f.step() {
            // The first 300 inputs of a new outcome class form the corpus (kept small).
            Ok(Some((class, input))) if saved < 300 => {
                let target = class.split(':').next().unwrap_or("x").to_string();
                let dir = root.join("corpus");
                let _ = std::fs::create_dir_all(&dir);
                let name = format!("{target}-{seed}-{i}");
                if std::fs::write(dir.join(&name), &input).is_ok() {
                    saved += 1;
                }
                eprintln!("new: {name}: {class}");
            }
            Ok(_) => {}
            Err(fail) => {
                let dir = root.join("failures");
                let _ = std::fs::create_dir_all(&dir);
                let name = format!("{}-{seed}-{i}", fail.target);
                let _ = std::fs::write(dir.join(&name), &fail.input);
                eprintln!(
                    "FAILURE after {} executions: {}: {} (input saved as fuzz/failures/{name})",
                    i + 1,
                    fail.target,
                    fail.what
                );
                std::process::exit(1);
            }
        }
        if last.elapsed().as_secs() >= 10 {
            last = Instant::now();
            let s = start.elapsed().as_secs_f64();
            eprintln!(
                "{} execs, {:.0} execs/s, {} models accepted, {} classes, worst load {:.3} of budget",
                f.stats.execs,
                f.stats.execs as f64 / s,
                f.stats.accepted_models,
                f.stats.classes.len(),
                f.stats.worst_load_ratio
            );
        }
    }
    let s = start.elapsed().as_secs_f64();
    println!(
        "fuzz: {} executions in {:.1} s ({:.0} execs/s), seed {seed}: no panic, no non-finite output, \
         no allocation over budget; {} mutated models accepted, {} outcome classes, {saved} new corpus \
         inputs, worst model load {:.3} of its budget",
        f.stats.execs,
        s,
        f.stats.execs as f64 / s,
        f.stats.accepted_models,
        f.stats.classes.len(),
        f.stats.worst_load_ratio
    );
}

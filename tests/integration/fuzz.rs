//! The fuzz harness's short deterministic run (a few seconds) and the replay of its corpus
//! (`fuzz/corpus/`): no panic, no non-finite output, no model load over its memory budget.
//! Long runs: `cargo run --release --example fuzz -- 10000000` (see the README).

use facemimic_testkit::fuzz as engine;

use crate::counting;

#[test]
fn fuzz_short_deterministic_run() {
    // The engine's memory budgets are measured by its counting allocator, which the binary's
    // allocator serves for this thread only (the other tests run beside it).
    counting::with_engine_counting(run);
}

fn run() {
    // The engine catches panics (and reports them as failures): silent on this thread only.
    let quiet = counting::QuietPanics::on_this_thread();
    let mut f = engine::Fuzzer::new(0x5eed);
    // Replay the committed corpus first.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus");
    let mut replayed = 0;
    if let Ok(entries) = std::fs::read_dir(&dir) {
        let mut names: Vec<_> = entries.flatten().map(|e| e.path()).collect();
        names.sort();
        for path in names {
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let Some(target) = engine::target_of(&name) else {
                continue;
            };
            let input = std::fs::read(&path).unwrap();
            if let Err(fail) = f.run(target, &input, true) {
                drop(quiet);
                panic!("corpus input {name}: {}", fail.what);
            }
            replayed += 1;
        }
    }
    let start = std::time::Instant::now();
    let mut failure = None;
    for _ in 0..20_000 {
        if let Err(fail) = f.step() {
            failure = Some(fail);
            break;
        }
    }
    drop(quiet);
    if let Some(fail) = failure {
        let path = std::env::temp_dir().join(format!("facemimic-fuzz-failure-{}", fail.target));
        let _ = std::fs::write(&path, &fail.input);
        panic!(
            "{}: {} (input of {} bytes saved to {})",
            fail.target,
            fail.what,
            fail.input.len(),
            path.display()
        );
    }
    eprintln!(
        "fuzz: {replayed} corpus inputs replayed, {} executions in {:.2} s, {} models accepted, {} classes",
        f.stats.execs,
        start.elapsed().as_secs_f64(),
        f.stats.accepted_models,
        f.stats.classes.len()
    );
    assert!(
        f.stats.accepted_models > 0,
        "the mutations never produced a loadable model"
    );
    assert!(
        f.stats.classes.len() > 20,
        "too few outcome classes: {:?}",
        f.stats.classes
    );
}

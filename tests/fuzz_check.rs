//! Fuzz target of the case parser and `sinterdem check` (issue 16): a proptest property over case
//! files mutated from a seed corpus — the bundled `cases/*.toml`, `cases/titanium/*.toml` and the
//! issue's reproducers in `tests/fuzz-corpus/` — asserting that parse + check never panics
//! (each execution runs under `catch_unwind`; a panic fails the property with the mutated case).
//!
//! Bounded for CI: `SINTERDEM_FUZZ_CASES` executions (default 150000, about 60 s in release on 2 cores) and at most
//! `SINTERDEM_FUZZ_SECONDS` seconds (default 60); the executions done, the corpus size and the
//! rate are printed (`--nocapture`) and written to `target/fuzz-check-stats.json`.
//! `SINTERDEM_FUZZ_SEED` picks the random stream (default fixed, so CI is reproducible).
//!
//! The mutations (1–4 per execution, byte-level edits of the TOML text for one in eight) are those of
//! `tests/common/mutate.rs`, shared with the run-path fuzzer `tests/fuzz_run.rs`.

use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

#[path = "common/mutate.rs"]
mod mutate;
use mutate::*;

#[test]
fn check_never_panics_on_mutated_cases() {
    // the memory check refuses scenes above ~12 000 heat particles, so that an execution stays
    // fast (the check path is the same; only the threshold is lower than the machine's memory)
    // SAFETY: the only test of this binary, before any thread is started.
    unsafe { std::env::set_var("SINTERDEM_MEMORY_AVAILABLE", "5e7") };
    let cases = env_num("SINTERDEM_FUZZ_CASES", 150000.0) as u32;
    let budget = env_num("SINTERDEM_FUZZ_SECONDS", 60.0);
    let seed = env_num("SINTERDEM_FUZZ_SEED", 16.0) as u64;
    let (seeds, strings) = corpus(&["cases", "cases/titanium", "tests/fuzz-corpus"]);
    let keys = set_keys();
    let executed = AtomicU64::new(0);
    let accepted = AtomicU64::new(0);
    let start = Instant::now();
    let config = Config { cases, failure_persistence: None, max_shrink_iters: 200, ..Config::default() };
    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &bytes));
    let result = runner.run(&input(), |inp| {
        if start.elapsed().as_secs_f64() > budget {
            return Ok(());
        }
        let s = &seeds[inp.seed % seeds.len()];
        let value = mutate(s, &inp, &strings, &keys);
        let dir = s.dir.clone();
        let outcome = std::panic::catch_unwind(|| {
            let value = if inp.raw.is_empty() { Ok(value.clone()) } else { apply_raw(&value, &inp) };
            match value {
                Ok(v) => sinterdem::calibrate::check_file(&v, &[], &dir).is_ok(),
                Err(_) => false,
            }
        });
        executed.fetch_add(1, Ordering::Relaxed);
        match outcome {
            Ok(ok) => {
                accepted.fetch_add(ok as u64, Ordering::Relaxed);
                Ok(())
            }
            Err(p) => {
                let msg = p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default();
                Err(TestCaseError::fail(format!("check panicked ({msg}) on seed {} mutated to:\n{}", s.name, toml::to_string(&value).unwrap_or_default())))
            }
        }
    });
    let secs = start.elapsed().as_secs_f64();
    let n = executed.load(Ordering::Relaxed);
    let stats = serde_json::json!({
        "executions": n,
        "accepted": accepted.load(Ordering::Relaxed),
        "corpus_files": seeds.len(),
        "seconds": secs,
        "executions_per_second": n as f64 / secs,
        "seed": seed,
    });
    eprintln!("fuzz check: {stats}");
    let _ = std::fs::write(Path::new(env!("CARGO_MANIFEST_DIR")).join("target/fuzz-check-stats.json"), stats.to_string());
    if let Err(e) = result {
        panic!("{e}");
    }
}

//! Fuzz target of the run path (issue 26): case, study and calibration files mutated from the
//! bundled seeds (`cases/*.toml`, `cases/titanium/E14B.toml`, `cases/calibration/*.toml`,
//! `cases/studies/*.toml`, `cases/conductivity/`, `cases/packing/`) by the mutator of
//! `tests/fuzz_check.rs` (`tests/common/mutate.rs`), each run by a child `sinterdem run`,
//! `sinterdem study` or `sinterdem calibrate` under a wall-time guard. Asserted for every execution:
//! - no panic (exit code 101, or "panicked at" on stderr) and no death by a signal (abort);
//! - no hang: the child gets SIGTERM after `SINTERDEM_FUZZ_SOFT` seconds (default 2; a heat or
//!   compact run or a study then ends after its current step with its outputs written, exit 143)
//!   and must have exited `SINTERDEM_FUZZ_GRACE` seconds later (default 20), else it is killed and
//!   counted as a hang. `generate`, `explicit_sinter` and `calibrate` do not stop on SIGTERM: a
//!   time-out of theirs is counted as `slow` (a mutation that asks for much work, e.g. 7 446 swarm
//!   particles), its case kept for inspection, and does not fail the test;
//! - no NaN, inf or null in the outputs of a run that exits 0 or 143: every `*.json` under its
//!   output directory holds no `null` number field (see [`NULL_OK`]) and every `*.csv` no field that
//!   parses as a non-finite number.
//!
//! The step budget: seeds are made small before they are mutated ([`small`]: short end times,
//! few optimiser iterations, a smaller memory limit through `SINTERDEM_MEMORY_AVAILABLE=5e7`,
//! as in the `check` fuzzer), and the SIGTERM stops what is still long.
//!
//! CI runs `SINTERDEM_FUZZ_RUNS` executions (default 40) within `SINTERDEM_FUZZ_SECONDS` seconds
//! (default 40); `SINTERDEM_FUZZ_SEED` picks the random stream (fixed default, so CI is
//! reproducible). The counts are printed (`--nocapture`) and written to
//! `target/fuzz-run-stats.json`; the case of every failure is kept under the temp directory
//! (`sinterdem-fuzz_run-failures-*`) and named in the assertion.

mod common;
#[path = "common/mutate.rs"]
mod mutate;

use mutate::*;
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// JSON fields that are `null` by design (not a number that became non-finite): texts and
/// optional settings of a summary, a study record or a calibration report (`series`: the file
/// of an experiment's time series, none without one).
const NULL_OK: &[&str] = &[
    "stop_reason",
    "error",
    "warning",
    "warnings",
    "message",
    "note",
    "reason",
    "failure",
    "failed_at",
    "checkpoint",
    "resumed_from",
    "started",
    "slurm",
    "job_id",
    "parent",
    "series",
];

#[derive(Clone, Copy, PartialEq, Debug)]
enum Cmd {
    Run,
    Study,
    Calibrate,
}

fn command_of(seed: &Seed) -> Cmd {
    if seed.name.starts_with("cases/studies/") {
        Cmd::Study
    } else if seed.value.get("data").is_some() && seed.value.get("parameters").is_some() {
        Cmd::Calibrate
    } else {
        Cmd::Run
    }
}

fn set(v: &mut toml::Value, kv: &str) {
    let _ = sinterdem::config::apply_override(v, kv);
}

/// The seed made small (the fuzz step budget): short end times and few calibration iterations,
/// each only where the seed has the key.
fn small(seed: &mut Seed) {
    let cmd = command_of(seed);
    let copper = seed.name.contains("copper");
    let v = &mut seed.value;
    let has = |v: &toml::Value, path: &[&str]| {
        let mut cur = v;
        for k in path {
            match cur.get(k) {
                Some(x) => cur = x,
                None => return false,
            }
        }
        true
    };
    match cmd {
        Cmd::Calibrate => {
            for kv in ["optimiser.swarm_size=2", "optimiser.swarm_iterations=1", "optimiser.local_iterations=1"] {
                set(v, kv);
            }
            if let Some(t) = v.as_table_mut() {
                t.remove("compact");
            }
        }
        Cmd::Study => {
            // a shorter compact base (the pair and explicit bases are fast)
            if let Some(o) = v.get_mut("overrides").and_then(|o| o.as_array_mut())
                && copper
            {
                o.push(toml::Value::String("time.end=20".into()));
                set(v, "collect.series.0.times=[5.0, 20.0]");
            }
        }
        Cmd::Run if v.get("kind").and_then(|k| k.as_str()) == Some("explicit_sinter") => {
            // fewer particles, a tenth of every protocol phase, a tenth of the strain
            if has(v, &["sample", "particles"]) {
                set(v, "sample.particles=40");
            }
            if let Some(p) = v.get_mut("protocol").and_then(|p| p.as_table_mut()) {
                for (k, x) in p.iter_mut() {
                    if k.starts_with("t_") || k == "t0_sinter" {
                        match x {
                            toml::Value::Float(f) => *f *= 0.1,
                            toml::Value::Array(a) => a.iter_mut().for_each(|y| {
                                if let toml::Value::Float(f) = y {
                                    *f *= 0.1
                                }
                            }),
                            _ => {}
                        }
                    }
                }
            }
            if has(v, &["compression", "max_strain"]) {
                set(v, "compression.max_strain=0.005");
            }
        }
        Cmd::Run if v.get("kind").and_then(|k| k.as_str()) == Some("generate") => {
            if let Some(n) = v.get("packing").and_then(|p| p.get("particles")).and_then(|n| n.as_integer()) {
                set(v, &format!("packing.particles={}", n.min(200)));
            }
        }
        Cmd::Run => {
            if has(v, &["time", "end"]) && v.get("kind").and_then(|k| k.as_str()) != Some("pair") {
                let end = v["time"]["end"].as_float().unwrap_or(1.0);
                set(v, &format!("time.end={:e}", end.min(60.0)));
            }
            for (path, kv) in [(&["output", "snapshots"][..], "output.snapshots=1"), (&["output", "vtu"][..], "output.vtu=false")] {
                if has(v, path) {
                    set(v, kv);
                }
            }
        }
    }
}

/// A mirror of `cases/` under `root` (directories of symbolic links to the bundled files), so
/// that a mutated case written into its seed's directory there finds the files it names.
fn mirror(cases: &Path, root: &Path) {
    std::fs::create_dir_all(root).unwrap();
    for e in std::fs::read_dir(cases).unwrap().flatten() {
        let to = root.join(e.file_name());
        if e.path().is_dir() {
            mirror(&e.path(), &to);
        } else {
            std::os::unix::fs::symlink(e.path(), &to).unwrap();
        }
    }
}

/// Where `v` holds a non-finite number: `null` numbers in JSON (serde writes NaN and inf as
/// `null`) outside [`NULL_OK`]; returns the path of the first.
fn json_bad(v: &serde_json::Value, path: &str) -> Option<String> {
    match v {
        serde_json::Value::Null => Some(path.to_string()),
        serde_json::Value::Object(m) => m.iter().filter(|(k, _)| !NULL_OK.contains(&k.as_str())).find_map(|(k, x)| json_bad(x, &format!("{path}.{k}"))),
        serde_json::Value::Array(a) => a.iter().enumerate().find_map(|(i, x)| json_bad(x, &format!("{path}[{i}]"))),
        _ => None,
    }
}

/// `study.json` without the collected outputs of its runs.
fn strip_outputs(mut v: serde_json::Value) -> serde_json::Value {
    if let Some(runs) = v.get_mut("runs").and_then(|r| r.as_array_mut()) {
        for r in runs {
            if let Some(m) = r.as_object_mut() {
                m.remove("outputs");
                // a run without a record (an interrupted study: exit 143) has no wall time
                if m.get("status").and_then(|s| s.as_str()) == Some("missing") {
                    m.remove("wall_seconds");
                }
            }
        }
    }
    v
}

/// The first non-finite value in the outputs under `dir`: a file and what is wrong there.
fn bad_output(dir: &Path) -> Option<String> {
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            let ext = p.extension().and_then(|x| x.to_str()).unwrap_or("");
            if ext == "json" {
                let text = std::fs::read_to_string(&p).unwrap_or_default();
                match serde_json::from_str::<serde_json::Value>(&text) {
                    Ok(v) => {
                        // study.json: a collected value the run does not have is an empty cell by
                        // design (docs/studies.md, "Collect"); the runs' own files are checked
                        let v = if p.file_name().is_some_and(|n| n == "study.json") { strip_outputs(v) } else { v };
                        // a study's record of a failed run has no summary (status and error say why)
                        let v = if p.file_name().is_some_and(|n| n == "result.json") && v.get("status").and_then(|s| s.as_str()) != Some("ok") {
                            let mut v = v;
                            v.as_object_mut().map(|m| m.remove("summary"));
                            v
                        } else {
                            v
                        };
                        if let Some(at) = json_bad(&v, "") {
                            return Some(format!("{}: null at {at}", p.display()));
                        }
                    }
                    Err(e) => return Some(format!("{}: not JSON ({e})", p.display())),
                }
            } else if ext == "csv" {
                let text = std::fs::read_to_string(&p).unwrap_or_default();
                for (i, line) in text.lines().enumerate() {
                    if line.starts_with('#') {
                        continue;
                    }
                    if let Some(f) = line.split(',').find(|f| f.trim().parse::<f64>().is_ok_and(|x| !x.is_finite())) {
                        return Some(format!("{}:{}: {f}", p.display(), i + 1));
                    }
                }
            }
        }
    }
    None
}

#[derive(Default, Debug, serde::Serialize)]
struct Counts {
    executions: u64,
    exit_0: u64,
    interrupted: u64,
    refused: u64,
    panics: u64,
    signals: u64,
    hangs: u64,
    slow: u64,
    non_finite: u64,
    by_command: [u64; 3],
}

fn env_num(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

#[test]
fn runs_of_mutated_cases_never_panic_hang_or_write_non_finite_values() {
    let runs = env_num("SINTERDEM_FUZZ_RUNS", 40.0) as u64;
    let budget = env_num("SINTERDEM_FUZZ_SECONDS", 40.0);
    let soft = env_num("SINTERDEM_FUZZ_SOFT", 2.0);
    let grace = env_num("SINTERDEM_FUZZ_GRACE", 20.0);
    let rng_seed = env_num("SINTERDEM_FUZZ_SEED", 26.0) as u64;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (mut seeds, strings) = corpus(&["cases", "cases/calibration", "cases/studies", "cases/conductivity", "cases/packing"]);
    // one pair experiment of the 28 titanium ones (the pair kind also comes from pair-copper)
    let (e14b, _) = corpus(&["cases/titanium"]);
    seeds.extend(e14b.into_iter().filter(|s| s.name.ends_with("E14B.toml")));
    // the compact model of a calibration is run by its calibration
    seeds.retain(|s| !s.name.contains("titanium-corner-compact"));
    for s in &mut seeds {
        small(s);
    }
    let keys = set_keys();
    let work = common::tmp_dir("work");
    let mirror_root = work.join("cases");
    mirror(&root.join("cases"), &mirror_root);
    let failures = common::tmp_dir("failures");

    let mut bytes = [0u8; 32];
    bytes[..8].copy_from_slice(&rng_seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(Config::default(), TestRng::from_seed(RngAlgorithm::ChaCha, &bytes));
    let strategy = run_input();
    let mut c = Counts::default();
    let mut problems: Vec<String> = Vec::new();
    let start = Instant::now();
    while c.executions < runs && start.elapsed().as_secs_f64() < budget {
        let inp = strategy.new_tree(&mut runner).unwrap().current();
        let s = &seeds[inp.seed % seeds.len()];
        let value = mutate(s, &inp, &strings, &keys);
        let value = if inp.raw.is_empty() { Ok(value) } else { apply_raw(&value, &inp) };
        let Ok(value) = value else { continue };
        let rel = Path::new(&s.name).parent().unwrap().strip_prefix("cases").unwrap().to_path_buf();
        let case = mirror_root.join(&rel).join(format!("fuzz-{}.toml", c.executions));
        std::fs::write(&case, toml::to_string(&value).unwrap_or_default()).unwrap();
        let out = work.join(format!("out-{}", c.executions));
        let cmd = command_of(s);
        let mut child = Command::new(env!("CARGO_BIN_EXE_sinterdem"));
        match cmd {
            Cmd::Run => child.arg("run").arg(&case).arg("--out").arg(&out),
            Cmd::Study => child.arg("study").arg(&case).arg("--out").arg(&out).arg("--jobs").arg("1"),
            Cmd::Calibrate => child.arg("calibrate").arg(&case).arg("--out").arg(&out),
        };
        let mut child =
            child.arg("--quiet").env("SINTERDEM_MEMORY_AVAILABLE", "5e7").stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
        let mut stderr = child.stderr.take().unwrap();
        let reader = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
            s
        });
        let t0 = Instant::now();
        let (mut termed, mut hung) = (false, false);
        let status = loop {
            if let Some(st) = child.try_wait().unwrap() {
                break st;
            }
            let el = t0.elapsed().as_secs_f64();
            if !termed && el > soft {
                let _ = Command::new("kill").arg("-TERM").arg(child.id().to_string()).status();
                termed = true;
            }
            if el > soft + grace {
                hung = true;
                let _ = child.kill();
                break child.wait().unwrap();
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        let err = reader.join().unwrap_or_default();
        c.executions += 1;
        c.by_command[cmd as usize] += 1;
        let code = status.code();
        let mut problem = None;
        // generate, explicit_sinter and calibrate do not stop on SIGTERM (only heat and compact
        // runs and studies do): their guard time-outs are counted as slow, kept and inspected
        let stops_on_term = match cmd {
            Cmd::Calibrate => false,
            Cmd::Study => true,
            Cmd::Run => !matches!(value.get("kind").and_then(|k| k.as_str()), Some("generate" | "explicit_sinter")),
        };
        if hung && !stops_on_term {
            c.slow += 1;
            let keep = failures.join(format!("slow-{}-{}", c.executions - 1, s.name.replace('/', "_")));
            let _ = std::fs::copy(&case, &keep);
            eprintln!("fuzz run: slow (no SIGTERM stop, killed after {} s): seed {}, case kept in {}", soft + grace, s.name, keep.display());
        } else if hung {
            c.hangs += 1;
            problem = Some(format!("hang: still running {grace} s after SIGTERM"));
        } else if code == Some(101) || err.contains("panicked at") {
            c.panics += 1;
            problem = Some(format!("panic: {}", err.lines().find(|l| l.contains("panicked")).unwrap_or(&err)));
        } else if code.is_none() && !termed {
            c.signals += 1;
            problem = Some(format!("killed by a signal: {status:?}; {err}"));
        } else if code == Some(0) || code == Some(143) {
            if code == Some(0) {
                c.exit_0 += 1;
            } else {
                c.interrupted += 1;
            }
            if let Some(b) = bad_output(&out) {
                c.non_finite += 1;
                problem = Some(format!("non-finite output: {b}"));
            }
        } else {
            c.refused += 1;
            if std::env::var_os("SINTERDEM_FUZZ_VERBOSE").is_some() {
                eprintln!("refused ({}): {}", s.name, err.lines().last().unwrap_or(""));
            }
        }
        if let Some(p) = problem {
            let keep = failures.join(format!("{}-{}", c.executions - 1, s.name.replace('/', "_")));
            let _ = std::fs::copy(&case, &keep);
            eprintln!("fuzz run: {p}\n  seed {} ({cmd:?}), case kept in {}", s.name, keep.display());
            problems.push(format!("{p} (seed {}, case {})", s.name, keep.display()));
        }
        let _ = std::fs::remove_file(&case);
        let _ = std::fs::remove_dir_all(&out);
    }
    let secs = start.elapsed().as_secs_f64();
    let stats = serde_json::json!({ "counts": c, "seconds": secs, "seed": rng_seed, "corpus_files": seeds.len() });
    eprintln!("fuzz run: {stats}");
    let _ = std::fs::write(root.join("target/fuzz-run-stats.json"), stats.to_string());
    assert!(c.executions >= runs.min(8), "too few executions in the time budget: {}", c.executions);
    assert!(problems.is_empty(), "{} of {} executions failed:\n{}", problems.len(), c.executions, problems.join("\n"));
}

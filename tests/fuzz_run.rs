//! Fuzz target of the run path (issue 26): case, study and calibration files mutated from the
//! bundled seeds (`cases/*.toml`, `cases/titanium/E14B.toml`, `cases/calibration/*.toml`,
//! `cases/studies/*.toml`, `cases/conductivity/`, `cases/packing/`) by the mutator of
//! `tests/fuzz_check.rs` (`tests/common/mutate.rs`), each run by a child `sinterdem run`,
//! `sinterdem study` or `sinterdem calibrate` — seeds with `[rve]` (the periodic RVE cases) by
//! `sinterdem rve`, the periodic packing of `cases/conductivity/` by `sinterdem conductivity` —
//! under a wall-time guard. Issue 38 added the new surfaces: rve and periodic runs; standard output
//! that fails (`conductivity` into a full device or a closed pipe, and after every execution
//! `sinterdem check` of the same case so); exit 0 with a promised result missing
//! ([`missing_results`]); and damaged checkpoints and rve points files
//! ([`damaged_checkpoints_are_refused_or_resume_to_the_uninterrupted_result`]). The Python API has
//! its own fuzzer (`python/tests/test_fuzz.py`). Asserted for every execution:
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
//! (default 60; an rve run gets `SINTERDEM_FUZZ_RVE_SOFT` seconds, default 15, before its
//! SIGTERM); `SINTERDEM_FUZZ_SEED` picks the random stream (fixed default, so CI is
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
    // optional state of a heat checkpoint: no step control (fixed Δt), no history of equal steps
    "dt_next",
    "hist_dt",
    "factor_sha256",
    "bdf2",
];

#[derive(Clone, Copy, PartialEq, Debug)]
enum Cmd {
    Run,
    Study,
    Calibrate,
    /// `sinterdem rve` of a seed with `[rve]` (the periodic RVE cases).
    Rve,
    /// `sinterdem conductivity` of the `cases/conductivity/` seeds (a periodic packing), its JSON
    /// on standard output.
    Conductivity,
}

fn command_of(seed: &Seed) -> Cmd {
    if seed.name.starts_with("cases/studies/") {
        Cmd::Study
    } else if seed.value.get("data").is_some() && seed.value.get("parameters").is_some() {
        Cmd::Calibrate
    } else if seed.value.get("rve").is_some() {
        Cmd::Rve
    } else if seed.name.starts_with("cases/conductivity/") {
        Cmd::Conductivity
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
        Cmd::Rve => {
            // a free run of 40 s with two branch points (each 7 branches of rve.steps steps)
            for kv in ["time.end=40.0", "rve.at=[20.0, 40.0]", "output.snapshots=0", "output.conductivity_at=[]"] {
                set(v, kv);
            }
        }
        Cmd::Conductivity => {}
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

/// Where a child's standard output goes.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Sink {
    Null,
    /// A pipe read to its end.
    Read,
    /// `/dev/full`: every write fails with ENOSPC.
    Full,
    /// A pipe whose reader is gone before the child writes: EPIPE.
    Closed,
}

impl Sink {
    fn of(n: u64) -> Sink {
        [Sink::Read, Sink::Full, Sink::Closed][(n % 3) as usize]
    }

    fn stdio(self) -> Stdio {
        match self {
            Sink::Null => Stdio::null(),
            Sink::Read | Sink::Closed => Stdio::piped(),
            Sink::Full => std::fs::OpenOptions::new().write(true).open("/dev/full").map(Stdio::from).unwrap_or_else(|_| Stdio::null()),
        }
    }
}

/// Waits for `child`: SIGTERM after `soft` seconds, SIGKILL `grace` seconds later. Returns
/// (status, whether SIGTERM was sent, whether it had to be killed: a hang).
fn guard(child: &mut std::process::Child, soft: f64, grace: f64) -> (std::process::ExitStatus, bool, bool) {
    let t0 = Instant::now();
    let mut termed = false;
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return (st, termed, false);
        }
        let el = t0.elapsed().as_secs_f64();
        if !termed && el > soft {
            let _ = Command::new("kill").arg("-TERM").arg(child.id().to_string()).status();
            termed = true;
        }
        if el > soft + grace {
            let _ = child.kill();
            return (child.wait().unwrap(), termed, true);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn read_json(p: &Path) -> Result<serde_json::Value, String> {
    let text = std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))
}

/// What a run of `cmd` that exited 0 (`ok`) or 143 lacks of what it promises, None when all is
/// there: exit 0 has the command's result files (heat, compact, pair: `summary.json` and
/// `series.csv`; rve: also `constitutive.csv`, `fit.json` and a summary of kind "rve"; study:
/// `study.csv`; calibration: `calibration.json`; conductivity: its JSON read in full, and no exit 0
/// when standard output failed) and a summary that does not say the run failed or was
/// interrupted; exit 143 never has a summary that says `completed = true`.
fn missing_results(cmd: Cmd, value: &toml::Value, out: &Path, ok: bool, sink: Sink, printed: &str) -> Option<String> {
    let kind = value.get("kind").and_then(|k| k.as_str()).unwrap_or("heat");
    let summary = out.join("summary.json");
    if !ok {
        // interrupted: what was written must say so
        return match read_json(&summary) {
            Ok(s) if s.get("completed").and_then(|c| c.as_bool()) == Some(true) => Some("exit 143 but summary.json says completed = true".into()),
            _ => None,
        };
    }
    let need = |files: &[&str]| files.iter().find(|f| !out.join(f).is_file()).map(|f| format!("{f} missing"));
    let summary_ok = || -> Option<String> {
        let s = match read_json(&summary) {
            Ok(s) => s,
            Err(e) => return Some(e),
        };
        if s.get("completed").and_then(|c| c.as_bool()) == Some(false) {
            let why = s.get("stop_reason").and_then(|r| r.as_str()).unwrap_or("");
            if why.is_empty() || why.contains("interrupted") || why.starts_with("error") || s.get("error").is_some_and(|e| !e.is_null()) {
                return Some(format!("exit 0 but summary.json says completed = false ({why})"));
            }
        }
        None
    };
    match cmd {
        Cmd::Run => match kind {
            "heat" | "compact" | "pair" => need(&["summary.json", "series.csv"]).or_else(summary_ok),
            "explicit_sinter" => need(&["summary.json"]).or_else(summary_ok),
            _ => None,
        },
        Cmd::Rve => need(&["summary.json", "series.csv", "constitutive.csv", "fit.json"]).or_else(summary_ok).or_else(|| {
            let s = read_json(&summary).ok()?;
            (s["kind"] != "rve").then(|| format!("the summary's kind is {} (not rve)", s["kind"]))
        }),
        Cmd::Study => need(&["study.csv"]),
        Cmd::Calibrate => need(&["calibration.json"]),
        Cmd::Conductivity => match sink {
            Sink::Full | Sink::Closed => Some(format!("exit 0 although its standard output ({sink:?}) could not be written")),
            Sink::Read => match serde_json::from_str::<serde_json::Value>(printed) {
                Ok(v) => json_bad(&v, "stdout").map(|at| format!("null at {at} in the printed JSON")),
                Err(e) => Some(format!("the printed JSON does not parse ({e}): {}", printed.chars().take(200).collect::<String>())),
            },
            Sink::Null => None,
        },
    }
}

/// The stdout class: `sinterdem check CASE` with its standard output a full device (odd `n`) or
/// a pipe closed before it writes (even `n`). Returns the problem, if any: a panic, a signal, a
/// hang, or exit 0 (the verdict went nowhere: check prints it on standard output).
fn check_into_failing_stdout(case: &Path, n: u64, c: &mut Counts) -> Option<String> {
    let sink = if n % 2 == 1 { Sink::Full } else { Sink::Closed };
    let mut child = Command::new(env!("CARGO_BIN_EXE_sinterdem"))
        .arg("check")
        .arg(case)
        .env("SINTERDEM_MEMORY_AVAILABLE", "5e7")
        .stdin(Stdio::null())
        .stdout(sink.stdio())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
        s
    });
    let (status, _, hung) = guard(&mut child, 30.0, 5.0);
    let err = reader.join().unwrap_or_default();
    c.stdout_checks += 1;
    if hung {
        c.hangs += 1;
        Some(format!("hang: check into {sink:?} standard output"))
    } else if status.code() == Some(101) || err.contains("panicked at") {
        c.panics += 1;
        Some(format!("panic: check into {sink:?} standard output: {}", err.lines().find(|l| l.contains("panicked")).unwrap_or(&err)))
    } else if status.code().is_none() {
        c.signals += 1;
        Some(format!("check into {sink:?} standard output killed by a signal: {status:?}"))
    } else if status.code() == Some(0) {
        c.wrong_exit_0 += 1;
        Some(format!("check exited 0 with its standard output {sink:?} (the verdict was not printed)"))
    } else {
        None
    }
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
    /// Exit 0 (or 143) with a promised result missing, an interrupted summary after exit 0, or
    /// exit 0 of a command whose standard output could not be written.
    wrong_exit_0: u64,
    /// `check` runs into a full device or a closed pipe (the stdout class), and how many failed.
    stdout_checks: u64,
    by_command: [u64; 5],
}

fn env_num(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default)
}

#[test]
fn runs_of_mutated_cases_never_panic_hang_or_write_non_finite_values() {
    let runs = env_num("SINTERDEM_FUZZ_RUNS", 40.0) as u64;
    let budget = env_num("SINTERDEM_FUZZ_SECONDS", 60.0);
    let soft = env_num("SINTERDEM_FUZZ_SOFT", 2.0);
    let grace = env_num("SINTERDEM_FUZZ_GRACE", 20.0);
    let rng_seed = env_num("SINTERDEM_FUZZ_SEED", 26.0) as u64;
    // an rve run (free run and 7 branches per point) gets longer before its SIGTERM
    let rve_soft = env_num("SINTERDEM_FUZZ_RVE_SOFT", 15.0);
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
            Cmd::Rve => child.arg("rve").arg(&case).arg("--out").arg(&out),
            Cmd::Conductivity => child.arg("conductivity").arg(&case),
        };
        // standard output: `conductivity` prints its JSON there: read it (one in three), or a
        // full device, or a pipe closed by the reader (a failure, never exit 0 nor a panic)
        let sink = if cmd == Cmd::Conductivity { Sink::of(c.executions) } else { Sink::Null };
        let mut child =
            child.arg("--quiet").env("SINTERDEM_MEMORY_AVAILABLE", "5e7").stdin(Stdio::null()).stdout(sink.stdio()).stderr(Stdio::piped()).spawn().unwrap();
        // a closed pipe: its reader is gone at once, before the child can print
        let stdout = match child.stdout.take() {
            Some(mut o) if sink == Sink::Read => Some(std::thread::spawn(move || {
                let mut s = String::new();
                let _ = std::io::Read::read_to_string(&mut o, &mut s);
                s
            })),
            other => {
                drop(other);
                None
            }
        };
        let mut stderr = child.stderr.take().unwrap();
        let reader = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
            s
        });
        let soft = if cmd == Cmd::Rve { rve_soft } else { soft };
        let (status, termed, hung) = guard(&mut child, soft, grace);
        let err = reader.join().unwrap_or_default();
        let printed = stdout.map(|h| h.join().unwrap_or_default()).unwrap_or_default();
        c.executions += 1;
        c.by_command[cmd as usize] += 1;
        let code = status.code();
        let mut problem = None;
        // generate, explicit_sinter and calibrate do not stop on SIGTERM (heat, compact and rve
        // runs and studies do): their guard time-outs are counted as slow, kept and inspected
        let stops_on_term = match cmd {
            Cmd::Calibrate | Cmd::Conductivity => false,
            Cmd::Study | Cmd::Rve => true,
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
            } else if let Some(m) = missing_results(cmd, &value, &out, code == Some(0), sink, &printed) {
                c.wrong_exit_0 += 1;
                problem = Some(format!("exit {code:?} with results missing or wrong: {m}"));
            }
        } else {
            c.refused += 1;
            if std::env::var_os("SINTERDEM_FUZZ_VERBOSE").is_some() {
                eprintln!("refused ({}): {}", s.name, err.lines().last().unwrap_or(""));
            }
        }
        // the stdout class: `check` of the same case into a full device or a closed pipe prints
        // its verdict there; it must fail with an i/o error (exit 5) or refuse the case (exit 1),
        // never exit 0 (a verdict nobody got) and never panic
        if problem.is_none() {
            problem = check_into_failing_stdout(&case, c.executions, &mut c);
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

/// A small deterministic generator (xorshift64*) for the checkpoint mutations.
struct Xs(u64);

impl Xs {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// The numeric leaves of a JSON value (paths as JSON pointers).
fn number_leaves(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Number(_) => out.push(at),
        serde_json::Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| number_leaves(x, format!("{at}/{i}"), out)),
        serde_json::Value::Object(m) => m.iter().for_each(|(k, x)| number_leaves(x, format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")), out)),
        _ => {}
    }
}

/// The arrays of a JSON value with at least one element (JSON pointers).
fn arrays(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Array(a) => {
            if !a.is_empty() {
                out.push(at.clone());
            }
            a.iter().enumerate().for_each(|(i, x)| arrays(x, format!("{at}/{i}"), out));
        }
        serde_json::Value::Object(m) => m.iter().for_each(|(k, x)| arrays(x, format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")), out)),
        _ => {}
    }
}

/// One mutation of a sealed file's text: (new text, whether it is sealed again). Byte-level
/// damage (a byte replaced, a digit changed, the file cut short, a span deleted) is left unsealed;
/// a changed number or a removed/duplicated array element is sealed again
/// ([`sinterdem::io::seal_value`]), so that only the content checks stand in its way.
fn damage(text: &str, rng: &mut Xs) -> (String, bool, String) {
    let mut b = text.as_bytes().to_vec();
    let n = b.len();
    match rng.below(6) {
        0 => {
            let i = rng.below(n);
            b[i] = rng.next() as u8;
            (String::from_utf8_lossy(&b).into_owned(), false, format!("byte {i} replaced"))
        }
        1 => {
            let digits: Vec<usize> = (0..n).filter(|&i| b[i].is_ascii_digit()).collect();
            let i = digits[rng.below(digits.len())];
            b[i] = b'0' + ((b[i] - b'0' + 1 + rng.below(9) as u8) % 10);
            (String::from_utf8_lossy(&b).into_owned(), false, format!("digit at byte {i} changed"))
        }
        2 => {
            let k = rng.below(n);
            (String::from_utf8_lossy(&b[..k]).into_owned(), false, format!("cut to {k} bytes"))
        }
        3 => {
            let i = rng.below(n);
            let k = (i + 1 + rng.below(64)).min(n);
            b.drain(i..k);
            (String::from_utf8_lossy(&b).into_owned(), false, format!("bytes {i}..{k} deleted"))
        }
        4 => {
            let mut v: serde_json::Value = serde_json::from_str(text).unwrap();
            let mut leaves = Vec::new();
            number_leaves(&v, String::new(), &mut leaves);
            let at = leaves[rng.below(leaves.len())].clone();
            let x = v.pointer(&at).and_then(|x| x.as_f64()).unwrap_or(0.0);
            let y = [x * (1.0 + 1e-9), -x, 0.0, x * 1e6, 1e300, x + 1.0][rng.below(6)];
            *v.pointer_mut(&at).unwrap() = serde_json::json!(y);
            (sinterdem::io::seal_value(&v), true, format!("{at} = {x:e} -> {y:e}, sealed again"))
        }
        _ => {
            let mut v: serde_json::Value = serde_json::from_str(text).unwrap();
            let mut arr = Vec::new();
            arrays(&v, String::new(), &mut arr);
            let at = arr[rng.below(arr.len())].clone();
            let a = v.pointer_mut(&at).and_then(|a| a.as_array_mut()).unwrap();
            let i = rng.below(a.len());
            let what = if rng.below(2) == 0 {
                a.remove(i);
                "removed"
            } else {
                let e = a[i].clone();
                a.insert(i, e);
                "duplicated"
            };
            (sinterdem::io::seal_value(&v), true, format!("{at}/{i} {what}, sealed again"))
        }
    }
}

/// Copies the files of `from` into a fresh `to` (one level: run directories without subfolders
/// are all this needs; a subfolder is copied as well).
fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// The corrupted-checkpoint class of the run-path fuzzer (issue 38): a finished periodic compact,
/// heat run and rve run, each made to look killed (its `summary.json` removed), have their sealed
/// resume state (`checkpoint.json`; for rve also `rve_points.json`) damaged at random, then
/// `sinterdem resume`. The untouched state resumes to the uninterrupted result bit for bit; a
/// damaged one that is not sealed again must be refused or resume to exactly that result (exit 0
/// with another result is a wrong exit 0); one sealed again (the content checks stand alone) may
/// resume to another result but never panics, hangs, dies or writes a non-finite value.
/// `SINTERDEM_FUZZ_CK_RUNS` resumes (default 18) within `SINTERDEM_FUZZ_CK_SECONDS` (default 90).
#[test]
fn damaged_checkpoints_are_refused_or_resume_to_the_uninterrupted_result() {
    let runs = env_num("SINTERDEM_FUZZ_CK_RUNS", 18.0) as u64;
    let budget = env_num("SINTERDEM_FUZZ_CK_SECONDS", 90.0);
    let mut rng = Xs(env_num("SINTERDEM_FUZZ_SEED", 26.0) as u64 * 0x9e37_79b9 + 1);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let work = common::tmp_dir("ck");
    let base = |name: &'static str, args: &[&str]| -> (&'static str, Vec<String>) { (name, args.iter().map(|s| s.to_string()).collect()) };
    let bases = [
        base(
            "compact-periodic",
            &[
                "run",
                "cases/periodic-copper-rve.toml",
                "--set",
                "time.end=4.0",
                "--set",
                "output.checkpoint_every=4",
                "--set",
                "output.snapshots=0",
                "--set",
                "output.conductivity_at=[]",
            ],
        ),
        base("heat", &["run", "cases/hot-plate.toml", "--set", "particles.cells=[3, 3, 4]", "--set", "time.end=600", "--set", "output.checkpoint_every=50"]),
        base(
            "rve",
            &[
                "rve",
                "cases/rve-copper.toml",
                "--set",
                "time.end=20.0",
                "--set",
                "rve.at=[10.0, 20.0]",
                "--set",
                "output.snapshots=0",
                "--set",
                "output.conductivity_at=[]",
                "--set",
                "output.checkpoint_every=3",
            ],
        ),
    ];
    let compared = |name: &str| -> &'static [&'static str] { if name == "rve" { &["series.csv", "constitutive.csv", "fit.json"] } else { &["series.csv"] } };
    let mut c = Counts::default();
    let mut problems = Vec::new();
    let start = Instant::now();
    for (name, args) in &bases {
        let full = work.join(format!("{name}-full"));
        let o = Command::new(env!("CARGO_BIN_EXE_sinterdem")).current_dir(root).arg("-q").args(args).arg("--out").arg(&full).output().unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let killed = work.join(format!("{name}-killed"));
        copy_dir(&full, &killed);
        std::fs::remove_file(killed.join("summary.json")).unwrap();
        assert!(killed.join("checkpoint.json").is_file(), "{name}: no checkpoint");
        let same =
            |dir: &Path| compared(name).iter().all(|f| std::fs::read(full.join(f)).ok().is_some_and(|a| std::fs::read(dir.join(f)).ok().as_ref() == Some(&a)));
        // the untouched state resumes to the uninterrupted result
        let w = work.join(format!("{name}-w"));
        copy_dir(&killed, &w);
        let o = Command::new(env!("CARGO_BIN_EXE_sinterdem")).args(["-q", "resume"]).arg(&w).output().unwrap();
        assert!(o.status.success() && same(&w), "{name}: the untouched checkpoint: {}", String::from_utf8_lossy(&o.stderr));
        let files: &[&str] = if *name == "rve" { &["checkpoint.json", "rve_points.json"] } else { &["checkpoint.json"] };
        let per_base = runs.div_ceil(bases.len() as u64);
        for k in 0..per_base {
            if start.elapsed().as_secs_f64() > budget {
                break;
            }
            let file = files[(k as usize) % files.len()];
            let good = std::fs::read_to_string(killed.join(file)).unwrap();
            let (bad, sealed, what) = damage(&good, &mut rng);
            copy_dir(&killed, &w);
            std::fs::write(w.join(file), &bad).unwrap();
            let mut child = Command::new(env!("CARGO_BIN_EXE_sinterdem"))
                .args(["-q", "resume"])
                .arg(&w)
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            let mut stderr = child.stderr.take().unwrap();
            let reader = std::thread::spawn(move || {
                let mut s = String::new();
                let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
                s
            });
            let (status, _, hung) = guard(&mut child, 120.0, 10.0);
            let err = reader.join().unwrap_or_default();
            c.executions += 1;
            let problem = if hung {
                c.hangs += 1;
                Some("hang".to_string())
            } else if status.code() == Some(101) || err.contains("panicked at") {
                c.panics += 1;
                Some(format!("panic: {}", err.lines().find(|l| l.contains("panicked")).unwrap_or(&err)))
            } else if status.code().is_none() {
                c.signals += 1;
                Some(format!("killed by a signal: {status:?}"))
            } else if status.code() == Some(0) {
                c.exit_0 += 1;
                if !sealed && !same(&w) {
                    c.wrong_exit_0 += 1;
                    Some("exit 0 with a result other than the uninterrupted one".to_string())
                } else if let Some(b) = bad_output(&w) {
                    c.non_finite += 1;
                    Some(format!("non-finite output: {b}"))
                } else {
                    let kind = if *name == "rve" { Cmd::Rve } else { Cmd::Run };
                    missing_results(kind, &toml::Value::Table(Default::default()), &w, true, Sink::Null, "").inspect(|_| c.wrong_exit_0 += 1)
                }
            } else {
                c.refused += 1;
                if std::env::var_os("SINTERDEM_FUZZ_VERBOSE").is_some() {
                    eprintln!("refused ({name}, {file}: {what}): {}", err.lines().last().unwrap_or(""));
                }
                None
            };
            if let Some(p) = problem {
                let keep = work.join(format!("failure-{}", c.executions));
                copy_dir(&w, &keep);
                eprintln!("fuzz checkpoint: {p}\n  {name}, {file}: {what}; kept in {}", keep.display());
                problems.push(format!("{p} ({name}, {file}: {what}; kept in {})", keep.display()));
            }
        }
    }
    let stats = serde_json::json!({ "counts": c, "seconds": start.elapsed().as_secs_f64() });
    eprintln!("fuzz checkpoint: {stats}");
    assert!(c.executions >= runs.min(6), "too few executions in the time budget: {}", c.executions);
    assert!(problems.is_empty(), "{} of {} resumes failed:\n{}", problems.len(), c.executions, problems.join("\n"));
}

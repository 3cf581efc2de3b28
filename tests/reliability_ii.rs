//! Reliability II (issue 26): nothing lost on resume, one writer per output directory, no loop on
//! subnormal times. The fault-injection harness kills a child `sinterdem resume` at seeded random
//! points and asserts that the next resume gives the uninterrupted result bit for bit;
//! `SINTERDEM_FAULT_KILLS=N` sets the number of kills (CI: 16; a long run: thousands).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sinterdem"))
}

/// A two-particle copper compact of 40 046 steps, one row each (series.csv ≈ 40 000 lines, so
/// that a resume spends tens of milliseconds cutting and rewriting it), checkpoints every 2 000
/// steps; runs in under a second.
fn long_series_case(dir: &Path, end: f64) -> PathBuf {
    std::fs::write(dir.join("packing.csv"), "x,y,z,r\n0,0,0,2.5e-5\n0,4.95e-5,0,2.5e-5\n").unwrap();
    let text = common::compact_text(
        &format!("end = {end:?}\ndt = 1.0e-6\ndt_max = 0.05"),
        &[common::COPPER],
        &common::file_particles(Path::new("packing.csv")),
        common::AT_1293_K,
    );
    let text = text.replace("hdf5 = false\n", "hdf5 = false\ncheckpoint_every = 2000\n");
    let case = dir.join("case.toml");
    std::fs::write(&case, text).unwrap();
    case
}

/// summary.json without the fields that measure wall time.
fn summary_without_times(dir: &Path) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let m = v.as_object_mut().unwrap();
    for k in ["wall_seconds", "timing_seconds"] {
        m.remove(k);
    }
    if let Some(p) = m.get_mut("mechanics_profile").and_then(|p| p.as_object_mut()) {
        p.retain(|k, _| !(k.contains("seconds") || k.ends_with("_s")));
    }
    v
}

fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        if e.path().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// xorshift64*: the kill delays, reproducible from the seed.
fn next(seed: &mut u64) -> u64 {
    *seed ^= *seed >> 12;
    *seed ^= *seed << 25;
    *seed ^= *seed >> 27;
    seed.wrapping_mul(0x2545_f491_4f6c_dd1d)
}

#[test]
fn class01_resumes_killed_at_random_points_continue_to_the_uninterrupted_result() {
    let d = common::tmp_dir("fault-resume");
    let case = long_series_case(&d, 2000.0);
    let full = d.join("full");
    let o = bin().arg("run").arg(&case).arg("--out").arg(&full).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let series = std::fs::read_to_string(full.join("series.csv")).unwrap();
    assert!(series.lines().count() > 40_000, "the series must be long enough to take time to rewrite");
    let summary = summary_without_times(&full);

    let kills: usize = std::env::var("SINTERDEM_FAULT_KILLS").ok().and_then(|v| v.parse().ok()).unwrap_or(16);
    let mut seed = 0x5eed_2026_u64;
    let work = d.join("work");
    let (mut killed, mut finished_before_kill) = (0, 0);
    let series_len = series.len() as u64;
    let (mut at_cut, mut cut_seen) = (0, 0);
    for k in 0..kills {
        copy_dir(&full, &work);
        // a run killed before its end has no summary.json (a finished one is not resumed: issue 25)
        std::fs::remove_file(work.join("summary.json")).unwrap();
        // three kinds of kill: (0) at the moment series.csv changes on disk (the cut back to the
        // checkpoint, where an in-place rewrite used to leave a truncated file), (1) after 0–40 ms
        // (start-up and the cut), (2) after 0–400 ms (a whole resume takes about 0.4 s), twice in a
        // row every other time: a kill during the resume of a killed resume
        let mode = k % 3;
        let repeats = if mode == 2 && k % 2 == 0 { 2 } else { 1 };
        for _ in 0..repeats {
            let delay = Duration::from_micros(match mode {
                1 => next(&mut seed) % 40_000,
                _ => next(&mut seed) % 400_000,
            });
            let mut child = bin().arg("resume").arg(&work).arg("--quiet").stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
            let t0 = Instant::now();
            loop {
                if child.try_wait().unwrap().is_some() || t0.elapsed() >= delay {
                    break;
                }
                if mode == 0 {
                    if std::fs::metadata(work.join("series.csv")).is_ok_and(|m| m.len() != series_len) {
                        cut_seen += 1;
                        break;
                    }
                } else {
                    std::thread::sleep(Duration::from_micros(500));
                }
            }
            if child.try_wait().unwrap().is_none() {
                child.kill().unwrap();
                killed += 1;
                at_cut += (mode == 0) as usize;
            } else {
                finished_before_kill += 1;
            }
            let _ = child.wait();
        }
        let o = bin().arg("resume").arg(&work).arg("--quiet").output().unwrap();
        assert!(o.status.success(), "kill {k}: the resume after a killed resume failed: {}", String::from_utf8_lossy(&o.stderr));
        assert!(std::fs::read_to_string(work.join("series.csv")).unwrap() == series, "kill {k}: series.csv differs from the uninterrupted run");
        assert_eq!(summary_without_times(&work), summary, "kill {k}: summary.json differs from the uninterrupted run");
    }
    eprintln!(
        "fault injection: {kills} trials, {killed} kills ({at_cut} by the watcher of series.csv, which saw the cut {cut_seen} times), {finished_before_kill} resumes finished before their kill; every next resume bit-identical"
    );
    assert!(cut_seen > 0, "the watcher never saw the cut of series.csv");
    assert!(killed >= kills / 2, "most trials must really kill a running resume ({killed} of {kills})");
}

#[test]
fn class02_a_new_run_takes_the_directory_and_an_earlier_checkpoint_cannot_be_resumed_into_it() {
    let d = common::tmp_dir("fault-stale");
    let case = long_series_case(&d, 200.0);
    let out = d.join("out");
    let o = bin().arg("run").arg(&case).arg("--out").arg(&out).arg("--quiet").output().unwrap();
    assert!(o.status.success());
    assert!(out.join("checkpoint.json").exists());
    // the second run writes no checkpoints; it needs --force (issue 25: a directory holding
    // another run's outputs is refused without it, and changes nothing)
    let second = |force: bool| {
        let mut c = bin();
        c.arg("run").arg(&case).arg("--out").arg(&out).arg("--quiet").args(["--set", "output.checkpoint_every=0", "--set", "time.end=100"]);
        if force {
            c.arg("--force");
        }
        c.output().unwrap()
    };
    let o = second(false);
    assert_eq!(o.status.code(), Some(5), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("checkpoint.json").exists(), "a refused run changes nothing");
    let o = second(true);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out.join("checkpoint.json").exists(), "the earlier run's checkpoint must not survive a new run");
    let log = std::fs::read_to_string(out.join("log.txt")).unwrap();
    assert!(log.contains("--force: removed the outputs of a run (checkpoint.json"), "{log}");
    let rows = std::fs::read_to_string(out.join("series.csv")).unwrap().lines().count();
    let o = bin().arg("resume").arg(&out).arg("--quiet").output().unwrap();
    assert!(!o.status.success(), "resume must refuse: there is no checkpoint of this run");
    assert_eq!(o.status.code(), Some(5), "an io error: {}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(out.join("series.csv")).unwrap().lines().count(), rows, "the refused resume changed nothing");
}

#[test]
fn class04_one_writer_per_output_directory_and_a_dead_holders_lock_is_taken_over() {
    let d = common::tmp_dir("fault-lock");
    let case = long_series_case(&d, 1e6);
    let out = d.join("out");
    let mut first = bin().arg("run").arg(&case).arg("--out").arg(&out).arg("--quiet").stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    let lock = out.join(".sinterdem.lock");
    let t0 = Instant::now();
    while !std::fs::read_to_string(&lock).is_ok_and(|s| s.contains("pid")) {
        assert!(t0.elapsed() < Duration::from_secs(30), "the first run never took its lock");
        std::thread::sleep(Duration::from_millis(10));
    }
    for cmd in ["run", "generate-like"] {
        let mut c = bin();
        if cmd == "run" {
            c.arg("run").arg(&case).arg("--out").arg(&out).arg("--quiet");
        } else {
            c.arg("resume").arg(&out).arg("--quiet");
        }
        let o = c.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        if cmd == "run" {
            assert_eq!(o.status.code(), Some(5), "a second writer is an io error: {err}");
            assert!(err.contains(&format!("pid {}", first.id())) && err.contains("one writer per output directory"), "{err}");
        } else {
            assert!(!o.status.success(), "a resume beside a running run must be refused: {err}");
        }
    }
    first.kill().unwrap();
    let _ = first.wait();
    // the dead holder's lock file is still there; the next writer takes it over and says so
    // (--force: the killed run left its outputs)
    let o = bin().arg("run").arg(&case).arg("--out").arg(&out).arg("--quiet").arg("--force").args(["--set", "time.end=10"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let log = std::fs::read_to_string(out.join("log.txt")).unwrap();
    assert!(log.contains("taken over from a process that is gone"), "{log}");
}

#[test]
fn class05_subnormal_times_that_used_to_hang_are_refused_by_check_and_run() {
    let d = common::tmp_dir("fault-subnormal");
    let case = long_series_case(&d, 10.0);
    let pair = d.join("pair.toml");
    std::fs::write(&pair, std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/pair-copper.toml")).unwrap()).unwrap();
    for (file, set, key) in
        [(&case, "time.end=5e-324", "time.end"), (&case, "solver.max_substep=5e-324", "solver.max_substep"), (&pair, "pair.end_time=5e-324", "pair.end_time")]
    {
        for cmd in ["check", "run"] {
            let mut c = bin();
            c.arg(cmd).arg(file).arg("--set").arg(set);
            if cmd == "run" {
                c.arg("--out").arg(d.join("out")).arg("--quiet");
            }
            let o = c.output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{cmd} {set}: a configuration error: {err}");
            assert!(err.contains(key), "{cmd} {set}: {err}");
        }
    }
}

#[test]
fn class09_pair_runs_and_pair_calibrations_stop_at_the_solidus_like_compacts() {
    let d = common::tmp_dir("solidus");
    let pair = d.join("pair.toml");
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/pair-copper.toml")).unwrap();
    std::fs::write(&pair, text).unwrap();
    // copper melts at 1358 K (bundled data): a constant 1400 K and a ramp through 1358 K are
    // refused by check and by run; 1350 K runs
    for (set, refused) in
        [("temperature={constant=1400.0}", true), ("temperature={table=[[0.0,300.0],[100.0,1500.0]]}", true), ("temperature={constant=1350.0}", false)]
    {
        for cmd in ["check", "run"] {
            let mut c = bin();
            c.arg(cmd).arg(&pair).arg("--set").arg(set).arg("--set").arg("pair.end_time=100");
            if cmd == "run" {
                c.arg("--out").arg(d.join("out")).arg("--quiet");
            }
            let o = c.output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            if refused {
                assert_eq!(o.status.code(), Some(1), "{cmd} {set}: {err}");
                assert!(err.contains("1358") && err.contains("solidus"), "{cmd} {set}: {err}");
            } else {
                assert!(o.status.success(), "{cmd} {set}: {err}");
            }
        }
    }
    // the crossing time of the ramp is exact: 300 + 12 K/s · t = 1358 K at t = 88.1666… s
    let o = bin().arg("check").arg(&pair).args(["--set", "temperature={table=[[0.0,300.0],[100.0,1500.0]]}", "--set", "pair.end_time=100"]).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("88.1666"), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn class08_run_refuses_what_check_refuses_for_explicit_sinter_protocols() {
    let d = common::tmp_dir("run-as-check");
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/luding-pressure.toml");
    let out = d.join("out");
    for cmd in ["check", "run"] {
        let mut c = bin();
        c.arg(cmd).arg(&case).args(["--set", "protocol.output_interval=1e-10"]);
        if cmd == "run" {
            c.arg("--out").arg(&out).arg("--quiet");
        }
        let o = c.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(err.contains("protocol.output_interval") && err.contains("at most 1e7"), "{cmd}: {err}");
    }
    assert!(!out.join("summary.json").exists(), "a refused run writes no summary");
}

#[test]
fn class03_a_resume_refuses_a_packing_changed_since_the_run_started() {
    let d = common::tmp_dir("inputs-changed");
    let case = long_series_case(&d, 200.0);
    let out = d.join("out");
    let o = bin().arg("run").arg(&case).arg("--out").arg(&out).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    // as a run killed before its end (a finished run has nothing to resume: issue 25)
    std::fs::remove_file(out.join("summary.json")).unwrap();
    // radii +3 %, as in the issue
    std::fs::write(d.join("packing.csv"), "x,y,z,r\n0,0,0,2.575e-5\n0,4.95e-5,0,2.575e-5\n").unwrap();
    let o = bin().arg("resume").arg(&out).arg("--quiet").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("particles.file") && err.contains("changed since the run started"), "{err}");
    assert_eq!(std::fs::read_to_string(out.join("series.csv")).unwrap(), series, "the refused resume changed nothing");
    // restored: the resume goes on
    std::fs::write(d.join("packing.csv"), "x,y,z,r\n0,0,0,2.5e-5\n0,4.95e-5,0,2.5e-5\n").unwrap();
    let o = bin().arg("resume").arg(&out).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(out.join("series.csv")).unwrap(), series);
}

#[test]
fn class11_compact_checkpoints_that_validated_but_gave_nan_are_refused() {
    let d = common::tmp_dir("ck-nan");
    let case = long_series_case(&d, 200.0);
    let run = d.join("run");
    let o = bin().arg("run").arg(&case).arg("--out").arg(&run).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let good: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("checkpoint.json")).unwrap()).unwrap();
    // the issue's corruptions: each validated before and ended with null summary fields
    let edits: Vec<(&str, serde_json::Value, &str)> = vec![
        ("/contacts/0/r0", serde_json::json!([5e-324, 2.5e-5]), "checkpoint.contacts[0].r0[0]"),
        ("/contacts/0/l0", serde_json::json!(0.0), "checkpoint.contacts[0].l0"),
        ("/contacts/0/l0", serde_json::json!(1.0), "checkpoint.contacts[0].l0"),
        ("/heat_in", serde_json::json!(1e308), "checkpoint.heat_in"),
        ("/heat_stored", serde_json::json!(-1e308), "checkpoint.heat_stored"),
    ];
    refused_edits(&d, &run, &good, edits);
}

#[test]
fn class11_heat_checkpoints_with_overflowing_accounts_or_unequal_histories_are_refused() {
    let d = common::tmp_dir("heat-ck-nan");
    let case = d.join("heat.toml");
    std::fs::write(
        &case,
        "[time]\nend = 10.0\ndt = 0.1\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\ncheckpoint_every = 20\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n\
         [particles]\nsource = \"pair\"\nradius = 25e-6\noverlap = 0.05\ninitial_temperature = 293.15\n[thermal.furnace]\nprofile = { constant = 1000.0 }\nconvection_coefficient = 10.0\n",
    )
    .unwrap();
    let run = d.join("run");
    let o = bin().arg("run").arg(&case).arg("--out").arg(&run).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let good: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("checkpoint.json")).unwrap()).unwrap();
    let n_hist = good.pointer("/state/hist").and_then(|h| h.as_array()).map_or(0, |h| h.len());
    let edits: Vec<(&str, serde_json::Value, &str)> = vec![
        ("/state/heat_in", serde_json::json!(1e308), "checkpoint.state.heat_in"),
        ("/state/stored0", serde_json::json!(-1e300), "checkpoint.state.stored0"),
        ("/state/hist_t", serde_json::json!(vec![1.0; n_hist + 1]), "state.hist_t"),
    ];
    refused_edits(&d, &run, &good, edits);
}

#[test]
fn class12_a_resumed_compact_summary_equals_the_uninterrupted_one_mechanics_counters_included() {
    let d = common::tmp_dir("resume-counters");
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/copper-compact.toml");
    let sets = ["time.end=900.0", "output.checkpoint_every=150", "output.snapshots=0", "output.vtu=false", "output.hdf5=false"];
    let full = d.join("full");
    let mut c = bin();
    c.arg("run").arg(&case).arg("--out").arg(&full).arg("--quiet");
    for s in sets {
        c.arg("--set").arg(s);
    }
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = summary_without_times(&full);
    let topo = summary["mechanics_profile"]["topology_changes"].as_u64().unwrap();
    assert!(topo > 2, "the case must change its topology several times ({topo})");
    let work = d.join("work");
    copy_dir(&full, &work);
    // as a run killed before its end: no summary.json (a finished run is not resumed)
    std::fs::remove_file(work.join("summary.json")).unwrap();
    let o = bin().arg("resume").arg(&work).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary_without_times(&work), summary);
    assert_eq!(std::fs::read_to_string(work.join("series.csv")).unwrap(), std::fs::read_to_string(full.join("series.csv")).unwrap());
}

/// Resumes a copy of the run directory `run` once per edit of its checkpoint `good` (a JSON
/// pointer, the new value, the text the error must contain): each is refused with exit 1 naming
/// the entry; then the untouched checkpoint resumes.
fn refused_edits(d: &Path, run: &Path, good: &serde_json::Value, edits: Vec<(&str, serde_json::Value, &str)>) {
    for (pointer, v, needle) in edits {
        let dir = d.join(format!("edit{}", pointer.replace('/', "-")));
        copy_dir(run, &dir);
        let _ = std::fs::remove_file(dir.join("summary.json"));
        let mut ck = good.clone();
        *ck.pointer_mut(pointer).unwrap_or_else(|| panic!("{pointer} not in the checkpoint")) = v.clone();
        std::fs::write(dir.join("checkpoint.json"), sinterdem::io::seal_value(&ck)).unwrap();
        let o = bin().arg("resume").arg(&dir).arg("--quiet").output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{pointer} = {v}: {err}");
        assert!(err.contains(needle), "{pointer} = {v}: {err}");
    }
    let o = bin().arg("resume").arg(run).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn class06_calibration_sigmas_below_the_floor_are_refused_before_any_fit() {
    let d = common::tmp_dir("sigma-floor");
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/calibration");
    let calib = std::fs::read_to_string(src.join("titanium-synthetic.toml"))
        .unwrap()
        .replace("\"../titanium-compact-e14b.toml\"", &format!("{:?}", src.join("../titanium-compact-e14b.toml")));
    std::fs::write(d.join("calib.toml"), calib).unwrap();
    let data = std::fs::read_to_string(src.join("titanium-synthetic.csv")).unwrap();
    // the issue's sigma of 5e-324 (inside the old (0, 1]) made chi^2 infinite and the SVD panic
    let bad = data.replacen(",1.0000e-2,", ",5e-324,", 1);
    assert_ne!(bad, data);
    std::fs::write(d.join("titanium-synthetic.csv"), bad).unwrap();
    let o = bin().arg("check").arg(d.join("calib.toml")).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("neck_ratio_sigma") && err.contains("1e-9"), "{err}");
    let o = bin().arg("calibrate").arg(d.join("calib.toml")).arg("--out").arg(d.join("fit")).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The small synthetic titanium calibration of these tests (28 pair experiments, one swarm
/// iteration of 2, one local iteration; no compact validation) in `d`, with `extra` lines appended
/// to its `[solver]` table.
fn small_calibration(d: &Path, extra: &str) -> PathBuf {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/calibration");
    std::fs::copy(src.join("titanium-synthetic.csv"), d.join("titanium-synthetic.csv")).unwrap();
    let text = std::fs::read_to_string(src.join("titanium-synthetic.toml")).unwrap();
    let text = text[..text.find("\n[compact]").unwrap()]
        .replace("swarm_size = 16 ", "swarm_size = 2 ")
        .replace("swarm_iterations = 25 ", "swarm_iterations = 1 ")
        .replace("local_iterations = 50 ", "local_iterations = 1 ")
        .replace("[solver]\n", &format!("[solver]\n{extra}\n"));
    let path = d.join("calib.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn class06_a_calibration_whose_every_run_fails_and_a_subnormal_fd_step_exit_non_zero() {
    let d = common::tmp_dir("calib-fail");
    // every pair run gives up after one substep: before, exit 0 with "chi2": null, every sigma
    // null and parameters that never moved
    let calib = small_calibration(&d, "max_substeps = 1");
    let o = bin().arg("calibrate").arg(&calib).arg("--out").arg(d.join("fit")).arg("--quiet").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("every run of the calibration fails") && err.contains("28 experiments"), "{err}");
    assert!(!d.join("fit/calibration.json").exists(), "no report of a fit that has no result");
    // the issue's fd_step of 5e-324 panicked the SVD; now below the floor of 1e-8, refused by both
    let calib = small_calibration(&d, "");
    let text = std::fs::read_to_string(&calib).unwrap().replace("fd_step = 1.0e-4 ", "fd_step = 5e-324 ");
    std::fs::write(&calib, text).unwrap();
    for cmd in ["check", "calibrate"] {
        let o = bin().arg(cmd).arg(&calib).arg("--out").arg(d.join("fit2")).output();
        let o = if cmd == "check" { bin().arg(cmd).arg(&calib).output() } else { o }.unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(err.contains("optimiser.fd_step") && err.contains("1e-8"), "{cmd}: {err}");
    }
}

/// A study of the bundled copper pair case with the `[[parameters]]`/`[design]` text `design`;
/// returns `sinterdem study`'s output.
fn study_with(d: &Path, name: &str, design: &str) -> std::process::Output {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/pair-copper.toml");
    let path = d.join(format!("{name}.toml"));
    std::fs::write(&path, format!("base = {:?}\n{design}\n[collect]\nsummary = [\"neck_ratio\"]\n", base.display().to_string())).unwrap();
    bin().arg("study").arg(&path).arg("--out").arg(d.join(name)).arg("--quiet").output().unwrap()
}

#[test]
fn class07_designs_that_cannot_be_honoured_are_refused_before_anything_runs() {
    let d = common::tmp_dir("designs");
    let refused = |name: &str, design: &str, says: &[&str]| {
        let t0 = Instant::now();
        let o = study_with(&d, name, design);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        for s in says {
            assert!(err.contains(s), "{name}: {err} should say {s}");
        }
        assert!(!d.join(name).join("runs").exists(), "{name}: nothing runs");
        // refused from the counts, not after expanding 1e9 points in memory
        assert!(t0.elapsed() < Duration::from_secs(20), "{name}: {:?}", t0.elapsed());
    };
    let p = |key: &str, rest: &str| format!("[[parameters]]\nkey = \"{key}\"\n{rest}\n");
    // the issue's 1e6 x 1e3 grid (each num inside [1, 1e6]) was expanded until the allocator aborted
    let grid = p("temperature.constant", "range = [1200.0, 1300.0]\nnum = 1000000") + &p("pair.end_time", "range = [10.0, 100.0]\nnum = 1000");
    refused("grid", &grid, &["1e9 runs", "at most 1e6 runs"]);
    let mut lhs = String::from("[design]\nkind = \"lhs\"\nsamples = 1000000\n");
    for k in 0..200 {
        lhs += &p(&format!("materials.0.fuzz{k}"), "min = 1.0\nmax = 2.0");
    }
    refused("lhs-size", &lhs, &["2e8 values", "1e8 values"]);
    // bounds of +-1.7e308 passed "finite min < max" and every value became inf
    let wide = String::from("[design]\nkind = \"lhs\"\nsamples = 4\n") + &p("temperature.constant", "min = -1.7e308\nmax = 1.7e308");
    refused("wide", &wide, &["overflows", "temperature.constant"]);
    // one key in two [[parameters]]: study.csv showed values that were never applied
    let twice = p("temperature.constant", "name = \"a\"\nvalues = [1200.0]") + &p("temperature.constant", "name = \"b\"\nvalues = [1250.0]");
    refused("twice", &twice, &["temperature.constant", "two [[parameters]]"]);
    // a parameter named like a fixed column of study.csv
    refused("status", &p("temperature.constant", "name = \"status\"\nvalues = [1200.0]"), &["\"status\"", "fixed column"]);
    // the limits leave ordinary studies alone
    let o = study_with(&d, "fine", &p("temperature.constant", "values = [1200.0, 1250.0]"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(d.join("fine/study.csv")).unwrap().lines().count(), 3);
}

#[test]
fn class08_check_refuses_the_generate_settings_that_generate_refuses() {
    let d = common::tmp_dir("generate-check");
    let case = |name: &str, sets: &[&str]| {
        let src = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut v: toml::Value = toml::from_str(&std::fs::read_to_string(src.join(name)).unwrap()).unwrap();
        for s in sets {
            sinterdem::config::apply_override(&mut v, s).unwrap();
        }
        let p = d.join(name.replace('/', "-"));
        std::fs::write(&p, toml::to_string(&v).unwrap()).unwrap();
        p
    };
    // the issue's two: 2 particles with spread 0.9 (a box narrower than two largest diameters);
    // a box edge of 5e-324 (the target box overflowed to inf, and the periodic insertion then
    // panicked with "capacity overflow": found by tests/fuzz_run.rs)
    for (name, sets) in [
        ("cases/green-copper.toml", &["packing.particles=2", "packing.size.spread=0.9"][..]),
        ("cases/green-copper.toml", &["packing.box.0=5e-324"][..]),
        ("cases/packing/periodic-copper.toml", &["packing.particles=2", "packing.box.0=5e-324"][..]),
    ] {
        let p = case(name, sets);
        for cmd in ["check", "run"] {
            let mut c = bin();
            c.arg(cmd).arg(&p);
            if cmd == "run" {
                c.arg("--out").arg(d.join("out"));
            }
            let o = c.arg("--quiet").output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{cmd} {name} {sets:?}: {err}");
            assert!(err.contains("packing.box") && err.contains("two largest diameters"), "{cmd} {name} {sets:?}: {err}");
        }
    }
}

/// Runs `args` of sinterdem with every file limited to `kib` KiB (RLIMIT_FSIZE through the
/// shell's `ulimit -f`; SIGXFSZ ignored, so a write past the limit fails with EFBIG as on a full
/// disk instead of killing the process). The fault injection of class 10: unprivileged, for real
/// writes, with no switch in the program.
fn with_file_limit(kib: u64, args: &[&std::ffi::OsStr]) -> std::process::Output {
    let mut cmd = format!("trap '' XFSZ; ulimit -f {kib}; exec {:?}", env!("CARGO_BIN_EXE_sinterdem"));
    for a in args {
        cmd.push_str(&format!(" {:?}", a.to_string_lossy()));
    }
    Command::new("bash").arg("-c").arg(cmd).output().unwrap()
}

#[test]
fn class10_a_failed_data_write_is_an_error_and_no_truncated_plot_is_left() {
    let d = common::tmp_dir("full-disk");
    // 60 s of the copper compact: series.csv about 38 kB, the plots 20-40 kB each
    let text = common::copper_compact_text(&Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/data/green-copper.csv"), 60.0).replace("dt = 1.0e-6", "dt = 1.0");
    let case = d.join("case.toml");
    std::fs::write(&case, text).unwrap();
    let o = bin().arg("run").arg(&case).arg("--out").arg(d.join("full")).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let size = |p: &Path| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    let dl = size(&d.join("full/dl_bar_end.csv"));
    let series = size(&d.join("full/series.csv"));
    assert!(dl > 100 * 1024 && series < 90 * 1024, "dl_bar_end.csv {dl} B, series.csv {series} B");
    // (a) dl_bar_end.csv cannot be written: before, exit 0 with the file missing
    let out = d.join("a");
    let o =
        with_file_limit(100, &[std::ffi::OsStr::new("run"), case.as_os_str(), std::ffi::OsStr::new("--out"), out.as_os_str(), std::ffi::OsStr::new("--quiet")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(5), "{err}");
    assert!(err.contains("dl_bar_end.csv") && err.contains("File too large"), "{err}");
    assert!(!out.join("dl_bar_end.csv").exists());
    // (b) only the larger plots cannot be written (93 particles: dl_bar_end.csv 14 kB, series.csv
    // 35 kB, shrinkage.png 40 kB): the data complete, exit 0 with a warning, and no PNG under its
    // final name that is not the whole image (before: shrinkage.png cut at the limit)
    let block = common::green_copper_block(2.2e-4, 2.2e-4);
    let packing = common::write_block(&d, "block.csv", "x,y,z,r", block.into_iter().map(|(l, _)| l));
    let small = d.join("small.toml");
    std::fs::write(&small, common::copper_compact_text(&packing, 60.0).replace("dt = 1.0e-6", "dt = 1.0")).unwrap();
    let out = d.join("b");
    let o =
        with_file_limit(36, &[std::ffi::OsStr::new("run"), small.as_os_str(), std::ffi::OsStr::new("--out"), out.as_os_str(), std::ffi::OsStr::new("--quiet")]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("plots not written") && err.contains("File too large"), "{err}");
    for f in ["series.csv", "summary.json", "dl_bar_end.csv"] {
        assert!(size(&out.join(f)) > 0, "{f} must be written before the plots");
    }
    let mut pngs = 0;
    for e in std::fs::read_dir(&out).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        assert!(!name.contains(".tmp"), "a temporary file is left: {name}");
        if name.ends_with(".png") {
            let bytes = std::fs::read(e.path()).unwrap();
            // a whole PNG ends with its IEND chunk (type + CRC)
            assert!(bytes.len() > 12 && &bytes[bytes.len() - 8..bytes.len() - 4] == b"IEND", "{name} is truncated ({} B)", bytes.len());
            pngs += 1;
        }
    }
    assert!(!out.join("shrinkage.png").exists(), "shrinkage.png exceeds the limit and must not exist");
    eprintln!("class 10: {pngs} whole PNGs written before the first that did not fit");
}

#[test]
fn class13_an_included_material_file_with_model_works_in_a_heat_case() {
    let d = common::tmp_dir("include-model");
    // a calibration's material.toml carries [model] (the fitted path factors); heat cases have none
    std::fs::write(d.join("material.toml"), "[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n\n[model]\npath_factor_gb = 2.0\n").unwrap();
    let text = "[time]\nend = 2.0\ndt = 1.0\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n[[materials]]\nname = \"copper\"\ninclude = \"material.toml\"\n\
                [particles]\nsource = \"lattice\"\nlattice = \"fcc\"\ncells = [2, 2, 2]\nradius = 25e-6\noverlap = 0.05\ninitial_temperature = 293.15\n\
                [thermal]\nmode = \"network\"\n[[thermal.fixed]]\nregion = { face = \"z-\" }\nprofile = { constant = 400.0 }\n";
    std::fs::write(d.join("heat.toml"), text).unwrap();
    for cmd in ["check", "run"] {
        let mut c = bin();
        c.arg(cmd).arg(d.join("heat.toml"));
        if cmd == "run" {
            c.arg("--out").arg(d.join("out"));
        }
        let o = c.arg("--quiet").output().unwrap();
        assert!(o.status.success(), "{cmd}: {}", String::from_utf8_lossy(&o.stderr));
    }
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("out/summary.json")).unwrap()).unwrap();
    // 2 s of an 8-cell copper lattice on a 400 K plate: the network reaches the plate (time constant ≪ 1 s)
    assert!(s["mean_temperature_K"].as_f64().is_some_and(|t| (t - 400.0).abs() < 0.5), "{s}");
}

/// A JSON document without its wall-time fields (any key naming seconds of wall time), recursively.
fn without_wall_times(mut v: serde_json::Value) -> serde_json::Value {
    match &mut v {
        serde_json::Value::Object(m) => {
            m.retain(|k, _| !(k.contains("wall") || k == "timing_seconds" || k.ends_with("_seconds") && k.contains("time")));
            for x in m.values_mut() {
                *x = without_wall_times(x.take());
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(|x| *x = without_wall_times(x.take())),
        _ => {}
    }
    v
}

fn json_of(path: &Path) -> serde_json::Value {
    without_wall_times(serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap())
}

/// study.csv without its `wall_seconds` column.
fn study_csv_without_times(dir: &Path) -> String {
    let text = std::fs::read_to_string(dir.join("study.csv")).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let w = header.iter().position(|h| *h == "wall_seconds").unwrap();
    text.lines().map(|l| l.split(',').enumerate().filter(|(i, _)| *i != w).map(|(_, x)| x).collect::<Vec<_>>().join(",") + "\n").collect()
}

/// Kills the child `cmd` after a seeded delay in [0, `span`), once or twice in a row; returns the
/// kills made (0 when the child finished first).
fn kill_after(cmd: &mut dyn FnMut() -> Command, span: Duration, seed: &mut u64, times: usize) -> usize {
    let mut kills = 0;
    for _ in 0..times {
        let delay = Duration::from_micros(next(seed) % span.as_micros() as u64);
        let mut child = cmd().stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        let t0 = Instant::now();
        while child.try_wait().unwrap().is_none() && t0.elapsed() < delay {
            std::thread::sleep(Duration::from_micros(300));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
        }
        let _ = child.wait();
    }
    kills
}

/// Kills per command of the extended harness: `SINTERDEM_FAULT_KILLS` / 2 (CI: 8), at least 2.
fn kills_per_command() -> usize {
    (std::env::var("SINTERDEM_FAULT_KILLS").ok().and_then(|v| v.parse::<usize>().ok()).unwrap_or(16) / 2).max(2)
}

#[test]
fn class01_runs_killed_at_random_points_resume_to_the_uninterrupted_result() {
    let d = common::tmp_dir("fault-run");
    let case = long_series_case(&d, 2000.0);
    let full = d.join("full");
    let o = bin().arg("run").arg(&case).arg("--out").arg(&full).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let series = std::fs::read_to_string(full.join("series.csv")).unwrap();
    let summary = summary_without_times(&full);
    let (trials, mut seed) = (kills_per_command(), 0x2026_0001_u64);
    let (mut killed, mut resumed, mut reran) = (0, 0, 0);
    let work = d.join("work");
    for k in 0..trials {
        let _ = std::fs::remove_dir_all(&work);
        // a run takes about 0.5 s; every other trial also kills the first resume
        killed += kill_after(&mut || bin().arg("run").arg(&case).arg("--out").arg(&work).arg("--quiet").tap(), Duration::from_millis(600), &mut seed, 1);
        if k % 2 == 1 && work.join("checkpoint.json").exists() {
            killed += kill_after(&mut || bin().arg("resume").arg(&work).arg("--quiet").tap(), Duration::from_millis(400), &mut seed, 1);
        }
        // the next invocation: resume from the last checkpoint, or (killed before the first one)
        // the run again
        let o = if work.join("checkpoint.json").exists() {
            resumed += 1;
            bin().arg("resume").arg(&work).arg("--quiet").output().unwrap()
        } else {
            reran += 1;
            // the killed run left its log: a new run into its directory needs --force
            bin().arg("run").arg(&case).arg("--out").arg(&work).arg("--quiet").arg("--force").output().unwrap()
        };
        assert!(o.status.success(), "trial {k}: {}", String::from_utf8_lossy(&o.stderr));
        assert!(std::fs::read_to_string(work.join("series.csv")).unwrap() == series, "trial {k}: series.csv differs from the uninterrupted run");
        assert_eq!(summary_without_times(&work), summary, "trial {k}: summary.json differs");
    }
    eprintln!("fault injection (run): {trials} trials, {killed} kills, {resumed} resumes and {reran} reruns, all bit-identical");
    assert!(killed >= trials / 2, "{killed} kills in {trials} trials");
}

#[test]
fn class01_studies_and_calibrations_killed_at_random_points_rerun_to_the_uninterrupted_result() {
    let d = common::tmp_dir("fault-study");
    // a study of 12 copper pair runs
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/pair-copper.toml");
    let study = d.join("study.toml");
    std::fs::write(
        &study,
        format!(
            "base = {:?}\n[[parameters]]\nkey = \"temperature.constant\"\nrange = [1150.0, 1300.0]\nnum = 12\n[collect]\nsummary = [\"neck_ratio\", \"shrinkage\", \"steps\"]\n",
            base.display().to_string()
        ),
    )
    .unwrap();
    let full = d.join("full");
    let t0 = Instant::now();
    let o = bin().arg("study").arg(&study).arg("--out").arg(&full).arg("--jobs").arg("1").arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let span = t0.elapsed() + Duration::from_millis(20);
    let reference = study_csv_without_times(&full);
    let (trials, mut seed) = (kills_per_command(), 0x2026_0002_u64);
    let mut killed = 0;
    let work = d.join("work");
    for k in 0..trials {
        let _ = std::fs::remove_dir_all(&work);
        let mut cmd = || bin().arg("study").arg(&study).arg("--out").arg(&work).arg("--jobs").arg("1").arg("--quiet").tap();
        killed += kill_after(&mut cmd, span, &mut seed, 1 + k % 2);
        let o = cmd().output().unwrap();
        assert!(o.status.success(), "study trial {k}: {}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(study_csv_without_times(&work), reference, "study trial {k}: study.csv differs from the uninterrupted study");
    }
    eprintln!("fault injection (study): {trials} trials, {killed} kills, every rerun bit-identical in study.csv");

    // the small synthetic calibration
    let calib = small_calibration(&d, "");
    let full = d.join("calib-full");
    let t0 = Instant::now();
    let o = bin().arg("calibrate").arg(&calib).arg("--out").arg(&full).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let span = t0.elapsed() + Duration::from_millis(20);
    let (report, residuals) = (json_of(&full.join("calibration.json")), std::fs::read_to_string(full.join("residuals.csv")).unwrap());
    let mut ckilled = 0;
    let work = d.join("calib-work");
    for k in 0..trials {
        let _ = std::fs::remove_dir_all(&work);
        let mut cmd = || bin().arg("calibrate").arg(&calib).arg("--out").arg(&work).arg("--quiet").tap();
        ckilled += kill_after(&mut cmd, span, &mut seed, 1 + k % 2);
        let o = cmd().output().unwrap();
        assert!(o.status.success(), "calibration trial {k}: {}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(json_of(&work.join("calibration.json")), report, "calibration trial {k}: calibration.json differs");
        assert!(std::fs::read_to_string(work.join("residuals.csv")).unwrap() == residuals, "calibration trial {k}: residuals.csv differs");
    }
    eprintln!(
        "fault injection (calibrate): {trials} trials, {ckilled} kills, every rerun bit-identical in calibration.json (wall times aside) and residuals.csv"
    );
    assert!(killed + ckilled >= trials, "{killed} + {ckilled} kills in 2 x {trials} trials");
}

/// `Command` builder methods return `&mut Command`; `tap` gives the owned one back for closures.
trait Tap {
    fn tap(&mut self) -> Command;
}

impl Tap for Command {
    fn tap(&mut self) -> Command {
        std::mem::replace(self, Command::new("true"))
    }
}

/// Defects the run-path fuzzer (`tests/fuzz_run.rs`) found: a heat run with more snapshot times
/// than steps wrote the same state once per snapshot time (73 083 snapshots of a 60-step run took
/// two minutes a step), and a per-contact tolerance of 4e-30 never finished a compact step.
#[test]
fn fuzz_found_heat_snapshots_are_one_per_step_and_rtol_has_a_floor() {
    let d = common::tmp_dir("fuzz-found");
    let text = "[time]\nend = 3.0\ndt = 1.0\n[output]\nsnapshots = 5000\nvtu = true\nhdf5 = false\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n\
                [particles]\nsource = \"lattice\"\nlattice = \"fcc\"\ncells = [2, 2, 2]\nradius = 25e-6\noverlap = 0.05\ninitial_temperature = 293.15\n\
                [thermal]\nmode = \"network\"\n[[thermal.fixed]]\nregion = { face = \"z-\" }\nprofile = { constant = 400.0 }\n";
    std::fs::write(d.join("heat.toml"), text).unwrap();
    let t0 = Instant::now();
    let o = bin().arg("run").arg(d.join("heat.toml")).arg("--out").arg(d.join("out")).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let vtus = std::fs::read_dir(d.join("out")).unwrap().flatten().filter(|e| e.file_name().to_string_lossy().starts_with("particles_")).count();
    // 3 steps: the initial state and one snapshot per step (before: 5000 files of 4 states)
    assert!((2..=4).contains(&vtus), "{vtus} particle snapshots for 3 steps");
    assert!(t0.elapsed() < Duration::from_secs(30));
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/periodic-copper-rve.toml");
    for cmd in ["check", "run"] {
        let mut c = bin();
        c.arg(cmd).arg(&case).arg("--set").arg("solver.rtol=4.2e-30");
        if cmd == "run" {
            c.arg("--out").arg(d.join("rve"));
        }
        let o = c.arg("--quiet").output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(err.contains("solver.rtol") && err.contains("1e-12"), "{cmd}: {err}");
    }
}

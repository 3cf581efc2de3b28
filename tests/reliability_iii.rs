//! Reliability III (issue 38), the command-line side: a rerun or `--force` removes exactly what
//! an earlier run recorded as its outputs (`outputs.json`), never the case, its inputs or a user's
//! files and folders; every kind killed with SIGKILL at a checkpoint resumes to the uninterrupted
//! result bit for bit (rve: its branch points, `constitutive.csv`, fit and plots) or is refused
//! with a reason; checkpoints carry a checksum and their contacts are checked against the
//! positions and radii.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sinterdem"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))).unwrap()
}

/// The names in `dir` (recursively, `/`-separated), sorted.
fn tree(dir: &Path) -> Vec<String> {
    fn walk(d: &Path, prefix: &str, out: &mut Vec<String>) {
        for e in std::fs::read_dir(d).unwrap().flatten() {
            let name = format!("{prefix}{}", e.file_name().to_string_lossy());
            if e.file_type().unwrap().is_dir() {
                out.push(format!("{name}/"));
                walk(&e.path(), &format!("{name}/"), out);
            } else {
                out.push(name);
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, "", &mut v);
    v.sort();
    v
}

/// A 27-particle titanium heat case reading its packing `pack.csv` from its own folder.
fn heat_case_in(dir: &Path) {
    let (r, s) = (32e-6, 2.0 * 32e-6 * 0.95);
    let mut csv = String::from("x,y,z,r\n");
    for i in 0..27 {
        csv.push_str(&format!("{:e},{:e},{:e},{r:e}\n", (i % 3) as f64 * s, ((i / 3) % 3) as f64 * s, (i / 9) as f64 * s));
    }
    std::fs::write(dir.join("pack.csv"), csv).unwrap();
    std::fs::write(
        dir.join("case.toml"),
        "[time]\nend = 5.0\ndt = 1.0\n[[materials]]\nname = \"titanium\"\npreset = \"titanium\"\n[particles]\nsource = \"file\"\nfile = \"pack.csv\"\n\
         initial_temperature = 293.15\n[thermal]\nmode = \"network\"\nconductance = \"linear\"\n[[thermal.fixed]]\nregion = { face = \"z-\" }\n\
         profile = { constant = 400.0 }\n",
    )
    .unwrap();
}

/// Group 1: a run with `--out` set to the case's own folder, again (a rerun of the same case),
/// then with `--force` and another case: the case, its packing, the user's notes, settings and a
/// folder of their own (holding a `summary.json` and a CSV) are all kept; only the run's files
/// change. A directory whose run files no manifest lists is refused, and nothing is removed.
#[test]
fn group1_a_rerun_and_force_remove_only_what_the_run_wrote() {
    let d = common::tmp_dir("keep");
    heat_case_in(&d);
    std::fs::write(d.join("notes.txt"), "my notes").unwrap();
    std::fs::write(d.join("settings.json"), "{\"mine\": 1}").unwrap();
    std::fs::create_dir_all(d.join("mine/deeper")).unwrap();
    std::fs::write(d.join("mine/summary.json"), "{\"mine\": true}").unwrap();
    std::fs::write(d.join("mine/deeper/data.csv"), "a,b\n1,2\n").unwrap();
    let user: Vec<String> = tree(&d);
    let run = |extra: &[&str]| bin().current_dir(&d).args(["-q", "run", "case.toml", "--out", "."]).args(extra).output().unwrap();
    for (what, extra) in [("first run", &[][..]), ("rerun", &[][..]), ("--force", &["--force", "--set", "time.end=4.0"][..])] {
        let o = run(extra);
        assert!(o.status.success(), "{what}: {}", stderr(&o));
        let now = tree(&d);
        for f in &user {
            assert!(now.contains(f), "{what} removed {f}: left {now:?}");
        }
        assert_eq!(std::fs::read_to_string(d.join("notes.txt")).unwrap(), "my notes");
        assert_eq!(std::fs::read_to_string(d.join("mine/summary.json")).unwrap(), "{\"mine\": true}");
    }
    assert_eq!(json(&d.join("summary.json"))["final_time_s"], 4.0);
    let manifest = json(&d.join("outputs.json"));
    let files: Vec<&str> = manifest["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap()).collect();
    assert!(files.contains(&"summary.json") && files.contains(&"series.csv") && !files.contains(&"pack.csv"), "{files:?}");
    let log = std::fs::read_to_string(d.join("log.txt")).unwrap();
    assert!(log.contains("kept case.toml, mine/, notes.txt, pack.csv, settings.json"), "{log}");

    // run files that no manifest lists (an older sinterdem's, or the user's): refused untouched
    let old = common::tmp_dir("legacy");
    for f in ["summary.json", "series.csv", "particles_000000.vtu"] {
        std::fs::write(old.join(f), "x").unwrap();
    }
    let o = bin().args(["-q", "run"]).arg(d.join("case.toml")).arg("--out").arg(&old).arg("--force").output().unwrap();
    assert_eq!(o.status.code(), Some(5), "{}", stderr(&o));
    assert!(stderr(&o).contains("no sinterdem command recorded as its outputs") && stderr(&o).contains("outputs.json"), "{}", stderr(&o));
    assert_eq!(tree(&old), [".sinterdem.lock", "particles_000000.vtu", "series.csv", "summary.json"]);
}

/// How the harness kills a run: once `ready` holds for its directory (a checkpoint exists; for
/// rve, a branch point is measured too), or at once when the kind writes no checkpoint.
struct KindRun {
    name: &'static str,
    args: Vec<String>,
    /// The files compared bit for bit with the uninterrupted run after the resume.
    same: &'static [&'static str],
    ready: fn(&Path) -> bool,
    resumes: bool,
}

fn has_checkpoint(d: &Path) -> bool {
    d.join("checkpoint.json").is_file()
}

fn has_rve_point(d: &Path) -> bool {
    has_checkpoint(d) && std::fs::read_to_string(d.join("rve_points.json")).is_ok_and(|t| t.contains("time"))
}

fn started(d: &Path) -> bool {
    d.join("log.txt").is_file()
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// Group 2: the kill/resume harness over every kind. Each kind runs once uninterrupted, once
/// killed (SIGKILL) at a checkpoint; `sinterdem resume` then gives the uninterrupted files bit for
/// bit with a summary of the same kind, completed; a kind that writes no checkpoint (pair,
/// generate) is refused by `resume` with the reason, never exit 0.
#[test]
fn group2_every_kind_killed_at_a_checkpoint_resumes_to_the_uninterrupted_result_or_is_refused() {
    let d = common::tmp_dir("kill");
    // a two-particle copper compact of ~40 000 steps, checkpoints every 2000 steps
    std::fs::write(d.join("two.csv"), "x,y,z,r\n0,0,0,2.5e-5\n0,4.95e-5,0,2.5e-5\n").unwrap();
    let compact =
        common::compact_text("end = 2000.0\ndt = 1.0e-6\ndt_max = 0.05", &[common::COPPER], &common::file_particles(&d.join("two.csv")), common::AT_1293_K)
            .replace("hdf5 = false\n", "hdf5 = false\ncheckpoint_every = 2000\n");
    std::fs::write(d.join("compact.toml"), compact).unwrap();
    // the luding sample of tests/explicit_checkpoint.rs: two pressures, two sintering times
    std::fs::write(
        d.join("explicit.toml"),
        "kind = \"explicit_sinter\"\nmodel = \"luding\"\n[sample]\nparticles = 24\nseed = 3\nradius_spread = 0.2\ninitial_fraction = 0.3\n\
         [walls]\npressures = [5e3, 5e4]\n[protocol]\nt_prepare = 0.006\nt_heat = 0.002\nt_sinter = [0.001, 0.002]\nt_cool = 0.002\n\
         t_relax = 0.002\nt0_sinter = 0.004\noutput_interval = 0.0005\n[compression]\nstrain_rate = 4.0\nmax_strain = 0.01\n\
         output_strain = 0.001\n[stepping]\ndt_fraction = 0.1\n[output]\ncheckpoint_every = 500\n",
    )
    .unwrap();
    let p = |f: &str| d.join(f).to_string_lossy().into_owned();
    let mut runs = vec![
        KindRun {
            name: "heat",
            args: strings(&[
                "run",
                "cases/hot-plate.toml",
                "--set",
                "particles.cells=[3, 3, 4]",
                "--set",
                "time.end=600",
                "--set",
                "output.checkpoint_every=50",
            ]),
            same: &["series.csv", "particles.pvd"],
            ready: has_checkpoint,
            resumes: true,
        },
        KindRun { name: "compact", args: vec!["run".into(), p("compact.toml")], same: &["series.csv"], ready: has_checkpoint, resumes: true },
        KindRun {
            name: "rve",
            args: strings(&[
                "rve",
                "cases/rve-copper.toml",
                "--set",
                "time.end=60.0",
                "--set",
                "rve.at=[20.0, 60.0]",
                "--set",
                "output.snapshots=0",
                "--set",
                "output.conductivity_at=[]",
                "--set",
                "output.checkpoint_every=3",
            ]),
            same: &["series.csv", "constitutive.csv", "fit.json", "rve_points.json"],
            ready: has_rve_point,
            resumes: true,
        },
        KindRun { name: "pair", args: strings(&["run", "cases/pair-copper.toml"]), same: &[], ready: started, resumes: false },
        KindRun {
            name: "generate",
            args: strings(&["generate", "cases/green-copper.toml", "--set", "packing.particles=400"]),
            same: &[],
            ready: started,
            resumes: false,
        },
    ];
    runs.push(KindRun {
        name: "explicit_sinter",
        args: vec!["run".into(), p("explicit.toml")],
        same: &["history_p5e4_ts0.002.csv", "compression_p5e4_ts0.002.csv", "forces_p5e3_ts0.001.csv"],
        ready: has_checkpoint,
        resumes: true,
    });
    let mut report = Vec::new();
    for k in &runs {
        let full = d.join(format!("{}-full", k.name));
        let work = d.join(format!("{}-work", k.name));
        let mut child = bin().arg("-q").args(&k.args).arg("--out").arg(&work).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        let t0 = Instant::now();
        while child.try_wait().unwrap().is_none() && !(k.ready)(&work) && t0.elapsed() < Duration::from_secs(120) {
            std::thread::sleep(Duration::from_millis(2));
        }
        let killed = child.try_wait().unwrap().is_none();
        if killed {
            child.kill().unwrap();
        }
        let _ = child.wait();
        let o = bin().args(["-q", "resume"]).arg(&work).output().unwrap();
        report.push(format!("{}: {}", k.name, if killed { "killed" } else { "finished before the kill" }));
        if !k.resumes {
            if killed {
                assert_ne!(o.status.code(), Some(0), "{}: a resume of a run without checkpoints must be refused", k.name);
                assert!(stderr(&o).contains("checkpoint"), "{}: {}", k.name, stderr(&o));
                assert!(!work.join("summary.json").exists() || json(&work.join("summary.json"))["completed"] != true, "{}", k.name);
            }
            continue;
        }
        assert!(killed || k.name != "rve", "the rve run must be killed before its end");
        assert!(o.status.success(), "{}: resume failed: {}", k.name, stderr(&o));
        let o = bin().arg("-q").args(&k.args).arg("--out").arg(&full).output().unwrap();
        assert!(o.status.success(), "{}: {}", k.name, stderr(&o));
        for f in k.same {
            let (a, b) = (std::fs::read(full.join(f)), std::fs::read(work.join(f)));
            assert!(a.is_ok() && a.as_ref().ok() == b.as_ref().ok(), "{}: {f} differs from the uninterrupted run (or is missing)", k.name);
        }
        let (sa, sb) = (json(&full.join("summary.json")), json(&work.join("summary.json")));
        assert_eq!(sb["kind"], sa["kind"], "{}: the summary's kind", k.name);
        assert_ne!(sb["completed"], false, "{}", k.name);
        if k.name == "rve" {
            assert_eq!(sb["kind"], "rve");
            for f in ["constitutive.png", "sintering_stress.png"] {
                assert!(work.join(f).is_file(), "rve: {f} missing after the resume");
            }
            let hint = stderr(&bin().args(["resume"]).arg(&work).output().unwrap());
            assert!(hint.contains("sinterdem rve CASE") && !hint.contains("sinterdem run CASE"), "{hint}");
        }
    }
    eprintln!("kill/resume harness: {}", report.join("; "));
}

/// Group 7 (checkpoints): a checkpoint changed after it was written (one digit) is refused by its
/// checksum; a contact re-pointed to a far particle, even with the checksum made good again, is
/// refused by the geometry check naming the pair.
#[test]
fn group7_a_changed_checkpoint_and_a_far_contact_are_refused() {
    let d = common::tmp_dir("ck");
    std::fs::write(d.join("three.csv"), "x,y,z,r\n0,0,0,2.5e-5\n0,4.95e-5,0,2.5e-5\n0,3e-4,0,2.5e-5\n").unwrap();
    let text =
        common::compact_text("end = 20.0\ndt = 1.0e-6\ndt_max = 0.05", &[common::COPPER], &common::file_particles(&d.join("three.csv")), common::AT_1293_K)
            .replace("hdf5 = false\n", "hdf5 = false\ncheckpoint_every = 50\n");
    std::fs::write(d.join("case.toml"), text).unwrap();
    let run = d.join("run");
    let o = bin().args(["-q", "run"]).arg(d.join("case.toml")).arg("--out").arg(&run).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::remove_file(run.join("summary.json")).unwrap();
    let good = std::fs::read_to_string(run.join("checkpoint.json")).unwrap();
    let resume = |text: &str| -> Output {
        let w: PathBuf = d.join("work");
        let _ = std::fs::remove_dir_all(&w);
        std::fs::create_dir_all(&w).unwrap();
        for e in std::fs::read_dir(&run).unwrap().flatten() {
            std::fs::copy(e.path(), w.join(e.file_name())).unwrap();
        }
        std::fs::write(w.join("checkpoint.json"), text).unwrap();
        bin().args(["-q", "resume"]).arg(&w).output().unwrap()
    };
    // one digit of the time changed
    let at = good.find("\"t\":").unwrap() + 4;
    let digit = good[at..].find(|c: char| c.is_ascii_digit()).unwrap() + at;
    let mut bad = good.clone().into_bytes();
    bad[digit] = if bad[digit] == b'1' { b'2' } else { b'1' };
    let o = resume(std::str::from_utf8(&bad).unwrap());
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("does not match its checksum"), "{}", stderr(&o));
    // the contact [0, 1] re-pointed to particle 2, 0.3 mm away, and sealed again
    let mut ck: serde_json::Value = serde_json::from_str(&good).unwrap();
    assert_eq!(ck["pairs"], serde_json::json!([[0, 1]]));
    ck["pairs"] = serde_json::json!([[0, 2]]);
    let o = resume(&sinterdem::io::seal_value(&ck));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("checkpoint.pairs[0] = [0, 2]") && stderr(&o).contains("centre distance"), "{}", stderr(&o));
    // the untouched checkpoint resumes
    let o = resume(&good);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Waits for `child` at most `limit`; kills it and returns None when it is still running.
fn wait_at_most(mut child: std::process::Child, limit: Duration) -> Option<Output> {
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Some(child.wait_with_output().unwrap())
}

/// Group 5 (hangs): an output time of 1e-310 s (inside the documented range) no longer spins in
/// the plot stage of the log-time axis; `--threads` above its maximum is refused before any
/// thread is spawned.
#[test]
fn group5_a_subnormal_output_time_ends_and_absurd_thread_counts_are_refused() {
    let d = common::tmp_dir("tiny");
    let child = bin()
        .args([
            "-q",
            "run",
            "cases/rve-copper.toml",
            "--set",
            "time.end=0.5",
            "--set",
            "output.conductivity_at=[1e-310]",
            "--set",
            "output.snapshots=0",
            "--out",
        ])
        .arg(d.join("out"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let o = wait_at_most(child, Duration::from_secs(120)).expect("a run with output.conductivity_at = [1e-310] hung");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("out/relative_density.png").is_file() && d.join("out/summary.json").is_file());
    let o = bin().args(["-q", "run", "cases/hot-plate.toml", "--threads", "1000000", "--out"]).arg(d.join("threads")).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("--threads = 1000000 is out of range") && stderr(&o).contains("4 per available core"), "{}", stderr(&o));
}

/// Group 6 (panics): `rve.interval = 1e-15` s, whose branch step is below the clock's resolution,
/// is refused by `check` and `rve` with the key (was an index panic in the branch runs); printing
/// into a full device or a closed pipe is an i/o error (exit 5), never a panic.
#[test]
fn group6_a_sub_resolution_rve_interval_and_a_failing_stdout_are_clear_errors() {
    let d = common::tmp_dir("interval");
    for cmd in ["check", "rve"] {
        let mut c = bin();
        c.args(["-q", cmd, "cases/rve-copper.toml", "--set", "rve.interval=1e-15"]);
        if cmd == "rve" {
            c.arg("--out").arg(d.join("out"));
        }
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{cmd}: {}", stderr(&o));
        assert!(stderr(&o).contains("rve.interval") && stderr(&o).contains("time resolution") && !stderr(&o).contains("panicked"), "{cmd}: {}", stderr(&o));
    }
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let neck = ["neck", "--r1", "1e-5", "--r2", "1e-5", "--overlap", "1e-7", "--kappa", "400"];
    let conductivity = ["conductivity", "cases/conductivity/periodic-random.toml"];
    for args in [&["keys"][..], &["check", "cases/hot-plate.toml"][..], &neck[..], &conductivity[..]] {
        let o = bin().args(args).stdout(full()).output().unwrap();
        assert_eq!(o.status.code(), Some(5), "{args:?} > /dev/full: {}", stderr(&o));
        assert!(stderr(&o).contains("standard output") && !stderr(&o).contains("panicked"), "{args:?}: {}", stderr(&o));
    }
    let mut child = bin().arg("keys").stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert!(!stderr(&o).contains("panicked") && o.status.code() != Some(101), "keys | (closed): {}", stderr(&o));
}

/// Issue 39 item 5: a run that fails part-way keeps what it computed. The library's alumina pair
/// at 1673 K (R = 0.5 µm, 3600 s) reaches the end of the two-cap geometry at y1/R ≈ 0.70: the
/// error says it is the model's validity limit, not the diffusion data; `series.csv` holds the
/// rows up to the failure, `summary.json` says `completed = false` with the error, and `log.txt`
/// has the error.
#[test]
fn issue39_a_failed_pair_run_keeps_its_rows_summary_and_error() {
    let d = common::tmp_dir("failed");
    std::fs::write(
        d.join("alumina.toml"),
        "kind = \"pair\"\n[pair]\nmaterial = \"alumina\"\nradius = 0.5e-6\noverlap = 0.0\nend_time = 3600.0\n[temperature]\nconstant = 1673.0\n",
    )
    .unwrap();
    let out = d.join("out");
    let o = bin().args(["-q", "run"]).arg(d.join("alumina.toml")).arg("--out").arg(&out).output().unwrap();
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("the end of the model's two-cap geometry") && stderr(&o).contains("not a data problem"), "{}", stderr(&o));
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let last: Vec<f64> = series.lines().last().unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    assert!(series.lines().count() > 10 && last[0] > 600.0 && last[0] < 3600.0 && last[2] > 0.68, "last row {last:?}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["completed"], false);
    assert!(common::rel(s["final_time_s"].as_f64().unwrap(), last[0]) < 1e-9, "{s}");
    assert!(common::rel(s["neck_ratio"].as_f64().unwrap(), last[2]) < 1e-9 && s["shrinkage"].as_f64().unwrap() > 0.05, "{s}");
    assert!(s["error"].as_str().is_some_and(|e| e.contains("two-cap geometry")), "{s}");
    let log = std::fs::read_to_string(out.join("log.txt")).unwrap();
    assert!(log.contains("error: model error") && log.contains("two-cap geometry"), "{log}");
}

/// Issue 38 group 8 (`--set` blame): an error of a key given twice by `--set` names the override
/// that was applied (the last), and an override of `materials.0.…` is named, not the
/// `[[materials]]` header's line of the file (the material checks name the element by its `name`).
#[test]
fn group8_an_error_names_the_set_that_gave_the_value() {
    let o = bin().args(["check", "cases/copper-compact.toml", "--set", "time.end=10", "--set", "time.end=-2"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("time.end = -2") && stderr(&o).contains("(set by --set time.end=-2)"), "{}", stderr(&o));
    let o = bin().args(["check", "cases/copper-compact.toml", "--set", "materials.0.poisson_ratio=0.9"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("poisson_ratio = 0.9") && stderr(&o).contains("(set by --set materials.0.poisson_ratio=0.9)"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("copper-compact.toml:"), "blamed the file: {}", stderr(&o));
    // a value from the file is still located in the file
    let d = common::tmp_dir("blame");
    let text = std::fs::read_to_string("cases/copper-compact.toml").unwrap().replacen("[time]\n", "[time]\nalpha = -3.0\n", 1);
    std::fs::write(d.join("case.toml"), text).unwrap();
    let o = bin().arg("check").arg(d.join("case.toml")).args(["--set", "time.end=10"]).output().unwrap();
    assert!(stderr(&o).contains("case.toml:") && stderr(&o).contains("time.alpha") && !stderr(&o).contains("set by --set"), "{}", stderr(&o));
}

/// Issue 38 group 8 (plots): a plot that cannot be written (its name taken by a folder) is a
/// warning in every kind — pair, generate and rve exited 5 while compact exited 0 — and the run's
/// data are complete; no temporary file of the failed plot is left behind.
#[test]
fn group8_a_plot_that_cannot_be_written_is_a_warning_in_every_kind() {
    let d = common::tmp_dir("plots");
    let runs: [(&str, Vec<&str>, &str, &[&str]); 4] = [
        ("pair", vec!["run", "cases/pair-copper.toml"], "neck_shrinkage.png", &["series.csv", "summary.json"]),
        (
            "generate",
            vec!["generate", "cases/green-copper.toml", "--set", "packing.particles=200"],
            "laminae.png",
            &["packing.csv", "laminae.csv", "summary.json"],
        ),
        (
            "rve",
            vec![
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
            ],
            "constitutive.png",
            &["constitutive.csv", "fit.json", "summary.json"],
        ),
        (
            "compact",
            vec!["run", "cases/copper-compact.toml", "--set", "time.end=20", "--set", "output.snapshots=0", "--set", "output.conductivity_at=[]"],
            "relative_density.png",
            &["series.csv", "summary.json"],
        ),
    ];
    for (name, args, png, data) in runs {
        let out = d.join(name);
        std::fs::create_dir_all(out.join(png)).unwrap();
        let o = bin().args(&args).arg("--out").arg(&out).output().unwrap();
        assert_eq!(o.status.code(), Some(0), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains("warning: plots not written") && stderr(&o).contains(png), "{name}: {}", stderr(&o));
        for f in data {
            assert!(out.join(f).is_file(), "{name}: {f} missing");
        }
        let left: Vec<String> = tree(&out).into_iter().filter(|f| f.contains(".tmp")).collect();
        assert!(left.is_empty(), "{name}: temporary files left: {left:?}");
    }
}

/// Issue 38 group 8 (periodic networks): two touching particles in a periodic box do not span it;
/// the tensor was −1.8e-17 W/(m K) along x with no word. Now `spans` says which axes the network
/// winds around, the tensor is exactly 0 along the others, and a warning says why. An SC lattice
/// (spanning every axis) has no such warning.
#[test]
fn group8_a_periodic_network_that_does_not_span_the_box_says_so() {
    let d = common::tmp_dir("span");
    std::fs::write(d.join("two.csv"), "x,y,z,r\n1e-4,1e-4,1e-4,2.5e-5\n1.495e-4,1e-4,1e-4,2.5e-5\n").unwrap();
    std::fs::write(
        d.join("case.toml"),
        "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n[particles]\nsource = \"file\"\nfile = \"two.csv\"\n\
         periodic_box = [4e-4, 4e-4, 4e-4]\n[conductivity]\nboundary = \"periodic\"\n",
    )
    .unwrap();
    let o = bin().arg("conductivity").arg(d.join("case.toml")).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["spans"], serde_json::json!([false, false, false]));
    for row in v["kappa_eff_W_per_mK"].as_array().unwrap() {
        for x in row.as_array().unwrap() {
            assert_eq!(x.as_f64(), Some(0.0), "{v}");
        }
    }
    assert!(stderr(&o).contains("does not span the periodic cell along x, y, z"), "{}", stderr(&o));
    assert!(v["warnings"].as_array().is_some_and(|w| w.iter().any(|w| w.as_str().unwrap().contains("does not span"))), "{v}");
    // the bundled random periodic packing spans every axis: no warning, positive diagonal
    let o = bin().args(["conductivity", "cases/conductivity/periodic-random.toml"]).output().unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["spans"], serde_json::json!([true, true, true]));
    assert!((0..3).all(|a| v["kappa_eff_W_per_mK"][a][a].as_f64().unwrap() > 1.0) && !stderr(&o).contains("does not span"), "{v}");
}

/// Issue 38 group 8 (box range): a periodic compact's box between 4 r_max and two largest reaches
/// 2·(2 r_max + g·r_mean) passed `check` and failed at t = 0 with a model error; now `check` and
/// the run refuse it as the range error of `particles.periodic_box`, and a box just above runs.
#[test]
fn group8_a_periodic_box_below_two_reaches_is_a_range_error() {
    let d = common::tmp_dir("reach");
    std::fs::write(
        d.join("p.csv"),
        "x,y,z,r\n2.5e-5,2.5e-5,2.5e-5,2.5e-5\n7.5e-5,2.5e-5,2.5e-5,2.5e-5\n2.5e-5,7.5e-5,2.5e-5,2.5e-5\n7.5e-5,7.5e-5,7.5e-5,2.5e-5\n",
    )
    .unwrap();
    let case = |l: f64| {
        format!(
            "kind = \"compact\"\n[time]\nend = 1.0\ndt = 1.0e-6\ndt_max = 0.5\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n[[materials]]\n{}\n\
             [particles]\nsource = \"file\"\nfile = \"p.csv\"\nperiodic_box = [{l:e}, {l:e}, {l:e}]\n[thermal]\nmode = \"isothermal\"\n\
             furnace = {{ profile = {} }}\n[contacts]\ngap_tolerance = 1.0e-3\n[mechanics]\nboundary = \"periodic\"\n[mechanics.cell]\n\
             components = \"normal\"\nxx = {{ stress = 0.0 }}\nyy = {{ stress = 0.0 }}\nzz = {{ stress = 0.0 }}\n",
            common::COPPER,
            common::AT_1293_K
        )
    };
    // two reaches: 2·(2·25 µm + 1e-3·25 µm) = 100.05 µm
    std::fs::write(d.join("narrow.toml"), case(1.00002e-4)).unwrap();
    for cmd in ["check", "run"] {
        let mut c = bin();
        c.args(["-q", cmd]).arg(d.join("narrow.toml"));
        if cmd == "run" {
            c.arg("--out").arg(d.join("out"));
        }
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{cmd}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("particles.periodic_box") && stderr(&o).contains("two largest reaches") && stderr(&o).contains("1.0005e-4"),
            "{cmd}: {}",
            stderr(&o)
        );
    }
    std::fs::write(d.join("wide.toml"), case(1.0006e-4)).unwrap();
    let o = bin().args(["-q", "check"]).arg(d.join("wide.toml")).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Issue 38 group 8 (rve at 300 K): copper does not creep at 300 K, so the branches' strain-rate
/// difference is exactly zero and K came out −inf ("non-finite constitutive value (-inf) at
/// quantity 0"). Now it is a model error that says what happened and what to do.
#[test]
fn group8_an_rve_where_nothing_creeps_says_why() {
    let d = common::tmp_dir("cold");
    let o = bin()
        .args(["-q", "rve", "cases/rve-copper.toml", "--set", "thermal.furnace.profile.constant=300.0", "--set", "time.end=20.0", "--set", "rve.at=[20.0]"])
        .args(["--set", "output.snapshots=0", "--set", "output.conductivity_at=[]", "--out"])
        .arg(d.join("out"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("did not creep measurably") && e.contains("300.0 K") && e.contains("rve.interval") && !e.contains("-inf"), "{e}");
}

/// Issue 38 group 8 (output times): `output.conductivity_at = [2, 1]` wrote two tensors at 2 s
/// (the second one labelled 1 s was taken at 2 s); `check` said ok. Now `check` and the run
/// refuse a list out of order, and both note times after `time.end` (never written).
#[test]
fn group8_output_times_are_checked_by_check_as_by_the_run() {
    let d = common::tmp_dir("times");
    let short = ["--set", "time.end=5", "--set", "output.snapshots=0", "--set", "rve.at=[5.0]"];
    for cmd in ["check", "run"] {
        let mut c = bin();
        c.args(["-q", cmd, "cases/rve-copper.toml"]).args(short).args(["--set", "output.conductivity_at=[2.0, 1.0]"]);
        if cmd == "run" {
            c.arg("--out").arg(d.join("out"));
        }
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{cmd}: {}", stderr(&o));
        assert!(stderr(&o).contains("output.conductivity_at.1") && stderr(&o).contains("increasing order"), "{cmd}: {}", stderr(&o));
    }
    let o = bin().args(["check", "cases/rve-copper.toml"]).args(short).args(["--set", "output.conductivity_at=[0.0, 1000.0]"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("output.conductivity_at: 1000 s after time.end = 5 s: not written"), "{}", stderr(&o));
}

/// Issue 38 group 8 (heat resume): a linear heat run at a fixed Δt factors its matrix once and
/// reuses it; resumed from a checkpoint it rebuilt the factor and counted it (`factorizations` 3
/// against 2). The summary of the resumed run now equals the uninterrupted one in every solver
/// count.
#[test]
fn group8_a_resumed_heat_run_counts_the_factorizations_of_the_uninterrupted_one() {
    let d = common::tmp_dir("factor");
    heat_case_in(&d);
    let text = std::fs::read_to_string(d.join("case.toml")).unwrap().replace("[[materials]]", "[output]\ncheckpoint_every = 2\n[[materials]]");
    std::fs::write(d.join("case.toml"), text).unwrap();
    let o = bin().args(["-q", "run"]).arg(d.join("case.toml")).arg("--out").arg(d.join("full")).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let w = d.join("w");
    std::fs::create_dir_all(&w).unwrap();
    for e in std::fs::read_dir(d.join("full")).unwrap().flatten() {
        if e.file_type().unwrap().is_file() && e.file_name() != "summary.json" {
            std::fs::copy(e.path(), w.join(e.file_name())).unwrap();
        }
    }
    let o = bin().args(["-q", "resume"]).arg(&w).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (json(&d.join("full/summary.json")), json(&w.join("summary.json")));
    assert_eq!(a["factorizations"], 2, "{a}");
    for k in ["factorizations", "steps", "final_time_s", "max_radiation_iterations", "steps_rejected"] {
        assert_eq!(a[k], b[k], "{k}");
    }
    assert_eq!(std::fs::read(d.join("full/series.csv")).unwrap(), std::fs::read(w.join("series.csv")).unwrap());
}

/// Issue 39 item 8: calibration bounds that exclude the starting value were accepted and the
/// start clamped to the nearer bound in silence; now `check` and `calibrate` refuse them naming
/// the parameter, the start and the bounds.
#[test]
fn issue39_calibration_bounds_that_exclude_the_start_are_refused() {
    let d = common::tmp_dir("bounds");
    let text = std::fs::read_to_string("cases/calibration/titanium-synthetic.toml").unwrap();
    let text = text[..text.find("[compact]").unwrap()].replacen("min = 1.0\n", "min = 100.0\n", 1);
    std::fs::write(d.join("calib.toml"), text).unwrap();
    std::fs::copy("cases/calibration/titanium-synthetic.csv", d.join("titanium-synthetic.csv")).unwrap();
    for cmd in ["check", "calibrate"] {
        let mut c = bin();
        c.args(["-q", cmd]).arg(d.join("calib.toml"));
        if cmd == "calibrate" {
            c.arg("--out").arg(d.join("out"));
        }
        let o = c.output().unwrap();
        assert_eq!(o.status.code(), Some(1), "{cmd}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("parameters[0].min (beta.d0_gb)") && e.contains("exclude the starting value 50.98") && e.contains("[100, 10000]"), "{cmd}: {e}");
    }
}

/// Issue 38 group 7 (rve) and issue 39 item 8 (constitutive.png): the rve points file is sealed
/// like a checkpoint — a digit changed in it was resumed with exit 0 into another
/// `constitutive.csv`; now refused, and the untouched file resumes to the uninterrupted table. The
/// plot of the same run labels at least two powers of ten on its log axis (it showed one: the
/// viscosities span less than a decade) and draws each fit in its data's colour.
#[test]
fn group7_the_rve_points_file_is_sealed_and_issue39_the_constitutive_plot_reads() {
    let d = common::tmp_dir("points");
    let full = d.join("full");
    let o = bin()
        .args(["-q", "rve", "cases/rve-copper.toml", "--set", "time.end=20.0", "--set", "rve.at=[10.0, 20.0]", "--set", "output.snapshots=0"])
        .args(["--set", "output.conductivity_at=[]", "--set", "output.checkpoint_every=3", "--out"])
        .arg(&full)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let copy = |to: &Path| {
        let _ = std::fs::remove_dir_all(to);
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(&full).unwrap().flatten() {
            if e.file_type().unwrap().is_file() && e.file_name() != "summary.json" {
                std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
            }
        }
    };
    let good = std::fs::read_to_string(full.join("rve_points.json")).unwrap();
    assert!(good.contains("\"points\"") && good.contains("content_sha256"), "{good}");
    // one digit of the first point's bulk viscosity changed
    let at = good.find("\"bulk_viscosity\":").unwrap() + 17;
    let mut bad = good.clone().into_bytes();
    bad[at] = if bad[at] == b'1' { b'2' } else { b'1' };
    let w = d.join("w");
    copy(&w);
    std::fs::write(w.join("rve_points.json"), &bad).unwrap();
    let o = bin().args(["-q", "resume"]).arg(&w).output().unwrap();
    assert_eq!(o.status.code(), Some(5), "{}", stderr(&o));
    assert!(stderr(&o).contains("rve_points.json") && stderr(&o).contains("does not match its checksum"), "{}", stderr(&o));
    copy(&w);
    let o = bin().args(["-q", "resume"]).arg(&w).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(full.join("constitutive.csv")).unwrap(), std::fs::read(w.join("constitutive.csv")).unwrap());

    // the plots of this run, as `rve` draws them
    let s = json(&full.join("summary.json"));
    let points: Vec<sinterdem::kinds::rve::Point> = serde_json::from_value(s["rve"]["rows"].clone()).unwrap();
    let r0 = json(&full.join("fit.json"))["r0_m"].as_f64().unwrap();
    let fit = sinterdem::kinds::rve::fit_rows(&points, r0, None);
    assert!(fit.is_ok(), "{fit:?}");
    let plots = sinterdem::kinds::rve::rve_plots(&("copper RVE".into(), String::new()), &points, &fit);
    let spec = plots.iter().find(|p| p.0 == "constitutive.png").unwrap().1.spec();
    let (lo, hi) = spec.y.range;
    let decades = (lo.log10().ceil() as i32..=hi.log10().floor() as i32).filter(|&e| 10f64.powi(e) >= lo && 10f64.powi(e) <= hi).count();
    assert!(decades >= 2, "y axis [{lo:e}, {hi:e}] holds {decades} power(s) of ten (labelled ticks)");
    let colour = |name: &str| spec.series.iter().find(|x| x.name.starts_with(name)).unwrap_or_else(|| panic!("{name}")).colour;
    let near = |a: [u8; 3], b: [u8; 3]| a.iter().zip(&b).all(|(x, y)| x.abs_diff(*y) <= 8);
    assert!(near(colour("bulk viscosity K"), colour("bulk, Skorohod")), "bulk fit in another colour");
    assert!(near(colour("shear viscosity G"), colour("shear, Skorohod")), "shear fit in another colour");
    assert!(!near(colour("bulk viscosity K"), colour("shear viscosity G")));
    let all: Vec<[u8; 3]> = spec.series.iter().map(|x| x.colour).collect();
    let mut unique = all.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), all.len(), "every series keeps a colour of its own (SVG dash keys)");
}

/// Issue 38 group 8 (lock holder): a second writer into a directory an `rve` run holds is told
/// "sinterdem rve" (was "sinterdem run").
#[test]
fn group8_the_lock_of_an_rve_run_names_rve() {
    let d = common::tmp_dir("lockname");
    let out = d.join("out");
    let mut child = bin()
        .args(["-q", "rve", "cases/rve-copper.toml", "--set", "time.end=60.0", "--set", "rve.at=[30.0, 60.0]", "--set", "output.snapshots=0", "--out"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !out.join("log.txt").is_file() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = bin().args(["-q", "run", "cases/hot-plate.toml", "--out"]).arg(&out).output().unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(o.status.code(), Some(5), "{}", stderr(&o));
    assert!(stderr(&o).contains("is being written by pid") && stderr(&o).contains("sinterdem rve"), "{}", stderr(&o));
}

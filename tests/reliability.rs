//! Issue 16 reproducers (fuzzing as a hostile user): every item is a test here that failed before
//! its fix. Items are numbered as in the issue.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `sinterdem check` through the library (the calls of its `Check` arm): Ok(description) or the
/// error text.
fn check(path: &Path, sets: &[&str]) -> Result<String, String> {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let base = path.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    sinterdem::config::load_case(path, &[]).and_then(|v| sinterdem::calibrate::check_file(&v, &sets, &base)).map_err(|e| e.to_string())
}

fn check_err(path: &Path, sets: &[&str]) -> String {
    match check(path, sets) {
        Ok(s) => panic!("{} with {sets:?} was accepted: {s}", path.display()),
        Err(e) => e,
    }
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sinterdem"))
}

const GENERATE: &str = r#"kind = "generate"
[packing]
particles = 60
box = [0.5e-3, 0.5e-3, 0.4e-3]
[packing.size]
distribution = "uniform"
mean_diameter = 50e-6
spread = 0.1
"#;

/// The copper compact on `packing.csv` beside the case, for 10 µs in steps of 1 µs.
fn compact_file() -> String {
    common::compact_text("end = 1e-5\ndt = 1e-6", &[common::COPPER], &common::file_particles(Path::new("packing.csv")), common::AT_1293_K)
}

const GOOD_CSV: &str = "x,y,z,r\n0,0,0,2.5e-5\n0,4.95e-5,0,2.5e-5\n";

const HEAT_PAIR: &str = r#"[time]
end = 10.0
dt = 1.0
[output]
snapshots = 0
vtu = false
hdf5 = false
[[materials]]
name = "copper"
preset = "copper-ivannikov2022"
[particles]
source = "pair"
radius = 25e-6
overlap = 0.05
initial_temperature = 293.15
[thermal.furnace]
profile = { constant = 293.1500000001 }
convection_coefficient = 10.0
"#;

fn compact_with(dir: &Path, csv: &[u8]) -> PathBuf {
    write(dir, "packing.csv", csv);
    write(dir, "case.toml", compact_file().as_bytes())
}

#[test]
fn item01_tiny_mean_diameter_is_refused_by_range() {
    let d = common::tmp_dir("i01");
    let c = write(&d, "gen.toml", GENERATE.as_bytes());
    assert!(check(&c, &[]).is_ok());
    let e = check_err(&c, &["packing.size.mean_diameter=5e-324"]);
    assert!(e.contains("packing.size.mean_diameter = 5e-324") && e.contains("[2e-9, 1]") && e.contains("(m)"), "{e}");
}

#[test]
fn item02_lamina_width_far_below_a_radius_is_refused() {
    let d = common::tmp_dir("i02");
    let c = write(&d, "gen.toml", GENERATE.as_bytes());
    for w in ["1e-300", "1e-12"] {
        let e = check_err(&c, &[&format!("packing.lamina_width={w}")]);
        assert!(e.contains("packing.lamina_width") && e.contains(w), "{e}");
    }
    // in range, but 1/2500 of the radius: an absurd number of laminae
    let e = check_err(&c, &["packing.lamina_width=1e-8"]);
    assert!(e.contains("packing.lamina_width") && e.contains("1/100 of the mean radius"), "{e}");
    assert!(check(&c, &["packing.lamina_width=25e-6"]).is_ok());
}

#[test]
fn item04_far_away_packing_coordinates_are_refused_with_their_line() {
    let d = common::tmp_dir("i04");
    let c = compact_with(&d, b"x,y,z,r\n1e300,0,0,2.5e-5\n1e300,4.95e-5,0,2.5e-5\n");
    let e = check_err(&c, &[]);
    assert!(e.contains("packing.csv, line 2") && e.contains("particles.position = 1e300") && e.contains("[-1000, 1000]"), "{e}");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    assert!(check(&c, &[]).is_ok());
}

/// A shortened `cases/luding-pressure.toml` (40 particles, one pressure, ms phases).
fn luding_short(out: &Path, extra: &[&str]) -> (serde_json::Value, Vec<String>) {
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/luding-pressure.toml");
    let mut cmd = bin();
    cmd.arg("run").arg(&case).arg("--out").arg(out).arg("--quiet");
    for s in [
        "protocol.t_prepare=0.003",
        "protocol.t_heat=0.001",
        "protocol.t_sinter=[0.001]",
        "protocol.t_cool=0.001",
        "protocol.t_relax=0.001",
        "protocol.t0_sinter=0.001",
        "compression.max_strain=0.005",
        "walls.pressures=[5e3]",
        "sample.particles=40",
    ]
    .iter()
    .chain(extra)
    {
        cmd.arg("--set").arg(s);
    }
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let csvs: Vec<String> = std::fs::read_dir(out)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "csv"))
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    assert!(!text.contains("null"), "null in summary.json: {text}");
    (serde_json::from_str(&text).unwrap(), csvs)
}

fn no_nan(csvs: &[String]) {
    for c in csvs {
        let low = c.to_ascii_lowercase();
        assert!(!low.contains("nan") && !low.contains("inf"), "NaN/inf in a CSV:\n{}", &c[..c.len().min(2000)]);
    }
}

#[test]
fn item05_luding_history_has_no_nan_without_contacts() {
    let d = common::tmp_dir("i05");
    let (_, csvs) = luding_short(&d, &[]);
    no_nan(&csvs);
}

#[test]
fn item06_luding_extremes_stay_finite() {
    let d = common::tmp_dir("i06");
    let (s, csvs) = luding_short(&d.join("tmelt"), &["luding.t_melt=1.0000000000000002"]);
    no_nan(&csvs);
    assert!(s["branches"][0]["stiffness_Pa"].as_f64().unwrap().is_finite());
    let (s, csvs) = luding_short(&d.join("mass"), &["walls.mass=1e6"]);
    no_nan(&csvs);
    let b = &s["branches"][0];
    assert!(b["max_force_cooled_N"].as_f64().is_some() && b["min_force_cooled_N"].as_f64().is_some(), "{b}");
    assert!(s["warnings"].as_array().unwrap().iter().any(|w| w.as_str().unwrap().contains("no contacts")), "{s}");
}

#[test]
fn item07_generate_mean_diameter_1e_300_refused_and_the_floor_runs_finite() {
    let d = common::tmp_dir("i07");
    let c = write(&d, "gen.toml", GENERATE.as_bytes());
    let e = check_err(&c, &["packing.size.mean_diameter=1e-300"]);
    assert!(e.contains("packing.size.mean_diameter = 1e-300"), "{e}");
    let o = bin().arg("generate").arg(&c).arg("--out").arg(d.join("out")).arg("--quiet").args(["--set", "packing.size.mean_diameter=2e-9"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("out/summary.json")).unwrap()).unwrap();
    let phi = s["solid_fraction"].as_f64().expect("solid_fraction is a number");
    assert!(phi > 0.3 && phi < 0.7, "{s}");
}

fn neck(args: &[&str]) -> (bool, String, String) {
    let o = bin().arg("neck").args(["--r1", "25e-6", "--r2", "25e-6", "--overlap", "1e-6", "--kappa", "400"]).args(args).output().unwrap();
    (o.status.success(), String::from_utf8_lossy(&o.stdout).to_string(), String::from_utf8_lossy(&o.stderr).to_string())
}

#[test]
fn item08_neck_checks_kappa2_and_contact_conductance() {
    for (flag, v) in [
        ("--kappa2", "nan"),
        ("--kappa2", "-3"),
        ("--kappa2", "0"),
        ("--contact-conductance", "nan"),
        ("--contact-conductance", "-1e-3"),
        ("--contact-conductance", "inf"),
    ] {
        let (ok, out, err) = neck(&[flag, v]);
        assert!(!ok, "{flag} {v} accepted: {out}");
        assert!(err.contains(flag) && err.contains("out of range"), "{err}");
    }
    let (ok, out, _) = neck(&["--kappa2", "200", "--contact-conductance", "1e-3"]);
    assert!(ok && !out.contains("null"), "{out}");
}

#[test]
fn item17_negative_numbers_are_values_and_get_the_range_answer() {
    let o = bin().arg("neck").args(["--r1", "-25e-6", "--r2", "25e-6", "--overlap", "1e-6", "--kappa", "400"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--r1 = -2.5e-5 is out of range"), "{err}");
}

#[test]
fn item09_steps_that_cannot_finish_are_refused() {
    let d = common::tmp_dir("i09");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    let e = check_err(&c, &["time.dt_max=1e-300"]);
    assert!(e.contains("time.dt_max"), "{e}");
    // in range, but 1e10 steps at the largest step
    let e = check_err(&c, &["time.end=10", "time.dt_max=1e-9"]);
    assert!(e.contains("time.dt_max") && e.contains("steps"), "{e}");
    let e = check_err(&c, &["time.dt_min=1e-3", "time.dt_max=1e-4"]);
    assert!(e.contains("time.dt_min") && e.contains("larger than time.dt_max"), "{e}");
    // dt_min above the default dt_max (10 s, strategy 2)
    let e = check_err(&c, &["time.dt_min=100"]);
    assert!(e.contains("time.dt_min") && e.contains("larger than time.dt_max = 10"), "{e}");
    // t + dt_min == t near the end time
    let e = check_err(&c, &["time.end=1e9", "time.dt_min=1e-9"]);
    assert!(e.contains("time.dt_min") && e.contains("resolution"), "{e}");
    let h = write(&d, "heat.toml", HEAT_PAIR.as_bytes());
    assert!(check(&h, &[]).is_ok());
    let e = check_err(&h, &["time.dt=1e-300"]);
    assert!(e.contains("time.dt = 1e-300"), "{e}");
    let e = check_err(&h, &["time.end=1e9", "time.dt=1e-3"]);
    assert!(e.contains("time.dt") && e.contains("1e12 steps"), "{e}");
}

#[test]
fn item10_keys_unused_in_the_mode_are_range_checked() {
    let d = common::tmp_dir("i10");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    for v in ["nan", "-1", "inf"] {
        let e = check_err(&c, &[&format!("particles.radius={v}")]);
        assert!(e.contains("particles.radius"), "{e}");
    }
    for k in ["convection_coefficient", "emissivity", "exposure"] {
        for v in ["nan", "-1"] {
            let e = check_err(&c, &[&format!("thermal.furnace.{k}={v}")]);
            assert!(e.contains(&format!("thermal.furnace.{k}")), "{e}");
        }
    }
}

#[test]
fn item11_lattice_beyond_the_memory_is_refused_with_an_estimate() {
    let d = common::tmp_dir("i11");
    let h = write(&d, "heat.toml", HEAT_PAIR.as_bytes());
    let sets = ["particles.source=lattice", "particles.lattice=fcc", "particles.cells=[200, 200, 200]", "particles.overlap=0.0"];
    let e = check_err(&h, &sets);
    assert!(e.contains("particles.cells") && e.contains("3.2e7 particles need about") && e.contains("GB"), "{e}");
}

#[test]
fn item12_tiny_radius_and_step_name_the_key_and_line() {
    let d = common::tmp_dir("i12");
    let c = compact_with(&d, b"x,y,z,r\n0,0,0,2.5e-5\n0,4.95e-5,0,1e-300\n");
    let e = check_err(&c, &[]);
    assert!(e.contains("packing.csv, line 3") && e.contains("particles.radius = 1e-300"), "{e}");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    let e = check_err(&c, &["time.dt=5e-324"]);
    assert!(e.contains("time.dt = 5e-324") && e.contains("(s)"), "{e}");
}

#[test]
fn item13_messages_name_line_key_and_print_tiny_values_short() {
    let d = common::tmp_dir("i13");
    let c = compact_with(&d, b"x,y,z,r,temperature\n0,0,0,2.5e-5,300\n0,4.95e-5,0,2.5e-5,-5\n");
    let e = check_err(&c, &[]);
    assert!(e.contains("line 3") && e.contains("particles.initial_temperature = -5"), "{e}");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    let e = check_err(&c, &["thermal.furnace.profile.constant=nan"]);
    assert!(e.contains("thermal.furnace.profile.constant = NaN") && !e.contains("profile.profile"), "{e}");
    let e = check_err(&c, &["particles.radius=5e-324"]);
    assert!(e.contains("5e-324") && e.len() < 200, "{e}");
    assert_eq!(sinterdem::error::fmt_value(1e-300), "1e-300");
    assert_eq!(sinterdem::error::fmt_value(293.15), "293.15");
}

#[test]
fn item14_byte_order_mark_accepted_and_header_required_as_documented() {
    let d = common::tmp_dir("i14");
    let mut csv = b"\xef\xbb\xbf".to_vec();
    csv.extend_from_slice(GOOD_CSV.as_bytes());
    let c = compact_with(&d, &csv);
    check(&c, &[]).unwrap();
    let mut toml = b"\xef\xbb\xbf".to_vec();
    toml.extend_from_slice(compact_file().as_bytes());
    let c = write(&d, "bom.toml", &toml);
    check(&c, &[]).unwrap();
    let c = compact_with(&d, b"0,0,0,2.5e-5\n0,4.95e-5,0,2.5e-5\n");
    let e = check_err(&c, &[]);
    assert!(e.contains("line 1") && e.contains("header"), "{e}");
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/case-file.md")).unwrap();
    assert!(!doc.contains("header optional"), "docs/case-file.md still says the CSV header is optional");
}

#[test]
fn item15_energy_balance_is_small_when_almost_no_heat_flows() {
    let d = common::tmp_dir("i15");
    let h = write(&d, "heat.toml", HEAT_PAIR.as_bytes());
    let o = bin().arg("run").arg(&h).arg("--out").arg(d.join("out")).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("out/summary.json")).unwrap()).unwrap();
    let q = s["heat_in_J"].as_f64().unwrap().abs();
    assert!(q < 1e-12, "this case is meant to move almost no heat: {q} J");
    let b = s["energy_balance_rel"].as_f64().unwrap();
    assert!(b < 1e-4, "energy balance {b} with {q} J of heat flow");
    assert!((sinterdem::heat::balance::energy_balance_rel(1.0, 1.5, 1.0, 1e3) - 0.5).abs() < 1e-12);
    // almost no flow: the floor 1e-6 × stored heat
    assert!((sinterdem::heat::balance::energy_balance_rel(1e-18, 2e-18, 2e-18, 1.0) - 1e-12).abs() < 1e-24);
}

#[test]
fn item16_non_regular_input_files_are_refused_at_once() {
    let d = common::tmp_dir("i16");
    let fifo = d.join("fifo.toml");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let (tx, rx) = std::sync::mpsc::channel();
    let f = fifo.clone();
    std::thread::spawn(move || tx.send(check(&f, &[])).unwrap());
    let r = rx.recv_timeout(std::time::Duration::from_secs(20)).expect("check of a FIFO blocked");
    let e = r.unwrap_err();
    assert!(e.contains("not a regular file"), "{e}");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    let t0 = std::time::Instant::now();
    let e = check_err(&c, &["particles.file=/dev/zero"]);
    assert!(e.contains("/dev/zero") && e.contains("not a regular file") && t0.elapsed().as_secs() < 5, "{e}");
    let e = check_err(&d, &[]);
    assert!(e.contains("directory"), "{e}");
}

/// Runs `cmd` with a time limit; Some(output) if it ended, None if it had to be killed.
fn run_with_limit(mut cmd: Command, secs: u64) -> Option<std::process::Output> {
    let mut child = cmd.stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let t0 = std::time::Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        if t0.elapsed().as_secs() >= secs {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

#[test]
fn item03_corrupted_checkpoints_are_refused_before_resuming() {
    let d = common::tmp_dir("i03");
    let c = compact_with(&d, GOOD_CSV.as_bytes());
    let run = d.join("run");
    let o =
        bin().arg("run").arg(&c).arg("--out").arg(&run).arg("--quiet").args(["--set", "time.end=10", "--set", "output.checkpoint_every=3"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let good: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("checkpoint.json")).unwrap()).unwrap();
    assert_eq!(good["pairs"].as_array().unwrap().len(), 1);
    let edits: Vec<(&str, serde_json::Value, &str)> = vec![
        ("pairs", serde_json::json!([[0, 99999]]), "checkpoint.pairs"),
        ("pairs", serde_json::json!([[1, 1]]), "checkpoint.pairs"),
        ("t", serde_json::json!(-1.0), "checkpoint.t"),
        ("t", serde_json::json!(1e9), "checkpoint.t"),
        ("dt", serde_json::json!(1e308), "checkpoint.dt"),
        ("dt", serde_json::json!(0.0), "checkpoint.dt"),
        ("dt", serde_json::json!(-1.0), "checkpoint.dt"),
        ("step", serde_json::json!(9223372036854775808u64), "checkpoint.step"),
        ("temperature", serde_json::json!([293.15, -5.0]), "checkpoint.temperature"),
        ("position", serde_json::json!([[0.0, 0.0, 0.0], [0.0, 1e300, 0.0]]), "checkpoint.position"),
        ("rotation", serde_json::json!([[0.0, 0.0, 0.0]]), "checkpoint.rotation"),
        ("dl_bar", serde_json::json!([]), "checkpoint.dl_bar"),
    ];
    for (k, v, needle) in edits {
        let dir = d.join(format!("edit-{k}-{}", v.to_string().replace(['[', ']', ',', ' '], "_")));
        std::fs::create_dir_all(&dir).unwrap();
        for f in ["series.csv", "log.txt"] {
            std::fs::copy(run.join(f), dir.join(f)).unwrap();
        }
        let mut ck = good.clone();
        ck[k] = v.clone();
        std::fs::write(dir.join("checkpoint.json"), sinterdem::io::seal_value(&ck)).unwrap();
        let mut cmd = bin();
        cmd.arg("resume").arg(&dir).arg("--quiet");
        let o = run_with_limit(cmd, 60).unwrap_or_else(|| panic!("resume with {k} = {v} did not finish within 60 s"));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "resume with {k} = {v}: exit {:?}\n{err}", o.status.code());
        assert!(err.contains(needle), "resume with {k} = {v}: \"{err}\" does not name {needle}");
    }
}

#[test]
fn item09_explicit_protocols_that_cannot_finish_are_refused() {
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/luding-pressure.toml");
    assert!(check(&case, &[]).is_ok());
    let e = check_err(&case, &["protocol.t_prepare=1e9"]);
    assert!(e.contains("protocol") && e.contains("steps"), "{e}");
    let e = check_err(&case, &["protocol.output_interval=1e-300"]);
    assert!(e.contains("protocol.output_interval") && e.contains("history rows"), "{e}");
    let t0 = std::time::Instant::now();
    assert!(check(&case, &["sample.particles=1000000"]).is_ok());
    assert!(t0.elapsed().as_secs() < 10, "check built the whole sample");
}

//! `explicit_sinter` runs checkpoint and resume like compact and heat runs: a run stopped right
//! after a checkpoint (in the preparation, in a branch's cool-down, in a compression test of the
//! second pressure) and resumed through the run API gives the uninterrupted run's CSV files byte
//! for byte and the same summary; a damaged or mismatched checkpoint is refused with the reason.

use sinterdem::kinds::explicit_sinter::run_explicit_from;
use sinterdem::kinds::{self, RunParams};
use std::path::Path;

mod common;

/// Two pressures, two sintering times: every stage of the protocol is crossed.
fn case(coupling: &str) -> toml::Value {
    format!(
        r#"
kind = "explicit_sinter"
model = "luding"
[sample]
particles = 24
seed = 3
radius_spread = 0.2
initial_fraction = 0.3
[walls]
pressures = [5e3, 5e4]
[protocol]
t_prepare = 0.006
t_heat = 0.002
t_sinter = [0.001, 0.002]
t_cool = 0.002
t_relax = 0.002
t0_sinter = 0.004
output_interval = 0.0005
[compression]
strain_rate = 4.0
max_strain = 0.01
output_strain = 0.001
[stepping]
dt_fraction = 0.1
[output]
checkpoint_every = 500
{coupling}
"#
    )
    .parse::<toml::Table>()
    .map(toml::Value::Table)
    .unwrap()
}

/// The text of every CSV file of a run directory, by name.
fn csv_files(dir: &Path) -> Vec<(String, String)> {
    let mut v: Vec<(String, String)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "csv"))
        .map(|p| (p.file_name().unwrap().to_string_lossy().to_string(), std::fs::read_to_string(&p).unwrap()))
        .collect();
    v.sort();
    v
}

fn without_wall_time(mut s: serde_json::Value) -> serde_json::Value {
    s.as_object_mut().unwrap().remove("wall_seconds");
    s
}

/// Runs `value` whole, then stopped after each of `stops` steps and resumed; returns the stages
/// the stops fell in.
fn resumed_equals_whole(name: &str, value: &toml::Value, stops: &[u64]) -> Vec<String> {
    let dir = common::tmp_dir(name);
    let params = RunParams { plots: false, ..Default::default() };
    let whole = kinds::run(value, &[], &dir.join("whole"), &params).unwrap();
    let whole_csv = csv_files(&dir.join("whole"));
    assert!(whole_csv.len() >= 12, "history, compression and forces of 4 branches: {:?}", whole_csv.iter().map(|c| &c.0).collect::<Vec<_>>());
    let mut stages = Vec::new();
    for &stop in stops {
        let part = dir.join(format!("part{stop}"));
        let r = run_explicit_from(value, &part, &mut |_| {}, Some(stop)).unwrap();
        assert!(r.is_null(), "the run ended before step {stop}");
        let ck: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(part.join("checkpoint.json")).unwrap()).unwrap();
        assert_eq!(ck["steps"], stop);
        stages.push(format!("{}:{}", ck["pressure_index"], ck["stage"]["stage"].as_str().unwrap()));
        let resumed = kinds::resume(&part, &RunParams::default()).unwrap();
        assert_eq!(resumed.kind, kinds::Kind::ExplicitSinter);
        let part_csv = csv_files(&part);
        assert_eq!(part_csv.len(), whole_csv.len());
        for ((na, a), (nb, b)) in part_csv.iter().zip(&whole_csv) {
            assert_eq!(na, nb);
            assert!(a == b, "{na} differs after resuming from step {stop}");
        }
        assert_eq!(without_wall_time(resumed.summary.clone()), without_wall_time(whole.summary.clone()), "stop at {stop}");
        let log = std::fs::read_to_string(part.join("log.txt")).unwrap();
        assert!(log.contains(&format!("resumed from the checkpoint at step {stop}")), "{log}");
    }
    stages
}

#[test]
fn an_explicit_run_resumed_from_its_checkpoint_equals_the_uninterrupted_run() {
    let stages = resumed_equals_whole("profile", &case(""), &[1000, 10000, 30000]);
    assert!(stages.iter().any(|s| s.starts_with("0:prepare")), "{stages:?}");
    assert!(stages.iter().any(|s| s.starts_with("1:")), "a stop in the second pressure: {stages:?}");
    assert!(stages.iter().any(|s| s.ends_with(":cool") || s.ends_with(":compress")), "a stop in a branch: {stages:?}");
}

#[test]
fn a_network_coupled_run_resumes_with_its_heat_networks() {
    let v = case("[coupling]\nmode = \"network\"\nheat_every = 20\nconductivity = 200.0\nspecific_heat = 1000.0");
    let stages = resumed_equals_whole("network", &v, &[10500]);
    assert!(stages.iter().any(|s| !s.ends_with(":prepare") && !s.ends_with(":start")), "{stages:?}");
}

#[test]
fn a_damaged_or_mismatched_checkpoint_is_refused_with_the_reason() {
    let dir = common::tmp_dir("bad");
    let part = dir.join("part");
    assert!(run_explicit_from(&case(""), &part, &mut |_| {}, Some(10000)).unwrap().is_null());
    let path = part.join("checkpoint.json");
    let good: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let refused = |edit: &dyn Fn(&mut serde_json::Value), want: &[&str]| {
        let mut bad = good.clone();
        edit(&mut bad);
        std::fs::write(&path, sinterdem::io::seal_value(&bad)).unwrap();
        let e = kinds::resume(&part, &RunParams::default()).unwrap_err().to_string();
        assert!(e.contains("checkpoint.json"), "{e}");
        for w in want {
            assert!(e.contains(w), "expected {w:?} in: {e}");
        }
    };
    // a trunk of another size than the case's sample
    refused(&|v| v["trunk"]["position"].as_array_mut().unwrap().truncate(20), &["trunk.position", "20 values", "expected 24"]);
    // a neighbour pair outside the sample
    refused(&|v| v["trunk"]["driver"]["pairs"][0] = serde_json::json!([3, 99]), &["trunk.driver.pairs", "(3, 99)"]);
    // a stage the case does not have
    refused(&|v| v["stage"] = serde_json::json!({"stage": "sinter", "k": 7}), &["the case has 2 sintering times"]);
    // a non-finite temperature (JSON null)
    refused(&|v| v["trunk"]["temperature"][0] = serde_json::Value::Null, &["invalid type: null"]);
    // another format
    refused(&|v| v["format"] = serde_json::json!("sinterdem-explicit-checkpoint-9"), &["sinterdem-explicit-checkpoint-9", "sinterdem-explicit-checkpoint-1"]);
    // a case that no longer parses
    refused(
        &|v| v["case_toml"] = serde_json::json!("kind = \"explicit_sinter\"\nmodel = \"luding\"\n[sample]\nparticles = -3\n"),
        &["case", "sample.particles"],
    );
    // not JSON at all
    std::fs::write(&path, "{\"format\": \"sinterdem-explicit-checkpoint-1\", \"case_toml\": ").unwrap();
    let e = kinds::resume(&part, &RunParams::default()).unwrap_err().to_string();
    // (a cut file has lost its checksum, the last member: refused before it is parsed)
    assert!(e.contains("checkpoint.json") && e.contains("has no checksum"), "{e}");
}

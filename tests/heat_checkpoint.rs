//! Heat runs checkpoint and resume like compact runs: a run stopped right after a checkpoint and
//! resumed through the run API gives the uninterrupted run's series.csv byte for byte and the
//! same summary (BDF2 with radiation, so the network's history and the loop state must carry).

use sinterdem::kinds::{self, RunParams};
use std::path::{Path, PathBuf};

mod common;

#[test]
fn a_heat_run_resumed_from_its_checkpoint_equals_the_uninterrupted_run() {
    let dir = common::tmp_dir("r");
    let case = sinterdem::config::load_case(Path::new("cases/hot-plate.toml"), &[]).unwrap();
    let sets: Vec<String> = ["time.end=120", "particles.cells=[4, 4, 6]", "output.snapshots=4", "output.checkpoint_every=25"].map(String::from).to_vec();
    let params = RunParams { base_dir: PathBuf::from("cases"), plots: false, ..Default::default() };
    let whole = kinds::run(&case, &sets, &dir.join("whole"), &params).unwrap();
    assert!(dir.join("whole/checkpoint.json").exists());
    // the same run stopped right after its checkpoint at step 50 (as if killed there) ...
    let value = kinds::resolve(&case, &sets).unwrap();
    let text = toml::to_string(&value).unwrap();
    let mut prep = sinterdem::scene::prepare(value, Path::new("cases")).unwrap();
    prep.source = Some((text, PathBuf::from("cases").canonicalize().unwrap()));
    let part = dir.join("part");
    let r = sinterdem::kinds::heat::run_from(prep, &part, false, &mut |_| {}, None, Some(50)).unwrap();
    assert!(r.is_null());
    let ck: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(part.join("checkpoint.json")).unwrap()).unwrap();
    assert_eq!(ck["state"]["steps"], 50);
    assert!(!ck["bdf2"].is_null(), "the BDF2 history is carried");
    // ... and resumed
    let resumed = kinds::resume(&part, &RunParams::default()).unwrap();
    assert_eq!(resumed.kind, kinds::Kind::Heat);
    assert_eq!(std::fs::read_to_string(part.join("series.csv")).unwrap(), std::fs::read_to_string(dir.join("whole/series.csv")).unwrap());
    for k in [
        "final_time_s",
        "steps",
        "energy_balance_rel",
        "heat_in_J",
        "stored_heat_J",
        "mean_temperature_K",
        "min_temperature_K",
        "max_temperature_K",
        "max_local_error_estimate_K",
        "snapshots",
    ] {
        assert_eq!(resumed.summary[k], whole.summary[k], "{k}");
    }
    assert_eq!(std::fs::read_to_string(part.join("particles.pvd")).unwrap(), std::fs::read_to_string(dir.join("whole/particles.pvd")).unwrap());
    // a damaged checkpoint is refused with the reason (in a run killed before its end: a finished
    // run, with its summary.json, has nothing to resume)
    std::fs::remove_file(part.join("summary.json")).unwrap();
    let mut bad = ck.clone();
    bad["state"]["t"] = serde_json::json!(-1.0);
    std::fs::write(part.join("checkpoint.json"), sinterdem::io::seal_value(&bad)).unwrap();
    let e = kinds::resume(&part, &RunParams::default()).unwrap_err().to_string();
    assert!(e.contains("checkpoint.json") && e.contains("t = -1"), "{e}");
}

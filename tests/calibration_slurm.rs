//! A packing-level calibration (`model = "compact"`) through the SLURM engine, against a real
//! single-node SLURM cluster on localhost started by `scripts/slurm-local.sh` (as in
//! tests/study_slurm.rs): every generation goes out as a job array, the calibration waits for it,
//! and the fit is bit-identical to the same fit on the local engine.
//!
//! `scripts/test-all.sh` starts the cluster once and passes `SINTERDEM_SLURM_DIR`; run alone, the
//! test starts (and stops) its own. Where the cluster cannot be started (not root, no apt-get),
//! the test says why and is skipped.

use std::path::Path;
use std::process::Command;

mod common;
mod slurm_cluster;
use slurm_cluster::{Cluster, repo};

fn cluster() -> Option<Cluster> {
    slurm_cluster::cluster("slurm calibration test", "slurm-cal")
}

fn setup(dir: &Path) {
    let text = std::fs::read_to_string(repo().join("cases/data/green-titanium.csv")).unwrap();
    let mut csv = String::from("x,y,z,r\n");
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.starts_with('x')) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        if v[0] < 1.6e-4 && v[1] < 1.6e-4 && v[2] < 1.6e-4 {
            csv.push_str(line);
            csv.push('\n');
        }
    }
    std::fs::write(dir.join("corner.csv"), csv).unwrap();
    std::fs::write(
        dir.join("compact.toml"),
        "kind = \"compact\"\n[time]\nend = 100.0\ndt = 1.0e-3\ndt_max = 10.0\n[[materials]]\nname = \"titanium-ivannikov2022\"\npreset = \"titanium-ivannikov2022\"\n\
         [particles]\nsource = \"file\"\nfile = \"corner.csv\"\n[thermal]\nmode = \"isothermal\"\nfurnace = { profile = { constant = 1373.0 } }\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("data.csv"),
        "id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\nA,6.4e-5,\"start 1273 K, heat 50 K/min to 1373 K, hold 3 min\",0.38,0.01,0.02,0.001\n",
    )
    .unwrap();
    let calib = "data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\nmodel = \"compact\"\nseed = 2\n[[parameters]]\nkey = \"beta.d0_gb\"\nmin = 1.0\nmax = 1.0e4\n\
                 [optimiser]\nswarm_size = 3\nswarm_iterations = 1\nlocal_iterations = 2\n[compact]\ncase = \"compact.toml\"\n";
    std::fs::write(dir.join("local.toml"), calib).unwrap();
    std::fs::write(
        dir.join("slurm.toml"),
        format!("{calib}engine = \"slurm\"\n[compact.slurm]\npartition = \"debug\"\ntime = \"00:10:00\"\nchunk = 2\npoll_seconds = 0.3\n"),
    )
    .unwrap();
}

fn calibration_json(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("calibration.json")).unwrap()).unwrap()
}

#[test]
fn packing_fit_through_slurm_matches_the_local_engine() {
    let Some(cluster) = cluster() else { return };
    let dir = common::tmp_dir("fit");
    setup(&dir);
    let run = |file: &str, out: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_sinterdem"))
            .arg("calibrate")
            .arg(dir.join(file))
            .arg("--out")
            .arg(dir.join(out))
            .env("SLURM_CONF", cluster.conf())
            .output()
            .unwrap();
        eprintln!("$ sinterdem calibrate {file}\n{}", String::from_utf8_lossy(&o.stderr));
        assert!(o.status.success());
    };
    run("local.toml", "local");
    let t0 = std::time::Instant::now();
    run("slurm.toml", "slurm");
    eprintln!("slurm engine: {:.1} s", t0.elapsed().as_secs_f64());
    let (l, s) = (calibration_json(&dir.join("local")), calibration_json(&dir.join("slurm")));
    assert_eq!(s["chi2"], l["chi2"]);
    assert_eq!(s["parameters"]["beta.d0_gb"]["value"], l["parameters"]["beta.d0_gb"]["value"]);
    assert_eq!(s["batches"], l["batches"]);
    // every generation was a job array of its own
    for b in s["batches"].as_array().unwrap() {
        let gdir = dir.join("slurm/compact-fit").join(format!("gen-{:04}-{}", b["batch"].as_u64().unwrap(), b["label"].as_str().unwrap()));
        let batch: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(gdir.join("slurm/batch-0.json")).unwrap()).unwrap();
        let runs = b["runs"].as_u64().unwrap() as usize;
        assert_eq!(batch["chunks"].as_array().unwrap().len(), runs.div_ceil(2), "{}", gdir.display());
    }
    std::fs::remove_dir_all(&dir).ok();
}

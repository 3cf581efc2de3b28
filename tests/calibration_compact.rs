//! `sinterdem calibrate --validate-compact`: the pair-calibrated material runs on a packing with
//! each chosen experiment's schedule, and the packing's shrinkage is reported beside the measured
//! and the pair's (Ivannikov et al. 2022 find packing and pair curves nearly indistinguishable).

mod common;

#[test]
fn validate_compact_runs_the_fitted_material_on_a_packing() {
    let dir = common::tmp_dir("v");
    // a corner of the bundled green titanium body
    let text = std::fs::read_to_string("cases/data/green-titanium.csv").unwrap();
    let mut csv = String::from("x,y,z,r\n");
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.starts_with('x')) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        if v[0] < 2.2e-4 && v[1] < 2.2e-4 && v[2] < 2.2e-4 {
            csv.push_str(line);
            csv.push('\n');
        }
    }
    std::fs::write(dir.join("corner.csv"), csv).unwrap();
    std::fs::write(
        dir.join("compact.toml"),
        "kind = \"compact\"\n[time]\nend = 100.0\ndt = 1.0e-3\ndt_max = 10.0\nsubsteps_allowed = 100\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n\
         [[materials]]\nname = \"titanium-ivannikov2022\"\npreset = \"titanium-ivannikov2022\"\n[particles]\nsource = \"file\"\nfile = \"corner.csv\"\n\
         [thermal]\nmode = \"isothermal\"\nfurnace = { profile = { constant = 1373.0 } }\n",
    )
    .unwrap();
    let schedule = "start 793 K, heat 20 K/min to 1373 K, hold 90 min, cool 20 K/min to 313 K";
    std::fs::write(
        dir.join("data.csv"),
        format!("id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\nE14B,6.66e-5,\"{schedule}\",0.54,0.01,0.0318,0.001\n"),
    )
    .unwrap();
    std::fs::write(
        dir.join("calib.toml"),
        "data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\nseed = 3\n[[parameters]]\nkey = \"beta.d0_gb\"\nmin = 10.0\nmax = 200.0\n\
         [optimiser]\nswarm_size = 2\nswarm_iterations = 1\nlocal_iterations = 1\n\
         [compact]\ncase = \"compact.toml\"\nexperiments = [\"E14B\"]\n",
    )
    .unwrap();
    let out = dir.join("out");
    sinterdem::calibrate::run_file(&dir.join("calib.toml"), &[], &out, true, false, true).unwrap();
    let case = std::fs::read_to_string(out.join("compact/case.toml")).unwrap();
    assert!(case.contains("phases") && case.contains("schedule"), "{case}");
    let v = std::fs::read_to_string(out.join("compact_validation.csv")).unwrap();
    let mut lines = v.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    assert_eq!(row[col("status")], "ok", "{v}");
    let pair: f64 = row[col("pair_shrinkage")].parse().unwrap();
    let compact: f64 = row[col("compact_shrinkage_mean")].parse().unwrap();
    // the packing runs the whole 10 320 s schedule (time.end follows the experiment), and its
    // shrinkage is of the pair's size (coordination and rearrangement make it differ somewhat)
    assert!(pair > 0.01 && compact > 0.5 * pair && compact < 2.0 * pair, "pair {pair}, compact {compact}");
}

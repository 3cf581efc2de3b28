//! The coupled loop end to end: a pair through the scheduler equals the free 7-DOF pair; thread
//! count does not change a bit; a run resumed from a checkpoint equals the uninterrupted run bit
//! for bit; strategies 1 and 2 agree; heat energy balance in a coupled run with a hot plate.

use sinterdem::coupled::{self, Simulation};
use std::path::{Path, PathBuf};

mod common;

/// A corner of the bundled green copper packing (particles with all coordinates below `edge`).
fn small_packing(dir: &Path, edge: f64) -> PathBuf {
    column_packing(dir, edge, edge)
}

/// A column of the bundled green copper packing: x, y below `edge`, z below `height`.
fn column_packing(dir: &Path, edge: f64, height: f64) -> PathBuf {
    let rows = common::green_copper_block(edge, height);
    assert!(rows.len() > 30, "{}", rows.len());
    common::write_block(dir, "small.csv", "x,y,z,r", rows.into_iter().map(|(l, _)| l))
}

fn compact_case(packing: &Path, sets: &[&str]) -> toml::Value {
    common::copper_compact(packing, 300.0, sets)
}

fn run_case(v: toml::Value, out: &Path) -> (serde_json::Value, Vec<f64>) {
    let sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    let s = sinterdem::kinds::compact::run(sim, out, false, &mut |_| {}).unwrap();
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let last: Vec<f64> = series.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
    (s, last)
}

#[test]
fn pair_through_the_scheduler_equals_the_free_pair() {
    let dir = common::tmp_dir("pair");
    let csv = dir.join("pair.csv");
    std::fs::write(&csv, "x,y,z,r\n0,0,0,25e-6\n50e-6,0,0,25e-6\n").unwrap();
    let v = compact_case(&csv, &["time.end=1000.0", "solver.rtol=1e-8"]);
    let mut log = Vec::new();
    let sim = coupled::prepare(v, Path::new("."), &mut |m| log.push(m.to_string())).unwrap();
    assert_eq!(sim.contacts.len(), 1);
    let out = dir.join("out");
    let s = sinterdem::kinds::compact::run(sim, &out, false, &mut |m| log.push(m.to_string())).unwrap();
    assert!(log.iter().any(|l| l.contains("mechanics is skipped")), "{log:?}");
    // the free pair, one integration over [0, 1000 s]; reference (docs/diffusion7.md §11) at 1000 s:
    // y1/R = 0.30939, ΔL/L0 = 1.571e-2
    let neck = s["neck_ratio"].as_f64().unwrap();
    assert!((neck / 0.30939 - 1.0).abs() < 2e-5, "{neck}");
    let pair_toml: toml::Value = toml::Value::Table(
        "kind = \"pair\"\n[pair]\nmaterial = \"copper-ivannikov2022\"\nradius = 25e-6\nend_time = 1000.0\n[temperature]\nconstant = 1293.0\n[solver]\nrtol = 1e-8\n"
            .parse()
            .unwrap(),
    );
    let spec = sinterdem::kinds::pair::parse_pair_case(&pair_toml).unwrap();
    let free = sinterdem::kinds::pair::run_pair(&spec, false, false).unwrap();
    let free_y1 = free.contact.y[0] / 25e-6;
    assert!((neck / free_y1 - 1.0).abs() < 1e-6, "scheduler {neck} vs free {free_y1}");
    // A stays, B approached by the free model's ΔL (the correction leaves y4, y7 unchanged): the
    // pair's extent, 100 µm at the start, shrank by exactly ΔL
    let sh = s["shrinkage_x"].as_f64().unwrap();
    let free_dl = free.contact.approach();
    assert!(sh > 0.0 && (sh * 100e-6 / free_dl - 1.0).abs() < 1e-6, "{} vs {free_dl}", sh * 100e-6);
}

#[test]
fn one_and_two_threads_are_bit_identical() {
    let dir = common::tmp_dir("threads");
    let csv = small_packing(&dir, 0.2e-3);
    let mut results = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let out = dir.join(format!("t{threads}"));
        let v = compact_case(&csv, &["time.end=100.0"]);
        let (s, last) = pool.install(|| run_case(v, &out));
        let pos = std::fs::read_to_string(out.join("series.csv")).unwrap();
        results.push((s["shrinkage_x"].clone(), s["neck_ratio"].clone(), s["steps"].clone(), last, pos));
    }
    assert_eq!(results[0].0, results[1].0);
    assert_eq!(results[0].1, results[1].1);
    assert_eq!(results[0].2, results[1].2);
    assert_eq!(results[0].3, results[1].3);
    assert_eq!(results[0].4, results[1].4, "series differ between 1 and 2 threads");
}

#[test]
fn resumed_run_is_bit_identical() {
    let dir = common::tmp_dir("resume");
    let csv = small_packing(&dir, 0.2e-3);
    let full = dir.join("full");
    let (s_full, _) = run_case(compact_case(&csv, &["time.end=200.0", "output.checkpoint_every=40"]), &full);
    // the same run, killed right after its checkpoint at step 80, then resumed
    let part = dir.join("part");
    let sim = coupled::prepare(compact_case(&csv, &["time.end=200.0", "output.checkpoint_every=40"]), Path::new("."), &mut |_| {}).unwrap();
    let r = sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(80)).unwrap();
    assert!(r.is_null());
    let ck = sinterdem::kinds::compact::read_checkpoint(&part).unwrap();
    assert_eq!(ck.step, 80);
    let s_res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in
        ["final_time_s", "steps", "shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "neck_ratio", "contacts", "rhs_evaluations", "mechanics"]
    {
        assert_eq!(s_full[key], s_res[key], "{key}");
    }
    // the mechanics met its tolerance at every step (a step whose warm start (B12) already met it
    // needs no Newton iteration)
    let m = &s_full["mechanics"];
    assert!(m["newton_iterations"].as_u64().unwrap() > 0);
    assert!(m["max_final_residual"].as_f64().unwrap() <= m["rtol"].as_f64().unwrap());
    let a = std::fs::read_to_string(full.join("series.csv")).unwrap();
    let b = std::fs::read_to_string(part.join("series.csv")).unwrap();
    assert_eq!(a, b, "series.csv of the resumed run differs");
    // the resumed run went on writing checkpoints; the last one restores the end state
    let (sim_a, _) = Simulation::from_checkpoint(&sinterdem::kinds::compact::read_checkpoint(&part).unwrap(), &mut |_| {}).unwrap();
    assert!(sim_a.step > 80 && sim_a.step < s_full["steps"].as_u64().unwrap());
}

#[test]
fn strategies_one_and_two_agree() {
    let dir = common::tmp_dir("strategies");
    let csv = small_packing(&dir, 0.2e-3);
    let (s2, _) = run_case(compact_case(&csv, &["time.end=300.0", "time.strategy=2"]), &dir.join("s2"));
    let (s1, _) = run_case(compact_case(&csv, &["time.end=300.0", "time.strategy=1", "time.dt_max=100.0"]), &dir.join("s1"));
    for key in ["shrinkage_x", "shrinkage_y", "shrinkage_z"] {
        let (a, b) = (s1[key].as_f64().unwrap(), s2[key].as_f64().unwrap());
        assert!(a > 0.0 && (a / b - 1.0).abs() < 0.02, "{key}: strategy 1 {a}, strategy 2 {b}");
    }
    assert!(s1["rejected_steps"].as_u64().unwrap() > 0);
}

/// A titanium compact on a hot plate (corner of the green packing, 7-DOF necks feed the
/// conductance): the bottom sinters more than the top, layer by layer, and the heat balance of
/// the coupled run closes to the radiation tolerance.
#[test]
fn hot_plate_compact_densifies_from_the_bottom_and_conserves_heat() {
    let dir = common::tmp_dir("hotplate");
    let csv = column_packing(&dir, 0.2e-3, 1.0);
    let v = compact_case(
        &csv,
        &[
            "time.end=300.0",
            "time.dt=1e-3",
            "time.substeps_allowed=20",
            "materials.0.preset=\"titanium-ivannikov2022\"",
            "materials.0.name=\"titanium\"",
            "thermal.mode=\"network\"",
            "thermal.furnace={ profile = { constant = 293.15 }, emissivity = 1.0, exposure = 0.5, exposed = { face = \"z+\" } }",
            "thermal.fixed=[{ region = { face = \"z-\" }, profile = { constant = 1373.0 } }]",
            "particles.initial_temperature=293.15",
            "contacts.neck=\"seven_dof\"",
        ],
    );
    let (s, _) = run_case(v, &dir.join("out"));
    let layers: Vec<f64> = s["layer_contact_shrinkage"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    for w in layers.windows(2) {
        assert!(w[0] > w[1], "densification not monotone from the plate up: {layers:?}");
    }
    let bal = s["energy_balance_rel"].as_f64().unwrap();
    assert!(bal < 1e-8, "coupled heat balance {bal:e}");
    assert!(s["max_temperature_K"].as_f64().unwrap() <= 1373.0 + 1e-9);
}

/// `time.stop_relative_density` ends the run at the first step whose relative density reaches
/// it: the summary says so, the density is at or above the threshold, and the step before was
/// below it (the last series rows straddle it).
#[test]
fn run_stops_at_the_relative_density_asked_for() {
    let dir = common::tmp_dir("stoprho");
    let csv = small_packing(&dir, 0.2e-3);
    let (full, _) = run_case(compact_case(&csv, &["time.end=300.0"]), &dir.join("full"));
    let (rho0, rho_end) = (full["relative_density_initial"].as_f64().unwrap(), full["relative_density"].as_f64().unwrap());
    let target = 0.5 * (rho0 + rho_end);
    let (s, last) = run_case(compact_case(&csv, &["time.end=300.0", &format!("time.stop_relative_density={target}")]), &dir.join("stop"));
    assert_eq!(s["completed"], serde_json::Value::Bool(false));
    assert!(s["stop_reason"].as_str().unwrap().contains("relative density"));
    let (t, rho) = (s["final_time_s"].as_f64().unwrap(), s["relative_density"].as_f64().unwrap());
    assert!(t < 300.0 && rho >= target, "t = {t}, rho = {rho}, target {target}");
    assert_eq!(last[5], rho);
    let series = std::fs::read_to_string(dir.join("stop/series.csv")).unwrap();
    let rows: Vec<Vec<f64>> = series.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    assert!(rows[rows.len() - 2][5] < target);
    assert_eq!(full["completed"], serde_json::Value::Bool(true));
}

/// A compact of equal spheres on an FCC lattice with the mechanics on: by symmetry every bonded
/// contact is loaded like every other, so each must shrink exactly as the free pair (the bonded
/// solve and the y4/y7 correction add nothing), and the centre lattice shrinks by the same strain.
#[test]
fn fcc_compact_of_equal_spheres_shrinks_like_the_free_pair() {
    let text = common::compact_text(&common::time_to(1000.0), &[common::COPPER], &common::fcc(2), common::AT_1293_K) + "[contacts]\ndetect_new = false\n";
    let v = common::case_value(&text, &[]);
    let mut sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    assert!(sim.contacts.len() > 50);
    let x0 = sim.x0.clone();
    while sim.t < sim.settings.end {
        sim.advance_step(&mut |_| {}).unwrap();
    }
    let pair_toml: toml::Value = toml::Value::Table(
        "kind = \"pair\"\n[pair]\nmaterial = \"copper-ivannikov2022\"\nradius = 25e-6\nend_time = 1000.0\n[temperature]\nconstant = 1293.0\n".parse().unwrap(),
    );
    let spec = sinterdem::kinds::pair::parse_pair_case(&pair_toml).unwrap();
    let free = sinterdem::kinds::pair::run_pair(&spec, false, false).unwrap();
    let free_strain = free.contact.approach() / 50e-6;
    assert!(free_strain > 0.01, "{free_strain}");
    let mut worst: f64 = 0.0;
    for (c, &[i, j]) in sim.contacts.state.iter().zip(&sim.contacts.pairs) {
        worst = worst.max((c.shrinkage() / free_strain - 1.0).abs());
        // the centres moved together by the same strain
        let p = &sim.prep.scene.particles.position;
        let (d0, d) = ((x0[j as usize] - x0[i as usize]).norm(), (p[j as usize] - p[i as usize]).norm());
        assert!(((1.0 - d / d0) / free_strain - 1.0).abs() < 1e-6, "centre strain {} vs {free_strain}", 1.0 - d / d0);
    }
    assert!(worst < 1e-6, "largest relative deviation of a contact's shrinkage from the free pair: {worst:e}");
}

/// The bundled hot-plate scene: densification and neck growth fall monotonically from the plate
/// to the radiating top, and the heat balance closes.
#[test]
fn bundled_hot_plate_scene_has_a_monotone_densification_gradient() {
    let dir = common::tmp_dir("hotplate-case");
    let v =
        sinterdem::config::load_case(Path::new("cases/hot-plate-compact.toml"), &["output.snapshots=0".into(), "output.checkpoint_every=0".into()]).unwrap();
    let sim = coupled::prepare(v, Path::new("cases"), &mut |_| {}).unwrap();
    let s = sinterdem::kinds::compact::run(sim, &dir, false, &mut |_| {}).unwrap();
    // measured: shrinkage 5.04 % at the bottom, 4.60 % at the top; neck ratio 0.496 and 0.479
    for (key, ratio) in [("layer_contact_shrinkage", 1.05), ("layer_neck_ratio", 1.02)] {
        let l: Vec<f64> = s[key].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        assert!(l.windows(2).all(|w| w[0] > w[1]), "{key} not monotone from the plate up: {l:?}");
        assert!(l[0] > ratio * l[4], "{key}: bottom {} vs top {}: no clear gradient", l[0], l[4]);
    }
    assert!(s["energy_balance_rel"].as_f64().unwrap() < 1e-8);
}

/// A 10:1 copper pair leaves the 7-DOF model's domain (the small sphere is absorbed) after some
/// hundred seconds: the run ends with the ModelError, after writing the summary of the last
/// completed step with `completed = false` and the reason.
#[test]
fn model_error_stops_the_run_with_a_summary() {
    let dir = common::tmp_dir("modelerror");
    let csv = dir.join("pair.csv");
    std::fs::write(&csv, "x,y,z,r\n0,0,0,25e-6\n27.5e-6,0,0,2.5e-6\n").unwrap();
    let v = compact_case(&csv, &["time.end=5000.0"]);
    let sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    let out = dir.join("out");
    let e = sinterdem::kinds::compact::run(sim, &out, false, &mut |_| {}).unwrap_err();
    assert!(matches!(e, sinterdem::error::Error::Model(_)), "{e}");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["completed"], serde_json::Value::Bool(false));
    let t = s["final_time_s"].as_f64().unwrap();
    assert!(t > 10.0 && t < 5000.0, "{t}");
    assert!(s["stop_reason"].as_str().unwrap().contains("model error"));
    assert!(s["neck_ratio"].as_f64().unwrap().is_finite() && s["shrinkage_x"].as_f64().unwrap() > 0.0);
}

/// `output.correction_histogram_at` writes the ΔL̄ of the step reaching that time, one row per
/// contact, whose mean is the one reported; the end of the run always gets one.
#[test]
fn correction_histograms_at_asked_times() {
    let dir = common::tmp_dir("histograms");
    let csv = small_packing(&dir, 0.2e-3);
    let (s, _) = run_case(compact_case(&csv, &["time.end=300.0", "output.correction_histogram_at=[100.0]"]), &dir.join("out"));
    let h = &s["correction_histograms"][0];
    assert_eq!(h["asked_time_s"].as_f64(), Some(100.0));
    let t = h["time_s"].as_f64().unwrap();
    assert!((100.0..=110.0).contains(&t), "{t}");
    let text = std::fs::read_to_string(dir.join("out/dl_bar_t100s.csv")).unwrap();
    assert!(text.starts_with("particle_a,particle_b,l0_m,dl_bar_m,dl_bar_rel\n"), "one plain header line");
    let rel: Vec<f64> = text.lines().skip(1).map(|l| l.split(',').nth(4).unwrap().parse().unwrap()).collect();
    assert!(rel.len() > 30);
    let mean = rel.iter().sum::<f64>() / rel.len() as f64;
    let reported = h["dl_bar_rel_mean"].as_f64().unwrap();
    assert!((mean - reported).abs() <= 1e-6 * h["dl_bar_rel_std"].as_f64().unwrap().max(1e-300), "{mean} vs {reported}");
    // the packing moves the contacts away from their own prediction, in both directions
    assert!(rel.iter().any(|&v| v > 0.0) && rel.iter().any(|&v| v < 0.0));
    assert!(dir.join("out/dl_bar_histogram_t100s.png").exists() && dir.join("out/dl_bar_end.csv").exists());
}

/// With HDF5 on: a run stopped right after a checkpoint resumes and its HDF5 file holds the
/// same snapshots as the uninterrupted run's; a file damaged by a kill in mid-write is moved
/// aside (logged) and the resumed run still ends with the same results.
#[cfg(feature = "h5")]
#[test]
fn resume_with_hdf5_snapshots_and_a_damaged_file() {
    let dir = common::tmp_dir("resume-h5");
    let csv = small_packing(&dir, 0.2e-3);
    let sets = ["time.end=200.0", "output.checkpoint_every=40", "output.hdf5=true", "output.snapshots=5"];
    let (s_full, _) = run_case(compact_case(&csv, &sets), &dir.join("full"));
    let count = |path: &Path| -> usize {
        // H5MD layout: one entry per snapshot along the first axis of every time-dependent element
        let f = hdf5_metno::File::open(path).unwrap();
        let n = f.dataset("particles/all/position/value").unwrap().shape()[0];
        assert_eq!(f.dataset("contacts/pairs/value").unwrap().shape()[0], n);
        assert_eq!(f.dataset("particles/all/position/time").unwrap().shape()[0], n);
        n
    };
    assert_eq!(count(&dir.join("full/sinterdem.h5")), 5);
    for damaged in [false, true] {
        let part = dir.join(format!("part-{damaged}"));
        let sim = coupled::prepare(compact_case(&csv, &sets), Path::new("."), &mut |_| {}).unwrap();
        assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(80)).unwrap().is_null());
        if damaged {
            std::fs::write(part.join("sinterdem.h5"), [0u8; 96]).unwrap();
        }
        let mut log = Vec::new();
        let s = sinterdem::kinds::compact::resume(&part, false, &mut |m| log.push(m.to_string())).unwrap();
        for key in ["steps", "shrinkage_x", "neck_ratio", "contacts"] {
            assert_eq!(s_full[key], s[key], "{key}");
        }
        let noted = log.iter().any(|l| l.contains("could not be reopened"));
        assert_eq!(noted, damaged, "{log:?}");
        assert_eq!(part.join("sinterdem.h5.damaged").exists(), damaged);
        // undamaged: every snapshot; damaged: those written after the checkpoint
        let n = count(&part.join("sinterdem.h5"));
        if damaged { assert!((1..5).contains(&n), "{n}") } else { assert_eq!(n, 5) }
    }
}

/// Steps are shortened to land exactly on the requested snapshot, conductivity and end times
/// (issue 14 item 6), without lowering the step controller's Δt: the run with outputs takes at
/// most one extra step per requested time.
#[test]
fn outputs_land_exactly_on_the_requested_times() {
    let dir = common::tmp_dir("landing");
    let csv = small_packing(&dir, 0.2e-3);
    let out = dir.join("with");
    let (s, _) = run_case(compact_case(&csv, &["time.end=200.0", "output.snapshots=5", "output.vtu=true", "output.conductivity_at=[33.0, 120.5]"]), &out);
    let pvd = std::fs::read_to_string(out.join("particles.pvd")).unwrap();
    let times: Vec<f64> = pvd.split("timestep=\"").skip(1).map(|t| t.split('"').next().unwrap().parse().unwrap()).collect();
    assert_eq!(times, vec![0.0, 50.0, 100.0, 150.0, 200.0]);
    let cond: Vec<f64> = s["conductivity"].as_array().unwrap().iter().map(|c| c["time_s"].as_f64().unwrap()).collect();
    assert_eq!(cond, vec![33.0, 120.5]);
    assert_eq!(s["final_time_s"].as_f64().unwrap(), 200.0);
    let (plain, _) = run_case(compact_case(&csv, &["time.end=200.0"]), &dir.join("without"));
    let (a, b) = (s["steps"].as_u64().unwrap(), plain["steps"].as_u64().unwrap());
    assert!(a >= b && a <= b + 6, "{a} steps with outputs, {b} without");
    // the trajectory stays within the step control's accuracy
    let (x, y) = (s["shrinkage_x"].as_f64().unwrap(), plain["shrinkage_x"].as_f64().unwrap());
    assert!((x / y - 1.0).abs() < 1e-3, "{x} vs {y}");
}

/// (H17b) in a compact run: `output.conductivity_at` on a body with cut faces (the bundled
/// periodic packing opened into a block) logs the cut-face warning once, lists it once in the
/// summary's `warnings`, and marks every faces-method result it concerns.
#[test]
fn conductivity_of_a_cut_body_carries_the_cut_face_warning_once() {
    let dir = common::tmp_dir("cut-face-run");
    let csv = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/data/periodic-copper-500.csv");
    let v = compact_case(&csv, &["time.end=20.0", "output.conductivity_at=[0.0, 10.0]", "output.snapshots=0"]);
    let sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    let mut log = Vec::new();
    let s = sinterdem::kinds::compact::run(sim, &dir.join("out"), false, &mut |m| log.push(m.to_string())).unwrap();
    assert_eq!(log.iter().filter(|l| l.starts_with("warning:") && l.contains("cut faces")).count(), 1, "{log:#?}");
    let listed: Vec<_> = s["warnings"].as_array().unwrap().iter().filter(|w| w.as_str().unwrap().contains("cut faces")).collect();
    assert_eq!(listed.len(), 1, "{}", s["warnings"]);
    let cond = s["conductivity"].as_array().unwrap();
    assert_eq!(cond.len(), 2);
    assert!(cond.iter().all(|c| c["warning"].as_str().unwrap().contains("cut faces")), "{cond:?}");
    let _ = std::fs::remove_dir_all(dir);
}

/// `mechanics.update_rank` (docs/coupled.md "Low-rank update of the factor"): new contacts served
/// by the Woodbury update of the kept factor give the same run within the Newton tolerance
/// (mechanics.rtol = 1e-6 of the scaled residual; the shrinkage agrees to 1e-6 relative), 1 and
/// 2 threads give the same bits, and a run resumed from a checkpoint repeats the uninterrupted
/// one bit for bit; a rank that is not an integer in [0, 2000] is a clear error.
#[test]
fn low_rank_update_is_exact_thread_safe_and_resumable() {
    let dir = common::tmp_dir("lowrank");
    let csv = small_packing(&dir, 0.2e-3);
    let sets = ["time.end=200.0", "output.checkpoint_every=40", "mechanics.update_rank=60"];
    let (s_off, _) = run_case(compact_case(&csv, &["time.end=200.0", "output.checkpoint_every=40", "mechanics.update_rank=0"]), &dir.join("off"));
    let mut series = Vec::new();
    let mut summaries = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let out = dir.join(format!("t{threads}"));
        let (s, _) = pool.install(|| run_case(compact_case(&csv, &sets), &out));
        series.push(std::fs::read_to_string(out.join("series.csv")).unwrap());
        summaries.push(s);
    }
    assert_eq!(series[0], series[1], "series differ between 1 and 2 threads");
    let s_on = &summaries[0];
    let updates = s_on["mechanics_profile"]["updates"].as_u64().unwrap_or(0);
    assert!(updates > 0, "no change of the bond set served by the update: {}", s_on["mechanics_profile"]);
    assert!(s_on["mechanics"]["factorizations"].as_u64().unwrap() < s_off["mechanics"]["factorizations"].as_u64().unwrap());
    assert_eq!(s_on["steps"], s_off["steps"]);
    for key in ["shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density"] {
        let (a, b) = (s_on[key].as_f64().unwrap(), s_off[key].as_f64().unwrap());
        assert!((a - b).abs() <= 1e-6 * b.abs(), "{key}: {a} with the update, {b} without");
    }
    // killed right after the checkpoint at step 80, then resumed
    let part = dir.join("part");
    let sim = coupled::prepare(compact_case(&csv, &sets), Path::new("."), &mut |_| {}).unwrap();
    assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(80)).unwrap().is_null());
    let s_res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in ["final_time_s", "steps", "shrinkage_x", "relative_density", "contacts", "mechanics"] {
        assert_eq!(s_on[key], s_res[key], "{key}");
    }
    for key in ["topology_changes", "updates"] {
        assert_eq!(s_on["mechanics_profile"][key], s_res["mechanics_profile"][key], "mechanics_profile.{key}");
    }
    assert_eq!(series[0], std::fs::read_to_string(part.join("series.csv")).unwrap(), "series.csv of the resumed run differs");
    for bad in ["mechanics.update_rank=1.5", "mechanics.update_rank=2001", "mechanics.update_rank=-1"] {
        let err = coupled::prepare(compact_case(&csv, &["time.end=200.0", bad]), Path::new("."), &mut |_| {}).err().expect(bad).to_string();
        assert!(err.contains("mechanics.update_rank"), "{bad}: {err}");
    }
}

/// Contacts kept unchanged by docs/diffusion7.md (T2) on a cooling branch: kept ones are counted,
/// the kept share makes the run no less exact than the integrated one within the tolerance, and
/// the decisions are the same on one and two threads and after a resume (their test reads the
/// checkpointed `Contact7::change_rate`).
#[test]
fn contacts_kept_by_t2_are_thread_and_resume_identical() {
    let dir = common::tmp_dir("kept");
    let csv = small_packing(&dir, 0.2e-3);
    let text = common::compact_text(
        &common::time_to(150.0),
        &[common::COPPER],
        &common::file_particles(&csv),
        "{ schedule = \"start 1293 K, hold 20 s, cool 600 K/min to 600 K\" }",
    );
    let case = |sets: &[&str]| common::case_value(&text, sets);
    let mut runs = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let out = dir.join(format!("t{threads}"));
        let (s, _) = pool.install(|| run_case(case(&["output.checkpoint_every=40"]), &out));
        runs.push((s, std::fs::read_to_string(out.join("series.csv")).unwrap()));
    }
    assert_eq!(runs[0].1, runs[1].1, "series differ between 1 and 2 threads");
    let s = &runs[0].0;
    let kept = s["contact_steps_skipped"].as_u64().unwrap();
    let contacts = s["contacts"].as_u64().unwrap();
    // below about 900 K (docs/diffusion7.md §7) every contact is kept: the last steps at 600 K
    assert!(kept >= 3 * contacts, "{kept} contact-steps kept of {contacts} contacts");
    // against every contact integrated: the same result within the tolerance's effect
    let (all, _) = run_case(case(&["solver.skip_unchanged=false"]), &dir.join("all"));
    assert_eq!(all["contact_steps_skipped"].as_u64(), Some(0));
    assert!(all["rhs_evaluations"].as_u64().unwrap() > s["rhs_evaluations"].as_u64().unwrap());
    for key in ["shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "neck_ratio"] {
        let (a, b) = (s[key].as_f64().unwrap(), all[key].as_f64().unwrap());
        assert!((a / b - 1.0).abs() < 1e-4, "{key}: kept {a}, all integrated {b}");
    }
    // killed after its checkpoint at step 80, resumed: the same run
    let part = dir.join("part");
    let sim = coupled::prepare(case(&["output.checkpoint_every=40"]), Path::new("."), &mut |_| {}).unwrap();
    assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(80)).unwrap().is_null());
    let s_res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in ["steps", "shrinkage_x", "relative_density", "neck_ratio", "rhs_evaluations", "contact_steps_skipped"] {
        assert_eq!(s[key], s_res[key], "{key}");
    }
    assert_eq!(runs[0].1, std::fs::read_to_string(part.join("series.csv")).unwrap(), "series.csv of the resumed run differs");
}

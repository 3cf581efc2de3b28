//! Thermal expansion of the particles in compact runs (docs/coupled.md "Thermal expansion",
//! (X1)–(X12)): α = 0 changes nothing, bit for bit; a compact heated uniformly without sintering
//! expands by exactly ε = α (T − T_ref) in every direction; with sintering, the sintering
//! shrinkage (X11) equals that of the run without expansion while the total differs by the
//! thermal strain; a hot plate expands the hot side more; a checkpointed run resumes bit for bit,
//! and 1 and 2 threads agree bit for bit;
//! bad values are rejected naming key, value, range and unit.

use sinterdem::config::apply_override;
use sinterdem::coupled::{self, Simulation};
use std::path::{Path, PathBuf};

mod common;

/// A box of the bundled green copper packing (x, y below `edge`, z below `height`).
fn packing(dir: &Path, edge: f64, height: f64) -> PathBuf {
    common::write_block(dir, "packing.csv", "x,y,z,r", common::green_copper_block(edge, height).into_iter().map(|(l, _)| l))
}

/// A copper compact in a furnace following `profile` (isothermal mode), with `sets` applied.
fn case(particles: &str, profile: &str, end: f64, sets: &[&str]) -> toml::Value {
    common::case_value(&common::compact_text(&common::time_to(end), &[common::COPPER], particles, profile), sets)
}

fn run(v: toml::Value, out: &Path) -> (serde_json::Value, String) {
    let sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    let s = sinterdem::kinds::compact::run(sim, out, false, &mut |_| {}).unwrap();
    (s, std::fs::read_to_string(out.join("series.csv")).unwrap())
}

fn f(s: &serde_json::Value, key: &str) -> f64 {
    s[key].as_f64().unwrap_or_else(|| panic!("summary lacks {key}"))
}

/// Heated from 293.15 K to 1293 K in 100 s, then held.
const RAMP: &str = "{ table = [[0.0, 293.15], [100.0, 1293.0], [300.0, 1293.0]] }";

/// `thermal_expansion = 0` gives the run without the key bit for bit (summary values and
/// series.csv), under a changing temperature with sintering and new contacts.
#[test]
fn zero_coefficient_is_bit_identical_to_no_key() {
    let dir = common::tmp_dir("zero");
    let p = packing(&dir, 0.2e-3, 0.2e-3);
    let (a, sa) = run(case(&common::file_particles(&p), RAMP, 200.0, &[]), &dir.join("none"));
    let (b, sb) = run(case(&common::file_particles(&p), RAMP, 200.0, &["materials.0.thermal_expansion=0.0"]), &dir.join("zero"));
    assert_eq!(sa, sb, "series.csv differs");
    for key in
        ["steps", "shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "neck_ratio", "contacts", "rhs_evaluations", "mechanics", "dl_bar_mean_m"]
    {
        assert_eq!(a[key], b[key], "{key}");
    }
    assert_eq!(b["thermal_expansion"], serde_json::Value::Bool(false));
    assert_eq!(f(&b, "thermal_strain"), 0.0);
    assert_eq!(b["sintering_shrinkage_x"], b["shrinkage_x"]);
    assert!(f(&a, "shrinkage_x") > 1e-3, "the comparison run sinters");
}

/// An FCC block and a corner of the random green packing heated uniformly from 293.15 K to 500 K
/// (where copper does not sinter: the run without expansion shrinks by 2e-12), α = 1.65e-5 1/K:
/// every extent grows by (1 + ε) with ε = α·206.85 K = 3.4130e-3 — the dilation (1 − s)/(1 − s₀)
/// against the run without expansion equals 1 + ε to 1e-12 —, the sintering shrinkage (X11) is
/// the run without expansion's, every bond's centre distance grew by ε, and the relative density
/// is unchanged.
#[test]
fn uniform_heating_without_sintering_expands_homogeneously_by_the_thermal_strain() {
    let dir = common::tmp_dir("uniform");
    let p = packing(&dir, 0.2e-3, 0.2e-3);
    let alpha = 1.65e-5;
    let eps = alpha * (500.0 - 293.15);
    let profile = "{ table = [[0.0, 293.15], [10.0, 500.0], [100.0, 500.0]] }";
    for (name, particles) in [("fcc", common::fcc(2)), ("random", common::file_particles(&p))] {
        let sets = ["mechanics.rtol=1e-12"];
        let (s0, series0) = run(case(&particles, profile, 100.0, &sets), &dir.join(format!("{name}-0")));
        let v = case(&particles, profile, 100.0, &["mechanics.rtol=1e-12", &format!("materials.0.thermal_expansion={alpha:e}")]);
        let mut sim = coupled::prepare(v.clone(), Path::new("."), &mut |_| {}).unwrap();
        assert!(sim.contacts.len() > 50, "{name}");
        let x0 = sim.x0.clone();
        while sim.t < sim.settings.end {
            sim.advance_step(&mut |_| {}).unwrap();
        }
        let (s, series) = run(v, &dir.join(format!("{name}-exp")));
        // series.csv has the expansion columns only with expansion (without they would repeat
        // shrinkage_* and be 0); the last row's sintering shrinkage is the run without's shrinkage
        let head = |t: &str| t.lines().next().unwrap().split(',').map(str::to_string).collect::<Vec<_>>();
        let (h, h0) = (head(&series), head(&series0));
        assert!(!h0.iter().any(|c| c.starts_with("sintering_shrinkage") || c == "thermal_strain"), "{h0:?}");
        let last: Vec<f64> = series.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        let last0: Vec<f64> = series0.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        for a in ["x", "y", "z"] {
            let k = h.iter().position(|c| *c == format!("sintering_shrinkage_{a}")).unwrap();
            let k0 = h0.iter().position(|c| *c == format!("shrinkage_{a}")).unwrap();
            assert!((last[k] - last0[k0]).abs() < 1e-12, "{name} {a}: {} vs {}", last[k], last0[k0]);
        }
        let k = h.iter().position(|c| c == "thermal_strain").unwrap();
        assert!((last[k] / eps - 1.0).abs() < 1e-13, "{name}: series thermal strain {}", last[k]);
        assert!((f(&s, "thermal_strain") / eps - 1.0).abs() < 1e-13, "{name}: thermal strain {} vs {eps}", f(&s, "thermal_strain"));
        assert!(f(&s0, "shrinkage_x").abs() < 1e-10, "{name}: no sintering at 500 K: {}", f(&s0, "shrinkage_x"));
        for a in ["x", "y", "z"] {
            let (total, without) = (f(&s, &format!("shrinkage_{a}")), f(&s0, &format!("shrinkage_{a}")));
            let dilation = (1.0 - total) / (1.0 - without);
            assert!((dilation - (1.0 + eps)).abs() < 1e-12, "{name} {a}: dilation {dilation} vs 1 + ε = {}", 1.0 + eps);
            let sint = f(&s, &format!("sintering_shrinkage_{a}"));
            assert!((sint - without).abs() < 1e-12, "{name} {a}: sintering shrinkage {sint} vs {without} without expansion");
        }
        assert!((f(&s, "relative_density") / f(&s0, "relative_density") - 1.0).abs() < 1e-12, "{name}: relative density");
        // every bond: d/d0 = 1 + ε (the 7-DOF approach at 500 K is below 1e-12 of d)
        let pos = &sim.prep.scene.particles.position;
        for &[i, j] in &sim.contacts.pairs {
            let (d0, d) = ((x0[j as usize] - x0[i as usize]).norm(), (pos[j as usize] - pos[i as usize]).norm());
            assert!((d / d0 - 1.0 - eps).abs() < 1e-11, "{name}: bond {i}–{j}: d/d0 − 1 = {} vs ε = {eps}", d / d0 - 1.0);
        }
    }
}

/// The corner of the random packing heated to 1293 K and sintered for 200 s, with and without
/// expansion (new contacts found on the way in both): the sintering shrinkage (X11) equals the
/// run without expansion's per axis, the total differs by the thermal strain ε = α·999.85 K =
/// 1.6498e-2, the relative density is the same. Tolerance 1e-7 relative: the expanded compact is
/// the unexpanded one scaled by 1 + ε (X7), so the runs differ only by the bonded solve's
/// tolerance (mechanics.rtol = 1e-6 of each step's load, set here below the compact default; measured
/// 9e-9 with the constant α, 1e-12 with rtol = 1e-10); the run with the bundled α(T) table meets the
/// same tolerance.
#[test]
fn sintering_shrinkage_equals_the_run_without_expansion_and_the_total_differs_by_the_thermal_strain() {
    let dir = common::tmp_dir("sinter");
    let p = packing(&dir, 0.2e-3, 0.2e-3);
    let (s0, _) = run(case(&common::file_particles(&p), RAMP, 300.0, &["mechanics.rtol=1e-6"]), &dir.join("without"));
    let alpha = 1.65e-5;
    let eps = alpha * (1293.0 - 293.15);
    let table = sinterdem::material::bundled_table("copper", sinterdem::material::Quantity::ThermalExpansion).unwrap();
    for (key, eps) in
        [(format!("materials.0.thermal_expansion={alpha:e}"), eps), ("materials.0.thermal_expansion_table=\"copper\"".into(), table.integral(293.15, 1293.0))]
    {
        let (s, _) = run(case(&common::file_particles(&p), RAMP, 300.0, &[&key, "mechanics.rtol=1e-6"]), &dir.join("with"));
        assert!((f(&s, "thermal_strain") / eps - 1.0).abs() < 1e-12, "{key}");
        assert_eq!(s["contacts"], s0["contacts"], "{key}: the same contacts form");
        for a in ["x", "y", "z"] {
            let without = f(&s0, &format!("shrinkage_{a}"));
            assert!(without > 5e-3, "{a}: {without}");
            let sint = f(&s, &format!("sintering_shrinkage_{a}"));
            assert!((sint / without - 1.0).abs() < 1e-7, "{key} {a}: sintering shrinkage {sint} vs {without} without expansion");
            // (1 − s_total) = (1 − s_without)(1 + ε): the total is the sintering shrinkage less ε
            let total = f(&s, &format!("shrinkage_{a}"));
            assert!(total < 0.0, "{key} {a}: the thermal strain outweighs 0.6 % sintering");
            assert!(((1.0 - total) / (1.0 - without) - (1.0 + eps)).abs() < 1e-9, "{key} {a}: total {total}");
        }
        assert!((f(&s, "relative_density") / f(&s0, "relative_density") - 1.0).abs() < 1e-8, "{key}");
    }
}

/// A two-particle compact (no bonded solve: B approaches A by the eigen-approach (X5), both moved
/// by the predictor (X7)) heated to 1293 K and sintered for 200 s: the sintering shrinkage along
/// the pair equals the unexpanded pair's to 1e-8 relative, and across it, where nothing sinters,
/// the pair dilates by exactly 1 + ε.
#[test]
fn two_particle_compact_expands_and_sinters_like_the_unexpanded_pair() {
    let dir = common::tmp_dir("pair");
    let csv = dir.join("pair.csv");
    std::fs::write(&csv, "x,y,z,r\n0,0,0,25e-6\n50e-6,0,0,25e-6\n").unwrap();
    let alpha = 1.65e-5;
    let eps = alpha * (1293.0 - 293.15);
    let (s0, _) = run(case(&common::file_particles(&csv), RAMP, 300.0, &[]), &dir.join("without"));
    let (s, _) = run(case(&common::file_particles(&csv), RAMP, 300.0, &[&format!("materials.0.thermal_expansion={alpha:e}")]), &dir.join("with"));
    let without = f(&s0, "shrinkage_x");
    assert!(without > 3e-3, "{without}");
    assert!((f(&s, "sintering_shrinkage_x") / without - 1.0).abs() < 1e-8, "{} vs {without}", f(&s, "sintering_shrinkage_x"));
    for a in ["y", "z"] {
        assert_eq!(f(&s0, &format!("shrinkage_{a}")), 0.0);
        assert!((f(&s, &format!("shrinkage_{a}")) + eps).abs() < 1e-12 * eps.max(1.0), "{a}: {}", f(&s, &format!("shrinkage_{a}")));
    }
}

/// A column of the green packing between a hot plate (z− face: 293.15 K → 800 K in 5 s) and a
/// face held at 293.15 K (z+), titanium (α = 8.6e-6 1/K), 60 s: a steady gradient through the
/// height. The bonds of the bottom fifth of the column lengthen more than those of the top fifth,
/// monotonically through the height, and in each fifth the mean bond strain d/d0 − 1 plus the
/// mean 7-DOF contact shrinkage (the sintering of the seed necks, 2–6e-4) equals the mean thermal
/// strain α(T̄_ij − 293.15 K) of the bonds' particles within 1 % of the bottom's (measured: 5e-4):
/// each layer expands by its own temperature, and the sintering is what the contacts report.
#[test]
fn hot_plate_expands_the_hot_side_more() {
    let dir = common::tmp_dir("plate");
    let p = packing(&dir, 0.2e-3, 1.0);
    let alpha = 8.6e-6;
    let ramp = "{ table = [[0.0, 293.15], [5.0, 800.0], [60.0, 800.0]] }";
    let text = format!(
        "kind = \"compact\"\n[time]\nend = 60.0\ndt = 1.0e-3\ndt_max = 1.0\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n\
         [[materials]]\nname = \"titanium\"\npreset = \"titanium-ivannikov2022\"\nthermal_expansion = {alpha:e}\n[particles]\nsource = \"file\"\nfile = \"{}\"\ninitial_temperature = 293.15\n\
         [thermal]\nmode = \"network\"\n\
         fixed = [{{ region = {{ face = \"z-\" }}, profile = {ramp} }}, {{ region = {{ face = \"z+\" }}, profile = {{ constant = 293.15 }} }}]\n\
         [contacts]\nneck = \"seven_dof\"\ndetect_new = false\n",
        p.display()
    );
    let v = toml::Value::Table(text.parse::<toml::Table>().unwrap());
    let mut sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    let x0 = sim.x0.clone();
    while sim.t < sim.settings.end {
        sim.advance_step(&mut |_| {}).unwrap();
    }
    let pt = &sim.prep.scene.particles;
    let (lo, hi) = (sim.planes.z, sim.planes.z + sim.extent0.z);
    // per fifth of the height (bond midpoints at the start): bond strain, ε of the bond, contact shrinkage
    let layers = 5;
    let mut acc = vec![(0.0, 0.0, 0.0, 0usize); layers];
    for (c, &[i, j]) in sim.contacts.state.iter().zip(&sim.contacts.pairs) {
        let (i, j) = (i as usize, j as usize);
        let z = 0.5 * (x0[i].z + x0[j].z);
        let k = (((z - lo) / (hi - lo) * layers as f64) as usize).min(layers - 1);
        acc[k].0 += (pt.position[j] - pt.position[i]).norm() / (x0[j] - x0[i]).norm() - 1.0;
        acc[k].1 += alpha * (0.5 * (pt.temperature[i] + pt.temperature[j]) - 293.15);
        acc[k].2 += c.shrinkage();
        acc[k].3 += 1;
    }
    let prof: Vec<[f64; 3]> = acc.iter().map(|&(s, e, c, n)| [s / n as f64, e / n as f64, c / n as f64]).collect();
    let (bottom, top) = (prof[0], prof[layers - 1]);
    assert!(bottom[1] > 3.0 * top[1] && top[1] > 0.0, "temperature gradient: mean ε bottom {} top {}", bottom[1], top[1]);
    assert!(prof.windows(2).all(|w| w[0][0] > w[1][0]), "bond strain not monotone from the plate up: {prof:?}");
    assert!(bottom[0] > 3.0 * top[0], "bond strain bottom {} vs top {}: the hot side must expand more", bottom[0], top[0]);
    for (k, l) in prof.iter().enumerate() {
        assert!(l[2] > 0.0 && l[2] < 0.2 * bottom[1], "layer {k}: contact shrinkage {} (little sintering below 800 K)", l[2]);
        assert!((l[0] + l[2] - l[1]).abs() < 0.01 * bottom[1], "layer {k}: bond strain {:e} + contact shrinkage {:e} vs mean ε {:e}", l[0], l[2], l[1]);
    }
}

/// A run with expansion on, stopped right after its checkpoint and resumed, ends bit-identical to
/// the uninterrupted run (the reference temperatures are rebuilt from the case, nothing else is
/// state).
#[test]
fn resumed_run_with_expansion_is_bit_identical() {
    let dir = common::tmp_dir("resume");
    let p = packing(&dir, 0.2e-3, 0.2e-3);
    let sets = ["time.end=200.0", "output.checkpoint_every=40", "materials.0.thermal_expansion_table=\"copper\""];
    let (full, series_full) = run(case(&common::file_particles(&p), RAMP, 200.0, &sets), &dir.join("full"));
    let part = dir.join("part");
    let sim = coupled::prepare(case(&common::file_particles(&p), RAMP, 200.0, &sets), Path::new("."), &mut |_| {}).unwrap();
    assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(80)).unwrap().is_null());
    let res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in ["steps", "shrinkage_x", "shrinkage_z", "sintering_shrinkage_y", "thermal_strain", "relative_density", "neck_ratio", "contacts"] {
        assert_eq!(full[key], res[key], "{key}");
    }
    assert_eq!(series_full, std::fs::read_to_string(part.join("series.csv")).unwrap());
    assert!(f(&full, "thermal_strain") > 1e-2);
    let (sim, _) = Simulation::from_checkpoint(&sinterdem::kinds::compact::read_checkpoint(&part).unwrap(), &mut |_| {}).unwrap();
    assert!(sim.expansion.as_ref().unwrap().reference_temperature.iter().all(|&t| t == 293.15));
}

/// With expansion on (bundled copper table, heating ramp, new contacts), 1 and 2 threads give the
/// same series.csv byte for byte.
#[test]
fn one_and_two_threads_are_bit_identical_with_expansion() {
    let dir = common::tmp_dir("threads");
    let p = packing(&dir, 0.2e-3, 0.2e-3);
    let mut series = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let v = case(&common::file_particles(&p), RAMP, 150.0, &["materials.0.thermal_expansion_table=\"copper\""]);
        let (s, text) = pool.install(|| run(v, &dir.join(format!("t{threads}"))));
        assert!(f(&s, "thermal_strain") > 1e-2);
        series.push(text);
    }
    assert_eq!(series[0], series[1], "series differ between 1 and 2 threads");
}

/// Bad values name the key, the value, the range and the unit.
#[test]
fn bad_expansion_input_is_rejected_with_key_value_range_and_unit() {
    let dir = common::tmp_dir("bad");
    let p = packing(&dir, 0.15e-3, 0.15e-3);
    let err = |set: &str| -> String {
        match coupled::prepare(case(&common::file_particles(&p), RAMP, 10.0, &[set]), Path::new("."), &mut |_| {}) {
            Ok(_) => panic!("{set} was accepted"),
            Err(e) => e.to_string(),
        }
    };
    for (set, want) in [
        ("materials.0.thermal_expansion=-1e-5", vec!["materials.copper.thermal_expansion = -1e-5", "[0, 0.001]", "1/K"]),
        ("materials.0.thermal_expansion=0.01", vec!["materials.copper.thermal_expansion = 0.01", "[0, 0.001]", "1/K"]),
        ("materials.0.thermal_expansion_table=[[300.0, 1.6e-5], [1300.0, 0.02]]", vec!["thermal_expansion_table[1]", "0.02", "(0, 1e-3]", "1/K"]),
        ("materials.0.thermal_expansion_table=[[300.0, 1.6e-5]]", vec!["thermal_expansion_table", "at least 2"]),
        ("materials.0.thermal_expansion_table=\"brass\"", vec!["thermal_expansion_table", "brass", "copper, titanium"]),
    ] {
        let e = err(set);
        for w in want {
            assert!(e.contains(w), "{set}: `{e}` lacks `{w}`");
        }
    }
    let mut v = case(&common::file_particles(&p), RAMP, 10.0, &["materials.0.thermal_expansion=1.6e-5"]);
    apply_override(&mut v, "materials.0.thermal_expansion_table=\"copper\"").unwrap();
    let e = coupled::prepare(v, Path::new("."), &mut |_| {}).err().unwrap().to_string();
    assert!(e.contains("thermal_expansion_table") && e.contains("not both"), "{e}");
}

/// Thermal expansion is a compact-run feature: a heat run whose material sets it says, in its log,
/// that it ignores the key (never silently).
#[test]
fn other_kinds_warn_that_they_ignore_thermal_expansion() {
    let dir = common::tmp_dir("heat-warning");
    let case = sinterdem::config::load_case(Path::new("cases/hot-plate.toml"), &[]).unwrap();
    let sets: Vec<String> =
        ["time.end=0.5", "output.snapshots=0", "output.vtu=false", "output.hdf5=false", "materials.0.thermal_expansion=8.6e-6"].map(String::from).to_vec();
    let params = sinterdem::kinds::RunParams { base_dir: PathBuf::from("cases"), plots: false, ..Default::default() };
    sinterdem::kinds::run(&case, &sets, &dir, &params).unwrap();
    let log = std::fs::read_to_string(dir.join("log.txt")).unwrap();
    assert!(log.contains("warning: materials.0.thermal_expansion is used by compact runs only; this heat run ignores it"), "log.txt:\n{log}");
    // the same key on a compact run is used, not warned about
    let compact = toml::Value::Table(
        "kind = \"compact\"\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\nthermal_expansion = 1.6e-5\n".parse::<toml::Table>().unwrap(),
    );
    assert!(sinterdem::kinds::compact_only_keys(&compact).is_empty());
}

//! `[mechanics] sliding` in compact runs (docs/mechanics.md "Viscous grain-boundary sliding"):
//! the free sintering of SC and FCC lattices is unchanged by sliding (no tangential force by
//! symmetry); `"none"` written out is the run without the key bit for bit; with sliding on, a
//! pressed random periodic cell resumes bit for bit and 1 and 2 threads agree; bad values are
//! errors naming key, value, range and unit.

use sinterdem::coupled;
use std::path::Path;

mod common;

use common::{advance_to_end as advance, periodic_copper_case as periodic_case, periodic_copper_particles as random_particles, run_compact as run};

/// SC (3³) and FCC (2³) lattices of touching copper spheres, free, 100 s at 1293 K: every bond is
/// loaded alike and the cell deforms affinely, so no bond shears and sliding (even at the
/// smallest factor read in the literature, 0.003, docs/decisions-mechanics.md 15) changes the
/// shrinkage by round-off only.
#[test]
fn lattice_free_sintering_is_unchanged_by_sliding() {
    for (lattice, cells) in [("sc", 3), ("fcc", 2)] {
        let particles = format!("source = \"lattice\"\nlattice = \"{lattice}\"\ncells = [{cells}, {cells}, {cells}]\nradius = 25e-6\noverlap = 0.0");
        let mut s = Vec::new();
        for sliding in [&[][..], &["mechanics.sliding=\"viscous\"", "mechanics.sliding_factor=0.003"][..]] {
            let mut sets = vec!["contacts.detect_new=false", "mechanics.rtol=1e-12"];
            sets.extend_from_slice(sliding);
            let mut sim = coupled::prepare(periodic_case(100.0, &particles, "components = \"all\"", &sets), Path::new("."), &mut |_| {}).unwrap();
            advance(&mut sim);
            if !sliding.is_empty() {
                let t = &sim.mechanics.tangential;
                assert_eq!(t.len(), sim.contacts.len());
                assert!(t.iter().all(|f| f.norm() < 1e-12), "{lattice}: a bond sheared: {:?}", t.iter().map(|f| f.norm()).fold(0.0, f64::max));
            }
            s.push(sim.shrinkage());
        }
        for a in 0..3 {
            assert!(s[0][a] > 5e-4 && (s[1][a] / s[0][a] - 1.0).abs() < 1e-9, "{lattice} axis {a}: {} with sliding, {} without", s[1][a], s[0][a]);
        }
    }
}

/// `sliding = "none"` written out is the run without the key, bit for bit (series and summary).
#[test]
fn sliding_none_is_the_elastic_link_bit_for_bit() {
    let dir = common::tmp_dir("sliding-none");
    let case = |sets: &[&str]| periodic_case(20.0, &random_particles(), "xx = { stress = -5.0e5 }", sets);
    let a = run(case(&[]), &dir.join("default"));
    let b = run(case(&["mechanics.sliding=\"none\""]), &dir.join("none"));
    for key in ["steps", "shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "periodic_cell"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    let sa = std::fs::read_to_string(dir.join("default/series.csv")).unwrap();
    assert_eq!(sa, std::fs::read_to_string(dir.join("none/series.csv")).unwrap());
    // and sliding changes the pressed cell
    let c = run(case(&["mechanics.sliding=\"viscous\"", "mechanics.sliding_factor=0.01"]), &dir.join("viscous"));
    assert_ne!(a["shrinkage_y"], c["shrinkage_y"]);
}

/// With sliding on, checkpoint and resume repeat the uninterrupted pressed cell bit for bit (the
/// stored tangential forces are in the checkpoint), and 1 and 2 threads give the same bits.
#[test]
fn sliding_resume_and_threads_are_bit_identical() {
    let dir = common::tmp_dir("sliding-resume");
    let sets = ["output.checkpoint_every=10", "mechanics.sliding=\"viscous\"", "mechanics.sliding_factor=0.01"];
    let case = || periodic_case(40.0, &random_particles(), "xx = { stress_table = [[0.0, 0.0], [40.0, -5.0e5]] }", &sets);
    let full = dir.join("full");
    let s_full = run(case(), &full);
    let part = dir.join("part");
    let sim = coupled::prepare(case(), Path::new("."), &mut |_| {}).unwrap();
    assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(25)).unwrap().is_null());
    let ck = sinterdem::kinds::compact::read_checkpoint(&part).unwrap();
    assert_eq!(ck.sliding_tangential.len(), ck.pairs.len());
    assert!(ck.sliding_tangential.iter().any(|f| f.iter().any(|v| *v != 0.0)));
    let s_res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in ["steps", "shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "contacts", "periodic_cell"] {
        assert_eq!(s_full[key], s_res[key], "{key}");
    }
    let a = std::fs::read_to_string(full.join("series.csv")).unwrap();
    assert_eq!(a, std::fs::read_to_string(part.join("series.csv")).unwrap(), "series.csv of the resumed run differs");
    let mut series = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let out = dir.join(format!("t{threads}"));
        let v = periodic_case(20.0, &random_particles(), "xx = { stress = -5.0e5 }", &sets[1..]);
        pool.install(|| run(v, &out));
        series.push(std::fs::read_to_string(out.join("series.csv")).unwrap());
    }
    assert_eq!(series[0], series[1], "1 and 2 threads differ");
}

fn error_of(v: toml::Value) -> String {
    match coupled::prepare(v, Path::new("."), &mut |_| {}) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

/// Bad values name the key, the value, the allowed range or values, and the unit.
#[test]
fn bad_sliding_values_are_clear_errors() {
    let case = |sets: &[&str]| periodic_case(10.0, &random_particles(), "", sets);
    let e = error_of(case(&["mechanics.sliding=\"slip\""]));
    assert!(e.contains("mechanics.sliding") && e.contains("slip") && e.contains("\"viscous\"") && e.contains("\"none\""), "{e}");
    for bad in ["0.0", "-1.0", "5e-4", "20.0"] {
        let e = error_of(case(&["mechanics.sliding=\"viscous\"", &format!("mechanics.sliding_factor={bad}")]));
        assert!(e.contains("mechanics.sliding_factor") && e.contains("[0.001, 10]"), "{bad}: {e}");
    }
    let e = error_of(case(&["mechanics.sliding_factor=0.5"]));
    assert!(e.contains("mechanics.sliding_factor") && e.contains("\"none\""), "{e}");
}

//! Periodic compact runs (`[mechanics] boundary = "periodic"`, docs/mechanics.md "Periodic
//! cell"): lattices of equal spheres sinter as the free pair in every normal component; a random
//! periodic packing sinters freely without mean stress, shrinks more along a compressive stress
//! than across it, and held at zero strain reports a tensile sintering stress; checkpoints,
//! threads and the errors of bad combinations.

use sinterdem::coupled;
use std::path::Path;

mod common;

use common::{
    PERIODIC_COPPER_BOX as BOX, advance_to_end as advance, periodic_copper_case as periodic_case, periodic_copper_particles as random_particles,
    run_compact as run,
};

/// The free copper pair (R = 25 µm, 1293 K) over `end` [s]: centre approach ΔL [m].
fn free_pair_approach(end: f64) -> f64 {
    let text = format!(
        "kind = \"pair\"\n[pair]\nmaterial = \"copper-ivannikov2022\"\nradius = 25e-6\nend_time = {end:?}\n[temperature]\nconstant = 1293.0\n[solver]\nrtol = 1e-12\n"
    );
    let spec = sinterdem::kinds::pair::parse_pair_case(&toml::Value::Table(text.parse().unwrap())).unwrap();
    sinterdem::kinds::pair::run_pair(&spec, false, false).unwrap().contact.approach()
}

/// Periodic SC and FCC lattices of touching equal spheres, free (zero stress on every normal
/// component): by symmetry every bond is loaded alike and the cell has no fluctuation, so each
/// axis shrinks by exactly the free pair's centre approach over the initial centre distance
/// 2R = 50 µm (1 − L/L0 = ΔL/d0), with no mean stress and no gauge reaction.
#[test]
fn lattices_shrink_in_every_axis_as_the_free_pair() {
    let end = 1000.0;
    let free = free_pair_approach(end) / 50e-6;
    assert!(free > 0.01, "{free}");
    for (lattice, cells) in [("sc", 3), ("fcc", 2)] {
        let particles = format!("source = \"lattice\"\nlattice = \"{lattice}\"\ncells = [{cells}, {cells}, {cells}]\nradius = 25e-6\noverlap = 0.0");
        let v = periodic_case(end, &particles, "components = \"normal\"", &["contacts.detect_new=false", "solver.rtol=1e-12", "mechanics.rtol=1e-12"]);
        let mut sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
        let per = if lattice == "sc" { 3 } else { 6 };
        assert_eq!(sim.contacts.len(), per * sim.prep.scene.particles.len(), "{lattice}: every bond across the faces found");
        advance(&mut sim);
        let s = sim.shrinkage();
        // the cell against the run's own contacts (the mechanics alone) and against the free pair
        let own = sim.contacts.state.iter().map(|c| c.approach()).sum::<f64>() / sim.contacts.len() as f64 / 50e-6;
        for a in 0..3 {
            assert!((s[a] / own - 1.0).abs() < 1e-9, "{lattice} axis {a}: cell {} vs contacts {own}", s[a]);
            assert!((s[a] / free - 1.0).abs() < 1e-9, "{lattice} axis {a}: cell {} vs free pair {free}", s[a]);
        }
        let cell = sim.cell.as_ref().unwrap();
        assert!(cell.gauge_reaction < 1e-9, "{}", cell.gauge_reaction);
        assert!(cell.stress.iter().all(|v| v.abs() < 1e-3), "{:?} Pa", cell.stress);
        // relative density from the cell: the particle volume is conserved
        let rho0 = sim.prep.scene.particles.radius.iter().map(|&r| sinterdem::units::sphere_volume(r)).sum::<f64>() / cell.matrix0().determinant();
        assert!((sim.relative_density() / (rho0 / (1.0 - free).powi(3)) - 1.0).abs() < 1e-8);
    }
}

/// The random periodic packing: free sintering (all six components) leaves the mean stress zero
/// to solver tolerance (against the held cell's mean stress, the scale of the bond forces); a uniaxial compressive stress of 1 MPa along x shrinks it more along x than
/// across and more than free sintering; held at zero strain rate the cell carries a tensile
/// mean stress.
#[test]
fn random_cell_free_pressed_and_constrained() {
    let dir = common::tmp_dir("periodic-random");
    let end = 200.0;
    // all six components free: the whole mean stress vanishes (with components = "normal" the
    // shears are held at zero strain and their reactions are reported instead)
    let free = run(periodic_case(end, &random_particles(), "components = \"all\"", &[]), &dir.join("free"));
    let pressed = run(periodic_case(end, &random_particles(), "xx = { stress = -1.0e6 }", &[]), &dir.join("pressed"));
    let held = run(
        periodic_case(end, &random_particles(), "xx = { strain_rate = 0.0 }\nyy = { strain_rate = 0.0 }\nzz = { strain_rate = 0.0 }", &[]),
        &dir.join("held"),
    );
    let f = |s: &serde_json::Value, k: &str| s[k].as_f64().unwrap_or_else(|| panic!("{k} in {s}"));
    let (fx, fy, fz) = (f(&free, "shrinkage_x"), f(&free, "shrinkage_y"), f(&free, "shrinkage_z"));
    println!("free: shrinkage {fx:.6e} {fy:.6e} {fz:.6e}, density {:.6}", f(&free, "relative_density"));
    assert!(fx > 1e-3 && fy > 1e-3 && fz > 1e-3);
    // isotropic within the packing's randomness
    assert!((fx - fy).abs() < 0.2 * fx && (fx - fz).abs() < 0.2 * fx);
    let stress = free["periodic_cell"]["mean_stress_Pa"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect::<Vec<_>>();
    let scale = held["periodic_cell"]["mean_normal_stress_Pa"].as_f64().unwrap();
    println!("free: mean stress {stress:?} Pa; held: mean stress {scale:e} Pa, tensor {}", held["periodic_cell"]["mean_stress_Pa"]);
    assert!(stress.iter().all(|s| s.abs() < 1e-9 * scale.abs()), "{stress:?} against {scale:e}");
    assert!(free["periodic_cell"]["gauge_reaction"].as_f64().unwrap() < 1e-6);
    let (px, py, pz) = (f(&pressed, "shrinkage_x"), f(&pressed, "shrinkage_y"), f(&pressed, "shrinkage_z"));
    println!("pressed 1 MPa along x: shrinkage {px:.6e} {py:.6e} {pz:.6e}");
    assert!(px > 1.2 * py && px > 1.2 * pz && px > 1.2 * fx, "{px} {py} {pz} free {fx}");
    // held: no shrinkage, a tensile mean stress (the bonds' eigenstress), and the sintering
    // stress (B23) of the contacts' capillary drive (M14): tensile, of order 0.1 MPa for 50 µm
    // copper (docs/mechanics.md "Sintering stress")
    assert!(f(&held, "shrinkage_x").abs() < 1e-12);
    assert!(scale > 0.0);
    let sigma_s = held["periodic_cell"]["sintering_stress_mean_Pa"].as_f64().unwrap();
    let sigma_free = free["periodic_cell"]["sintering_stress_mean_Pa"].as_f64().unwrap();
    println!("sintering stress (B23): held {sigma_s:e} Pa, free {sigma_free:e} Pa");
    assert!(sigma_s > 3e4 && sigma_s < 3e6, "{sigma_s:e} Pa");
}

/// Checkpoint and resume repeat the uninterrupted periodic run bit for bit (the cell, its stress
/// and the particles), and so do 1 and 2 threads.
#[test]
fn periodic_resume_and_threads_are_bit_identical() {
    let dir = common::tmp_dir("periodic-resume");
    let case = || periodic_case(60.0, &random_particles(), "xx = { stress_table = [[0.0, 0.0], [60.0, -5.0e5]] }", &["output.checkpoint_every=20"]);
    let full = dir.join("full");
    let s_full = run(case(), &full);
    let part = dir.join("part");
    let sim = coupled::prepare(case(), Path::new("."), &mut |_| {}).unwrap();
    assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(40)).unwrap().is_null());
    assert!(sinterdem::kinds::compact::read_checkpoint(&part).unwrap().cell.is_some());
    let s_res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in ["steps", "shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "neck_ratio", "contacts", "periodic_cell"] {
        assert_eq!(s_full[key], s_res[key], "{key}");
    }
    let a = std::fs::read_to_string(full.join("series.csv")).unwrap();
    assert_eq!(a, std::fs::read_to_string(part.join("series.csv")).unwrap(), "series.csv of the resumed run differs");
    let mut series = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let out = dir.join(format!("t{threads}"));
        let v = periodic_case(30.0, &random_particles(), "xx = { stress = -5.0e5 }", &[]);
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

/// Bad combinations name the key, the value and what is allowed.
#[test]
fn bad_periodic_cases_are_clear_errors() {
    let dir = common::tmp_dir("periodic-errors");
    let walled_file = common::write_block(&dir, "p.csv", "x,y,z,r", ["0,0,0,25e-6".to_string(), "50e-6,0,0,25e-6".into(), "100e-6,0,0,25e-6".into()]);
    // periodic mechanics without a periodic box
    let e = error_of(periodic_case(10.0, &common::file_particles(&walled_file), "", &[]));
    assert!(e.contains("mechanics.boundary") && e.contains("periodic_box"), "{e}");
    // stress and strain rate on the same component
    let e = error_of(periodic_case(10.0, &random_particles(), "yy = { stress = 0.0, strain_rate = 0.0 }", &[]));
    assert!(e.contains("mechanics.cell.yy") && e.contains("not both"), "{e}");
    // out of range, with unit
    let e = error_of(periodic_case(10.0, &random_particles(), "zz = { strain_rate = 5.0 }", &[]));
    assert!(e.contains("mechanics.cell.zz.strain_rate") && e.contains("1/s") && e.contains("[-1, 1]"), "{e}");
    let e = error_of(periodic_case(10.0, &random_particles(), "xx = { stress_table = [[10.0, 0.0], [5.0, 1.0]] }", &[]));
    assert!(e.contains("mechanics.cell.xx.stress_table[1]"), "{e}");
    // a shear without components = "all"; an unknown components value; an unknown boundary
    let e = error_of(periodic_case(10.0, &random_particles(), "xy = { stress = 0.0 }", &[]));
    assert!(e.contains("mechanics.cell.xy") && e.contains("\"all\""), "{e}");
    let e = error_of(periodic_case(10.0, &random_particles(), "components = \"some\"", &[]));
    assert!(e.contains("mechanics.cell.components") && e.contains("\"normal\""), "{e}");
    let e = error_of(periodic_case(10.0, &common::file_particles(&walled_file), "", &["mechanics.boundary=\"torus\""]));
    assert!(e.contains("mechanics.boundary") && e.contains("\"walls\""), "{e}");
    // a periodic box on a walled compact; [load] on a periodic cell; a cell table on walls
    let text = common::compact_text(&common::time_to(10.0), &[common::COPPER], &random_particles(), common::AT_1293_K);
    let e = error_of(common::case_value(&text, &[]));
    assert!(e.contains("particles.periodic_box") && e.contains("mechanics.boundary"), "{e}");
    let e = error_of(periodic_case(10.0, &random_particles(), "", &["load.mode=\"isostatic\"", "load.stress=1e6"]));
    assert!(e.contains("load") && e.contains("mechanics.cell"), "{e}");
    let text = common::compact_text(&common::time_to(10.0), &[common::COPPER], &common::file_particles(&walled_file), common::AT_1293_K)
        + "[mechanics]\n[mechanics.cell]\nxx = { stress = 0.0 }\n";
    let e = error_of(common::case_value(&text, &[]));
    assert!(e.contains("mechanics.cell") && e.contains("\"periodic\""), "{e}");
}

/// (M14) as the sintering stress (B23) uses it: at the state of docs/diffusion7.md §11 (copper,
/// 1293 K, R = 25 µm) the force F_s = v0/M_c, applied as a tension, stops the approach
/// (−(ẏ4 + ẏ7) = 0 to 1e-9 of v0), and it is the 4.3·10⁻⁴ N docs/diffusion7.md gives.
#[test]
fn load_response_gives_the_force_that_stops_a_contact() {
    use sinterdem::models::diffusion7::{ContactParams, Material, PathFactors, evaluate, load_response};
    let r = 25e-6;
    let y = [0.3 * r, r, 0.05 * r, 0.97 * r, r, 0.05 * r, 0.97 * r];
    let mut k = ContactParams::single(&Material::copper(), 0, PathFactors::default()).at(1293.0).unwrap();
    let (v0, m) = load_response(&y, &k).unwrap();
    let f_s = v0 / m;
    assert!(v0 > 0.0 && (f_s / 4.3e-4 - 1.0).abs() < 0.02, "v0 = {v0:e} m/s, M_c = {m:e} m/(N s), F_s = {f_s:e} N");
    k.normal_force = -f_s;
    let e = evaluate(&y, &k).unwrap();
    assert!((e.dydt[3] + e.dydt[6]).abs() < 1e-9 * v0, "{:e}", e.dydt[3] + e.dydt[6]);
}

/// `output.conductivity_at` of a periodic run writes the full tensor, and at t = 0 it is the
/// tensor `sinterdem conductivity` gives the same packing with `boundary = "periodic"` (the same
/// necks, minimum-image branch vectors and cell volume), to round-off.
#[test]
fn conductivity_tensor_of_a_periodic_run() {
    let dir = common::tmp_dir("periodic-kappa");
    let v = periodic_case(1.0, &random_particles(), "", &["output.conductivity_at=[0.0]"]);
    let sim = coupled::prepare(v.clone(), Path::new("."), &mut |_| {}).unwrap();
    let p = &sim.prep.scene.particles;
    let (pipes, branch) =
        sinterdem::heat::conductivity::periodic_pipes(p, nalgebra::Vector3::repeat(BOX), &sim.prep.scene.materials, &sim.prep.conductance).unwrap();
    let want = sinterdem::heat::conductivity::periodic(p, &pipes, &branch, nalgebra::Vector3::repeat(BOX)).unwrap();
    let s = run(v, &dir.join("out"));
    let got = &s["conductivity"][0];
    assert_eq!(got["method"], "periodic");
    for r in 0..3 {
        for c in 0..3 {
            let k = got["kappa_eff_W_per_mK"][r][c].as_f64().unwrap();
            assert!((k - want[(r, c)]).abs() < 1e-12 * want[(0, 0)], "κ[{r}][{c}] = {k} vs {}", want[(r, c)]);
        }
    }
    assert!(want[(0, 0)] > 100.0 && want[(0, 0)] < 140.0, "{want}");
}

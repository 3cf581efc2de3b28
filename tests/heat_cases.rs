//! End-to-end heat cases: lattice effective conductivity against the exact closed forms, the
//! faces method against its own closed form, rejection of bad case files with the key named, and
//! the hot-plate compact over six decades of Δt.

use sinterdem::config::{apply_override, load_case};
use sinterdem::kinds::conductivity;
use sinterdem::kinds::heat::run;
use sinterdem::scene::prepare;
use std::path::Path;

mod common;

fn case(text: &str, sets: &[&str]) -> toml::Value {
    let mut v: toml::Value = toml::Value::Table(text.parse::<toml::Table>().unwrap());
    for s in sets {
        apply_override(&mut v, s).unwrap();
    }
    v
}

const LATTICE: &str = r#"
[time]
end = 1.0
dt = 0.1
[[materials]]
name = "copper"
preset = "copper-ivannikov2022"
[particles]
source = "lattice"
lattice = "sc"
cells = [4, 4, 4]
radius = 1.0e-3
overlap = 0.1
[conductivity]
boundary = "periodic"
"#;

/// κ_eff = K/D (SC), √3 K/D (BCC), 2√2 K/D (FCC) for a periodic lattice (docs/heat-model.md "Effective conductivity"),
/// K with the lattice's crowding φ = 1, 4/3, 2 ((H8c)); with `multi_neck = "none"` the pair's K.
#[test]
fn periodic_lattices_match_the_closed_forms() {
    for (lat, factor, overlap, phi) in
        [("sc", 1.0, 0.3, 1.0), ("bcc", 3f64.sqrt(), 0.2, 4.0 / 3.0), ("fcc", 2.0 * 2f64.sqrt(), 0.3, 2.0), ("fcc", 2.0 * 2f64.sqrt(), 0.3, 1.0)]
    {
        let multi = if phi == 1.0 && lat == "fcc" { "none" } else { "fabric" };
        let v = case(LATTICE, &[&format!("particles.lattice=\"{lat}\""), &format!("particles.overlap={overlap}"), &format!("thermal.multi_neck=\"{multi}\"")]);
        let out = conductivity::run_case(v, Path::new(".")).unwrap();
        let r = 1.0e-3;
        let d = (2.0 - overlap) * r;
        let neck = sinterdem::neck::solve(r, r, 2.0 * r - d).unwrap();
        let law = sinterdem::heat::Conductance { multi_neck: sinterdem::heat::MultiNeck::Fabric, ..Default::default() };
        let k = law.pipe_crowded(394.0, 394.0, r, r, neck.a, [phi, phi]).pair;
        // the bound (H8d) holds dense lattices at the Hashin–Shtrikman value of their solid
        // fraction (FCC at h/r = 0.3: φ > 1, so κ_s); below it the closed form stands
        let exact = (factor * k / d).min(out["hashin_shtrikman_upper"].as_f64().unwrap() * 394.0);
        let t = &out["kappa_eff_W_per_mK"];
        for a in 0..3 {
            for b in 0..3 {
                let v = t[a][b].as_f64().unwrap();
                if a == b {
                    assert!((v / exact - 1.0).abs() < 1e-10, "{lat}: κ_{a}{b} = {v}, exact {exact}");
                } else {
                    assert!(v.abs() < 1e-10 * exact, "{lat}: off-diagonal κ_{a}{b} = {v}");
                }
            }
        }
        assert!((out["lattice_closed_form_W_per_mK"].as_f64().unwrap() / exact - 1.0).abs() < 1e-12);
    }
}

/// Faces method on a finite SC lattice: the exact nodal solution is linear between the two
/// layers, so Q = n_x n_y K ΔT/(n_z − 1), L_D = (n_z − 1) D and κ = n_x n_y K D / A with A the
/// bounding-box cross-section.
#[test]
fn faces_method_on_a_simple_cubic_block() {
    // the pair law: the closed form is the network of equal pipes (with the default
    // multi_neck = "fabric" the faces' particles, which miss their outer necks, get crowding 1/2
    // on the inward neck, (H8a))
    let v = case(LATTICE, &["conductivity.boundary=\"faces\"", "particles.cells=[3, 4, 6]", "particles.overlap=0.2", "thermal.multi_neck=\"none\""]);
    let out = conductivity::run_case(v, Path::new(".")).unwrap();
    let r = 1.0e-3;
    let d = 1.8 * r;
    let neck = sinterdem::neck::solve(r, r, 0.2 * r).unwrap();
    let k = sinterdem::heat::Conductance::default().pipe(394.0, 394.0, r, r, neck.a).pair;
    let ext = |n: f64| (n - 1.0) * d + 2.0 * r;
    let cells = [3.0, 4.0, 6.0];
    for (axis, item) in out["axes"].as_array().unwrap().iter().enumerate() {
        let (n_a, n_b) = (cells[(axis + 1) % 3], cells[(axis + 2) % 3]);
        let area = ext(n_a) * ext(n_b);
        let exact = n_a * n_b * k * d / area;
        let kappa = item["kappa"].as_f64().unwrap();
        assert!((kappa / exact - 1.0).abs() < 1e-10, "axis {axis}: {kappa} vs {exact}");
        let (qh, qc) = (item["q_hot"].as_f64().unwrap(), item["q_cold"].as_f64().unwrap());
        assert!((qh - qc).abs() < 1e-10 * qh);
    }
}

/// (H17a): a particle standing proud of the top face of an SC block (bonded to one top particle)
/// must not become the cold layer by itself. Before the face placement by coverage, the layer was
/// that particle alone and κ_z fell to a few per cent of the block's; now the face moves to the
/// block's top layer and κ_z is the block's closed form again (the proud particle is in the cold
/// layer at T_cold, outside the mean of L_D). The other axes keep their closed forms.
#[test]
fn a_particle_standing_proud_of_a_face_does_not_become_the_layer() {
    let dir = common::tmp_dir("faces-proud");
    let (r, d, cells) = (1.0e-3, 1.8e-3, [4usize, 4, 6]);
    let mut csv = String::from("x_m,y_m,z_m,radius_m\n");
    for i in 0..cells[0] {
        for j in 0..cells[1] {
            for k in 0..cells[2] {
                csv += &format!("{:e},{:e},{:e},{r:e}\n", r + i as f64 * d, r + j as f64 * d, r + k as f64 * d);
            }
        }
    }
    // on top of particle (1, 2, top), at the lattice distance
    csv += &format!("{:e},{:e},{:e},{r:e}\n", r + d, r + 2.0 * d, r + cells[2] as f64 * d);
    std::fs::write(dir.join("block.csv"), csv).unwrap();
    let text =
        LATTICE.replace("source = \"lattice\"\nlattice = \"sc\"\ncells = [4, 4, 4]\nradius = 1.0e-3\noverlap = 0.1", "source = \"file\"\nfile = \"block.csv\"");
    let v = case(&text, &["conductivity.boundary=\"faces\"", "thermal.multi_neck=\"none\""]);
    let out = conductivity::run_case(v, &dir).unwrap();
    let neck = sinterdem::neck::solve(r, r, 2.0 * r - d).unwrap();
    let k = sinterdem::heat::Conductance::default().pipe(394.0, 394.0, r, r, neck.a).pair;
    let ext = |n: usize| (n - 1) as f64 * d + 2.0 * r;
    for (axis, item) in out["axes"].as_array().unwrap().iter().enumerate() {
        let (n_a, n_b) = (cells[(axis + 1) % 3], cells[(axis + 2) % 3]);
        let exact = (n_a * n_b) as f64 * k * d / (ext(n_a) * ext(n_b));
        let kappa = item["kappa"].as_f64().unwrap();
        assert!((kappa / exact - 1.0).abs() < 1e-9, "axis {axis}: {kappa} vs {exact}: {item}");
    }
    let z = &out["axes"][2];
    assert!((z["cold_face_shift_m"].as_f64().unwrap() - d).abs() < 1e-12, "{z}");
    assert_eq!(z["cold_particles"].as_u64().unwrap(), 17, "{z}");
    assert!(z["cold_coverage"].as_f64().unwrap() > 0.9 && z["hot_face_shift_m"].as_f64().unwrap() == 0.0, "{z}");
}

fn expect_err(text: &str, sets: &[&str], needles: &[&str]) {
    let v = case(text, sets);
    let e = match prepare(v, Path::new(".")) {
        Ok(_) => panic!("accepted a bad case: {sets:?}"),
        Err(e) => e.to_string(),
    };
    for n in needles {
        assert!(e.contains(n), "error \"{e}\" does not mention \"{n}\"");
    }
}

#[test]
fn bad_case_files_are_rejected_naming_the_key() {
    expect_err(LATTICE, &["time.ned=3"], &["ned"]);
    expect_err(LATTICE, &["time.dt=-1"], &["time.dt", "-1", "[1e-15, 1e7]", "s"]);
    expect_err(LATTICE, &["materials.0.density=0"], &["materials.copper.density", "kg/m^3"]);
    expect_err(LATTICE, &["materials.0.conductivity=\"high\""], &["conductivity"]);
    expect_err(LATTICE, &["particles.overlap=0.7"], &["particles.overlap"]);
    expect_err(LATTICE, &["particles.lattice=\"hcp\""], &["particles.lattice", "hcp"]);
    expect_err(LATTICE, &["particles.radius=0"], &["particles.radius", "m"]);
    expect_err(LATTICE, &["particles.material=\"gold\""], &["particles.material", "gold"]);
    expect_err(LATTICE, &["thermal.mode=\"isothermal\""], &["thermal.mode"]);
    expect_err(
        LATTICE,
        &["thermal.mode=\"isothermal\"", "thermal.furnace.profile.constant=900", "thermal.furnace.emissivity=0.5"],
        &["thermal.mode", "isothermal"],
    );
    expect_err(LATTICE, &["thermal.furnace.profile.constant=-3"], &["thermal.furnace.profile", "K"]);
    expect_err(LATTICE, &["thermal.furnace.profile.constant=900", "thermal.furnace.emissivity=1.5"], &["thermal.furnace.emissivity", "[0, 1]"]);
    expect_err(LATTICE, &["thermal.conductance=\"magic\""], &["magic"]);
    expect_err(LATTICE, &["particles.initial_temperature=nan"], &["particles.initial_temperature"]);
    // keys only a compact run reads are refused, not ignored (checkpoints are read by heat runs
    // too: tests/heat_checkpoint.rs)
    expect_err(LATTICE, &["time.strategy=2"], &["time.strategy", "compact"]);
    expect_err(LATTICE, &["time.stop_relative_density=0.8"], &["time.stop_relative_density", "compact"]);
}

#[test]
fn bundled_cases_pass_check() {
    {
        let f = "cases/hot-plate.toml";
        let v = load_case(Path::new(f), &[]).unwrap();
        prepare(v, Path::new("cases")).unwrap();
    }
}

/// The hot-plate compact (shortened, smaller) from Δt = 1e-3 to 1e3 × the explicit limit
/// C/(2ΣK): finite, the energy balance closed to the radiation tolerance, temperatures between
/// the furnace and the plate (backward Euler is monotone).
#[test]
fn hot_plate_over_six_decades_of_time_step() {
    let sets: Vec<String> =
        ["particles.cells=[3, 3, 5]", "output.snapshots=0", "output.vtu=false", "output.hdf5=false"].iter().map(|s| s.to_string()).collect();
    let base = load_case(Path::new("cases/hot-plate.toml"), &sets).unwrap();
    let prep = prepare(base.clone(), Path::new("cases")).unwrap();
    let p = &prep.scene.particles;
    let mut sum_k = vec![0.0; p.len()];
    for (e, &[i, j]) in prep.pipes.pairs.iter().enumerate() {
        sum_k[i as usize] += prep.pipes.conductance[e];
        sum_k[j as usize] += prep.pipes.conductance[e];
    }
    let limit = (0..p.len()).map(|i| p.capacity[i] / (2.0 * sum_k[i])).fold(f64::INFINITY, f64::min);
    let dir = common::tmp_dir("hot-plate");
    for scheme in ["backward_euler", "bdf2", "crank_nicolson"] {
        for e in [-3, -1, 1, 3] {
            let dt = limit * 10f64.powi(e);
            let steps = 40.0;
            let v = {
                let mut v = base.clone();
                apply_override(&mut v, &format!("time.dt={dt:e}")).unwrap();
                apply_override(&mut v, &format!("time.end={:e}", dt * steps)).unwrap();
                apply_override(&mut v, &format!("time.scheme=\"{scheme}\"")).unwrap();
                // a hot plate held at a fixed 1273 K, so that every step sees a gradient
                apply_override(&mut v, "thermal.fixed.0.profile={ constant = 1273.0 }").unwrap();
                v
            };
            let prep = prepare(v, Path::new("cases")).unwrap();
            let s = run(prep, &dir, false, &mut |_| {}).unwrap();
            let bal = s["energy_balance_rel"].as_f64().unwrap();
            let (lo, hi) = (s["min_temperature_K"].as_f64().unwrap(), s["max_temperature_K"].as_f64().unwrap());
            assert!(bal < 1e-8, "{scheme} dt = {dt:e}: balance {bal:e}");
            assert!(lo.is_finite() && hi.is_finite());
            if scheme == "backward_euler" {
                assert!(lo >= 293.15 - 1e-9 && hi <= 1273.0 + 1e-9, "dt = {dt:e}: [{lo}, {hi}]");
            } else {
                assert!(lo > 200.0 && hi < 1400.0, "{scheme} dt = {dt:e}: [{lo}, {hi}]");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

//! User-defined diffusion materials in compact cases: `[[materials.phases]]` written in the case
//! or included from a file (a calibration's `material.toml`) run the same contact model as the
//! bundled preset, and change the result when their data change; bonds between particles of two
//! materials take their own elastic constants (two half-links in series).

use sinterdem::kinds::{self, RunParams};
use sinterdem::mechanics::bond::series_elastic;
use std::path::{Path, PathBuf};

mod common;

/// A corner of the bundled green copper packing, with a material column alternating 0, 1.
fn packing(dir: &Path, edge: f64) -> PathBuf {
    let rows = common::green_copper_block(edge, edge);
    assert!(rows.len() > 30, "{}", rows.len());
    let lines = rows.into_iter().enumerate().map(|(n, (_, v))| format!("{},{},{},{},{}", v[0], v[1], v[2], v[3], n % 2));
    common::write_block(dir, "packing.csv", "x,y,z,r,material", lines)
}

const COPPER_PHASE: &str = r#"
[[materials.phases]]
name = "fcc"
from_temperature = 0.0
atomic_volume = 1.18e-29
gamma_surface = 1.78
gamma_gb = 0.55
delta_surface = 0.23e-9
delta_gb = 0.69e-9
mobile_fraction_surface = 0.2
mobile_fraction_gb = 0.1
mobile_fraction_lattice = 1.0
d0_surface = 7.0e6
q_surface = 370.0e3
d0_gb = D0GB
q_gb = 500.0e3
d0_lattice = 6.2e-5
q_lattice = 207.0e3
"#;

/// A compact case with two materials `a` and `b` (TOML bodies of `[[materials]]` entries).
fn case(packing: &Path, a: &str, b: &str) -> toml::Value {
    common::case_value(&common::compact_text(&common::time_to(200.0), &[a, b], &common::file_particles(packing), common::AT_1293_K), &[])
}

fn shrink(dir: &Path, name: &str, case: &toml::Value) -> [f64; 3] {
    let s = kinds::run(case, &[], &dir.join(name), &RunParams { base_dir: dir.to_path_buf(), plots: false, ..Default::default() }).unwrap();
    [s.f64("shrinkage_x").unwrap(), s.f64("shrinkage_y").unwrap(), s.f64("shrinkage_z").unwrap()]
}

const PRESET_A: &str = "name = \"copper\"\npreset = \"copper-ivannikov2022\"";
const PRESET_B: &str = "name = \"copper2\"\npreset = \"copper-ivannikov2022\"";

#[test]
fn inline_and_included_phases_equal_the_preset_and_their_data_matter() {
    let dir = common::tmp_dir("inline");
    let p = packing(&dir, 1.6e-4);
    let preset = shrink(&dir, "preset", &case(&p, PRESET_A, PRESET_B));
    // the same data written in the case: bit-identical
    let inline_b = format!("{PRESET_B}\ncalibrated_min_temperature = 1193.0\ncalibrated_max_temperature = 1353.0\n{}", COPPER_PHASE.replace("D0GB", "2.7e11"));
    let inline = shrink(&dir, "inline", &case(&p, PRESET_A, &inline_b));
    assert_eq!(inline, preset);
    // the same data from an included file (the layout of a calibration's material.toml)
    let file = format!(
        "[[materials]]\nname = \"copper2\"\nsource = \"calibrated\"\nyoung_modulus = 72.0e9\npoisson_ratio = 0.34\ncalibrated_min_temperature = 1193.0\ncalibrated_max_temperature = 1353.0\n{}",
        COPPER_PHASE.replace("D0GB", "2.7e11")
    );
    std::fs::write(dir.join("material.toml"), file).unwrap();
    let included = shrink(&dir, "included", &case(&p, PRESET_A, "name = \"copper2\"\npreset = \"copper-ivannikov2022\"\ninclude = \"material.toml\""));
    assert_eq!(included, preset);
    // faster grain-boundary diffusion in half of the particles: more shrinkage
    let fast_b = format!("{PRESET_B}\ncalibrated_min_temperature = 1193.0\ncalibrated_max_temperature = 1353.0\n{}", COPPER_PHASE.replace("D0GB", "2.7e12"));
    let fast = shrink(&dir, "fast", &case(&p, PRESET_A, &fast_b));
    for a in 0..3 {
        assert!(fast[a] > preset[a] * 1.05, "axis {a}: {} vs {}", fast[a], preset[a]);
    }
    // a bad include names the key and the file
    let e = kinds::run(
        &case(&p, PRESET_A, "name = \"x\"\ninclude = \"nope.toml\""),
        &[],
        &dir.join("bad"),
        &RunParams { base_dir: dir.clone(), ..Default::default() },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("materials.1.include") && e.contains("nope.toml"), "{e}");
}

#[test]
fn series_elastic_constants_are_harmonic_means_of_e_and_g() {
    let a = [72e9, 0.34];
    assert_eq!(series_elastic(a, a), a);
    let b = [144e9, 0.2];
    let [e, nu] = series_elastic(a, b);
    assert!((e - 96e9).abs() < 1e-3, "harmonic mean of 72 and 144 GPa is 96 GPa: {e}");
    let g = |m: [f64; 2]| m[0] / (2.0 * (1.0 + m[1]));
    let gm = 2.0 * g(a) * g(b) / (g(a) + g(b));
    assert!((e / (2.0 * (1.0 + nu)) - gm).abs() < 1e-3 * gm);
    assert_eq!(series_elastic(a, b), series_elastic(b, a));
}

#[test]
fn mixed_material_bonds_use_their_own_poisson_ratio() {
    // only ν shapes the bonded response (E cancels with the load F5), so a packing whose second
    // material has another ν must differ from both uniform packings and lie between them; new
    // contacts are searched every step (as before `detect_every` defaulted to 5), so that the three
    // runs see their contact-formation events at the same times
    let dir = common::tmp_dir("mixed");
    let p = packing(&dir, 1.6e-4);
    let fixed = |v: toml::Value| {
        let mut v = v;
        v.as_table_mut().unwrap().insert("contacts".into(), toml::Value::Table(toml::toml! { detect_every = 1 }));
        v
    };
    let case = |p: &Path, a: &str, b: &str| fixed(case(p, a, b));
    let nu = |a: f64, b: f64| case(&p, &format!("{PRESET_A}\npoisson_ratio = {a}"), &format!("{PRESET_B}\npoisson_ratio = {b}"));
    let lo = shrink(&dir, "lo", &nu(0.1, 0.1));
    let hi = shrink(&dir, "hi", &nu(0.45, 0.45));
    let mixed = shrink(&dir, "mixed", &nu(0.1, 0.45));
    // E differing by a factor of 3 with equal ν: E cancels within each bond (its load F5 uses its
    // own E) but not between bonds of different stiffness, so the result moves, a little (before
    // per-material bonds every bond had the first material's E and nothing moved)
    let e_only = shrink(&dir, "e", &case(&p, &format!("{PRESET_A}\npoisson_ratio = 0.1"), &format!("{PRESET_B}\npoisson_ratio = 0.1\nyoung_modulus = 216e9")));
    for a in 0..3 {
        assert!((lo[a] - hi[a]).abs() > 1e-6 * lo[a].abs(), "axis {a}: ν must matter: {lo:?} {hi:?}");
        let (min, max) = (lo[a].min(hi[a]), lo[a].max(hi[a]));
        assert!(mixed[a] > min && mixed[a] < max, "axis {a}: mixed {} not between {min} and {max}", mixed[a]);
        let rel = (e_only[a] / lo[a] - 1.0).abs();
        assert!(rel > 1e-6 && rel < 0.05, "axis {a}: E of the second material: {} vs {} ({rel:e})", e_only[a], lo[a]);
    }
}

#[test]
fn a_calibrated_material_file_runs_in_a_compact() {
    // the file exactly as `sinterdem calibrate` writes it, with grain-boundary diffusion ten
    // times faster than the bundled copper: the compact includes it and shrinks more
    let dir = common::tmp_dir("calibrated");
    let p = packing(&dir, 1.6e-4);
    let mut m = sinterdem::models::diffusion7::Material::copper();
    m.phases[0].d0_gb *= 10.0;
    sinterdem::calibrate::report::write_material(&dir.join("material.toml"), &m, None, "test").unwrap();
    let inc = "name = \"copper\"\npreset = \"copper-ivannikov2022\"\ninclude = \"material.toml\"";
    let fast = shrink(&dir, "cal", &case(&p, inc, PRESET_B));
    let base = shrink(&dir, "base", &case(&p, PRESET_A, PRESET_B));
    for a in 0..3 {
        assert!(fast[a] > base[a] * 1.02, "axis {a}: {} vs {}", fast[a], base[a]);
    }
}

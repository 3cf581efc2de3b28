//! Honest reporting of compact runs: warnings when contact temperatures leave the calibrated range
//! of the diffusion data, a ModelError at the melting temperature, isolated particles named and
//! left out of the temperature statistics, and shrinkage without constrained planes measured
//! from both faces (so that it agrees with the constrained run on a symmetric packing).

use sinterdem::kinds::{self, RunParams};
use std::path::{Path, PathBuf};

mod common;

/// A corner of the bundled green copper packing (all coordinates below `edge`), plus `extra` rows
/// (lines of `x,y,z,r`).
fn packing(dir: &Path, edge: f64, extra: &str) -> PathBuf {
    let rows = common::green_copper_block(edge, edge).into_iter().map(|(l, _)| l);
    common::write_block(dir, "packing.csv", "x,y,z,r", rows.chain(extra.lines().map(String::from)))
}

/// `material` "copper" or "titanium" takes the seed paper's fitted set (`…-ivannikov2022`).
fn isothermal(packing: &Path, material: &str, temperature: f64, end: f64) -> toml::Value {
    let preset = format!("name = \"{material}\"\npreset = \"{material}-ivannikov2022\"");
    let text = common::compact_text(&common::time_to(end), &[&preset], &common::file_particles(packing), &format!("{{ constant = {temperature:?} }}"));
    common::case_value(&text, &[])
}

fn params(dir: &Path) -> RunParams {
    RunParams { base_dir: dir.to_path_buf(), plots: false, ..Default::default() }
}

/// A compact held below its calibrated range sinters wholly on extrapolated data: the share of
/// the dose below the range (docs/diffusion7.md (V3)) is 1 at every contact, and the end-of-run
/// verdict warns once, naming the material, the share, a contact and the temperature; inside the
/// range there is no verdict at all.
#[test]
fn a_compact_held_below_the_calibrated_range_warns_at_the_end_with_share_one() {
    let dir = common::tmp_dir("range");
    let p = packing(&dir, 1.6e-4, "");
    // copper-ivannikov2022 data are declared for 1273–1353 K
    let s = kinds::run(&isothermal(&p, "copper", 1100.0, 50.0), &[], &dir.join("cold"), &params(&dir)).unwrap();
    let w: Vec<String> = serde_json::from_value(s.summary["warnings"].clone()).unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].contains("copper") && w[0].contains("100.000 %") && w[0].contains("below the calibrated range 1273.0–1353.0 K"), "{w:?}");
    assert!(w[0].contains("down to 1100.0 K") && w[0].contains("contact "), "{w:?}");
    let v = &s.summary["extrapolated_below_range"]["copper-ivannikov2022"];
    assert_eq!(v["share"].as_f64(), Some(1.0), "{v}");
    assert_eq!(v["lowest_temperature_K"].as_f64(), Some(1100.0), "{v}");
    let log = std::fs::read_to_string(dir.join("cold/log.txt")).unwrap();
    // the first time below the range stays in log.txt (detail), the verdict is the warning
    assert!(log.contains("material \"copper-ivannikov2022\": contact temperature below the calibrated range"), "{log}");
    assert_eq!(log.matches("warning: material \"copper-ivannikov2022\"").count(), 1, "{log}");
    let s = kinds::run(&isothermal(&p, "copper", 1293.0, 50.0), &[], &dir.join("ok"), &params(&dir)).unwrap();
    assert_eq!(s.summary["warnings"].as_array().unwrap().len(), 0);
    assert_eq!(s.summary["extrapolated_below_range"], serde_json::json!({}));
}

/// Two equal spheres of radius r with their centres d > 2r apart along x (no contact yet): the
/// relative density is the solid volume over the box of their outer faces,
/// 2·(4/3)πr³ / ((d + 2r)(2r)(2r)) = 2πr / (3(d + 2r)) (eq. 49 with the box of the particles).
#[test]
fn two_spheres_apart_have_the_density_of_their_bounding_box() {
    let dir = common::tmp_dir("two");
    let (r, d) = (2.5e-5, 6.0e-5);
    let p = common::write_block(&dir, "two.csv", "x,y,z,r", [format!("0,0,0,{r:e}"), format!("{d:e},0,0,{r:e}")]);
    let s = kinds::run(&isothermal(&p, "copper", 1293.0, 1.0e-3), &[], &dir.join("out"), &params(&dir)).unwrap();
    let rho = 2.0 * std::f64::consts::PI * r / (3.0 * (d + 2.0 * r));
    for key in ["relative_density", "relative_density_initial"] {
        let v = s.f64(key).unwrap();
        assert!((v / rho - 1.0).abs() < 1e-12, "{key}: {v} vs {rho}");
    }
}

#[test]
fn a_particle_at_the_melting_temperature_stops_the_run() {
    let dir = common::tmp_dir("melt");
    let p = packing(&dir, 1.6e-4, "");
    for (m, t, tm) in [("copper", 1400.0, "1358"), ("titanium", 2000.0, "1941")] {
        let e = kinds::run(&isothermal(&p, m, t, 50.0), &[], &dir.join(m), &params(&dir)).unwrap_err().to_string();
        assert!(e.contains("melting") && e.contains(tm) && e.contains(m) && e.contains("particle"), "{e}");
        // the summary of the last completed step is still written, saying why the run stopped
        let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join(m).join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["completed"], false);
    }
}

#[test]
fn an_isolated_particle_is_named_and_left_out_of_the_temperatures() {
    let dir = common::tmp_dir("isolated");
    // one particle far above the corner: no contact, not on the hot face, not exposed
    let p = packing(&dir, 1.6e-4, "8.0e-5,8.0e-5,6.0e-4,2.5e-5\n");
    let text = format!(
        "kind = \"compact\"\n[time]\nend = 20.0\ndt = 1.0e-3\ndt_max = 1.0\nscheme = \"bdf2\"\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n\
         [[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n[particles]\nsource = \"file\"\nfile = \"{}\"\ninitial_temperature = 1200.0\n\
         [thermal]\nmode = \"network\"\n[[thermal.fixed]]\nregion = {{ face = \"z-\" }}\nprofile = {{ constant = 1293.0 }}\n",
        p.display()
    );
    let case = toml::Value::Table(text.parse::<toml::Table>().unwrap());
    let s = kinds::run(&case, &[], &dir.join("out"), &params(&dir)).unwrap();
    let n = s.summary["particles"].as_u64().unwrap();
    // the added particle (the last one) and any rattler of the corner that touches nothing
    let ids: Vec<u64> = serde_json::from_value(s.summary["isolated_particle_ids"].clone()).unwrap();
    assert_eq!(s.summary["isolated_particles"].as_u64().unwrap(), ids.len() as u64);
    assert!(ids.contains(&(n - 1)) && ids.len() < 5, "{ids:?}");
    assert_eq!(s.summary["temperatures_exclude_isolated"], true);
    // the isolated particle keeps 1200 K; the connected body warms towards the plate's 1293 K
    let lo = s.f64("min_temperature_K").unwrap();
    assert!(lo > 1200.0 + 1e-6, "min temperature {lo} must not be the isolated particle's 1200 K");
    let log = std::fs::read_to_string(dir.join("out/log.txt")).unwrap();
    assert!(log.contains(&format!("{} particle", ids.len())) && log.contains("without a conductive path") && log.contains(&format!("{}", n - 1)), "{log}");
}

#[test]
fn shrinkage_without_constrained_planes_agrees_with_the_constrained_run() {
    let dir = common::tmp_dir("planes");
    // a symmetric packing: an FCC block
    let case = |constrain: bool| -> toml::Value {
        let text = common::compact_text(&common::time_to(200.0), &[common::COPPER], &common::fcc(3), common::AT_1293_K);
        common::case_value(&format!("{text}[mechanics]\nconstrain_planes = {constrain}\n"), &[])
    };
    let c = kinds::run(&case(true), &[], &dir.join("c"), &params(&dir)).unwrap();
    let f = kinds::run(&case(false), &[], &dir.join("f"), &params(&dir)).unwrap();
    for a in ["shrinkage_x", "shrinkage_y", "shrinkage_z"] {
        let (sc, sf) = (c.f64(a).unwrap(), f.f64(a).unwrap());
        assert!(sc > 1e-3, "{a}: {sc}");
        assert!((sf / sc - 1.0).abs() < 0.05, "{a}: free {sf} vs constrained {sc}");
    }
    let (rc, rf) = (c.f64("relative_density").unwrap(), f.f64("relative_density").unwrap());
    assert!((rf / rc - 1.0).abs() < 0.01, "relative density free {rf} vs constrained {rc}");
}

/// The dose accumulators are checkpointed: a run under a ramp through the lower end of
/// copper-ivannikov2022's range (1100 → 1293 K), killed after its checkpoint and resumed, gives the uninterrupted run's
/// verdict bit for bit (a share strictly between 0 and 1, so that both integrals matter).
#[test]
fn the_below_range_verdict_survives_a_resume_bit_for_bit() {
    let dir = common::tmp_dir("verdict-resume");
    let p = packing(&dir, 1.2e-4, "");
    let text = common::compact_text(
        &common::time_to(60.0),
        &[common::COPPER],
        &common::file_particles(&p),
        "{ table = [[0.0, 1100.0], [40.0, 1293.0], [60.0, 1293.0]] }",
    );
    let case = common::case_value(&text, &["output.checkpoint_every=10"]);
    let prep = |v: &toml::Value| sinterdem::coupled::prepare(v.clone(), Path::new("."), &mut |_| {}).unwrap();
    let full = sinterdem::kinds::compact::run(prep(&case), &dir.join("full"), false, &mut |_| {}).unwrap();
    let part = dir.join("part");
    assert!(sinterdem::kinds::compact::run_from(prep(&case), &part, false, &mut |_| {}, None, Some(20)).unwrap().is_null());
    let resumed = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    let v = &full["extrapolated_below_range"]["copper-ivannikov2022"];
    let share = v["share"].as_f64().unwrap();
    assert!(share > 1e-3 && share < 0.9, "{v}");
    assert_eq!(full["extrapolated_below_range"], resumed["extrapolated_below_range"]);
    assert_eq!(full["warnings"], resumed["warnings"]);
}

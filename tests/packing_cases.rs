//! Bundled packing cases. The copper green body (805 particles, ≈ 4 s of CPU in release) is checked
//! against the acceptance numbers; the titanium one (3619 particles, ≈ 17 s) is
//! ignored (run with `cargo test --release --test packing_cases -- --ignored`).
use std::path::Path;

mod common;

fn load(name: &str) -> toml::Value {
    sinterdem::config::load_case(&Path::new(env!("CARGO_MANIFEST_DIR")).join("cases").join(name), &[]).unwrap()
}

/// The acceptance numbers of a green body: box solid fraction (eq. 49) within ±0.01 of the
/// target, interior laminae (eq. 48) within ±0.05 of their mean, stress-free (largest overlap
/// < 1e-3 r̄, kinetic energy below its threshold), coordination reported and mechanically sensible.
fn assert_green_body(s: &sinterdem::kinds::generate::GenerateSummary) {
    assert!(s.thresholds_met, "{s:#?}");
    assert!((s.solid_fraction - 0.60).abs() <= 0.01, "solid fraction {} not within 0.60 ± 0.01", s.solid_fraction);
    for a in 0..3 {
        assert!(s.laminae_max_deviation[a] < 0.05, "axis {a}: interior laminae deviate by {} from their mean", s.laminae_max_deviation[a]);
        // away from the walls the packing is denser than the box average (wall layers)
        assert!(s.laminae_mean[a] > s.solid_fraction && s.laminae_mean[a] < 0.64, "{s:#?}");
    }
    assert!(s.max_overlap_rel < 1e-3, "{}", s.max_overlap_rel);
    // a frictionless jammed packing: between 4 and 6 contacts per particle (rattlers and opened
    // contacts lower it from the isostatic 6)
    assert!(s.coordination_mean > 4.0 && s.coordination_mean < 6.5, "{}", s.coordination_mean);
    assert!(s.rattlers < s.particles / 20, "{}", s.rattlers);
    assert!(s.size_ks_distance < 0.05, "{}", s.size_ks_distance);
}

#[test]
fn copper_green_body_reaches_the_target_stress_free_and_homogeneous() {
    let dir = common::tmp_dir("green-copper");
    let s = sinterdem::kinds::generate::generate_case(&load("green-copper.toml"), &dir, false).unwrap();
    assert_eq!(s.particles, 805);
    assert_green_body(&s);
    // the box keeps the requested shape 0.5 : 0.5 : 0.4 (within 2 %: a box accepted at jamming lies
    // on the straight compaction path, short of its end)
    assert!((s.box_size[2] / s.box_size[0] / 0.8 - 1.0).abs() < 0.02 && (s.box_size[1] / s.box_size[0] - 1.0).abs() < 1e-9, "{:?}", s.box_size);
    for f in ["packing.csv", "packing.vtu", "packing_contacts.vtu", "laminae.csv", "laminae.png", "summary.json"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
#[ignore]
fn titanium_green_body_reaches_the_target_stress_free_and_homogeneous() {
    let dir = common::tmp_dir("green-titanium");
    let s = sinterdem::kinds::generate::generate_case(&load("green-titanium.toml"), &dir, false).unwrap();
    assert_eq!(s.particles, 3619);
    assert_green_body(&s);
    println!("{s:#?}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn bundled_cases_pass_the_check() {
    for name in ["green-copper.toml", "green-titanium.toml"] {
        sinterdem::kinds::generate::check_generate_case(&load(name)).unwrap();
    }
}

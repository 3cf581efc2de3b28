//! The initial state of a contact created during a compact run (`contacts.new_contact_state`,
//! docs/coupled.md "New contacts"): "seed" is (I1)–(I4) exactly as before; "volume_conserving"
//! starts from crate::neck's neck of the overlap at detection; `contacts.new_contact_gap = 0`
//! waits for a real overlap; the contacts of the green body are seeded under every option; a bad
//! name is refused with the allowed ones.

use sinterdem::coupled::{self, NewContactState, Simulation};
use sinterdem::models::diffusion7::Contact7;
use sinterdem::models::diffusion7::contact::{DEFAULT_EPSILON, DEFAULT_ETA};
use std::path::Path;

mod common;

const RA: f64 = 25e-6;
const RB: f64 = 30e-6;
const RC: f64 = 20e-6;
const XB: f64 = 80e-6;

/// Three copper spheres on a line: A (25 µm) touching B (30 µm), C (20 µm) half a mean radius
/// away from B (no contact at the start).
fn three_spheres(sets: &[&str]) -> Result<Simulation, sinterdem::error::Error> {
    let dir = common::tmp_dir_per_call(&format!("newc-{}", sets.join("-").replace(['"', '=', '.'], "_")));
    let csv = dir.join("three.csv");
    let x_c = XB + RB + RC + 12.5e-6;
    std::fs::write(&csv, format!("x,y,z,r\n{RA:e},30e-6,30e-6,{RA:e}\n{XB:e},30e-6,30e-6,{RB:e}\n{x_c:e},30e-6,30e-6,{RC:e}\n")).unwrap();
    let text = common::compact_text("end = 100.0\ndt = 1.0e-3", &[common::COPPER], &common::file_particles(&csv), common::AT_1293_K);
    coupled::prepare(common::case_value(&text, sets), Path::new("."), &mut |_| {})
}

/// Moves C to surface gap `gap` [m] from B (negative: overlap), as if the run had brought it
/// there, and runs the detection of a later step. Returns the contacts added.
fn detect_c_at(sim: &mut Simulation, gap: f64) -> usize {
    sim.prep.scene.particles.position[2].x = XB + RB + RC + gap;
    sim.step = 10;
    sim.t = 500.0;
    sim.add_new_contacts(&mut |_| {}).unwrap()
}

fn overlap_b_c(sim: &Simulation) -> (f64, f64) {
    let p = &sim.prep.scene.particles;
    let d = (p.position[2] - p.position[1]).norm();
    (d, RB + RC - d)
}

#[test]
fn volume_conserving_new_contact_starts_from_the_neck_of_its_overlap() {
    let mut sim = three_spheres(&["contacts.new_contact_state=\"volume_conserving\""]).unwrap();
    assert_eq!(sim.settings.new_state, NewContactState::VolumeConserving);
    // the green body's contact A–B is seeded as under every option
    assert_eq!(sim.contacts.pairs, vec![[0, 1]]);
    let p = &sim.prep.scene.particles;
    let d_ab = (p.position[1] - p.position[0]).norm().min(RA + RB);
    assert_eq!(sim.contacts.state[0], Contact7::new(RA, RB, d_ab, 0.0, DEFAULT_EPSILON, DEFAULT_ETA).unwrap());

    // overlap 2e-3 of the smaller radius: the neck is crate::neck's, bit for bit
    assert_eq!(detect_c_at(&mut sim, -2e-3 * RC), 1);
    assert_eq!(sim.contacts.pairs[1], [1, 2]);
    let (d, h) = overlap_b_c(&sim);
    assert!((h / RC - 2e-3).abs() < 1e-9, "{h}");
    let neck = sinterdem::neck::solve(RB, RC, h).unwrap();
    let c = sim.contacts.state[1];
    assert_eq!(c.y[0], neck.a);
    // just below Coble's √(2 r* h) = 1.3856 µm, against the seed's r_c + ε R_min = 0.9796 + 0.2 µm
    assert!((c.y[0] - 1.38521e-6).abs() < 1e-11, "{}", c.y[0]);
    let seed = Contact7::new(RB, RC, d, 500.0, DEFAULT_EPSILON, DEFAULT_ETA).unwrap();
    assert!((seed.y[0] - 1.17957e-6).abs() < 1e-11, "{}", seed.y[0]);
    // the rest of the geometry is (I1), (I3): radical plane and the cone on the spheres
    assert_eq!([c.y[1], c.y[3], c.y[4], c.y[6]], [seed.y[1], seed.y[3], seed.y[4], seed.y[6]]);
    assert!((c.l0 / d - 1.0).abs() < 1e-15, "{} {d}", c.l0);
    assert_eq!(c.t_created, 500.0);
    let h0 = (1.0 + DEFAULT_ETA) * c.y[0];
    assert!((c.y[3] - c.y[2] - (RB * RB - h0 * h0).sqrt()).abs() < 1e-15, "cone height of side A");
}

#[test]
fn volume_conserving_neck_takes_the_seed_below_a_tiny_overlap_and_within_the_gap() {
    // within the gap tolerance without overlap: touching with the seed neck ε·R_min
    let mut sim = three_spheres(&["contacts.new_contact_state=\"volume_conserving\""]).unwrap();
    assert_eq!(detect_c_at(&mut sim, 0.5e-3 * 25e-6), 1);
    let c = sim.contacts.state[1];
    assert_eq!(c.y[0], DEFAULT_EPSILON * RC);
    assert!((c.l0 / (RB + RC) - 1.0).abs() < 1e-15, "{}", c.l0);
    // an overlap of 1e-5 R_min has the volume-conserving neck 0.0049 R_min < ε R_min: the seed's ε R_min
    let mut sim = three_spheres(&["contacts.new_contact_state=\"volume_conserving\""]).unwrap();
    assert_eq!(detect_c_at(&mut sim, -1e-5 * RC), 1);
    let (d, h) = overlap_b_c(&sim);
    let a_vc = sinterdem::neck::solve(RB, RC, h).unwrap().a;
    assert!((a_vc / RC - 0.004899).abs() < 1e-6, "{}", a_vc / RC);
    assert_eq!(sim.contacts.state[1].y[0], DEFAULT_EPSILON * RC);
    assert_eq!(coupled::new_contact_neck(RB, RC, d, DEFAULT_EPSILON).unwrap(), DEFAULT_EPSILON * RC);
}

#[test]
fn seed_is_the_default_and_unchanged() {
    for sets in [&[][..], &["contacts.new_contact_state=\"seed\""][..]] {
        let mut sim = three_spheres(sets).unwrap();
        assert_eq!(sim.settings.new_state, NewContactState::Seed);
        assert_eq!(sim.settings.new_gap, sim.settings.gap);
        assert_eq!(detect_c_at(&mut sim, -2e-3 * RC), 1);
        let (d, _) = overlap_b_c(&sim);
        assert_eq!(sim.contacts.state[1], Contact7::new(RB, RC, d, 500.0, DEFAULT_EPSILON, DEFAULT_ETA).unwrap());
    }
}

#[test]
fn new_contact_gap_zero_waits_for_a_real_overlap() {
    let mut sim = three_spheres(&["contacts.new_contact_gap=0.0"]).unwrap();
    assert_eq!(sim.settings.new_gap, 0.0);
    assert_eq!(sim.settings.gap, 1e-3);
    // within gap_tolerance but apart: no contact yet
    assert_eq!(detect_c_at(&mut sim, 0.5e-3 * 25e-6), 0);
    assert_eq!(detect_c_at(&mut sim, 0.0), 0, "touching exactly is not an overlap");
    assert_eq!(detect_c_at(&mut sim, -1e-4 * RC), 1);
    assert_eq!(sim.contacts.len(), 2);
}

#[test]
fn bad_new_contact_options_are_refused_with_the_allowed_values() {
    let e = three_spheres(&["contacts.new_contact_state=\"volume\""]).err().unwrap().to_string();
    assert!(e.contains("contacts.new_contact_state") && e.contains("\"volume\"") && e.contains("\"seed\", \"volume_conserving\""), "{e}");
    let e = three_spheres(&["contacts.new_contact_gap=0.5"]).err().unwrap().to_string();
    assert!(e.contains("contacts.new_contact_gap") && e.contains("0.1"), "{e}");
}

//! Temperature-dependent properties of the heat network (docs/heat-model.md eqs. P1–P4) against
//! exact solutions: enthalpy conservation and the equilibrium of a pair with linear c(T); the
//! steady chain with linear κ(T) by its Kirchhoff transform; the energy balance with tables and a
//! heated end; a case with the bundled titanium tables; bad tables rejected naming the key.

use sinterdem::heat::properties::ThermalProperties;
use sinterdem::heat::{HeatNetwork, HeatSources, PipeConductance, Scheme};
use sinterdem::material::{Quantity, Table};
use sinterdem::profile::Profile;
use std::path::Path;

mod common;

/// Two particles m1 = 1 kg, m2 = 3 kg, c(T) = 400 + 0.2 (T − 200) J/(kg K) (linear table), a
/// constant pipe K = 50 W/K, isolated: the enthalpy Σ m H(T) is conserved and the pair ends at the
/// T_eq of (m1 + m2) H(T_eq) = m1 H(T1) + m2 H(T2), H(T) = 80000 + 400 (T − 200) + 0.1 (T − 200)².
#[test]
fn pair_with_linear_heat_capacity_conserves_enthalpy_and_reaches_the_exact_equilibrium() {
    let c = Table::new(&[[200.0, 400.0], [1200.0, 600.0]], "c", Quantity::HeatCapacity).unwrap();
    let h = |t: f64| 80000.0 + 400.0 * (t - 200.0) + 0.1 * (t - 200.0).powi(2);
    let (m1, m2, t1, t2) = (1.0, 3.0, 1000.0, 300.0);
    let target = (m1 * h(t1) + m2 * h(t2)) / (m1 + m2);
    // 0.1 x² + 400 x + 80000 − target = 0, x = T − 200
    let x = (-400.0 + (400.0f64.powi(2) - 4.0 * 0.1 * (80000.0 - target)).sqrt()) / 0.2;
    let t_eq = 200.0 + x;
    // c·ΔT with c at the start temperatures would end elsewhere: the test tells them apart
    let naive = (m1 * c.at(t1) * t1 + m2 * c.at(t2) * t2) / (m1 * c.at(t1) + m2 * c.at(t2));
    assert!((naive - t_eq).abs() > 1.0, "{naive} vs {t_eq}");
    for scheme in [Scheme::BackwardEuler, Scheme::CrankNicolson, Scheme::Bdf2] {
        let mut net = HeatNetwork::new(vec![m1 * 385.0, m2 * 385.0], HeatSources::default(), scheme, 1e-13);
        net.set_properties(Some(ThermalProperties {
            mass: vec![m1, m2],
            material: vec![0, 0],
            heat_capacity: vec![Some(c.clone())],
            conductivity: vec![None],
            contact: None,
        }));
        net.set_topology(&[[0, 1]]).unwrap();
        let mut temps = vec![t1, t2];
        let e0 = net.stored_heat(&temps);
        assert!((e0 - (m1 * h(t1) + m2 * h(t2))).abs() < 1e-9 * e0);
        let (mut t, mut heat_in, mut stored, mut plain) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..400 {
            let dt = if k < 200 { 0.5 } else { 50.0 };
            let info = net.step(t, dt, &mut temps, &[50.0]).unwrap();
            heat_in += info.heat_in;
            stored += info.stored_change;
            plain += info.stored_change_plain;
            t += dt;
        }
        let e1 = net.stored_heat(&temps);
        assert!(heat_in.abs() < 1e-9, "{scheme:?}: heat in {heat_in}");
        assert!((e1 - e0).abs() < 1e-9 * e0, "{scheme:?}: enthalpy {e0} → {e1}");
        assert!((plain - (e1 - e0)).abs() < 1e-9 * e0 && stored.abs() < 1e-9 * e0, "{scheme:?}: {plain} {stored}");
        for v in &temps {
            assert!((v - t_eq).abs() < 1e-6, "{scheme:?}: {temps:?} vs T_eq = {t_eq}");
        }
    }
}

/// A chain of N = 15 free particles between ends held at 300 K and 1300 K, equal pipes whose
/// halves carry κ(T) = κ(300 K) + (T − 300)(κ(1300) − κ(300))/1000 with κ(300) = 401 and
/// κ(1300) = 340 W/(m K). In steady state each pipe carries s (Φ(T_k) − Φ(T_k+1)), Φ(T) = ∫κ dT
/// (eq. P3), so Φ(T_k) is linear in k: T_k = Φ⁻¹(Φ(300) + k/(N+1) (Φ(1300) − Φ(300))).
#[test]
fn steady_chain_with_linear_conductivity_matches_the_kirchhoff_transform() {
    let n = 15usize;
    let kappa = Table::new(&[[300.0, 401.0], [1300.0, 340.0]], "k", Quantity::Conductivity).unwrap();
    let (k1, k0) = ((340.0 - 401.0) / 1000.0, 401.0 - (340.0 - 401.0) / 1000.0 * 300.0);
    let phi = |t: f64| k0 * t + 0.5 * k1 * t * t;
    let phi_inv = |p: f64| (-k0 + (k0 * k0 + 2.0 * k1 * p).sqrt()) / k1;
    let kref = 394.0;
    let s = 1e-3; // m: pipe shape factor, K = s κ̄
    let sources = HeatSources {
        fixed: (0..n + 2)
            .map(|i| {
                if i == 0 {
                    Some(0)
                } else if i == n + 1 {
                    Some(1)
                } else {
                    None
                }
            })
            .collect(),
        profiles: vec![Profile::constant(300.0).unwrap(), Profile::constant(1300.0).unwrap()],
        ..Default::default()
    };
    for scheme in [Scheme::BackwardEuler, Scheme::Bdf2] {
        let mut net = HeatNetwork::new(vec![1e-3; n + 2], sources.clone(), scheme, 1e-14);
        net.set_properties(Some(ThermalProperties {
            mass: vec![1e-6; n + 2],
            material: vec![0; n + 2],
            heat_capacity: vec![None],
            conductivity: vec![Some((kappa.clone(), kref))],
            contact: None,
        }));
        let pipes: Vec<[u32; 2]> = (0..=n as u32).map(|i| [i, i + 1]).collect();
        net.set_topology(&pipes).unwrap();
        let parts = vec![PipeConductance { half_i: 2.0 * s * kref, half_j: 2.0 * s * kref, pair: s * kref, boundary: 0.0 }; pipes.len()];
        // plain conductances are refused: κ(T) needs the halves
        assert!(net.step(0.0, 1.0, &mut vec![500.0; n + 2], &vec![1.0; pipes.len()]).is_err());
        let mut temps = vec![500.0; n + 2];
        net.apply_fixed(0.0, &mut temps);
        let mut t = 0.0;
        for _ in 0..40 {
            net.step_pipes(t, 1e3, &mut temps, &parts).unwrap();
            t += 1e3;
        }
        let (p0, p1) = (phi(300.0), phi(1300.0));
        for (k, v) in temps.iter().enumerate() {
            let exact = phi_inv(p0 + k as f64 / (n + 1) as f64 * (p1 - p0));
            assert!((v - exact).abs() < 1e-7, "{scheme:?} particle {k}: {v} vs {exact}");
        }
        // the constant-κ profile would be linear in k: the κ(T) profile differs visibly from it
        let mid = temps[8]; // the middle of 17 particles
        assert!((mid - 800.0).abs() > 5.0, "{mid}");
    }
}

/// Tables for both properties, a Dirichlet end following a ramp and radiation to a cold furnace:
/// Σ heat in = Σ scheme stored change (enthalpy, eq. P1) to the iteration tolerance.
#[test]
fn energy_balance_closes_with_tables_ramp_and_radiation() {
    let n = 12usize;
    let c = Table::new(&[[200.0, 465.0], [300.0, 522.0], [1000.0, 675.0], [1200.0, 620.0]], "c", Quantity::HeatCapacity).unwrap();
    let kappa = Table::new(&[[300.0, 21.9], [800.0, 19.7], [1200.0, 22.0]], "k", Quantity::Conductivity).unwrap();
    let spec = sinterdem::profile::ProfileSpec { schedule: Some("start 300 K, heat 600 K/min to 1200 K, hold 1 min".into()), ..Default::default() };
    let ramp = Profile::from_spec(&spec, "p").unwrap();
    let sources = HeatSources {
        fixed: (0..n).map(|i| if i == 0 { Some(0) } else { None }).collect(),
        profiles: vec![ramp],
        exposed_area: (0..n).map(|i| if i == n - 1 { 1e-6 } else { 0.0 }).collect(),
        furnace: Some(sinterdem::heat::Furnace {
            gas: Profile::constant(300.0).unwrap(),
            wall: Profile::constant(300.0).unwrap(),
            convection: 10.0,
            emissivity: 0.4,
        }),
        ..Default::default()
    };
    for scheme in [Scheme::BackwardEuler, Scheme::CrankNicolson, Scheme::Bdf2] {
        let mass = vec![1e-6; n];
        let mut net = HeatNetwork::new(vec![522e-6; n], sources.clone(), scheme, 1e-13);
        net.set_properties(Some(ThermalProperties {
            mass: mass.clone(),
            material: vec![0; n],
            heat_capacity: vec![Some(c.clone())],
            conductivity: vec![Some((kappa.clone(), 21.9))],
            contact: Some(1.0),
        }));
        let pipes: Vec<[u32; 2]> = (0..n as u32 - 1).map(|i| [i, i + 1]).collect();
        net.set_topology(&pipes).unwrap();
        let parts = vec![PipeConductance { half_i: 2e-3, half_j: 2e-3, pair: 1.0 / (1.0 / 2e-3 + 1.0 / 2e-3 + 1.0), boundary: 0.0 }; pipes.len()];
        let mut temps = vec![300.0; n];
        net.apply_fixed(0.0, &mut temps);
        let (mut t, mut heat_in, mut stored, mut scale) = (0.0, 0.0, 0.0, 0.0);
        let e0 = net.stored_heat(&temps);
        while t < 150.0 - 1e-9 {
            let info = net.step_pipes(t, 0.5, &mut temps, &parts).unwrap();
            heat_in += info.heat_in;
            stored += info.stored_change;
            scale += info.heat_in.abs();
            t += 0.5;
        }
        assert!(temps[n - 1] > 400.0, "{scheme:?}: heat reached the far end: {temps:?}");
        let rel = (stored - heat_in).abs() / scale;
        assert!(rel < 1e-9, "{scheme:?}: balance {rel:e} (in {heat_in}, stored {stored})");
        if scheme != Scheme::Bdf2 {
            // one-step schemes: the scheme's stored change is the enthalpy change itself
            assert!((net.stored_heat(&temps) - e0 - stored).abs() < 1e-9 * scale, "{scheme:?}");
        }
    }
}

fn hot_plate(sets: &[&str]) -> toml::Value {
    let mut all: Vec<String> =
        ["particles.cells=[3, 3, 4]", "output.snapshots=0", "output.vtu=false", "output.hdf5=false", "time.end=60"].iter().map(|s| s.to_string()).collect();
    all.extend(sets.iter().map(|s| s.to_string()));
    sinterdem::config::load_case(Path::new("cases/hot-plate.toml"), &all).unwrap()
}

/// The bundled hot plate with the bundled titanium tables (Incropera et al. 2007): the run closes
/// its energy balance and, heated towards 1273 K where the table's c is above the constant
/// 523 J/(kg K), stores more heat per kelvin: its mean temperature stays below the constant run's.
#[test]
fn hot_plate_with_bundled_titanium_tables() {
    let dir = common::tmp_dir("hot-plate");
    let run = |v: toml::Value| {
        let prep = sinterdem::scene::prepare(v, Path::new("cases")).unwrap();
        sinterdem::kinds::heat::run(prep, &dir, false, &mut |_| {}).unwrap()
    };
    let constant = run(hot_plate(&[]));
    let tables = run(hot_plate(&["materials.0.conductivity_table=\"titanium\"", "materials.0.heat_capacity_table=\"titanium\""]));
    assert_eq!(tables["temperature_dependent_properties"], true);
    assert_eq!(constant["temperature_dependent_properties"], false);
    let bal = tables["energy_balance_rel"].as_f64().unwrap();
    assert!(bal < 1e-8, "balance {bal:e}");
    let (mc, mt) = (constant["mean_temperature_K"].as_f64().unwrap(), tables["mean_temperature_K"].as_f64().unwrap());
    assert!(mt < mc && mt > 293.15, "{mt} vs {mc}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bad table in a case is refused with the key, the value and the allowed range.
#[test]
fn bad_tables_in_a_case_are_rejected_naming_the_key() {
    for (set, needles) in [
        ("materials.0.conductivity_table=[[300.0, 20.0]]", vec!["materials.titanium.conductivity_table", "at least 2"]),
        ("materials.0.conductivity_table=[[300.0, 20.0], [300.0, 21.0]]", vec!["conductivity_table[1] = [300, 21]", "increase strictly"]),
        ("materials.0.heat_capacity_table=[[300.0, 500.0], [400.0, -5.0]]", vec!["heat_capacity_table[1]", "-5", "(0, 1e5] J/(kg K)"]),
        ("materials.0.heat_capacity_table=\"brass\"", vec!["heat_capacity_table", "brass", "copper, titanium"]),
        ("materials.0.conductivity=20.0", vec![]),
    ] {
        let mut v = hot_plate(&[set]);
        if needles.is_empty() {
            // a constant and a table for the same property: ambiguous
            sinterdem::config::apply_override(&mut v, "materials.0.conductivity_table=\"titanium\"").unwrap();
        }
        let e = sinterdem::scene::prepare(v, Path::new("cases")).err().expect(set).to_string();
        let needles = if needles.is_empty() { vec!["either", "conductivity_table"] } else { needles };
        for n in needles {
            assert!(e.contains(n), "{set}: {e}");
        }
    }
}

//! The gap model (docs/heat-model.md "Heat across gaps", (H18)–(H23)): the gas conductance against
//! its closed form for equal spheres and the logarithmic near-contact law, two separated spheres
//! relaxing at the lumped rate G(1/C1 + 1/C2), radiation across the gap against the exact
//! solution of the quartic exchange, the isolated particle of the bundled hot-plate compact
//! warmed through the gas, results unchanged bit for bit while no gap pipe exists, a resumed
//! compact run with the model equal to the uninterrupted one, and bad keys refused.

use sinterdem::config::apply_override;
use sinterdem::coupled;
use sinterdem::heat::gap::{gas_conductance, gas_conductance_equal, outer_radius, radiation_coefficient};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

mod common;
use common::rel;

const K_G: f64 = 0.05; // W/(m K), argon near 1300 K

/// (H18) = (H20) for equal spheres over nine decades of the gap, with and without the jump
/// distance; an independent Simpson rule in r for unequal spheres; monotone in the gap and zero
/// from s = f·R_L on.
#[test]
fn gas_conductance_matches_its_closed_form_and_falls_to_zero_at_the_layer_edge() {
    let (r, f) = (25e-6, 0.2);
    for jump in [0.0, 0.5e-6] {
        for sr in [1e-9, 1e-6, 1e-4, 1e-3, 1e-2, 0.05, 0.1, 0.15, 0.199] {
            let d = 2.0 * r + sr * r;
            let ro = outer_radius(r, r, d, f).unwrap();
            let g = gas_conductance(K_G, r, r, d, ro, jump);
            let exact = gas_conductance_equal(K_G, r, d, ro, jump);
            assert!(rel(g, exact) < 1e-11, "s/R = {sr}, M = {jump}: quadrature {g} vs closed form {exact}");
        }
    }
    // unequal radii 20 and 30 µm, s = 1 µm, M = 0.2 µm: plain composite Simpson in r
    let (ri, rj, s, m) = (20e-6, 30e-6, 1e-6, 0.2e-6);
    let d = ri + rj + s;
    let ro = outer_radius(ri, rj, d, f).unwrap();
    let integrand = |x: f64| 2.0 * PI * x / (d - (ri * ri - x * x).sqrt() - (rj * rj - x * x).sqrt() + m);
    let n = 200_000;
    let h = ro / n as f64;
    let mut sum = integrand(0.0) + integrand(ro);
    for k in 1..n {
        sum += integrand(k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    let simpson = K_G * sum * h / 3.0;
    let g = gas_conductance(K_G, ri, rj, d, ro, m);
    assert!(rel(g, simpson) < 1e-10, "{g} vs Simpson {simpson}");
    // monotone decreasing in the gap, continuous to zero at the layer edge s = f·R_L, none beyond
    let mut last = f64::INFINITY;
    for k in 1..=400 {
        let s = 0.2 * rj * k as f64 / 400.0 * (1.0 - 1e-12);
        let d = ri + rj + s;
        let ro = outer_radius(ri, rj, d, f).unwrap();
        let g = gas_conductance(K_G, ri, rj, d, ro, 0.0);
        assert!(g < last && g > 0.0, "not decreasing at s = {s:e} m: {g} after {last}");
        last = g;
    }
    assert!(last < 1e-3 * gas_conductance(K_G, ri, rj, ri + rj + 0.1 * rj, outer_radius(ri, rj, ri + rj + 0.1 * rj, f).unwrap(), 0.0));
    assert!(outer_radius(ri, rj, ri + rj + 0.2 * rj * (1.0 + 1e-9), f).is_none());
    assert!(outer_radius(ri, rj, ri + rj, f).is_none(), "touching pairs are contacts, not gaps");
}

/// (H21) For a gap small against R′ = 2 r_i r_j/(r_i + r_j) the conductance follows the
/// logarithm of Batchelor & O'Brien (1977), G ≈ π k_g R′ [ln(R′/(s + M)) + c]: its slope in
/// ln s is −π k_g R′ for unequal spheres, and for equal spheres the constant is
/// c = ln(2σ/R) − σ/R, σ = R − √(R² − r_out²) the sag of the conducting disc.
#[test]
fn small_gaps_follow_the_logarithmic_law() {
    let f = 0.2;
    for (ri, rj) in [(25e-6, 25e-6), (20e-6, 30e-6), (10e-6, 40e-6)] {
        let rp = 2.0 * ri * rj / (ri + rj);
        let g = |s: f64| {
            let d = ri + rj + s;
            gas_conductance(K_G, ri, rj, d, outer_radius(ri, rj, d, f).unwrap(), 0.0)
        };
        let (s1, s2) = (1e-8 * rp, 1e-9 * rp);
        let slope = (g(s2) - g(s1)) / (s1 / s2).ln() / (PI * K_G * rp);
        assert!((slope - 1.0).abs() < 1e-6, "r = {ri:e}, {rj:e}: slope {slope}");
    }
    // equal spheres: the constant
    let r = 25e-6;
    let s = 1e-9 * r;
    let ro = outer_radius(r, r, 2.0 * r + s, f).unwrap();
    let sag = r - (r * r - ro * ro).sqrt();
    let c = (2.0 * sag / r).ln() - sag / r;
    let g = gas_conductance(K_G, r, r, 2.0 * r + s, ro, 0.0);
    let c_num = g / (PI * K_G * r) - (r / s).ln();
    assert!((c_num - c).abs() < 1e-6, "constant {c_num} vs {c}");
    assert!((c + 1.624).abs() < 1e-3, "{c}"); // f = 0.2: r_out = 0.456 R
    // with a jump distance the conductance stays finite as the gap closes: it tends to the value
    // at u = s + M = M
    let m = 0.4e-6;
    let g0 = gas_conductance(K_G, r, r, 2.0 * r + 1e-15, outer_radius(r, r, 2.0 * r + 1e-15, f).unwrap(), m);
    let gm = gas_conductance_equal(K_G, r, 2.0 * r + 1e-15, outer_radius(r, r, 2.0 * r + 1e-15, f).unwrap(), m);
    assert!(rel(g0, gm) < 1e-11 && g0 < PI * K_G * r * ((r / m).ln() + c + 0.1), "{g0} {gm}");
}

/// The neighbour list (a Verlet list over the contact detection's cell list) finds exactly the
/// pairs of a brute-force O(N²) enumeration, with the same conductances, while 300 random
/// spheres drift and grow over 40 steps: the gap pipes depend on the configuration only.
#[test]
fn the_neighbour_list_finds_every_gap_pair_of_a_brute_force_search() {
    use nalgebra::Vector3;
    use sinterdem::heat::gap::{GapModel, GapNetwork};
    let mut seed = 0x2545F4914F6CDD1Du64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let n = 300;
    let mut x: Vec<Vector3<f64>> = (0..n).map(|_| Vector3::new(rnd(), rnd(), rnd()) * 4e-4).collect();
    let mut r: Vec<f64> = (0..n).map(|_| 25e-6 * (0.8 + 0.4 * rnd())).collect();
    let model = GapModel { gas_conductivity: K_G, layer_thickness: 0.3, jump_distance: 0.1e-6, emissivity: 0.5 };
    let mut net = GapNetwork::new(model);
    let mut total = 0;
    for step in 0..40 {
        let contacts: Vec<[u32; 2]> = sinterdem::contacts::detect::touching_pairs(&x, &r, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
        let got = net.update(&x, &r, &contacts).clone();
        let mut want = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                let pr = [i as u32, j as u32];
                if contacts.contains(&pr) {
                    continue;
                }
                if let Some((g, c)) = model.pair(r[i], r[j], (x[j] - x[i]).norm()) {
                    want.push((pr, g, c));
                }
            }
        }
        assert_eq!(got.pairs, want.iter().map(|w| w.0).collect::<Vec<_>>(), "step {step}");
        assert_eq!(got.gas, want.iter().map(|w| w.1).collect::<Vec<_>>(), "step {step}");
        assert_eq!(got.radiation, want.iter().map(|w| w.2).collect::<Vec<_>>(), "step {step}");
        total += got.len();
        // drift by up to 2 µm per step and grow by up to 0.1 µm
        for (xi, ri) in x.iter_mut().zip(r.iter_mut()) {
            *xi += Vector3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * 4e-6;
            *ri += 1e-7 * rnd();
        }
    }
    assert!(total > 40 * 50, "{total} gap pairs in all");
    assert!(net.searches > 1 && net.searches < 40, "{} searches", net.searches);
}

fn two_sphere_case(dir: &Path, rows: &str, gap: &str, extra: &str) -> toml::Value {
    let csv = dir.join("pair.csv");
    std::fs::write(&csv, format!("x,y,z,r,temperature\n{rows}")).unwrap();
    let text = format!(
        "[time]\nend = 1.0\ndt = 1.0e-3\nscheme = \"bdf2\"\n[output]\nsnapshots = 5\nvtu = false\nhdf5 = false\nseries_every = 100\n\
         [[materials]]\nname = \"titanium\"\npreset = \"titanium-ivannikov2022\"\n{extra}\n[particles]\nsource = \"file\"\nfile = \"{}\"\n\
         [thermal]\nmode = \"network\"\nradiation_tolerance = 1e-14\n[thermal.gap]\n{gap}\n",
        csv.display()
    );
    toml::Value::Table(text.parse::<toml::Table>().unwrap())
}

/// Runs a heat case, returns its summary and the temperatures at the snapshot times.
fn heat_run(v: toml::Value, out: &Path) -> (serde_json::Value, Vec<(f64, Vec<f64>)>) {
    let prep = sinterdem::scene::prepare(v, Path::new(".")).unwrap();
    sinterdem::kinds::heat::run_returning_temperatures(prep, out, false, &mut |_| {}, None, None, true).unwrap()
}

/// Two titanium spheres (20 and 30 µm) 1 µm apart, no contact, 400 K and 300 K: with the gas
/// alone the temperature difference decays as exp(−G(1/C1 + 1/C2) t) with G from (H18), to 1e-6
/// relative, and Σ C T stays constant to 1e-9 relative. A κ(T) table and an interface
/// conductance K_c, which act on contact pipes, leave the gap pipe alone.
#[test]
fn two_separated_spheres_relax_at_the_lumped_rate() {
    let dir = common::tmp_dir("pair");
    let (r1, r2, s) = (20e-6, 30e-6, 1e-6);
    let d = r1 + r2 + s;
    let rows = format!("0,0,0,{r1:e},400\n{d:e},0,0,{r2:e},300\n");
    let g = gas_conductance(K_G, r1, r2, d, outer_radius(r1, r2, d, 0.2).unwrap(), 0.0);
    let (rho, c) = (4506.0, 523.0);
    let cap = |r: f64| rho * c * 4.0 / 3.0 * PI * r * r * r;
    let (c1, c2) = (cap(r1), cap(r2));
    let lambda = g * (1.0 / c1 + 1.0 / c2);
    // run for two time constants with 4000 steps per time constant
    let tau = 1.0 / lambda;
    let timing = |v: &mut toml::Value| {
        apply_override(v, &format!("time.end={:e}", 2.0 * tau)).unwrap();
        apply_override(v, &format!("time.dt={:e}", tau / 4000.0)).unwrap();
    };
    for (name, extra, sets) in
        [("plain", "", vec![]), ("tables", "conductivity_table = [[300.0, 10.0], [500.0, 40.0]]", vec!["thermal.contact_conductance=1e-12"])]
    {
        let mut v = two_sphere_case(&dir, &rows, &format!("gas_conductivity = {K_G}"), extra);
        timing(&mut v);
        for s in sets {
            apply_override(&mut v, s).unwrap();
        }
        let (summary, temps) = heat_run(v, &dir.join(name));
        assert_eq!(summary["gap_pipes"], 1, "{name}");
        assert_eq!(summary["contacts"], 0, "{name}");
        assert!(temps.len() >= 5);
        let e0 = c1 * 400.0 + c2 * 300.0;
        for (t, tt) in &temps {
            let exact = 100.0 * (-lambda * t).exp();
            let got = tt[0] - tt[1];
            assert!(rel(got, exact) < 1e-6, "{name}: t = {t:e} s: ΔT {got} vs {exact}");
            assert!(rel(c1 * tt[0] + c2 * tt[1], e0) < 1e-9, "{name}: energy at t = {t:e} s");
        }
        assert!(temps.last().unwrap().1[0] - temps.last().unwrap().1[1] < 14.0, "{name}: two time constants");
    }
}

/// Radiation alone across the gap (ε = 0.8, vacuum) between equal spheres: with
/// x = T2 − T1 and the mean T_m fixed, C dx/dt = −2c(T2⁴ − T1⁴) = −2c(4T_m³x + T_m x³), whose
/// solution is x² = a/((a/x0² + b) e^{2at} − b), a = 8cT_m³/C, b = 2cT_m/C. The network's Picard
/// iteration on the exact secant (H23) follows it to 1e-6 relative and conserves Σ C T to 1e-9.
#[test]
fn radiation_across_the_gap_follows_the_quartic_exchange() {
    let dir = common::tmp_dir("rad");
    let (r, s, eps) = (25e-6, 1e-6, 0.8);
    let d = 2.0 * r + s;
    let rows = format!("0,0,0,{r:e},1000\n{d:e},0,0,{r:e},1400\n");
    let c_rad = radiation_coefficient(eps, outer_radius(r, r, d, 0.2).unwrap());
    let cap = 4506.0 * 523.0 * 4.0 / 3.0 * PI * r * r * r;
    let tm: f64 = 1200.0;
    let a = 8.0 * c_rad * tm.powi(3) / cap;
    let b = 2.0 * c_rad * tm / cap;
    let tau = 1.0 / a;
    let mut v = two_sphere_case(&dir, &rows, &format!("emissivity = {eps}"), "");
    apply_override(&mut v, &format!("time.end={:e}", 2.0 * tau)).unwrap();
    apply_override(&mut v, &format!("time.dt={:e}", tau / 4000.0)).unwrap();
    let (summary, temps) = heat_run(v, &dir.join("out"));
    assert_eq!(summary["gap_pipes"], 1);
    let x0: f64 = 400.0;
    for (t, tt) in &temps {
        let exact = (a / ((a / (x0 * x0) + b) * (2.0 * a * t).exp() - b)).sqrt();
        let got = tt[1] - tt[0];
        assert!(rel(got, exact) < 1e-6, "t = {t:e} s: ΔT {got} vs {exact}");
        assert!(rel(tt[0] + tt[1], 2.0 * tm) < 1e-9, "energy at t = {t:e} s");
    }
    // the quartic matters: the linearised rate a alone would be off by more than 1e-3 at t = τ/2
    let (t_half, _) = temps.iter().find(|(t, _)| *t > 0.3 * tau).unwrap();
    let lin = x0 * (-a * t_half).exp();
    let exact = (a / ((a / (x0 * x0) + b) * (2.0 * a * t_half).exp() - b)).sqrt();
    assert!(rel(lin, exact) > 1e-3);
}

/// The bundled hot-plate compact, 200 s: five particles touch nothing at the start (the nearest
/// neighbour of 798 is 75 nm away, outside the 25 nm gap tolerance); some find a contact as the
/// body shrinks (all but 798 by the end of the bundled 1200 s run), the others stay at 293.15 K. With argon's gas conductivity at the process
/// temperature (k_g = 0.05 W/(m·K)) none is isolated, 798 follows its gap neighbours within a few
/// kelvin and is named as reached only across gaps; the summary's minimum then includes it.
#[test]
fn the_isolated_particle_of_the_hot_plate_warms_through_the_gas() {
    let dir = common::tmp_dir("hotplate");
    let sets = ["time.end=200.0", "output.snapshots=0", "output.checkpoint_every=0", "output.vtu=false", "output.hdf5=false"];
    let load = |extra: &[&str]| {
        let all: Vec<String> = sets.iter().chain(extra).map(|s| s.to_string()).collect();
        sinterdem::config::load_case(Path::new("cases/hot-plate-compact.toml"), &all).unwrap()
    };
    // the bundled case carries the gas (issue 25): off is the same case with k_g = 0
    let mut off = coupled::prepare(load(&["thermal.gap.gas_conductivity=0.0"]), Path::new("cases"), &mut |_| {}).unwrap();
    assert_eq!(off.isolated_particles(), vec![136, 266, 640, 651, 798]);
    while off.t < off.settings.end {
        off.advance_step(&mut |_| {}).unwrap();
    }
    let iso = off.isolated_particles();
    assert!(iso.contains(&798) && iso.iter().all(|i| [136, 266, 640, 651, 798].contains(i)), "{iso:?}");
    for &i in &iso {
        assert!((off.prep.scene.particles.temperature[i as usize] - 293.15).abs() < 1e-9);
    }
    let mut on = coupled::prepare(load(&["thermal.gap.gas_conductivity=0.05"]), Path::new("cases"), &mut |_| {}).unwrap();
    assert!(on.isolated_particles().is_empty());
    assert_eq!(on.particles_connected_only_through_gaps(), vec![136, 266, 640, 651, 798]);
    while on.t < on.settings.end {
        on.advance_step(&mut |_| {}).unwrap();
    }
    assert!(on.isolated_particles().is_empty());
    // 798 still hangs on the gas (others of the five may not have sintered to a neighbour yet)
    let via = on.particles_connected_only_through_gaps();
    assert!(via.contains(&798) && via.iter().all(|i| [136, 266, 640, 651, 798].contains(i)), "{via:?}");
    let t = &on.prep.scene.particles.temperature;
    // its neighbours across the gas (surface gap below f·R_L)
    let gp = on.prep.gap.as_ref().unwrap().pipes().unwrap();
    let nb: Vec<usize> = gp.pairs.iter().filter(|pr| pr.contains(&798)).map(|&[i, j]| if i == 798 { j as usize } else { i as usize }).collect();
    assert!(nb.contains(&187), "{nb:?}");
    let mean_nb = nb.iter().map(|&k| t[k]).sum::<f64>() / nb.len() as f64;
    assert!(t[798] > 1300.0 && (t[798] - mean_nb).abs() < 5.0, "particle 798 at {} K, its gap neighbours at {mean_nb} K", t[798]);
    // through the driver: the summary lists nobody as isolated and names 798 as reached across gaps
    let sim = coupled::prepare(load(&["thermal.gap.gas_conductivity=0.05"]), Path::new("cases"), &mut |_| {}).unwrap();
    let s = sinterdem::kinds::compact::run(sim, &dir.join("on"), false, &mut |_| {}).unwrap();
    assert_eq!(s["isolated_particles"], 0);
    assert_eq!(s["particles_connected_only_through_gaps"], serde_json::json!(via));
    assert!(s["gap_pipes"].as_u64().unwrap() > 100);
    assert!(s["min_temperature_K"].as_f64().unwrap() <= t[798] + 1e-9);
    assert!(s["energy_balance_rel"].as_f64().unwrap() < 1e-8);
}

/// While no gap pipe exists the results are those without the model, bit for bit: the bundled
/// hot-plate compact (100 s) and the bundled hot-plate heat run (120 s), each without
/// `[thermal.gap]`, with it turned off (k_g = 0, ε = 0) and with a gas layer too thin to reach any
/// neighbour (the gap plumbing active, no pipe found).
#[test]
fn without_gap_pipes_the_results_are_unchanged_bit_for_bit() {
    let dir = common::tmp_dir("identical");
    let params = sinterdem::kinds::RunParams { base_dir: PathBuf::from("cases"), plots: false, ..Default::default() };
    for (case, sets) in [
        ("cases/hot-plate-compact.toml", vec!["time.end=100.0", "output.snapshots=0", "output.checkpoint_every=0"]),
        ("cases/hot-plate.toml", vec!["time.end=120.0", "particles.cells=[4, 4, 6]", "output.snapshots=0"]),
    ] {
        // the case without its [thermal.gap] table (the bundled hot-plate compact carries the
        // gas since issue 25), written beside the outputs; relative paths resolve from `cases`
        let text: String = {
            let full = std::fs::read_to_string(case).unwrap();
            let mut keep = true;
            full.lines()
                .filter(|l| {
                    if l.starts_with('[') {
                        keep = l.trim() != "[thermal.gap]";
                    }
                    keep
                })
                .map(|l| format!("{l}\n"))
                .collect()
        };
        assert!(!text.lines().any(|l| l.trim() == "[thermal.gap]"));
        let stripped = dir.join(Path::new(case).file_name().unwrap());
        std::fs::write(&stripped, text).unwrap();
        let v = sinterdem::config::load_case(&stripped, &[]).unwrap();
        let mut series = Vec::new();
        for (k, extra) in [vec![], vec!["thermal.gap.gas_conductivity=0.0"], vec!["thermal.gap.gas_conductivity=0.05", "thermal.gap.layer_thickness=1e-9"]]
            .into_iter()
            .enumerate()
        {
            let all: Vec<String> = sets.iter().chain(&extra).map(|s| s.to_string()).collect();
            let out = dir.join(format!("{}-{k}", Path::new(case).file_stem().unwrap().to_string_lossy()));
            let s = sinterdem::kinds::run(&v, &all, &out, &params).unwrap();
            if k == 2 {
                assert_eq!(s.summary["gap_pipes"], 0, "{case}");
            }
            series.push(std::fs::read_to_string(out.join("series.csv")).unwrap());
        }
        assert!(series[0].lines().count() > 5);
        assert_eq!(series[0], series[1], "{case}: [thermal.gap] turned off changed the series");
        assert_eq!(series[0], series[2], "{case}: a gap model without pipes changed the series");
    }
}

/// A compact run with the gap model, killed right after its checkpoint and resumed, equals the
/// uninterrupted run: the gap pipes depend on the positions only, not on when the neighbour
/// list was built.
#[test]
fn a_compact_run_with_the_gap_model_resumes_bit_for_bit() {
    let dir = common::tmp_dir("resume");
    let sets: Vec<String> =
        ["time.end=60.0", "output.snapshots=0", "output.checkpoint_every=7", "thermal.gap.gas_conductivity=0.05", "thermal.gap.layer_thickness=0.4"]
            .map(String::from)
            .to_vec();
    let v = sinterdem::config::load_case(Path::new("cases/hot-plate-compact.toml"), &sets).unwrap();
    let full = dir.join("full");
    let sim = coupled::prepare(v.clone(), Path::new("cases"), &mut |_| {}).unwrap();
    let s_full = sinterdem::kinds::compact::run(sim, &full, false, &mut |_| {}).unwrap();
    let part = dir.join("part");
    let sim = coupled::prepare(v, Path::new("cases"), &mut |_| {}).unwrap();
    assert!(sinterdem::kinds::compact::run_from(sim, &part, false, &mut |_| {}, None, Some(14)).unwrap().is_null());
    let s_res = sinterdem::kinds::compact::resume(&part, false, &mut |_| {}).unwrap();
    for key in ["steps", "shrinkage_z", "min_temperature_K", "mean_temperature_K", "gap_pipes", "energy_balance_rel"] {
        assert_eq!(s_full[key], s_res[key], "{key}");
    }
    assert_eq!(std::fs::read_to_string(full.join("series.csv")).unwrap(), std::fs::read_to_string(part.join("series.csv")).unwrap());
}

/// Bad `[thermal.gap]` input is refused naming key, value, allowed range and unit; the model in
/// an isothermal scene and unknown keys are refused too.
#[test]
fn bad_gap_keys_are_refused_with_key_value_range_and_unit() {
    let dir = common::tmp_dir("bad");
    let rows = "0,0,0,25e-6,400\n51e-6,0,0,25e-6,300\n";
    for (gap, key, value, range, unit) in [
        ("gas_conductivity = -0.1", "thermal.gap.gas_conductivity", "-0.1", "[0, 1]", "W/(m K)"),
        ("gas_conductivity = 5.0", "thermal.gap.gas_conductivity", "5", "[0, 1]", "W/(m K)"),
        ("layer_thickness = 0.0", "thermal.gap.layer_thickness", "0", "(0, 1]", "1"),
        ("layer_thickness = 1.5", "thermal.gap.layer_thickness", "1.5", "(0, 1]", "1"),
        ("jump_distance = -1e-7", "thermal.gap.jump_distance", "-1e-7", "[0, 0.001]", "m"),
        ("emissivity = 1.2", "thermal.gap.emissivity", "1.2", "[0, 1]", "1"),
    ] {
        let v = two_sphere_case(&dir, rows, gap, "");
        let e = sinterdem::scene::prepare(v, Path::new(".")).err().expect(gap).to_string();
        for part in [key, value, range, unit] {
            assert!(e.contains(part), "{gap}: «{part}» missing in: {e}");
        }
    }
    let v = two_sphere_case(&dir, rows, "gas_conductivity = 0.02\nlayer = 0.3", "");
    let e = sinterdem::scene::prepare(v, Path::new(".")).err().unwrap().to_string();
    assert!(e.contains("layer"), "{e}");
    let mut v = two_sphere_case(&dir, rows, "gas_conductivity = 0.02", "");
    let th = v.get_mut("thermal").unwrap().as_table_mut().unwrap();
    th.insert("mode".into(), "isothermal".into());
    th.insert("furnace".into(), toml::Value::Table("profile = { constant = 1000.0 }".parse::<toml::Table>().unwrap()));
    let e = sinterdem::scene::prepare(v, Path::new(".")).err().unwrap().to_string();
    assert!(e.contains("thermal.gap") && e.contains("isothermal"), "{e}");
}

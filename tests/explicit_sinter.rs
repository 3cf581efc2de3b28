//! The explicit sintering laws in the velocity-Verlet driver and Luding's protocol (issue 6 items
//! 3–4): closed forms through the driver, the paper's qualitative trends with numbers on tiny
//! samples, stress control, thread-count determinism, rejection of bad input.
use nalgebra::Vector3;
use sinterdem::explicit::law::ContactModel;
use sinterdem::explicit::sinter::{FrenkelLaw, LudingLaw};
use sinterdem::explicit::{Explicit, Settings, time_step};
use sinterdem::kinds::explicit_sinter::{check_explicit_case, parse_explicit_case, run_explicit, run_explicit_case};
use sinterdem::models::frenkel::{FrenkelParams, FrenkelSpec};
use sinterdem::models::luding::{LudingParams, LudingSpec};
use sinterdem::particles::Particles;

mod common;

type V3 = Vector3<f64>;

fn tab(text: &str) -> toml::Value {
    toml::Value::Table(text.parse::<toml::Table>().unwrap())
}

fn pair(v: f64, r: f64, temperature: f64) -> Particles {
    let mut p = Particles::default();
    p.push(V3::new(-r - 1e-7, 0.0, 0.0), r, 0, 2000.0, 1000.0, temperature);
    p.push(V3::new(r + 1e-7, 0.0, 0.0), r, 0, 2000.0, 1000.0, temperature);
    p.velocity[0] = V3::new(0.5 * v, 0.0, 0.0);
    p.velocity[1] = V3::new(-0.5 * v, 0.0, 0.0);
    p
}

/// Head-on collision through the driver; returns (restitution, largest overlap, driver).
fn collide<M: ContactModel>(law: M, v: f64, r: f64, temperature: f64) -> (f64, f64, Explicit<M>) {
    let mut p = pair(v, r, temperature);
    let (dt, _) = time_step(&law, &p, 0.002, v, false).unwrap();
    let mut s = Settings::new(dt, r);
    s.rotation = false;
    let mut sim = Explicit::new(s, law, vec![]).unwrap();
    let mut on = false;
    let mut dmax: f64 = 0.0;
    for _ in 0..2_000_000 {
        sim.step(&mut p).unwrap();
        let d = 2.0 * r - (p.position[0] - p.position[1]).norm();
        dmax = dmax.max(d);
        let touching = !sim.contacts().is_empty();
        on |= touching;
        if on && !touching {
            break;
        }
    }
    ((p.velocity[1][0] - p.velocity[0][0]) / v, dmax, sim)
}

#[test]
fn luding_collision_in_the_driver_has_the_hysteretic_restitution() {
    // Undamped, cohesionless, cold: loading on k1, unloading on k2(δ_max) (eqs. 4, 7) gives the
    // Walton–Braun restitution e = √(k1/k2(δ_max)) with δ_max = v·√(m_ij/k1).
    let spec = LudingSpec { gamma_n: 0.0, gamma_t: 0.0, kc: 0.0, friction: 0.0, ..LudingSpec::default() };
    let r = 1e-3;
    let p = LudingParams::new(&spec, r).unwrap();
    let m = 2000.0 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    for v in [0.05, 0.5, 2.0] {
        let (e, dmax, sim) = collide(LudingLaw::new(p.clone()), v, r, 300.0);
        let dmax_exact = v * (0.5 * m / p.k1).sqrt();
        let e_exact = (p.k1 / p.k2_of(dmax_exact)).sqrt();
        assert!((dmax - dmax_exact).abs() < 2e-3 * dmax_exact, "v {v}: dmax {dmax} vs {dmax_exact}");
        assert!((e - e_exact).abs() < 3e-3, "v {v}: e {e} vs {e_exact}");
        // the state the driver kept is the law's history: δ_max and k1(T,t) = k1 (cold)
        assert!(sim.counters.steps > 0);
    }
    // hot contact (T = T_melt + 20 K): k1(T) = k1·(1 + tanh(−2))/2, much softer loading, so a
    // deeper overlap and a lower restitution
    let t_hot = p.t_melt + 20.0;
    let k1t = p.k1_of_temperature(t_hot);
    let v = 0.05;
    let (e, dmax, _) = collide(LudingLaw::new(p.clone()), v, r, t_hot);
    let dmax_exact = v * (0.5 * m / k1t).sqrt();
    assert!((dmax - dmax_exact).abs() < 5e-3 * dmax_exact, "hot: dmax {dmax} vs {dmax_exact}");
    assert!((e - (k1t / p.k2_of(dmax_exact)).sqrt()).abs() < 5e-3, "hot: e {e}");
}

#[test]
fn frenkel_pair_in_the_driver_sinters_at_the_steady_rate() {
    // A free pair under the constant-rate law (docs/frenkel.md): in steady free sintering F → f_a = s_a·D*
    // and the plastic overlap grows at ṙ = 2·k_s·D*. Through the driver (damped, pull included).
    let r = 1e-3;
    let spec = FrenkelSpec {
        k1: 1e5,
        k2_max: 2e5,
        penetration_depth_max: 0.2,
        damping: 0.2,
        sinter_adhesion: 50.0,
        sinter_rate: Some(0.05),
        ..FrenkelSpec::default()
    };
    let params = FrenkelParams::new(&spec).unwrap();
    let law = FrenkelLaw { params };
    let mut p = pair(0.0, r, 300.0);
    // start at the elastic equilibrium with the pull, k1·δ = s_a·D* = 0.05 N
    p.position[0][0] = -r + 2.5e-7;
    p.position[1][0] = r - 2.5e-7;
    let (dt, _) = time_step(&law, &p, 0.02, 0.0, false).unwrap();
    let mut s = Settings::new(dt, r);
    s.rotation = false;
    let mut sim = Explicit::new(s, law, vec![]).unwrap();
    let steps = (0.02 / dt) as u64;
    sim.run(&mut p, steps).unwrap();
    let dp0 = sim.contact_states()[0].2.delta_p;
    let t0 = sim.time;
    sim.run(&mut p, steps).unwrap();
    let dp1 = sim.contact_states()[0].2.delta_p;
    let rate = (dp1 - dp0) / (sim.time - t0);
    let expect = 2.0 * 0.05 * r; // 2 k_s D*, D* = 2 R_red = r
    assert!((rate / expect - 1.0).abs() < 0.02, "rate {rate:e} vs {expect:e}");
    // the contact force settles at the pull: F − f_a → 0 (force on the pair)
    let f = sim.contact_states()[0].1;
    assert!(f.abs() < 0.02 * 50.0 * r, "net normal force {f}");
}

fn small_luding_case(pressures: &str, t_sinter: &str, particles: usize) -> toml::Value {
    format!(
        r#"
kind = "explicit_sinter"
model = "luding"
[sample]
particles = {particles}
seed = 3
radius_spread = 0.2
initial_fraction = 0.3
[walls]
pressures = {pressures}
[protocol]
t_prepare = 0.02
t_heat = 0.004
t_sinter = {t_sinter}
t_cool = 0.004
t_relax = 0.004
t0_sinter = 0.004
output_interval = 0.0005
[compression]
strain_rate = 4.0
max_strain = 0.03
output_strain = 0.001
"#
    )
    .parse::<toml::Table>()
    .map(toml::Value::Table)
    .unwrap()
}

#[test]
fn luding_protocol_reproduces_the_papers_trends() {
    let case = parse_explicit_case(&small_luding_case("[5e3, 5e4]", "[0.002, 0.03]", 40)).unwrap();
    let run = run_explicit(&case, false).unwrap();
    assert_eq!(run.branches.len(), 4);
    let b = |p: f64, ts: f64| run.branches.iter().find(|b| b.pressure == p && b.t_sinter == ts).unwrap();
    for &p in &[5e3, 5e4] {
        let (short, long) = (b(p, 0.002), b(p, 0.03));
        eprintln!(
            "p {p:e}: prepared {:.4}, sintered {:.4} / {:.4}, final {:.4} / {:.4}, fmin cooled {:.3e} / {:.3e}, peak {:.4e} / {:.4e}",
            short.density_prepared,
            short.density_sintered,
            long.density_sintered,
            short.density_final,
            long.density_final,
            short.min_force_cooled,
            long.min_force_cooled,
            short.peak_stress,
            long.peak_stress
        );
        // identical preparation for both branches
        assert_eq!(short.density_prepared, long.density_prepared);
        // density rises with sintering time (Fig. 9)
        assert!(long.density_sintered > short.density_sintered + 0.005, "p {p}: {} vs {}", long.density_sintered, short.density_sintered);
        assert!(long.density_final > short.density_final, "p {p}");
        // longer sintering: stronger in compression (Figs. 17, 19)
        assert!(long.peak_stress > short.peak_stress, "p {p}: peak {} vs {}", long.peak_stress, short.peak_stress);
        // stress control: averaged over the history after the first compaction, the top wall
        // carries the confining pressure (eq. 1 in equilibrium)
        for br in [short, long] {
            let s: Vec<f64> = br.history.iter().filter(|r| r.time >= 0.01).map(|r| r.stress[2]).collect();
            let mean = s.iter().sum::<f64>() / s.len() as f64;
            assert!((mean / p - 1.0).abs() < 0.15, "p {p}: mean sigma_zz {mean}");
        }
    }
    // attractive contacts after cool-down (Figs. 14–15): the smallest normal force after cooling
    // and relaxing is negative and more attractive than at the end of sintering, except for the
    // long-sintered sample at the high pressure, whose 40-particle packing stays all-compressive
    for (p, ts) in [(5e3, 0.002), (5e3, 0.03), (5e4, 0.002)] {
        let br = b(p, ts);
        assert!(br.min_force_cooled < 0.0 && br.min_force_cooled < br.min_force_sintered, "p {p} ts {ts}: {} / {}", br.min_force_cooled, br.min_force_sintered);
    }
    // density rises with confining pressure
    assert!(b(5e4, 0.03).density_final > b(5e3, 0.03).density_final);
    assert!(b(5e4, 0.002).density_sintered > b(5e3, 0.002).density_sintered);
}

#[test]
fn frenkel_protocol_densifies_with_sintering_time() {
    let text = r#"
kind = "explicit_sinter"
model = "frenkel"
[sample]
particles = 40
seed = 3
radius_spread = 0.2
[walls]
pressures = [2e4]
[protocol]
t_prepare = 0.012
t_heat = 0.004
t_sinter = [0.002, 0.03]
t_cool = 0.004
t_relax = 0.004
output_interval = 0.0005
[compression]
enabled = false
[frenkel]
k1 = 1e5
k2_max = 2e5
kc = 1e5
penetration_depth_max = 0.1
damping = 0.2
sinter_adhesion = 50.0
sinter_type = "temperature_frenkel"
rate_table = [[353.15, 0.0], [393.15, 0.0], [413.15, 2.0]]
friction = 0.5
tangential_stiffness = 4e4
tangential_damping = 0.05
"#;
    let v: toml::Value = text.parse::<toml::Table>().map(toml::Value::Table).unwrap();
    let case = parse_explicit_case(&v).unwrap();
    let run = run_explicit(&case, false).unwrap();
    let (short, long) = (&run.branches[0], &run.branches[1]);
    eprintln!("frenkel: sintered {:.4} / {:.4}, final {:.4} / {:.4}", short.density_sintered, long.density_sintered, short.density_final, long.density_final);
    assert!(long.density_sintered > short.density_sintered + 0.005);
    assert!(long.density_final > short.density_final);
    // mean plastic overlap grows during sintering and not before (k_s = 0 when cold)
    let h = &long.history;
    let before = h.iter().rfind(|r| r.time <= 0.012).unwrap().state_mean;
    let after = h.iter().rfind(|r| r.time <= 0.046).unwrap().state_mean;
    assert!(after > 2.0 * before, "delta_p {before:e} -> {after:e}");
}

#[test]
fn protocol_is_bit_identical_for_any_thread_count() {
    let mut v = small_luding_case("[5e4]", "[0.001]", 24);
    let t = v.as_table_mut().unwrap();
    t.insert("stepping".into(), tab("parallel_threshold = 0"));
    let proto = t.get_mut("protocol").unwrap().as_table_mut().unwrap();
    proto.insert("t_prepare".into(), toml::Value::Float(0.004));
    proto.insert("t_heat".into(), toml::Value::Float(0.002));
    let case = parse_explicit_case(&v).unwrap();
    let run_with = |n: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
        pool.install(|| run_explicit(&case, false).unwrap())
    };
    let (a, b) = (run_with(1), run_with(2));
    let key = |r: &sinterdem::kinds::explicit_sinter::ExplicitSinterRun| {
        r.branches
            .iter()
            .flat_map(|b| {
                b.history.iter().chain(&b.compression).flat_map(|r| [r.density, r.stress[2], r.force_min, r.state_mean]).chain(b.forces_cooled.iter().copied())
            })
            .map(f64::to_bits)
            .collect::<Vec<u64>>()
    };
    assert!(!key(&a).is_empty());
    assert_eq!(key(&a), key(&b));
}

#[test]
fn network_coupling_heats_the_interior_through_the_contacts() {
    let mut v = small_luding_case("[5e4]", "[0.004]", 30);
    let t = v.as_table_mut().unwrap();
    t.insert("coupling".into(), tab("mode = \"network\"\nheat_every = 50\nconductivity = 200.0\nspecific_heat = 1000.0"));
    t.insert("compression".into(), tab("enabled = false"));
    let case = parse_explicit_case(&v).unwrap();
    let run = run_explicit(&case, false).unwrap();
    let b = &run.branches[0];
    assert!(b.heat_solves > 10);
    // the mean temperature follows the wall profile with a lag: below T_hot at the end of heating,
    // above T_cold at the start of cooling, back at T_cold after relaxing
    let hot = 413.15;
    let end_heat = b.history.iter().rfind(|r| r.time <= 0.016).unwrap();
    assert!(end_heat.temperature <= hot + 1e-9);
    let last = b.history.last().unwrap();
    assert!(last.temperature > 353.15 - 1e-6 && last.temperature < 353.15 + 20.0, "final T {}", last.temperature);
    // a coarse heat step is reported
    let mut v2 = v.clone();
    v2["coupling"].as_table_mut().unwrap().insert("heat_every".into(), toml::Value::Integer(20000));
    let run2 = run_explicit(&parse_explicit_case(&v2).unwrap(), false).unwrap();
    assert!(run2.warnings.iter().any(|w| w.contains("fastest thermal time")), "{:?}", run2.warnings);
}

#[test]
fn writes_series_plots_and_summary() {
    let mut v = small_luding_case("[5e4]", "[0.001]", 16);
    let proto = v.as_table_mut().unwrap().get_mut("protocol").unwrap().as_table_mut().unwrap();
    proto.insert("t_prepare".into(), toml::Value::Float(0.004));
    let dir = common::tmp_dir("run");
    let s = run_explicit_case(&v, &dir, false).unwrap();
    assert_eq!(s["branches"].as_array().unwrap().len(), 1);
    for f in [
        "summary.json",
        "density.png",
        "compression_stress.png",
        "force_pdf_cooled.png",
        "history_p5e4_ts0.001.csv",
        "compression_p5e4_ts0.001.csv",
        "forces_p5e4_ts0.001.csv",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let csv = std::fs::read_to_string(dir.join("history_p5e4_ts0.001.csv")).unwrap();
    assert!(csv.starts_with("time_s,temperature_K,density,coordination,sigma_xx_Pa"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_is_rejected_with_the_key_named() {
    let base = small_luding_case("[5e4]", "[0.01]", 20);
    let with = |path: &[&str], val: toml::Value| {
        let mut v = base.clone();
        let mut t = v.as_table_mut().unwrap();
        for k in &path[..path.len() - 1] {
            t = t.entry(k.to_string()).or_insert_with(|| toml::Value::Table(Default::default())).as_table_mut().unwrap();
        }
        t.insert(path[path.len() - 1].to_string(), val);
        check_explicit_case(&v).unwrap_err().to_string()
    };
    assert!(check_explicit_case(&base).is_ok());
    let e = with(&["walls", "pressures"], toml::Value::Array(vec![toml::Value::Float(-1.0)]));
    assert!(e.contains("walls.pressures"), "{e}");
    let e = with(&["luding", "k2"], toml::Value::Float(5e4));
    assert!(e.contains("luding.k2"), "{e}");
    let e = with(&["luding", "t_var"], toml::Value::Float(0.0));
    assert!(e.contains("luding.t_var"), "{e}");
    let e = with(&["protocol", "t_sintering"], toml::Value::Float(1.0));
    assert!(e.contains("t_sintering"), "{e}");
    let e = with(&["model"], toml::Value::String("hertz".into()));
    assert!(e.contains("model"), "{e}");
    let e = with(&["sample", "particles"], toml::Value::Float(10.5));
    assert!(e.contains("sample.particles"), "{e}");
    let e = with(&["coupling", "mode"], toml::Value::String("network".into()));
    assert!(e.contains("coupling.conductivity"), "{e}");
    let e = with(&["stepping", "dt_fraction"], toml::Value::Float(2.0));
    assert!(e.contains("stepping.dt_fraction"), "{e}");
}

#[test]
fn bundled_cases_check() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let path = e.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if (name.starts_with("luding-") || name.starts_with("frenkel-")) && name.ends_with(".toml") {
            let v = sinterdem::config::load_case(&path, &[]).unwrap();
            check_explicit_case(&v).unwrap_or_else(|e| panic!("{name}: {e}"));
            n += 1;
        }
    }
    assert!(n >= 3, "{n} bundled explicit_sinter cases");
}

//! Applied load (docs/pressure.md): zero load is bit-identical to no load; the stress term (M11)
//! of the 7-DOF model is linear in the force, has the closed-form response (M13) and keeps the
//! dissipation identity (M12); a compact under uniaxial stress shrinks more along the load, its
//! macroscopic stress (P4) carries the applied stress; bad load keys give clear errors.

use sinterdem::config::apply_override;
use sinterdem::coupled;
use sinterdem::kinds::pair::{parse_pair_case, run_pair};
use sinterdem::models::diffusion7::{Contact7, evaluate, invariants};
use std::path::{Path, PathBuf};

mod common;

/// A block of the bundled green copper packing: x, y below `edge`, z below `height` [m].
fn column_packing(dir: &Path, edge: f64, height: f64) -> PathBuf {
    common::write_block(dir, "block.csv", "x,y,z,r", common::green_copper_block(edge, height).into_iter().map(|(l, _)| l))
}

/// The copper compact of the tests on `packing` until 300 s, with the `[load]` table `load`.
fn compact_case(packing: &Path, load: &str, sets: &[&str]) -> toml::Value {
    common::case_value(&format!("{}{load}\n", common::copper_compact_text(packing, 300.0)), sets)
}

fn run(v: toml::Value, out: &Path) -> (serde_json::Value, String) {
    let sim = coupled::prepare(v, Path::new("."), &mut |_| {}).unwrap();
    let s = sinterdem::kinds::compact::run(sim, out, false, &mut |_| {}).unwrap();
    (s, std::fs::read_to_string(out.join("series.csv")).unwrap())
}

#[test]
fn zero_load_is_bit_identical_to_no_load() {
    let dir = common::tmp_dir("zero");
    let csv = column_packing(&dir, 0.2e-3, 0.2e-3);
    let (a, sa) = run(compact_case(&csv, "", &[]), &dir.join("none"));
    for (k, load) in [
        "[load]\nmode = \"uniaxial\"\naxis = \"z\"\nstress = 0.0\ncontact_stress_limit = 3.0e7",
        "[load]\nmode = \"isostatic\"\nstress_table = [[0.0, 0.0], [1000.0, 0.0]]",
        "[load]\nmode = \"none\"",
    ]
    .iter()
    .enumerate()
    {
        let (b, sb) = run(compact_case(&csv, load, &[]), &dir.join(format!("zero{k}")));
        for key in ["shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "neck_ratio", "steps", "contacts", "rhs_evaluations", "dl_bar_mean_m"] {
            assert_eq!(a[key], b[key], "{key} differs with {load}");
        }
        // the columns of both runs are bit-identical; a [load] (even of zero stress) adds the
        // load columns (docs/outputs.md "CSV"), which then read 0
        let (ha, hb): (Vec<&str>, Vec<&str>) = (sa.lines().next().unwrap().split(',').collect(), sb.lines().next().unwrap().split(',').collect());
        let load_cols = ["applied_stress_Pa", "sigma_xx_Pa", "sigma_yy_Pa", "sigma_zz_Pa", "sigma_yz_Pa", "sigma_xz_Pa", "sigma_xy_Pa", "normal_force_mean_N"];
        let mode_none = load.contains("\"none\"");
        assert_eq!(hb.len(), ha.len() + if mode_none { 0 } else { load_cols.len() }, "{hb:?}");
        for (la, lb) in sa.lines().zip(sb.lines()).skip(1) {
            let (va, vb): (Vec<&str>, Vec<&str>) = (la.split(',').collect(), lb.split(',').collect());
            for (k, name) in hb.iter().enumerate() {
                match ha.iter().position(|h| h == name) {
                    Some(j) => assert_eq!(va[j], vb[k], "{name} differs with {load}"),
                    None => assert!(load_cols.contains(name) && vb[k].parse::<f64>().unwrap() == 0.0, "{name} = {} with {load}", vb[k]),
                }
            }
        }
        assert_eq!(b["stress_tensor_Pa"]["zz"], 0.0);
    }
}

fn pair_spec(force: f64) -> sinterdem::kinds::pair::PairSpec {
    let text = format!(
        "kind = \"pair\"\n[pair]\nmaterial = \"copper-ivannikov2022\"\nradius = 25e-6\nend_time = 1000.0\n[temperature]\nconstant = 1293.0\n[solver]\nrtol = 1e-9\n[load]\nforce = {force:e}\n"
    );
    parse_pair_case(&toml::Value::Table(text.parse().unwrap())).unwrap()
}

#[test]
fn stress_term_has_the_closed_form_response_and_keeps_the_dissipation_identity() {
    // the single state of docs/diffusion7.md §11 (copper, 1293 K, R = 25 µm)
    let r = 25e-6;
    let y = [0.3 * r, r, 0.05 * r, 0.97 * r, r, 0.05 * r, 0.97 * r];
    let spec = pair_spec(0.0);
    let params = spec.materials().params_at(1293.0);
    let mut k = params.at(1293.0).unwrap();
    let e0 = evaluate(&y, &k).unwrap();
    let f = 4e-4;
    k.normal_force = f;
    let e1 = evaluate(&y, &k).unwrap();
    // (M11): only μ4 and μ7 move, by Ω F/(∂V/∂y4), Ω F/(∂V/∂y7)
    for i in [0, 1, 2, 4, 5] {
        assert_eq!(e0.mu[i], e1.mu[i]);
    }
    assert!((e1.mu[3] - e0.mu[3] - k.omega * f / e0.dv[3]).abs() < 1e-12 * e1.mu[3].abs());
    // compression speeds up the approach, by the closed form (M13)
    let dv0 = -(e0.dydt[3] + e0.dydt[6]);
    let dv1 = -(e1.dydt[3] + e1.dydt[6]);
    let mobility = k.omega * ((k.k_gb + k.k_lat_gb[0] * y[0]) / (e0.dv[3] * e0.dv[3]) + (k.k_gb + k.k_lat_gb[1] * y[0]) / (e0.dv[6] * e0.dv[6]));
    assert!(dv1 > dv0 && dv0 > 0.0);
    assert!(((dv1 - dv0) / (f * mobility) - 1.0).abs() < 1e-9, "{} vs {}", dv1 - dv0, f * mobility);
    // the effective GB area ∂V/∂y4 of (M11) against π a² (docs/pressure.md: 1.235 at this state)
    let ratio = e0.dv[3] / (std::f64::consts::PI * y[0] * y[0]);
    assert!((ratio - 1.2356).abs() < 1e-3, "{ratio}");
    // the load equivalent of the capillary drive (M14): the force that doubles the approach rate
    println!("approach rate {dv0:.4e} m/s, mobility {mobility:.4e} m/(N s), F_s = {:.4e} N", dv0 / mobility);
    // (M12): dΨ/dt of Ψ = 𝒢 + F (y4 + y7) along the flow equals Σ μ_i Q_i / Ω and is negative;
    // the load's power −F·d(y4 + y7)/dt is a large share of it, so the check sees the term's form
    let psi = |yy: &[f64; 7]| invariants(yy, &params).unwrap().1 + f * (yy[3] + yy[6]);
    assert!(f * dv1 > 0.2 * e1.dg_dt.abs(), "{} vs {}", f * dv1, e1.dg_dt);
    let fd = |step: f64| {
        let h = step * r / e1.dydt.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let yp: [f64; 7] = std::array::from_fn(|i| y[i] + h * e1.dydt[i]);
        let ym: [f64; 7] = std::array::from_fn(|i| y[i] - h * e1.dydt[i]);
        (psi(&yp) - psi(&ym)) / (2.0 * h)
    };
    // central differences converge quadratically to it (1e-2: 8e-3, 1e-3: 7e-5, 1e-4: 7e-7)
    let dpsi = fd(1e-4);
    assert!(e1.dg_dt < 0.0);
    assert!((dpsi / e1.dg_dt - 1.0).abs() < 1e-5, "finite difference {dpsi} vs {}", e1.dg_dt);
}

#[test]
fn pair_densifies_faster_linearly_in_a_small_force() {
    // copper pair 50 µm, 1293 K, 1000 s; forces far below the load-equivalent of the capillary
    // drive (about 1e-4 N at y1/R = 0.3, docs/pressure.md)
    let s0 = run_pair(&pair_spec(0.0), false, false).unwrap().contact.shrinkage();
    let f = 2e-6;
    let s1 = run_pair(&pair_spec(f), false, false).unwrap().contact.shrinkage();
    let s2 = run_pair(&pair_spec(2.0 * f), false, false).unwrap().contact.shrinkage();
    let (d1, d2) = (s1 - s0, s2 - s0);
    println!("shrinkage at 1000 s: F = 0: {s0:.6e}; F = {f:e} N: +{d1:.4e}; 2F: +{d2:.4e}; ratio {:.4}", d2 / d1);
    assert!(d1 > 1e-3 * s0, "a force of {f} N must be visible: {d1}");
    assert!((d2 / d1 - 2.0).abs() < 0.04, "increments at F and 2F: ratio {}", d2 / d1);
    // tension slows it down, symmetrically at small force
    let sm = run_pair(&pair_spec(-f), false, false).unwrap().contact.shrinkage();
    assert!(((s0 - sm) / d1 - 1.0).abs() < 0.04, "{sm} {s0} {d1}");
    // a contact created with the force carries it
    let c: Contact7 = pair_spec(f).new_contact().unwrap();
    assert_eq!(c.normal_force, f);
}

#[test]
fn uniaxial_compact_shrinks_more_along_the_load_and_carries_the_stress() {
    let dir = common::tmp_dir("uniaxial");
    let csv = column_packing(&dir, 0.25e-3, 0.4e-3);
    let (free, _) = run(compact_case(&csv, "", &[]), &dir.join("free"));
    let sigma = 2.0e6;
    let load = format!("[load]\nmode = \"uniaxial\"\naxis = \"z\"\nstress = {sigma:e}\ncontact_stress_limit = 3.0e7");
    let (s, series) = run(compact_case(&csv, &load, &[]), &dir.join("z"));
    let g = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    let (sx, sy, sz) = (g(&s, "shrinkage_x"), g(&s, "shrinkage_y"), g(&s, "shrinkage_z"));
    println!(
        "free: {:.4e} {:.4e} {:.4e}; {sigma:e} Pa along z: {sx:.4e} {sy:.4e} {sz:.4e}",
        g(&free, "shrinkage_x"),
        g(&free, "shrinkage_y"),
        g(&free, "shrinkage_z")
    );
    println!("stress tensor {}", s["stress_tensor_Pa"]);
    assert!(sz > 1.2 * sx && sz > 1.2 * sy, "load along z: {sx} {sy} {sz}");
    assert!(sz > 1.2 * g(&free, "shrinkage_z"), "pressure must speed up densification");
    assert!(g(&s, "relative_density") > g(&free, "relative_density"));
    // (P4): σ_zz carries the applied stress, reduced by the lever of the centres against the
    // box height (the load acts at the top-layer centres, the reactions at the bottom-layer
    // centres): σ_zz ≈ −σ (H − 2 r̄)/H within 15 %; lateral stresses small
    let st = &s["stress_tensor_Pa"];
    let zz = st["zz"].as_f64().unwrap();
    let h = 0.4e-3 * (1.0 - sz);
    let r = 25e-6;
    let expect = -sigma * (h - 2.0 * r) / h;
    assert!((zz / expect - 1.0).abs() < 0.15, "sigma_zz {zz} vs {expect}");
    for c in ["xx", "yy", "xy", "xz", "yz"] {
        assert!(st[c].as_f64().unwrap().abs() < 0.1 * zz.abs(), "{c}: {}", st[c]);
    }
    assert!(g(&s, "normal_force_mean_N") > 0.0);
    let header = series.lines().next().unwrap();
    assert!(header.ends_with("applied_stress_Pa,sigma_xx_Pa,sigma_yy_Pa,sigma_zz_Pa,sigma_yz_Pa,sigma_xz_Pa,sigma_xy_Pa,normal_force_mean_N"), "{header}");
    // isostatic: the three axes shrink alike, more than without load
    let load = format!("[load]\nmode = \"isostatic\"\nstress = {sigma:e}\ncontact_stress_limit = 3.0e7");
    let (iso, _) = run(compact_case(&csv, &load, &[]), &dir.join("iso"));
    let (ix, iy, iz) = (g(&iso, "shrinkage_x"), g(&iso, "shrinkage_y"), g(&iso, "shrinkage_z"));
    println!("isostatic: {ix:.4e} {iy:.4e} {iz:.4e}; stress {}", iso["stress_tensor_Pa"]);
    assert!(ix > 1.2 * g(&free, "shrinkage_x") && iy > 1.2 * g(&free, "shrinkage_y") && iz > 1.2 * g(&free, "shrinkage_z"));
    let st = &iso["stress_tensor_Pa"];
    for c in ["xx", "yy", "zz"] {
        assert!(st[c].as_f64().unwrap() < -0.5 * sigma, "{c}: {}", st[c]);
    }
}

fn check_err(v: toml::Value) -> String {
    match coupled::prepare(v, Path::new("."), &mut |_| {}) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_load_keys_give_clear_errors() {
    let dir = common::tmp_dir("keys");
    let csv = column_packing(&dir, 0.2e-3, 0.2e-3);
    let cases = [
        ("[load]\nmode = \"press\"\nstress = 1e6", "load.mode"),
        ("[load]\nmode = \"uniaxial\"\naxis = \"w\"\nstress = 1e6", "load.axis"),
        ("[load]\nmode = \"uniaxial\"\nstress = -1e6", "load.stress"),
        ("[load]\nmode = \"uniaxial\"\nstress = 1e6\nstress_table = [[0.0, 1e6]]", "exactly one"),
        ("[load]\nmode = \"uniaxial\"", "exactly one"),
        ("[load]\nmode = \"isostatic\"\naxis = \"z\"\nstress = 1e6", "load.axis"),
        ("[load]\nmode = \"uniaxial\"\nstress_table = [[0.0, 0.0], [0.0, 1e6]]", "load.stress_table[1]"),
        ("[load]\nmode = \"uniaxial\"\nstress = 1e6\ncontact_stress_limit = 0.0", "load.contact_stress_limit"),
        ("[load]\nmode = \"uniaxial\"\nstress = 1e6\npressure = 1.0", "pressure"),
    ];
    for (load, want) in cases {
        let e = check_err(compact_case(&csv, load, &[]));
        assert!(e.contains(want), "{load}: {e}");
    }
    let e = check_err(compact_case(&csv, "[load]\nmode = \"uniaxial\"\nstress = -1e6", &[]));
    assert!(e.contains("Pa") && e.contains("[0, 1e9]") || e.contains("1000000000"), "{e}");
    // a two-particle compact skips the mechanics: a load there is refused
    let pair = dir.join("pair.csv");
    std::fs::write(&pair, "x,y,z,r\n0,0,0,25e-6\n50e-6,0,0,25e-6\n").unwrap();
    let e = check_err(compact_case(&pair, "[load]\nmode = \"uniaxial\"\nstress = 1e6", &[]));
    assert!(e.contains("load.force"), "{e}");
    // pair kind: range of load.force
    let text =
        "kind = \"pair\"\n[pair]\nmaterial = \"copper-ivannikov2022\"\nradius = 25e-6\nend_time = 1.0\n[temperature]\nconstant = 1293.0\n[load]\nforce = 1e4\n";
    let e = parse_pair_case(&toml::Value::Table(text.parse().unwrap())).unwrap_err().to_string();
    assert!(e.contains("load.force") && e.contains("N"), "{e}");
}

/// The figure of docs/pressure.md: the bundled hot-pressing case at 0, 5 and 10 MPa, shrinkage per
/// axis against time (`docs/figures/hot-pressing-shrinkage.png`, `.csv`).
/// `cargo test --release --test pressure -- --ignored --nocapture hot_pressing_figure`
#[test]
#[ignore]
fn hot_pressing_figure() {
    use sinterdem::plot::{Plot, Series};
    let dir = common::tmp_dir("figure");
    let mut p = Plot::new("hot pressing, titanium column, E14B: shrinkage per axis").labels("time t [s]", "shrinkage 1 - L/L0 [1]");
    let mut csv = String::from("stress_MPa,time_s,shrinkage_x,shrinkage_y,shrinkage_z,relative_density\n");
    let mut finals = Vec::new();
    for mpa in [0.0, 5.0, 10.0] {
        let text = std::fs::read_to_string("cases/hot-pressing-titanium.toml").unwrap();
        let mut v = toml::Value::Table(text.parse().unwrap());
        apply_override(&mut v, &format!("load.stress_table=[[0.0,0.0],[1740.0,{:e}],[7140.0,{:e}],[7200.0,0.0]]", mpa * 1e6, mpa * 1e6)).unwrap();
        apply_override(&mut v, "output.snapshots=0").unwrap();
        let out = dir.join(format!("s{mpa}"));
        let sim = coupled::prepare(v, Path::new("cases"), &mut |_| {}).unwrap();
        let s = sinterdem::kinds::compact::run(sim, &out, false, &mut |_| {}).unwrap();
        let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
        let rows: Vec<Vec<f64>> = series.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
        for r in &rows {
            csv.push_str(&format!("{mpa},{},{},{},{},{}\n", r[0], r[2], r[3], r[4], r[5]));
        }
        for (a, name) in [(2, "x"), (4, "z")] {
            p.add(Series::new(format!("{mpa} MPa, {name}"), rows.iter().map(|r| (r[0], r[a])).collect()));
        }
        finals.push((
            mpa,
            s["final_time_s"].clone(),
            s["shrinkage_x"].clone(),
            s["shrinkage_y"].clone(),
            s["shrinkage_z"].clone(),
            s["relative_density"].clone(),
            s["stop_reason"].clone(),
        ));
    }
    std::fs::create_dir_all("docs/figures").unwrap();
    p.save_png(Path::new("docs/figures/hot-pressing-shrinkage.png")).unwrap();
    std::fs::write("docs/figures/hot-pressing-shrinkage.csv", csv).unwrap();
    for f in finals {
        println!("{f:?}");
    }
}

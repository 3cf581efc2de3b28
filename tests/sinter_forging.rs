//! Two scales (issue 36 item 5, docs/rve.md "Two scales: sinter-forging against the RVE's law"):
//! the copper RVE with sliding gives the linear viscous law (R12)–(R15) (`fit.json` →
//! `density_law`); the walled compact of `cases/sinter-forging-copper.toml`, presintered freely
//! and then sinter-forged under a uniaxial 0.25 MPa (discontinuous sinter-forging), creeps along and
//! across the load at the rates that law predicts at the same state. The state is matched by the
//! mean neck ratio: the box density (S6) of a walled body counts its loose surface layer.

use std::path::Path;

mod common;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn params() -> sinterdem::kinds::RunParams {
    sinterdem::kinds::RunParams { base_dir: root().join("cases"), plots: false, ..Default::default() }
}

fn sets(s: &[&str]) -> Vec<String> {
    s.iter().map(|x| x.to_string()).collect()
}

/// Columns of a run's series.csv: time, true strains ln(L/L0) of x, y, z, box density, mean neck ratio.
struct Series {
    t: Vec<f64>,
    strain: [Vec<f64>; 3],
    rho: Vec<f64>,
    neck: Vec<f64>,
}

fn series(dir: &Path) -> Series {
    let text = std::fs::read_to_string(dir.join("series.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |k: &str| head.iter().position(|h| *h == k).unwrap_or_else(|| panic!("{k}"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let get = |k: &str| rows.iter().map(|r| r[col(k)]).collect::<Vec<f64>>();
    let strain = ["x", "y", "z"].map(|a| get(&format!("shrinkage_{a}")).iter().map(|s| (1.0 - s).ln()).collect());
    Series { t: get("time_s"), strain, rho: get("relative_density"), neck: get("neck_ratio_mean") }
}

/// The row at (or first after) time `t`.
fn row(s: &Series, t: f64) -> usize {
    s.t.iter().position(|v| *v >= t - 1e-9).unwrap_or_else(|| panic!("the run does not reach {t} s"))
}

/// True strain rates (x, y, z) between the rows at t0 and t1.
fn rates(s: &Series, t0: f64, t1: f64) -> [f64; 3] {
    let (a, b) = (row(s, t0), row(s, t1));
    [0, 1, 2].map(|k| (s.strain[k][b] - s.strain[k][a]) / (s.t[b] - s.t[a]))
}

/// The relative density of the free cell when its mean neck ratio is `neck` (linear between rows).
fn density_at_neck(cell: &Series, neck: f64) -> f64 {
    let k = cell.neck.windows(2).position(|w| w[0] <= neck && neck <= w[1]).unwrap_or_else(|| panic!("neck ratio {neck} not in the free cell's run"));
    let w = (neck - cell.neck[k]) / (cell.neck[k + 1] - cell.neck[k]);
    cell.rho[k] + w * (cell.rho[k + 1] - cell.rho[k])
}

const STRESS: f64 = 2.5e5; // Pa, compressive, the bundled case's
const LOAD_AT: f64 = 3000.0; // s, the bundled case's load step (free before)

#[test]
fn sinter_forged_compact_follows_the_rve_law_along_and_across_the_load() {
    // 1. the RVE's law from its rows at 1000–10 000 s (ρ 0.68–0.74, around the compact's state)
    let dir = common::tmp_dir("sinter-forging-rve");
    let case = sinterdem::config::load_case(&root().join("cases/rve-copper-sliding.toml"), &[]).unwrap();
    let rve_sets = sets(&["time.end=10000.0", "rve.at=[1000.0, 3000.0, 6000.0, 10000.0]", "output.snapshots=0", "output.conductivity_at=[]"]);
    sinterdem::kinds::rve::run(&case, &rve_sets, &dir, &params()).unwrap();
    let fit: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("fit.json")).unwrap()).unwrap();
    let law = &fit["density_law"];
    assert!(law["uniaxial"].is_object() && law["poisson_slope"].is_number(), "{fit}");
    let cell = series(&dir);
    let visc = |p: &serde_json::Value, rho: f64| {
        let f = |k: &str| p[k].as_f64().unwrap();
        f("prefactor_Pa_s") * rho.powf(f("density_exponent")) * (1.0 - rho).powf(-f("porosity_exponent"))
    };
    let num = |k: &str| law[k].as_f64().unwrap();
    // the creep rates of the linear law under the uniaxial stress, (axial, lateral): from K and G
    // (R12), the isotropic body ((R6): ν_p = ν_iso since tension reaches the necks, (P5)), and
    // from the uniaxial fields (R14)–(R15), −σ/E_p and ν_p σ/E_p
    let predict = |rho: f64| {
        let (k, g, e) = (visc(&law["bulk"], rho), visc(&law["shear"], rho), visc(&law["uniaxial"], rho));
        let nu = num("poisson_intercept") + num("poisson_slope") * rho;
        ((-STRESS / (9.0 * k) - STRESS / (3.0 * g), -STRESS / (9.0 * k) + STRESS / (6.0 * g)), (-STRESS / e, nu * STRESS / e))
    };

    // 2. the bundled compact: free to 3000 s, then 1 MPa along z to 3400 s
    let out = common::tmp_dir("sinter-forging-compact");
    let case = sinterdem::config::load_case(&root().join("cases/sinter-forging-copper.toml"), &[]).unwrap();
    sinterdem::kinds::run(&case, &sets(&["output.snapshots=0"]), &out, &params()).unwrap();
    let c = series(&out);
    // windows after the load step (its first step is the elastic jump of the bonded compact): the
    // first 90 s and the whole 400 s; the creep rate is the forged rate less the free rate of the
    // 90 s before the load (the free rate changes by a few per cent over 100 s at 3000 s)
    let t_end = c.t[c.t.len() - 1];
    let free = rates(&c, LOAD_AT - 90.0, LOAD_AT);
    for (t0, t1) in [(LOAD_AT + 10.0, LOAD_AT + 100.0), (LOAD_AT + 10.0, t_end)] {
        let r = rates(&c, t0, t1);
        let neck = 0.5 * (c.neck[row(&c, t0)] + c.neck[row(&c, t1)]);
        let rho_eq = density_at_neck(&cell, neck);
        let rho_box = 0.5 * (c.rho[row(&c, t0)] + c.rho[row(&c, t1)]);
        let ((axial, lateral), (axial_u, lateral_u)) = predict(rho_eq);
        let creep_axial = r[2] - free[2];
        let creep_lateral = 0.5 * (r[0] + r[1]) - 0.5 * (free[0] + free[1]);
        eprintln!(
            "compact {t0}-{t1} s: neck ratio {neck:.4} (cell density there {rho_eq:.4}, box density {rho_box:.4}); creep axial {creep_axial:.4e} vs law {axial:.4e} ({:.3}; (R14) {:.3}); lateral {creep_lateral:.4e} vs law {lateral:.4e} ({:.3}; (R15) {:.3})",
            creep_axial / axial,
            creep_axial / axial_u,
            creep_lateral / lateral,
            creep_lateral / lateral_u
        );
        // the box density lies far below the cell's at the same necks: not the index to compare at
        // (measured 2026-12-07: 0.655-0.660 against 0.695-0.697)
        assert!(rho_box < rho_eq - 0.03, "{rho_box} {rho_eq}");
        // along the load and across it: the law within 15 % (issue 36 item 5)
        assert!(common::rel(creep_axial, axial) < 0.15, "axial {creep_axial} vs {axial}");
        assert!(creep_lateral > 0.0 && common::rel(creep_lateral, lateral) < 0.15, "lateral {creep_lateral} vs {lateral}");
    }
}

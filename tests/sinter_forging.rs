//! Two scales (issue 36 item 5, docs/rve.md "Two scales: sinter-forging against the RVE's law"):
//! the copper RVE with sliding gives the linear viscous law (R12)–(R13); a cell of the same
//! packing sinter-forged under a constant uniaxial stress follows that law along the load, and the
//! walled compact of `cases/sinter-forging-copper.toml` follows the forged cell at the same neck
//! size (not at the same box density (S6), which counts the loose surface layer of a walled body).

use std::path::Path;

mod common;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn params() -> sinterdem::kinds::RunParams {
    sinterdem::kinds::RunParams { base_dir: root().join("cases"), plots: false, ..Default::default() }
}

const STRESS: f64 = 1.0e6; // Pa, compressive, as the bundled case

/// Columns of a run's series.csv.
struct Series {
    t: Vec<f64>,
    strain: [Vec<f64>; 3],
    rho: Vec<f64>,
    neck: Vec<f64>,
    sigma_zz: Vec<f64>,
}

fn series(dir: &Path) -> Series {
    let text = std::fs::read_to_string(dir.join("series.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |k: &str| head.iter().position(|h| *h == k).unwrap_or_else(|| panic!("{k}"));
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let get = |k: &str| rows.iter().map(|r| r[col(k)]).collect::<Vec<f64>>();
    // true strain ln(L/L0) = ln(1 − s)
    let strain = ["x", "y", "z"].map(|a| get(&format!("shrinkage_{a}")).iter().map(|s| (1.0 - s).ln()).collect());
    Series { t: get("time_s"), strain, rho: get("relative_density"), neck: get("neck_ratio_mean"), sigma_zz: get("sigma_zz_Pa") }
}

/// True strain rates (x, y, z) and the mean σ_zz over the rows whose `index` (ρ or neck ratio)
/// lies within `target ± half`.
fn rates_at(s: &Series, index: &[f64], target: f64, half: f64) -> ([f64; 3], f64) {
    let lo = index.iter().position(|v| *v >= target - half).unwrap();
    let hi = index.iter().position(|v| *v >= target + half).unwrap_or_else(|| panic!("the run does not reach {}", target + half));
    let dt = s.t[hi] - s.t[lo];
    let rate = [0, 1, 2].map(|a| (s.strain[a][hi] - s.strain[a][lo]) / dt);
    let szz = s.sigma_zz[lo..=hi].iter().sum::<f64>() / (hi - lo + 1) as f64;
    (rate, szz)
}

/// (K, G, σ_s) of fit.json's density_law at ρ (R12)–(R13).
fn law(fit: &serde_json::Value, rho: f64) -> (f64, f64, f64) {
    let d = &fit["density_law"];
    let visc = |p: &serde_json::Value| {
        let f = |k: &str| p[k].as_f64().unwrap();
        f("prefactor_Pa_s") * rho.powf(f("density_exponent")) * (1.0 - rho).powf(-f("porosity_exponent"))
    };
    let s0 = d["stress_prefactor_Pa"].as_f64().unwrap();
    (visc(&d["bulk"]), visc(&d["shear"]), s0 * rho.powf(d["stress_density_exponent"].as_f64().unwrap()))
}

/// The linear viscous law ε̇_ij = σ'_ij/(2G) + (σ_m − σ_s)/(3K) δ_ij under σ_zz = −σ alone
/// (tension positive): (axial, lateral) rates.
fn law_rates(k: f64, g: f64, ss: f64, sigma: f64) -> (f64, f64) {
    let sm = -sigma / 3.0;
    ((-sigma - sm) / (2.0 * g) + (sm - ss) / (3.0 * k), (-sm) / (2.0 * g) + (sm - ss) / (3.0 * k))
}

#[test]
fn sinter_forging_follows_the_rve_law_along_the_load() {
    let rve_case = root().join("cases/rve-copper-sliding.toml");
    // 1. the RVE's law from four branch points, ρ 0.68–0.74
    let dir = common::tmp_dir("sinter-forging-rve");
    let case = sinterdem::config::load_case(&rve_case, &[]).unwrap();
    let sets: Vec<String> = ["time.end=10000.0", "rve.at=[1000.0, 3000.0, 6000.0, 10000.0]", "output.snapshots=0", "output.conductivity_at=[]"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    sinterdem::kinds::rve::run(&case, &sets, &dir, &params()).unwrap();
    let fit: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("fit.json")).unwrap()).unwrap();
    assert!(fit["density_law"].is_object(), "{fit}");

    // 2. the same cell sinter-forged: σ_zz = −1 MPa held, the lateral stresses zero
    let dir = common::tmp_dir("sinter-forging-cell");
    let sets: Vec<String> = ["mechanics.cell.zz.stress=-1.0e6", "time.end=2500.0", "rve.at=[100.0]", "output.snapshots=0", "output.conductivity_at=[]"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    sinterdem::kinds::run(&case, &sets, &dir, &params()).unwrap();
    let cell = series(&dir);
    for rho in [0.70, 0.72] {
        let (r, _) = rates_at(&cell, &cell.rho, rho, 0.005);
        let (k, g, ss) = law(&fit, rho);
        let (axial, lateral) = law_rates(k, g, ss, STRESS);
        let lat = 0.5 * (r[0] + r[1]);
        eprintln!("cell rho {rho}: axial {:e} vs law {axial:e} ({:.3}), lateral {lat:e} vs law {lateral:e}", r[2], r[2] / axial);
        // measured 2026-12-07: 1.050 and 1.031 of this 4-point law (0.83–1.02 of the full 10-point
        // fit, whose own rms residual is 17–19 %, docs/rve.md): the 15 %
        assert!(common::rel(r[2], axial) < 0.15, "axial {} vs {axial}", r[2]);
        // the lateral rate is a small difference of the load's and the sintering stress's terms:
        // measured and law both below 40 % of the axial rate
        assert!(lat.abs() < 0.4 * r[2].abs() && lateral.abs() < 0.4 * axial.abs(), "lateral {lat} vs {lateral}");
    }

    // 3. the walled compact, to box density 0.72
    let dir = common::tmp_dir("sinter-forging-compact");
    let case = sinterdem::config::load_case(&root().join("cases/sinter-forging-copper.toml"), &[]).unwrap();
    let sets: Vec<String> = ["time.stop_relative_density=0.72", "output.snapshots=0"].iter().map(|s| s.to_string()).collect();
    sinterdem::kinds::run(&case, &sets, &dir, &params()).unwrap();
    let compact = series(&dir);
    // at the same box density (S6) the walled compact is 3x slower than the law …
    let (r, _) = rates_at(&compact, &compact.rho, 0.70, 0.005);
    let (k, g, ss) = law(&fit, 0.70);
    let (axial, _) = law_rates(k, g, ss, STRESS);
    eprintln!("compact rho 0.70: axial {:e} vs law {axial:e} ({:.3})", r[2], r[2] / axial);
    assert!(r[2] / axial > 0.2 && r[2] / axial < 0.5, "{} vs {axial}", r[2]);
    // (measured 0.365) … because its necks are larger at that density; at the same neck ratio it follows the
    // forged cell, per unit of its own axial stress (P4) (measured 0.8–0.9: walls and surface)
    for neck in [0.45, 0.48] {
        let (rc, szz) = rates_at(&compact, &compact.neck, neck, 0.005);
        let (rp, _) = rates_at(&cell, &cell.neck, neck, 0.005);
        let ratio = (rc[2] / -szz) / (rp[2] / STRESS);
        eprintln!("neck {neck}: compact {:e} at sigma_zz {szz:e}, cell {:e}, ratio per unit stress {ratio:.3}", rc[2], rp[2]);
        assert!(ratio > 0.7 && ratio < 1.1, "{ratio}");
    }
}

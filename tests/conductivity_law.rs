//! The default conductance law and its limits (issue 42): Holm's constriction for a tiny neck.

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sinterdem"))
}

fn neck(args: &[&str]) -> serde_json::Value {
    let o = bin().arg("neck").args(args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Holm: a circular contact of radius a on a large body conducts 4κa per side, so a pipe of two
/// halves conducts 2κa as a → 0. The default law reaches it within 3 %; the seed paper's linear
/// law, still selectable, gives 1.064·π/4 = 0.836 of it.
#[test]
fn default_neck_of_a_tiny_contact_is_within_3_percent_of_holm() {
    let base = ["--r1", "1e-3", "--r2", "1e-3", "--overlap", "2e-8", "--kappa", "1"];
    let v = neck(&base);
    let (a, k) = (v["a"].as_f64().unwrap(), v["K_pair"].as_f64().unwrap());
    assert_eq!(v["conductance"], "fe_fit");
    assert!((k / (2.0 * a) - 1.0).abs() < 0.03, "K_pair = {k} W/K, 2κa = {}", 2.0 * a);
    let lin = neck(&[&base[..], &["--conductance", "linear"]].concat());
    let kl = lin["K_pair"].as_f64().unwrap();
    assert!((kl / (2.0 * a) - 1.064 * std::f64::consts::PI / 4.0).abs() < 1e-9, "{kl}");
}

mod common;

use nalgebra::Vector3;

fn run_case(dir: &std::path::Path, name: &str, text: &str) -> serde_json::Value {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let v = sinterdem::config::load_case(&path, &[]).unwrap();
    sinterdem::kinds::conductivity::run_case(v, dir).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// κ_eff/κ_s of a result: the diagonal and the mean of the diagonal.
fn diagonal(out: &serde_json::Value) -> ([f64; 3], f64) {
    let t = &out["kappa_eff_over_kappa"];
    let d = [0, 1, 2].map(|a| t[a][a].as_f64().unwrap());
    (d, d.iter().sum::<f64>() / 3.0)
}

/// The bound (H8d) holds: no diagonal component above κ_s (nor above φκ_s), the mean of the
/// diagonal not above the Hashin–Shtrikman upper bound 2φ/(3 − φ)·κ_s (φ capped at 1).
fn assert_bounded(name: &str, out: &serde_json::Value) {
    let phi = out["solid_fraction"].as_f64().unwrap();
    let hs = out["hashin_shtrikman_upper"].as_f64().unwrap();
    let pc = phi.min(1.0);
    assert!((hs - 2.0 * pc / (3.0 - pc)).abs() < 1e-15, "{name}");
    let (d, mean) = diagonal(out);
    for k in d {
        assert!(k <= pc * (1.0 + 1e-12) && k <= 1.0 + 1e-12, "{name}: component {k} above φ_c = {pc}");
    }
    assert!(mean <= hs * (1.0 + 1e-12), "{name}: mean {mean} above Hashin–Shtrikman {hs} at φ = {phi}");
}

/// SC, BCC and FCC lattices from small necks up to their second-neighbour limit: κ_eff never
/// above the Hashin–Shtrikman bound of the lattice's solid fraction, nor κ_s; below it the closed
/// form is the network's. The law's own value exceeds the bound on FCC from h/r ≈ 0.14 (issue 42),
/// so the bound must act there; results beyond the validated mean h/r carry the mark.
#[test]
fn lattices_never_exceed_hashin_shtrikman_up_to_the_second_neighbour_limit() {
    let dir = common::tmp_dir("bound-lattices");
    let mut bound_acted = false;
    for (lat, limit) in [("sc", 2.0 - 2f64.sqrt()), ("bcc", 2.0 - 3f64.sqrt()), ("fcc", 2.0 - 2f64.sqrt())] {
        let n = 24;
        for k in 1..=n {
            let h = limit * k as f64 / (n as f64 + 0.5);
            let case = format!(
                "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n[particles]\nsource = \"lattice\"\nlattice = \"{lat}\"\ncells = [3, 3, 3]\nradius = 25e-6\noverlap = {h}\n[conductivity]\nboundary = \"periodic\"\n"
            );
            let name = format!("{lat}-{k}");
            let out = run_case(&dir, &name, &case);
            assert_bounded(&name, &out);
            let (d, mean) = diagonal(&out);
            // cubic: isotropic, and the closed form (with the bound) is the network's value
            let closed = out["lattice_closed_form_W_per_mK"].as_f64().unwrap() / out["kappa_material_W_per_mK"].as_f64().unwrap();
            assert!(d.iter().all(|&x| (x / closed - 1.0).abs() < 1e-9), "{name}: {d:?} vs closed form {closed}");
            let hs = out["hashin_shtrikman_upper"].as_f64().unwrap();
            bound_acted |= (mean / hs - 1.0).abs() < 1e-9;
            // the network is the law's closed form f K/d ((H8c) crowding) held at Hashin–Shtrikman:
            // min(law, HS), so the bound leaves every lattice below HS untouched (all up to h/r 0.12)
            let r = 25e-6;
            let dist = (2.0 - h) * r;
            let (f, crowd) = match lat {
                "sc" => (1.0, 1.0),
                "bcc" => (3f64.sqrt(), 4.0 / 3.0),
                _ => (2.0 * 2f64.sqrt(), 2.0),
            };
            let a = sinterdem::neck::solve(r, r, h * r).unwrap().a;
            let alone = f * sinterdem::heat::Conductance::default().pipe_crowded(1.0, 1.0, r, r, a, [crowd, crowd]).pair / dist;
            assert!((mean / alone.min(hs) - 1.0).abs() < 1e-9, "{name}: {mean} vs law {alone}, HS {hs}");
            if h <= 0.12 {
                assert!(alone < hs, "{name}: the law alone {alone} reaches HS {hs} inside the validated range");
            }
            let hr = out["mean_overlap_over_radius"].as_f64().unwrap();
            assert!((hr - h).abs() < 1e-9, "{name}: mean h/r {hr}");
            assert_eq!(out["extrapolated"].as_bool().unwrap(), h > 0.12, "{name}");
        }
    }
    assert!(bound_acted, "the bound never acted: the test does not reach the dense lattices");
}

/// Random periodic packings across the density range (solid fraction 0.58 → 0.58/λ³ up to ≈ 0.9):
/// κ_eff never above Hashin–Shtrikman nor κ_s, and the mark set exactly beyond the validated mean
/// h/r.
#[test]
fn random_packings_never_exceed_hashin_shtrikman_across_density() {
    let dir = common::tmp_dir("bound-random");
    let mut densest: f64 = 0.0;
    for (k, h) in [0.02, 0.08, 0.14, 0.2, 0.26].into_iter().enumerate() {
        let (pos, rad, l) = common::random_periodic(120, 50e-6, 0.1, 0.58, h, 11 + k as u64, 3000);
        let mut csv = String::from("x,y,z,r\n");
        for (x, r) in pos.iter().zip(&rad) {
            csv.push_str(&format!("{:e},{:e},{:e},{:e}\n", x.x, x.y, x.z, r));
        }
        let name = format!("random-{k}");
        std::fs::write(dir.join(format!("{name}.csv")), csv).unwrap();
        let case = format!(
            "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper\"\n[particles]\nsource = \"file\"\nfile = \"{name}.csv\"\nperiodic_box = [{l:e}, {l:e}, {l:e}]\n[conductivity]\nboundary = \"periodic\"\n"
        );
        let out = run_case(&dir, &name, &case);
        assert_bounded(&name, &out);
        let hr = out["mean_overlap_over_radius"].as_f64().unwrap();
        assert_eq!(out["extrapolated"].as_bool().unwrap(), sinterdem::heat::conductance::beyond_validated(hr), "{name}: h/r {hr}");
        densest = densest.max(out["solid_fraction"].as_f64().unwrap());
    }
    assert!(densest > 0.85, "the packings reach solid fraction {densest} only");
}

/// The number written after `name = ` on the first line of `doc` that contains `marker`.
fn quoted(doc: &str, marker: &str, name: &str) -> f64 {
    let line = doc.lines().find(|l| l.contains(marker)).unwrap_or_else(|| panic!("no line with {marker}"));
    let at = line.find(&format!("{name} = ")).unwrap_or_else(|| panic!("{marker}: no `{name} = ` in {line}")) + name.len() + 3;
    let num: String = line[at..].trim_start().chars().take_while(|c| c.is_ascii_digit() || matches!(c, '.' | '-' | '−' | 'e')).collect();
    num.replace('−', "-").parse().unwrap_or_else(|e| panic!("{marker}: {name} = {num}: {e}"))
}

/// docs/heat-model.md (H6)–(H8d) quote the constants of the code: they cannot drift apart.
#[test]
fn heat_model_doc_quotes_the_codes_constants() {
    use sinterdem::heat::{conductance, fe_fit};
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/heat-model.md")).unwrap();
    assert_eq!(quoted(&doc, "(H8b) 1/K_i", "β"), conductance::MULTI_NECK_BETA);
    assert_eq!(quoted(&doc, "p1 = 0.", "p1"), fe_fit::FE_FIT_P1);
    assert_eq!(quoted(&doc, "p1 = 0.", "p2"), fe_fit::FE_FIT_P2);
    assert_eq!(quoted(&doc, "p1 = 0.", "p3"), fe_fit::FE_FIT_P3);
    assert_eq!(quoted(&doc, "`\"linear\"`: f ≡ c_K", "c_K"), sinterdem::heat::Conductance::default().factor);
    assert!(doc.contains(&format!("mean h/r exceeds {}", conductance::VALIDATED_MEAN_OVERLAP_RATIO)));
    // the default named in the docs is the code's
    assert!(doc.contains("- `\"fe_fit\"` (the default)"));
    assert_eq!(sinterdem::heat::Conductance::default().law, sinterdem::heat::ConductanceLaw::FeFit);
    let case_doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/case-file.md")).unwrap();
    assert!(case_doc.contains("| `conductance` | `\"fe_fit\"` |"), "docs/case-file.md names another default");
    let val = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/validation-conductance.md")).unwrap();
    assert_eq!(quoted(&val, "p1 =  0.", "p1"), fe_fit::FE_FIT_P1);
    assert_eq!(quoted(&val, "p2 = −0.", "p2"), fe_fit::FE_FIT_P2);
    assert_eq!(quoted(&val, "p3 = −0.", "p3"), fe_fit::FE_FIT_P3);
    assert!(!val.contains("still the default"), "docs/validation-conductance.md calls a non-default law the default");
}

fn lattice_case(lat: &str, h: f64, extra: &str) -> String {
    format!(
        "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n[particles]\nsource = \"lattice\"\nlattice = \"{lat}\"\ncells = [3, 3, 3]\nradius = 25e-6\noverlap = {h}\n{extra}[conductivity]\nboundary = \"periodic\"\n"
    )
}

/// `thermal.boundary_resistance` R_b adds R_b/(π a²) in series with each pipe (H7): on an SC lattice
/// (φ = 1, no bound acting at h/r = 0.1) κ_eff = K/D with 1/K = 1/K_pipe + R_b/(π a²); it lowers
/// κ_eff and vanishes for R_b = 0; the κ(T) network keeps it when it rescales the halves.
#[test]
fn boundary_resistance_is_in_series_with_each_pipe() {
    let dir = common::tmp_dir("boundary-resistance");
    let (r, h) = (25e-6, 0.1);
    let neck = sinterdem::neck::solve(r, r, h * r).unwrap();
    let d = (2.0 - h) * r;
    let k0 = sinterdem::heat::Conductance::default().pipe(394.0, 394.0, r, r, neck.a).pair;
    let base = run_case(&dir, "sc-0", &lattice_case("sc", h, ""));
    let kb = diagonal(&base).0[0] * 394.0;
    assert!((kb / (k0 / d) - 1.0).abs() < 1e-9, "{kb} vs {}", k0 / d);
    for rb in [1e-9, 1e-7] {
        let out = run_case(&dir, &format!("sc-{rb}"), &lattice_case("sc", h, &format!("[thermal]\nboundary_resistance = {rb:e}\n")));
        let want = 1.0 / (1.0 / k0 + rb / (std::f64::consts::PI * neck.a * neck.a)) / d;
        let got = diagonal(&out).0[0] * 394.0;
        assert!((got / want - 1.0).abs() < 1e-9, "R_b = {rb}: {got} vs {want}");
        assert!(got < kb);
        // the Kirchhoff-rescaled pipe (heat-model.md eq. P4) keeps R_b/(π a²) as it is
        let law = sinterdem::heat::Conductance { boundary_resistance: rb, ..Default::default() };
        let pc = law.pipe(394.0, 394.0, r, r, neck.a);
        assert!((pc.boundary - rb / (std::f64::consts::PI * neck.a * neck.a)).abs() < 1e-12 * pc.boundary);
        let mat = sinterdem::material::parse_one(toml::from_str("name = \"cu\"\npreset = \"copper\"\nconductivity_table = \"copper\"\n").unwrap()).unwrap();
        let props = sinterdem::heat::properties::ThermalProperties::of(&[1.0, 1.0], &[0, 0], std::slice::from_ref(&mat), None).unwrap();
        let t = 900.0;
        let s = mat.conductivity_table.as_ref().unwrap().at(t) / mat.conductivity;
        let want_t = 1.0 / (2.0 / (pc.half_i * s) + pc.boundary);
        assert!((props.pipe(&pc, 0, 1, t, t) / want_t - 1.0).abs() < 1e-12);
    }
}

/// `quantity = "electrical"`: the same network with σ_e = 1/ρ_e(T) for κ. For one material the
/// ratio σ_eff/σ_s equals κ_eff/κ_s; copper reports %IACS against 58.0 MS/m; a material without a
/// resistivity gets an error naming the key.
#[test]
fn electrical_conductivity_is_the_same_network_with_sigma_for_kappa() {
    let dir = common::tmp_dir("electrical");
    let (pos, rad, l) = common::random_periodic(120, 50e-6, 0.1, 0.6, 0.06, 5, 3000);
    let mut csv = String::from("x,y,z,r\n");
    for (x, r) in pos.iter().zip(&rad) {
        csv.push_str(&format!("{:e},{:e},{:e},{:e}\n", x.x, x.y, x.z, r));
    }
    std::fs::write(dir.join("p.csv"), csv).unwrap();
    let case = |q: &str| {
        format!(
            "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper\"\n[particles]\nsource = \"file\"\nfile = \"p.csv\"\nperiodic_box = [{l:e}, {l:e}, {l:e}]\n[conductivity]\nboundary = \"periodic\"\nquantity = \"{q}\"\n"
        )
    };
    let th = run_case(&dir, "thermal", &case("thermal"));
    let el = run_case(&dir, "electrical", &case("electrical"));
    let rho = sinterdem::material::bundled_table("copper", sinterdem::material::Quantity::ElectricalResistivity).unwrap().at(293.15);
    // Matula (1979): pure copper 1.678e-8 Ω m at 293 K, 1.725e-8 at 300 K
    assert!(rho > 1.678e-8 && rho < 1.68e-8, "{rho}");
    assert!((el["resistivity_material_ohm_m"].as_f64().unwrap() / rho - 1.0).abs() < 1e-10);
    // the particles' mean temperature (the default initial temperature), summed over 120 particles
    assert!((el["temperature_K"].as_f64().unwrap() - 293.15).abs() < 1e-9);
    for a in 0..3 {
        for b in 0..3 {
            let kt = th["kappa_eff_over_kappa"][a][b].as_f64().unwrap();
            let ke = el["sigma_eff_over_sigma"][a][b].as_f64().unwrap();
            assert!((kt - ke).abs() < 1e-12, "{a}{b}: {kt} vs {ke}");
        }
        let sigma = el["sigma_eff_S_per_m"][a][a].as_f64().unwrap();
        assert!((sigma * rho / el["sigma_eff_over_sigma"][a][a].as_f64().unwrap() - 1.0).abs() < 1e-10);
        let iacs = el["iacs_percent"][a].as_f64().unwrap();
        assert!((iacs - 100.0 * sigma / 58.0e6).abs() < 1e-9, "{iacs}");
    }
    // the faces method too
    let faces = run_case(&dir, "faces", &case("electrical").replace("boundary = \"periodic\"", "boundary = \"faces\""));
    assert!(faces["sigma_eff_S_per_m"][0][0].as_f64().unwrap() > 0.0 && faces.get("kappa_eff_W_per_mK").is_none());
    // a preset without a bundled ρ_e(T): the error names the key
    let path = dir.join("ti.toml");
    std::fs::write(&path, case("electrical").replace("preset = \"copper\"", "preset = \"titanium\"")).unwrap();
    let v = sinterdem::config::load_case(&path, &[]).unwrap();
    let e = sinterdem::kinds::conductivity::run_case(v, &dir).unwrap_err().to_string();
    assert!(e.contains("materials.copper.electrical_resistivity"), "{e}");
    // a given resistivity is used as it is
    let path = dir.join("given.toml");
    std::fs::write(&path, case("electrical").replace("preset = \"copper\"\n", "preset = \"titanium\"\nelectrical_resistivity = 4.2e-7\n")).unwrap();
    let v = sinterdem::config::load_case(&path, &[]).unwrap();
    let out = sinterdem::kinds::conductivity::run_case(v, &dir).unwrap();
    assert_eq!(out["sigma_material_S_per_m"].as_f64().unwrap(), 1.0 / 4.2e-7);
    assert!(out.get("iacs_percent").is_none());
    // unknown quantity
    let path = dir.join("bad.toml");
    std::fs::write(&path, case("magnetic")).unwrap();
    let v = sinterdem::config::load_case(&path, &[]).unwrap();
    let e = sinterdem::kinds::conductivity::run_case(v, &dir).unwrap_err().to_string();
    assert!(e.contains("conductivity.quantity") && e.contains("electrical"), "{e}");
}

/// One row of the model beside measured compacts (validation/data/measured_compacts_model.csv).
#[derive(Debug, Clone)]
struct ModelRow {
    source: String,
    solid_fraction: f64,
    mean_h_over_r: f64,
    extrapolated: bool,
    kappa: f64,
    hashin_shtrikman: f64,
    sigma: f64,
    rb: [f64; 3],
}

/// The boundary resistances of the model's R_b columns [m²·K/W].
const MODEL_RB: [f64; 3] = [1e-8, 1e-7, 1e-6];

/// The mean of the diagonal of κ_eff/κ_s (thermal) of a periodic copper packing written to `dir`,
/// with an optional `[thermal]` block; and the full output.
fn copper_cell(dir: &std::path::Path, name: &str, pos: &[Vector3<f64>], rad: &[f64], l: f64, extra: &str, q: &str) -> serde_json::Value {
    let mut csv = String::from("x,y,z,r\n");
    for (x, r) in pos.iter().zip(rad) {
        csv.push_str(&format!("{:e},{:e},{:e},{:e}\n", x.x, x.y, x.z, r));
    }
    std::fs::write(dir.join(format!("{name}.csv")), csv).unwrap();
    let case = format!(
        "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper\"\n[particles]\nsource = \"file\"\nfile = \"{name}.csv\"\nperiodic_box = [{l:e}, {l:e}, {l:e}]\n{extra}[conductivity]\nboundary = \"periodic\"\nquantity = \"{q}\"\n"
    );
    run_case(dir, &format!("{name}-{q}-{}", extra.len()), &case)
}

/// The model row of one periodic copper packing: thermal, electrical and the R_b columns.
fn model_row(dir: &std::path::Path, source: &str, pos: &[Vector3<f64>], rad: &[f64], l: f64) -> ModelRow {
    let th = copper_cell(dir, source, pos, rad, l, "", "thermal");
    assert_bounded(source, &th);
    let el = copper_cell(dir, source, pos, rad, l, "", "electrical");
    let sigma = (0..3).map(|a| el["sigma_eff_over_sigma"][a][a].as_f64().unwrap()).sum::<f64>() / 3.0;
    let rb = MODEL_RB.map(|rb| diagonal(&copper_cell(dir, source, pos, rad, l, &format!("[thermal]\nboundary_resistance = {rb:e}\n"), "thermal")).1);
    ModelRow {
        source: source.to_string(),
        solid_fraction: th["solid_fraction"].as_f64().unwrap(),
        mean_h_over_r: th["mean_overlap_over_radius"].as_f64().unwrap(),
        extrapolated: th["extrapolated"].as_bool().unwrap(),
        kappa: diagonal(&th).1,
        hashin_shtrikman: th["hashin_shtrikman_upper"].as_f64().unwrap(),
        sigma,
        rb,
    }
}

/// The RVE beside measured compacts: a random periodic copper packing of 400 spheres
/// (d = 50 µm ± 10 %) relaxed at solid fraction 0.60, then densified geometrically to each
/// `target` (centres moved together; the necks are the volume-conserving necks of the overlaps).
fn densified_rows(dir: &std::path::Path, targets: &[f64]) -> Vec<ModelRow> {
    let (pos0, rad, l0) = common::random_periodic(400, 50e-6, 0.1, 0.60, 0.0, 3, 3000);
    let phi0: f64 = rad.iter().map(|r| 4.0 / 3.0 * std::f64::consts::PI * r * r * r).sum::<f64>() / l0.powi(3);
    targets
        .iter()
        .map(|&target| {
            let lambda = (phi0 / target).cbrt();
            let pos: Vec<Vector3<f64>> = pos0.iter().map(|x| x * lambda).collect();
            model_row(dir, &format!("rve-{target}"), &pos, &rad, l0 * lambda)
        })
        .collect()
}

/// The loosest stored FE cells (validation/data/random, mean h/r 0.02, solid fraction 0.51–0.56):
/// the network there is within 2 % of the 3-D FE (docs/validation-conductance.md), and no
/// geometric densification of a 0.60 packing reaches below 0.60.
const LOOSE_FE_CELLS: [&str; 4] = ["n16-h002", "n16s-h002", "v-n16s-h002-s3", "n64-h002"];

fn loose_rows(dir: &std::path::Path) -> Vec<ModelRow> {
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/validation/data/random"));
    LOOSE_FE_CELLS
        .iter()
        .map(|name| {
            let (p, bbox) = stored_cell(&root.join(name));
            model_row(dir, name, &p.position, &p.radius, bbox.x)
        })
        .collect()
}

/// The densities of the RVE rows of validation/data/measured_compacts_model.csv: the measured
/// compacts' densities (0.766, 0.78, 0.87, 0.916, 0.92) and a grid.
const MODEL_TARGETS: [f64; 12] = [0.62, 0.65, 0.70, 0.75, 0.766, 0.78, 0.82, 0.85, 0.87, 0.90, 0.916, 0.92];

fn model_csv(rows: &[ModelRow]) -> String {
    let mut out = String::from(
        "# The network's effective conductivity beside measured sintered compacts (docs/validation-conductance.md, \"Measured compacts\").\n\
         # Written by `MEASURED_COMPACTS_MODEL_CSV=validation/data/measured_compacts_model.csv cargo test --release --features h5 --test conductivity_law -- --ignored measured_compacts_model_table`.\n\
         # rve-<target>: 400 copper spheres (d = 50 um +- 10 %) relaxed at solid fraction 0.60, densified geometrically to <target>; the loose rows: stored FE cells (validation/data/random).\n\
         # Default law (fe_fit + fabric) with the bound (H8d); mean of the diagonal. kappa_rb_*: thermal.boundary_resistance [m2 K/W].\n\
         source,solid_fraction,mean_h_over_r,extrapolated,kappa_over_kappa_s,hashin_shtrikman,sigma_over_sigma_s,kappa_rb_1e-8,kappa_rb_1e-7,kappa_rb_1e-6\n",
    );
    for r in rows {
        out.push_str(&format!(
            "{},{:.6},{:.6},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}\n",
            r.source, r.solid_fraction, r.mean_h_over_r, r.extrapolated as u8, r.kappa, r.hashin_shtrikman, r.sigma, r.rb[0], r.rb[1], r.rb[2]
        ));
    }
    out
}

/// Writes validation/data/measured_compacts_model.csv (to the path in
/// `MEASURED_COMPACTS_MODEL_CSV`, else prints it): every model row of the comparison.
#[test]
#[ignore]
fn measured_compacts_model_table() {
    let dir = common::tmp_dir("measured-compacts");
    let mut rows = loose_rows(&dir);
    rows.extend(densified_rows(&dir, &MODEL_TARGETS));
    let text = model_csv(&rows);
    match std::env::var("MEASURED_COMPACTS_MODEL_CSV") {
        Ok(path) => std::fs::write(path, text).unwrap(),
        Err(_) => print!("{text}"),
    }
}

/// The stored model table (validation/data/measured_compacts_model.csv) as rows.
fn stored_model_rows() -> Vec<ModelRow> {
    let text = include_str!("../validation/data/measured_compacts_model.csv");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("source"))
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let f = |k: usize| c[k].parse::<f64>().unwrap();
            ModelRow {
                source: c[0].to_string(),
                solid_fraction: f(1),
                mean_h_over_r: f(2),
                extrapolated: c[3] == "1",
                kappa: f(4),
                hashin_shtrikman: f(5),
                sigma: f(6),
                rb: [f(7), f(8), f(9)],
            }
        })
        .collect()
}

/// One measured row of validation/data/measured/compacts.csv.
struct Measured {
    source: String,
    material: String,
    thermal: bool,
    rho: [f64; 2],
    /// The measured κ/κ_s or σ/σ_s [1].
    ratio: f64,
}

fn measured_rows() -> Vec<Measured> {
    let text = include_str!("../validation/data/measured/compacts.csv");
    let mut out = Vec::new();
    for l in text.lines().filter(|l| !l.starts_with('#') && !l.starts_with("source")) {
        // the last field may be quoted with commas: only the first eight are read
        let c: Vec<&str> = l.splitn(10, ',').collect();
        let (material, thermal) = (c[1].to_string(), c[3] == "thermal");
        let value: f64 = c[6].parse().unwrap();
        // the bulk properties of the library at 300 K (Incropera Table A.1: Cu 401, Ag 429
        // W/(m K)) and at 293 K (Matula 1979 for Cu, CRC for Ag)
        let bulk = |q: sinterdem::material::Quantity| {
            let preset = if material == "copper" { "copper" } else { "silver" };
            sinterdem::material::bundled_table(preset, q).unwrap()
        };
        let ratio = if thermal {
            value / bulk(sinterdem::material::Quantity::Conductivity).at(300.0)
        } else {
            bulk(sinterdem::material::Quantity::ElectricalResistivity).at(293.15) / value
        };
        out.push(Measured { source: c[0].to_string(), material, thermal, rho: [c[4].parse().unwrap(), c[5].parse().unwrap()], ratio });
    }
    out
}

/// The model's κ_eff/κ_s (or σ/σ_s: equal for one material) of the RVE rows at relative density
/// `rho`, linear between the rows.
fn model_at(rows: &[ModelRow], rho: f64) -> f64 {
    let rve: Vec<&ModelRow> = rows.iter().filter(|r| r.source.starts_with("rve-")).collect();
    let k = rve.windows(2).position(|w| w[0].solid_fraction <= rho && rho <= w[1].solid_fraction).unwrap_or_else(|| panic!("{rho} outside the RVE rows"));
    let (a, b) = (rve[k], rve[k + 1]);
    a.kappa + (b.kappa - a.kappa) * (rho - a.solid_fraction) / (b.solid_fraction - a.solid_fraction)
}

/// The model beside measured compacts (docs/validation-conductance.md "Measured compacts"): the
/// stored model table is what the code gives (rows recomputed), and each measured data set sits
/// where the documentation says, with the reason stated there:
/// - well-sintered compacts of coarse-grained metal at ρ 0.77–0.92 (pss2008 copper, kim2021
///   silver): the network of perfect necks is 1.2–2.0 times too conductive;
/// - loose-sintered copper at ρ 0.50 (fang2024): the loosest FE-validated packings (ρ 0.51–0.57,
///   tiny necks) read 0.35–1.15 of the measured, 0.5–0.9 on their mean (a looser start reaches
///   ρ 0.5 with larger necks);
/// - nanocrystalline copper (rosinski2005): more than 3 times, the bulk of 80 nm grains conducts
///   six times worse than coarse copper;
/// - the pressure-less silver paste (agsinter) band lies below the model at its densest end.
#[test]
fn measured_compacts_against_the_model() {
    let stored = stored_model_rows();
    let dir = common::tmp_dir("measured-compacts-check");
    // the stored table is the code's: two RVE rows and one FE cell recomputed
    let fresh = densified_rows(&dir, &[0.78, 0.916]);
    let (p, bbox) = stored_cell(&std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/validation/data/random")).join("n16-h002"));
    let fresh_loose = model_row(&dir, "n16-h002", &p.position, &p.radius, bbox.x);
    for f in fresh.iter().chain(std::iter::once(&fresh_loose)) {
        let s = stored.iter().find(|r| r.source == f.source).unwrap_or_else(|| panic!("{} not stored", f.source));
        for (a, b) in [(f.kappa, s.kappa), (f.sigma, s.sigma), (f.solid_fraction, s.solid_fraction), (f.rb[0], s.rb[0]), (f.rb[1], s.rb[1])] {
            assert!((a - b).abs() < 2e-6, "{}: {a} computed, {b} stored: regenerate validation/data/measured_compacts_model.csv", f.source);
        }
        assert_eq!(f.extrapolated, s.extrapolated);
        assert!(f.kappa <= f.hashin_shtrikman * (1.0 + 1e-12));
    }
    let loose: Vec<&ModelRow> = stored.iter().filter(|r| LOOSE_FE_CELLS.contains(&r.source.as_str())).collect();
    assert_eq!(loose.len(), LOOSE_FE_CELLS.len());
    let measured = measured_rows();
    let sources: std::collections::BTreeSet<(&str, bool)> = measured.iter().map(|m| (m.source.as_str(), m.thermal)).collect();
    assert!(sources.iter().filter(|s| s.1).count() >= 2 && sources.iter().filter(|s| !s.1).count() >= 2, "{sources:?}");
    for m in &measured {
        let what = format!("{} {} ρ {:?}: measured {:.4}", m.source, m.material, m.rho, m.ratio);
        match m.source.as_str() {
            "pss2008" | "kim2021" => {
                let r = model_at(&stored, m.rho[0]) / m.ratio;
                assert!((1.2..2.0).contains(&r), "{what}, model/measured {r}");
            }
            "fang2024" => {
                // every loose cell within 0.35–1.15 of the measured, their mean 0.5–0.9, although
                // each cell is denser (0.51–0.57) than the compacts (0.50)
                for c in &loose {
                    let r = c.kappa / m.ratio;
                    assert!((0.35..1.15).contains(&r) && c.solid_fraction > m.rho[1], "{what}, {} model/measured {r}", c.source);
                }
                let mean = loose.iter().map(|c| c.kappa).sum::<f64>() / loose.len() as f64 / m.ratio;
                assert!((0.5..0.9).contains(&mean), "{what}, mean of the loose cells/measured {mean}");
            }
            "rosinski2005" => {
                for rho in m.rho {
                    let r = model_at(&stored, rho) / m.ratio;
                    assert!(r > 3.0, "{what}, model/measured {r}");
                }
            }
            "agsinter" => assert!(m.ratio < model_at(&stored, m.rho[1]), "{what}"),
            other => panic!("no comparison for {other}"),
        }
    }
}

/// A stored FE cell (validation/data/random/<case>/): particles from `packing.csv` [m] and the
/// periodic box of its case file [m].
fn stored_cell(case: &std::path::Path) -> (sinterdem::particles::Particles, Vector3<f64>) {
    let name = case.file_name().unwrap().to_str().unwrap();
    let toml_text = std::fs::read_to_string(case.join(format!("{name}.toml"))).unwrap();
    let line = toml_text.lines().find(|l| l.starts_with("periodic_box")).unwrap();
    let l: Vec<f64> = line[line.find('[').unwrap() + 1..line.find(']').unwrap()].split(',').map(|x| x.trim().parse().unwrap()).collect();
    let mut p = sinterdem::particles::Particles::default();
    for row in std::fs::read_to_string(case.join("packing.csv")).unwrap().lines().filter(|l| !l.starts_with('#') && !l.starts_with('x')) {
        let v: Vec<f64> = row.split(',').map(|x| x.parse().unwrap()).collect();
        p.push(Vector3::new(v[0], v[1], v[2]), v[3], 0, 8960.0, 385.0, 293.15);
    }
    (p, Vector3::new(l[0], l[1], l[2]))
}

/// The bound (H8d) leaves the validated range alone: on every stored FE cell
/// (validation/data/random, mean h/r 0.02–0.12, docs/validation-conductance.md) the periodic tensor
/// with the bound equals the network of the law alone (the pipes of (H6)–(H8c) without any scale)
/// to 1e-12, with the default `fabric` and with `none`; the default's mean of the diagonal on
/// n16-h012 is the 0.48021 of the FE comparison (FE converged 0.48172), which the earlier
/// per-particle cap had lowered to 0.47779.
#[test]
fn stored_fe_cells_are_unchanged_by_the_bound() {
    use sinterdem::heat::{Conductance, MultiNeck, conductivity, pipes};
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/validation/data/random"));
    let mut cases: Vec<_> = std::fs::read_dir(root).unwrap().map(|e| e.unwrap().path()).filter(|p| p.join("packing.csv").exists()).collect();
    cases.sort();
    assert!(cases.len() >= 14, "{} stored cells", cases.len());
    let mat = sinterdem::material::parse_one(toml::from_str("name = \"cu\"\npreset = \"copper-ivannikov2022\"\n").unwrap()).unwrap();
    let kappa = mat.conductivity;
    for case in &cases {
        let (p, bbox) = stored_cell(case);
        for multi in [MultiNeck::Fabric, MultiNeck::None] {
            let law = Conductance { multi_neck: multi, ..Default::default() };
            let (bounded, branch) = conductivity::periodic_pipes(&p, bbox, std::slice::from_ref(&mat), &law).unwrap();
            let phi_s = pipes::solid_fraction(&p.radius, bbox.x * bbox.y * bbox.z);
            let voigt: f64 = bounded.conductance.iter().zip(&branch).map(|(k, b)| k * b.norm_squared()).sum::<f64>() / 3.0 / (bbox.x * bbox.y * bbox.z) / kappa;
            assert_eq!(bounded.bounded, 0, "{case:?} {multi:?}: the bound acted (φ {phi_s}, Voigt {voigt}, n {})", p.len());
            let phi = pipes::crowding(&bounded.pairs, &branch, &bounded.neck, p.len(), &law);
            let mut alone = bounded.clone();
            for (k, &[i, j]) in alone.pairs.iter().enumerate() {
                alone.conductance[k] = law.pipe_crowded(kappa, kappa, p.radius[i as usize], p.radius[j as usize], alone.neck[k], phi[k]).pair;
            }
            let (kb, ka) = (conductivity::periodic(&p, &bounded, &branch, bbox).unwrap(), conductivity::periodic(&p, &alone, &branch, bbox).unwrap());
            assert!((kb - ka).norm() <= 1e-12 * ka.norm(), "{case:?} {multi:?}: {kb} vs {ka}");
            if case.ends_with("n16-h012") && multi == MultiNeck::Fabric {
                let mean = kb.trace() / 3.0 / kappa;
                assert!((mean - 0.48021).abs() < 5e-6, "n16-h012: {mean}");
            }
        }
    }
}

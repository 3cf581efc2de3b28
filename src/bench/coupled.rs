//! `sinterdem bench coupled`.

use crate::coupled::*;
use crate::error::{ConfigError, Error};
use std::path::Path;
use std::time::Instant;

/// `sinterdem bench coupled`: the bundled copper compact run whole (wall time and the share of
/// each stage), then the cost per step of isothermal FCC compacts of about `sizes` particles;
/// `overrides` (`KEY=VALUE`) apply to every run.
pub fn bench_coupled(copper_case: Option<&Path>, sizes: &[usize], steps: u64, overrides: &[String]) -> Result<String, Error> {
    use std::fmt::Write as _;
    let mut out = String::new();
    let _ = writeln!(out, "# sinterdem bench coupled ({} rayon threads)", rayon::current_num_threads());
    if let Some(case) = copper_case {
        let value = crate::config::load_case(case, &[])?;
        let sets: Vec<String> = ["output.snapshots=0", "output.vtu=false", "output.hdf5=false", "output.checkpoint_every=0", "output.conductivity_at=[]"]
            .map(String::from)
            .into_iter()
            .chain(overrides.iter().cloned())
            .collect();
        let base = case.parent().unwrap_or(Path::new(".")).to_path_buf();
        let dir = std::env::temp_dir().join(format!("sinterdem-bench-{}", std::process::id()));
        let params = crate::kinds::RunParams { base_dir: base, plots: false, force: true, ..Default::default() };
        let s = crate::kinds::run(&value, &sets, &dir, &params)?.summary;
        let _ = std::fs::remove_dir_all(&dir);
        let tm: Timing = serde_json::from_value(s["timing_seconds"].clone()).unwrap_or_default();
        let total = s["wall_seconds"].as_f64().unwrap_or(0.0);
        let _ = writeln!(out, "{}: {} steps, {} contacts at the end, wall {:.2} s", case.display(), s["steps"], s["contacts"], total);
        let _ = writeln!(
            out,
            "  mechanics: {} Newton iterations, {} factorisations; profile {}",
            s["mechanics"]["newton_iterations"], s["mechanics"]["factorizations"], s["mechanics_profile"]
        );
        let rhs = s["rhs_evaluations"].as_f64().unwrap_or(0.0);
        let _ = writeln!(
            out,
            "  7-DOF sweep: {:.3e} right-hand sides in {:.3} s = {:.3e} per second ({} ODE steps)",
            rhs,
            tm.diffusion,
            rhs / tm.diffusion.max(1e-300),
            s["ode_steps"]
        );
        for (name, v) in [
            ("detection", tm.detection),
            ("heat", tm.heat),
            ("diffusion", tm.diffusion),
            ("mechanics", tm.mechanics),
            ("correction", tm.correction),
            ("output", tm.output),
        ] {
            let _ = writeln!(out, "  {name:<11} {v:>9.3} s  {:>5.1} %", 100.0 * v / total.max(1e-300));
        }
    }
    let _ = writeln!(
        out,
        "{:>9} {:>9} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>9}",
        "particles", "contacts", "s/step", "detection", "diffusion", "mechanics", "correction", "newton/step", "cg/step", "rhs/contact", "rhs/s", "in lanes"
    );
    for &n in sizes {
        let cells = ((n as f64 / 4.0).cbrt().round() as u32).max(2);
        let text = format!(
            "kind = \"compact\"\n[time]\nend = {end}\ndt = 1.0\ndt_max = 1.0\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n[[materials]]\nname = \"copper\"\npreset = \"copper\"\n[particles]\nsource = \"lattice\"\nlattice = \"fcc\"\ncells = [{cells}, {cells}, {cells}]\nradius = 25e-6\noverlap = 0.0\n[thermal]\nmode = \"isothermal\"\nfurnace = {{ profile = {{ constant = 1293.0 }} }}\n[contacts]\ndetect_new = true\n",
            end = steps as f64
        );
        let mut value = toml::Value::Table(text.parse::<toml::Table>().map_err(|e| ConfigError::invalid(e.to_string()))?);
        for o in overrides {
            crate::config::apply_override(&mut value, o)?;
        }
        let mut sim = prepare(value, Path::new("."), &mut |_| {})?;
        // the first step of a new contact is the stiff start; time the later steps
        sim.advance_step(&mut |_| {})?;
        let t0 = sim.timing;
        let (n0, c0, r0, l0) = (sim.mechanics.newton_iterations, sim.mechanics.profile.cg_iterations, sim.ode.rhs, sim.contacts_in_lanes);
        let w = Instant::now();
        let mut k = 0;
        while sim.t < sim.settings.end && k < steps {
            sim.advance_step(&mut |_| {})?;
            k += 1;
        }
        let per = w.elapsed().as_secs_f64() / k.max(1) as f64;
        let lanes_share = (sim.contacts_in_lanes - l0) as f64 / (k.max(1) as f64 * sim.contacts.len().max(1) as f64);
        let tm = sim.timing;
        let d = |a: f64, b: f64| (a - b) / k.max(1) as f64;
        let _ = writeln!(
            out,
            "{:>9} {:>9} {:>12.4} {:>12.4} {:>12.4} {:>12.4} {:>12.4} {:>12.1} {:>12.1} {:>12.2} {:>12.3e} {:>8.1}%",
            sim.prep.scene.particles.len(),
            sim.contacts.len(),
            per,
            d(tm.detection, t0.detection),
            d(tm.diffusion, t0.diffusion),
            d(tm.mechanics, t0.mechanics),
            d(tm.correction, t0.correction),
            d(sim.mechanics.newton_iterations as f64, n0 as f64),
            d(sim.mechanics.profile.cg_iterations as f64, c0 as f64),
            d(sim.ode.rhs as f64, r0 as f64) / sim.contacts.len().max(1) as f64,
            (sim.ode.rhs - r0) as f64 / (tm.diffusion - t0.diffusion).max(1e-300),
            100.0 * lanes_share
        );
    }
    Ok(out)
}

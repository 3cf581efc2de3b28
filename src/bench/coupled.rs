//! `sinterdem bench coupled`.

use crate::coupled::*;
use crate::error::{ConfigError, Error};
use std::path::Path;
use std::time::Instant;

/// `sinterdem bench coupled`: the bundled copper compact run whole (wall time and the share of
/// each stage), then the cost per step of isothermal FCC compacts of about `sizes` particles and
/// of the copper-compact schedule on each packing file of `packings` (random packings: new
/// contacts every fifth step from the start); `overrides` (`KEY=VALUE`) apply to every run.
pub fn bench_coupled(copper_case: Option<&Path>, sizes: &[usize], packings: &[std::path::PathBuf], steps: u64, overrides: &[String]) -> Result<String, Error> {
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
        "{:>9} {:>9} {:>10} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>9} {:>12} {:>12} {:>9} {:>10}",
        "particles",
        "contacts",
        "first s",
        "s/step",
        "detection",
        "diffusion",
        "mechanics",
        "correction",
        "newton/step",
        "cg/step",
        "new/step",
        "rhs/contact",
        "rhs/s",
        "in lanes",
        "peak kB/p"
    );
    for &n in sizes {
        let cells = ((n as f64 / 4.0).cbrt().round() as u32).max(2);
        let text = format!(
            "kind = \"compact\"\n[time]\nend = {end}\ndt = 1.0\ndt_max = 1.0\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n[particles]\nsource = \"lattice\"\nlattice = \"fcc\"\ncells = [{cells}, {cells}, {cells}]\nradius = 25e-6\noverlap = 0.0\n[thermal]\nmode = \"isothermal\"\nfurnace = {{ profile = {{ constant = 1293.0 }} }}\n[contacts]\ndetect_new = true\n",
            end = steps as f64 + 1.0
        );
        let _ = writeln!(out, "{}", time_steps(&text, Path::new("."), steps, overrides)?);
    }
    for file in packings {
        let abs = std::fs::canonicalize(file).map_err(|e| ConfigError::invalid(format!("--packing {}: {e}", file.display())))?;
        let particles = format!("[particles]\nsource = \"file\"\nfile = {:?}\n", abs.display().to_string());
        let periodic = periodic_box_beside(&abs);
        if periodic.is_some() {
            let _ = writeln!(out, "{}: as a block with faces on the principal planes", file.display());
        }
        let _ = writeln!(out, "{}", time_steps(&format!("{PACKING_CASE}{particles}"), Path::new("."), steps, overrides)?);
        if let Some(b) = periodic {
            // the same packing as the periodic cell it was generated in: free sintering (the
            // three normal stresses held at zero), then one conductivity tensor by (H18)
            let cell = format!(
                "{}\n[mechanics.cell]\ncomponents = \"normal\"\nxx = {{ stress = 0.0 }}\nyy = {{ stress = 0.0 }}\nzz = {{ stress = 0.0 }}\n",
                PACKING_CASE.replace(PLANES, PERIODIC)
            );
            let particles = format!("{particles}periodic_box = [{:e}, {:e}, {:e}]\n", b[0], b[1], b[2]);
            let _ = writeln!(out, "{}: as the periodic cell it was generated in (free sintering)", file.display());
            let _ = writeln!(out, "{}", time_steps(&format!("{cell}{particles}"), Path::new("."), steps, overrides)?);
            // a static heat case of the packing (the compact's overrides do not apply to it)
            let heat = format!(
                "[time]\nend = 1.0\ndt = 0.1\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n{particles}[conductivity]\nboundary = \"periodic\"\n"
            );
            let value = toml::Value::Table(heat.parse::<toml::Table>().map_err(|e| ConfigError::invalid(e.to_string()))?);
            let t = Instant::now();
            let k = crate::kinds::conductivity::run_case(value, Path::new("."))?;
            let _ = writeln!(
                out,
                "  one periodic conductivity tensor (sinterdem conductivity, boundary = \"periodic\"): {:.3} s with {} contacts, mean of the diagonal {:.2} W/(m K)",
                t.elapsed().as_secs_f64(),
                k["periodic_contacts"],
                (0..3).map(|a| k["kappa_eff_W_per_mK"][a][a].as_f64().unwrap_or(f64::NAN)).sum::<f64>() / 3.0
            );
        }
    }
    let _ = writeln!(
        out,
        "first s: the first step (topology analysis, first factorisation or AMG setup, stiff start of every contact); \
         the other columns are means over the {steps} steps after it; new/step: contacts found per step; \
         peak kB/p: the process's peak resident memory (VmHWM, so far in this bench) per particle"
    );
    Ok(out)
}

/// The copper compact's settings (cases/large/copper-compact-100k.toml) without its packing: the
/// per-step cost of a random packing under the schedule users run.
const PACKING_CASE: &str = "kind = \"compact\"\n[time]\nend = 5000.0\ndt = 1.0e-6\nstrategy = 2\ndt_max = 10.0\nalpha = 1.5\n\
[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n[[materials]]\nname = \"copper\"\npreset = \"copper-ivannikov2022\"\n\
[thermal]\nmode = \"isothermal\"\nfurnace = { profile = { constant = 1293.0 } }\n\
[contacts]\ndetect_new = true\ndetect_every = 5\ngap_tolerance = 1.0e-3\nneck = \"volume_conserving\"\n\
[solver]\nmethod = \"dopri5\"\nrtol = 1.0e-5\n[mechanics]\nconstrain_planes = true\nplane_margin = 1.01\nsolver = \"auto\"\n";

/// The walled schedule's mechanics section of [`PACKING_CASE`] and its periodic replacement.
const PLANES: &str = "[mechanics]\nconstrain_planes = true\nplane_margin = 1.01\nsolver = \"auto\"\n";
const PERIODIC: &str = "[mechanics]\nboundary = \"periodic\"\nsolver = \"auto\"\n";

/// The periodic box [m] of a packing written by `generate` with `boundary = "periodic"`: the
/// `box_size_m` of the `summary.json` beside the file; None for any other file.
fn periodic_box_beside(file: &Path) -> Option<[f64; 3]> {
    let text = std::fs::read_to_string(file.parent()?.join("summary.json")).ok()?;
    let s: serde_json::Value = serde_json::from_str(&text).ok()?;
    if s["boundary"] != "periodic" {
        return None;
    }
    let b = s["box_size_m"].as_array()?;
    Some([b.first()?.as_f64()?, b.get(1)?.as_f64()?, b.get(2)?.as_f64()?])
}

/// Peak resident memory of this process so far [bytes] (`VmHWM` of /proc/self/status; 0 where
/// it is not known).
fn peak_memory_bytes() -> f64 {
    let text = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    text.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok()).map_or(0.0, |kb| kb * 1024.0)
}

/// One row of the per-step table: prepares the case `text` (overrides applied), runs and times
/// its first step, then `steps` more steps, per stage.
fn time_steps(text: &str, base: &Path, steps: u64, overrides: &[String]) -> Result<String, Error> {
    let mut value = toml::Value::Table(text.parse::<toml::Table>().map_err(|e| ConfigError::invalid(e.to_string()))?);
    for o in overrides {
        crate::config::apply_override(&mut value, o)?;
    }
    let mut sim = prepare(value, base, &mut |_| {})?;
    // the first step of a new contact is the stiff start; time the later steps
    let w0 = Instant::now();
    sim.advance_step(&mut |_| {})?;
    let first = w0.elapsed().as_secs_f64();
    let t0 = sim.timing;
    let (n0, c0, r0, l0, k0) = (sim.mechanics.newton_iterations, sim.mechanics.profile.cg_iterations, sim.ode.rhs, sim.contacts_in_lanes, sim.contacts.len());
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
    let particles = sim.prep.scene.particles.len();
    Ok(format!(
        "{:>9} {:>9} {:>10.3} {:>12.4} {:>12.4} {:>12.4} {:>12.4} {:>12.4} {:>12.1} {:>12.1} {:>9.1} {:>12.2} {:>12.3e} {:>8.1}% {:>10.2}",
        particles,
        sim.contacts.len(),
        first,
        per,
        d(tm.detection, t0.detection),
        d(tm.diffusion, t0.diffusion),
        d(tm.mechanics, t0.mechanics),
        d(tm.correction, t0.correction),
        d(sim.mechanics.newton_iterations as f64, n0 as f64),
        d(sim.mechanics.profile.cg_iterations as f64, c0 as f64),
        d(sim.contacts.len() as f64, k0 as f64),
        d(sim.ode.rhs as f64, r0 as f64) / sim.contacts.len().max(1) as f64,
        (sim.ode.rhs - r0) as f64 / (tm.diffusion - t0.diffusion).max(1e-300),
        100.0 * lanes_share,
        peak_memory_bytes() / 1024.0 / particles.max(1) as f64
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The periodic variant of the packing schedule really swaps the mechanics section (a silent
    /// no-op would time the walled block twice).
    #[test]
    fn the_periodic_schedule_replaces_the_planes() {
        assert!(PACKING_CASE.contains(PLANES));
        let cell = PACKING_CASE.replace(PLANES, PERIODIC);
        assert!(cell.contains("boundary = \"periodic\"") && !cell.contains("constrain_planes"));
        let dir = std::env::temp_dir().join(format!("sinterdem-bench-box-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("summary.json"), r#"{"boundary": "periodic", "box_size_m": [1e-3, 2e-3, 3e-3]}"#).unwrap();
        assert_eq!(periodic_box_beside(&dir.join("packing.csv")), Some([1e-3, 2e-3, 3e-3]));
        std::fs::write(dir.join("summary.json"), r#"{"box_size": [1e-3, 2e-3, 3e-3]}"#).unwrap();
        assert_eq!(periodic_box_beside(&dir.join("packing.csv")), None);
        let _ = std::fs::remove_dir_all(dir);
    }
}

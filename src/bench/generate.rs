//! `sinterdem bench generate`: packing generation timed on copper-like benchmark cases.

use crate::error::Error;
use crate::kinds::generate::generate_case;
use std::path::Path;
use std::time::Instant;

/// The benchmark case for `n` particles: copper-like (mean diameter 50 µm, uniform ±10 %), box
/// shape 1:1:0.8, target 0.60, seed 1.
pub fn bench_case(n: usize) -> toml::Value {
    let text = format!(
        "kind = \"generate\"\n[packing]\nparticles = {n}\nseed = 1\ntarget_solid_fraction = 0.60\nbox = [0.5e-3, 0.5e-3, 0.4e-3]\n[packing.size]\ndistribution = \"uniform\"\nmean_diameter = 50e-6\nspread = 0.1\n"
    );
    toml::Value::Table(text.parse::<toml::Table>().expect("static bench case"))
}

/// The periodic benchmark case for `n` particles: the bundled `cases/packing/periodic-copper.toml`
/// recipe (mean diameter 50 µm, uniform ±10 %, cubic periodic box, target 0.62, seed 1).
pub fn bench_case_periodic(n: usize) -> toml::Value {
    let text = format!(
        "kind = \"generate\"\n[packing]\nparticles = {n}\nseed = 1\ntarget_solid_fraction = 0.62\nboundary = \"periodic\"\nbox = [1.0, 1.0, 1.0]\n[packing.size]\ndistribution = \"uniform\"\nmean_diameter = 50e-6\nspread = 0.1\n"
    );
    toml::Value::Table(text.parse::<toml::Table>().expect("static bench case"))
}

/// Library entry point of `sinterdem bench generate [--periodic]`: generates the benchmark case
/// ([`bench_case`], or [`bench_case_periodic`]) for each size, writing into `out_dir/bench-N`, and
/// returns a table of wall-clock times and results.
pub fn bench_generate(out_dir: &Path, sizes: &[usize], periodic: bool) -> Result<String, Error> {
    let mut s = format!(
        "# sinterdem bench generate{} ({} rayon threads)\n{:>9} {:>10} {:>9} {:>8} {:>9} {:>10} {:>10}\n",
        if periodic { " --periodic" } else { "" },
        rayon::current_num_threads(),
        "particles",
        "time [s]",
        "steps",
        "phi",
        "Z_mean",
        "overlap/r",
        "laminae dev"
    );
    for &n in sizes {
        let t = Instant::now();
        let case = if periodic { bench_case_periodic(n) } else { bench_case(n) };
        let summary = generate_case(&case, &out_dir.join(format!("bench-{n}")), false)?;
        let el = t.elapsed().as_secs_f64();
        let line = format!(
            "{:>9} {:>10.2} {:>9} {:>8.4} {:>9.3} {:>10.2e} {:>10.3}\n",
            n,
            el,
            summary.steps,
            summary.solid_fraction,
            summary.coordination_mean,
            summary.max_overlap_rel,
            summary.laminae_max_deviation.iter().copied().fold(0.0, f64::max)
        );
        eprint!("{line}");
        s.push_str(&line);
    }
    Ok(s)
}

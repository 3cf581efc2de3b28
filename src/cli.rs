//! The `sinterdem` command line, as a library function: [`main`] parses the arguments, runs the
//! command and returns the process exit code. The Rust binary (`src/main.rs`) and the Python
//! wheel's `sinterdem` console entry point both call it, so they are one program. Exit codes by
//! error class: [`crate::error::Error::exit_code`] (docs/outputs.md, "Exit codes").

use crate::error::Error;
use clap::{Args, Parser, Subcommand};
use std::ffi::OsString;
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(name = "sinterdem", version, about = "Coupled thermo-mechanical simulator of powder sintering")]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Print only warnings and errors (no progress bar, no info lines).
    #[arg(short, long, global = true)]
    quiet: bool,
    /// More detail in the log (-v debug, -vv trace); DIR/log.txt always gets every info line.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
}

#[derive(Args, Clone)]
struct CaseArgs {
    /// Case file (TOML, SI units).
    case: PathBuf,
    /// Override a key: --set time.end=10 (repeatable; arrays by index: thermal.fixed.0.profile.constant=900).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

#[derive(Subcommand)]
enum Command {
    /// Run a case and write its results to --out.
    Run {
        #[command(flatten)]
        case: CaseArgs,
        /// Output directory (default: out/<case name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Compact, heat and explicit_sinter runs: write DIR/checkpoint.json every N steps (same as --set output.checkpoint_every=N).
        #[arg(long, value_name = "N")]
        checkpoint_every: Option<u64>,
        /// Threads of the run (default: every core; RAYON_NUM_THREADS too).
        #[arg(long, value_name = "N")]
        threads: Option<usize>,
        /// Remove the outputs of an earlier command in the output directory first (without it such a directory is refused; docs/outputs.md).
        #[arg(long)]
        force: bool,
    },
    /// Generate a green packing (kind = "generate"): packing.csv, packing.vtu, summary.json, laminae.
    #[command(mut_arg("set", |a| a.help("Override a key: --set packing.particles=500 (repeatable; arrays by index: materials.0.density=8960)")))]
    Generate {
        #[command(flatten)]
        case: CaseArgs,
        /// Output directory (default: out/<case name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Remove the outputs of an earlier command in the output directory first (without it such a directory is refused; docs/outputs.md).
        #[arg(long)]
        force: bool,
    },
    /// Constitutive data of a periodic compact (docs/rve.md): the free run, branch runs under
    /// small stress perturbations at rve.at, then constitutive.csv, fit.json, plots, summary.json.
    Rve {
        #[command(flatten)]
        case: CaseArgs,
        /// Output directory (default: out/<case name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Remove the outputs of an earlier command in the output directory first (without it such a directory is refused; docs/outputs.md).
        #[arg(long)]
        force: bool,
    },
    /// Continue an interrupted compact, heat or explicit_sinter run from DIR/checkpoint.json.
    Resume {
        /// The run's output directory.
        dir: PathBuf,
    },
    /// Validate a case file (parse, ranges, scene construction) or a calibration file (its data, parameters and packing), without running.
    Check {
        #[command(flatten)]
        case: CaseArgs,
    },
    /// Neck geometry and pipe conductance of two spheres; prints JSON (SI units).
    Neck {
        /// Radius of particle 1 [m].
        #[arg(long, allow_hyphen_values = true)]
        r1: f64,
        /// Radius of particle 2 [m].
        #[arg(long, allow_hyphen_values = true)]
        r2: f64,
        /// Overlap h = r1 + r2 − d [m].
        #[arg(long, allow_hyphen_values = true)]
        overlap: f64,
        /// Thermal conductivity of particle 1 [W/(m K)].
        #[arg(long, allow_hyphen_values = true)]
        kappa: f64,
        /// Thermal conductivity of particle 2 [W/(m K)] (default: --kappa).
        #[arg(long, allow_hyphen_values = true)]
        kappa2: Option<f64>,
        /// Conductance law: fe_fit (the FE-fitted factor, default) or linear (1.064 κ π a).
        #[arg(long, default_value = "fe_fit")]
        conductance: String,
        /// c_K of the linear law.
        #[arg(long, default_value_t = 1.064, allow_hyphen_values = true)]
        factor: f64,
        /// Interface conductance in series [W/K].
        #[arg(long, allow_hyphen_values = true)]
        contact_conductance: Option<f64>,
    },
    /// Steady-state effective conductivity tensor of a packing; prints JSON.
    Conductivity {
        #[command(flatten)]
        case: CaseArgs,
    },
    /// The 28 titanium experiments as pair runs: an alias of
    /// `sinterdem study cases/studies/titanium-28.toml` (the bundled file, found from any directory).
    Titanium {
        /// Output directory.
        #[arg(long, default_value = "out/titanium")]
        out: PathBuf,
        /// Heat from 313 K instead of truncating the heating branch below 793 K.
        #[arg(long)]
        full: bool,
        /// Use one common particle diameter [m] instead of each experiment's own.
        #[arg(long, allow_hyphen_values = true)]
        diameter: Option<f64>,
        /// Remove the outputs of an earlier command in the output directory first (without it a directory holding another command's outputs is refused; the study's own is continued).
        #[arg(long)]
        force: bool,
    },
    /// Run a study: many runs over a design of parameters, locally or on SLURM (docs/studies.md).
    Study {
        /// Study file (TOML).
        study: PathBuf,
        /// Where the runs execute.
        #[arg(long, value_enum, default_value = "local")]
        engine: EngineArg,
        /// Local engine: runs at a time (default: cores / threads per run).
        #[arg(long)]
        jobs: Option<usize>,
        /// Output directory (default: out/<study name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// SLURM: wait for the job array, resubmit lost tasks, then gather study.csv.
        #[arg(long)]
        wait: bool,
        /// Run again the runs that failed before.
        #[arg(long)]
        retry_failed: bool,
        /// Remove the outputs of an earlier command in the output directory first and start over (without it a directory holding another command's outputs is refused; the study's own is continued).
        #[arg(long)]
        force: bool,
        /// Override a key of every run (repeatable), after the study's own overrides.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// SLURM partition (overrides slurm.partition).
        #[arg(long)]
        partition: Option<String>,
        /// SLURM time limit per array task, e.g. 01:00:00 (overrides slurm.time).
        #[arg(long)]
        time: Option<String>,
        /// SLURM account (overrides slurm.account).
        #[arg(long)]
        account: Option<String>,
        /// SLURM cpus per array task (overrides slurm.cpus_per_task).
        #[arg(long)]
        cpus_per_task: Option<usize>,
        /// SLURM: runs per array task (overrides slurm.chunk).
        #[arg(long)]
        chunk: Option<usize>,
        /// Extra #SBATCH line (repeatable), e.g. --sbatch "--mem=4G".
        #[arg(long = "sbatch", value_name = "OPTION", allow_hyphen_values = true)]
        sbatch: Vec<String>,
    },
    /// Internal: one SLURM array task of a study (written into the job script).
    #[command(hide = true)]
    StudyTask {
        dir: PathBuf,
        #[arg(long)]
        batch: usize,
        #[arg(long)]
        task: usize,
        #[arg(long, default_value_t = 1)]
        threads: usize,
    },
    /// Fit diffusion data / path factors to measured neck ratios and shrinkages (docs/calibration.md).
    #[command(mut_arg("set", |a| a.help("Override a key of the calibration file: --set optimiser.swarm_iterations=0 (repeatable)")))]
    Calibrate {
        #[command(flatten)]
        case: CaseArgs,
        /// Output directory.
        #[arg(long, default_value = "out/calibration")]
        out: PathBuf,
        /// Rewrite the file's data CSV with the bundled synthetic titanium data instead of fitting.
        #[arg(long, hide = true)]
        generate_synthetic: bool,
        /// After the fit, run the experiments of [compact] on its packing with the fitted material
        /// and write compact_validation.csv (docs/calibration.md).
        #[arg(long)]
        validate_compact: bool,
        /// Remove the outputs of an earlier command in the output directory first and start over (without it a directory holding another command's outputs is refused; the calibration's own is continued).
        #[arg(long)]
        force: bool,
    },
    /// Print every numeric case-file key with its allowed range and unit (Markdown).
    Keys {
        /// The keys of a study file instead (docs/studies.md).
        #[arg(long)]
        study: bool,
    },
    /// The bundled materials library (docs/materials.md): one line per preset, or with
    /// `--markdown` the generated part of docs/materials.md.
    Materials {
        /// Print the generated part of docs/materials.md (Markdown) instead.
        #[arg(long)]
        markdown: bool,
    },
    /// Benchmarks (print figures; not tests).
    Bench {
        #[command(subcommand)]
        which: Bench,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum EngineArg {
    Local,
    Slurm,
}

#[derive(Subcommand)]
enum Bench {
    /// The study engine: a pair study of --runs runs on the local engine (wall time, overhead per run).
    Study {
        /// Number of runs.
        #[arg(long, default_value_t = 1000)]
        runs: usize,
        /// Runs at a time (default: cores).
        #[arg(long)]
        jobs: Option<usize>,
        /// Output directory of the study.
        #[arg(long, default_value = "out/bench-study")]
        out: PathBuf,
    },
    /// Assembly, factorisation and solve times of one implicit heat step on random packings.
    Heat {
        /// Particle counts (repeatable).
        #[arg(long = "particles", default_values_t = vec![1000usize, 10000, 100000])]
        particles: Vec<usize>,
        /// Repetitions per size (median reported).
        #[arg(long, default_value_t = 3)]
        repeat: usize,
    },
    /// Work-precision of the heat step: fixed Δt against error-controlled Δt (time.heat_tolerance)
    /// on the hot plate switched on at t = 0; prints the table and writes DIR/work_precision.csv.
    HeatStep {
        /// Output directory.
        #[arg(long, default_value = "out/bench-heat-step")]
        out: PathBuf,
        /// FCC cells of the compact (x, y, z).
        #[arg(long, num_args = 3, default_values_t = vec![4u32, 4, 8])]
        cells: Vec<u32>,
        /// Simulated end time [s].
        #[arg(long, default_value_t = 20.0)]
        end: f64,
    },
    /// Packing generation time for given particle counts.
    Generate {
        /// Particle counts (repeatable).
        #[arg(long = "particles", default_values_t = vec![805usize, 3619])]
        particles: Vec<usize>,
        /// Output directory.
        #[arg(long, default_value = "out/bench-generate")]
        out: PathBuf,
        /// Periodic packings (cubic box, target 0.62; docs/packing.md "Periodic packings") instead
        /// of the walled box.
        #[arg(long)]
        periodic: bool,
    },
    /// The coupled loop: the copper compact whole (stage shares), then the cost per step of FCC
    /// compacts of the given sizes.
    Coupled {
        /// Compact case to run whole (default cases/copper-compact.toml; "none" to skip).
        #[arg(long, default_value = "cases/copper-compact.toml")]
        case: String,
        /// Particle counts of the per-step measurement (repeatable).
        #[arg(long = "particles", default_values_t = vec![1000usize, 10000, 100000])]
        particles: Vec<usize>,
        /// Packing files (packing.csv of `generate`) run with the copper compact's schedule and
        /// timed per step like the lattices (repeatable; docs/coupled.md "Scaling").
        #[arg(long = "packing")]
        packing: Vec<PathBuf>,
        /// Steps timed per size.
        #[arg(long, default_value_t = 3)]
        steps: u64,
        /// Override a key of every run (repeatable), e.g. --set mechanics.warm_start=false.
        #[arg(long = "set")]
        set: Vec<String>,
    },
    /// Run time against error of the coupled loop: the copper compact and a corner of the E14B
    /// packing over a ladder of settings against a tight reference (CSV + PNG, docs/coupled.md).
    Precision {
        /// Copper compact case ("none" to skip).
        #[arg(long, default_value = "cases/copper-compact.toml")]
        copper: String,
        /// E14B titanium compact case whose packing's corner is run ("none" to skip).
        #[arg(long, default_value = "cases/titanium-compact-e14b.toml")]
        e14b: String,
        /// Edge of the E14B corner [m]: particles with x, y below it and z below twice it.
        #[arg(long, default_value_t = 4e-4)]
        corner_edge: f64,
        /// Output directory.
        #[arg(long, default_value = "out/bench-precision")]
        out: PathBuf,
    },
    /// The bonded 6-DOF solve: assembly, symbolic, factorisation, solve and PCG on bonded packings.
    Mechanics {
        /// Particle counts (repeatable).
        #[arg(long = "particles", default_values_t = vec![1000usize, 10000])]
        particles: Vec<usize>,
        /// Skip the Cholesky columns above this many particles (its factor needs ≈ 14 GB at 10⁵).
        #[arg(long = "cholesky-max", default_value_t = usize::MAX)]
        cholesky_max: usize,
        /// One solver alone (cholesky, cg, amg or hypre): setup, iterations and solve of a first
        /// and a second step, for comparisons and `/usr/bin/time -v` (docs/coupled.md "hypre's BoomerAMG against our AMG").
        #[arg(long)]
        solver: Option<String>,
    },
    /// The 7-DOF sweep: copper contacts integrated one at a time and in lanes of four, right-hand sides per second
    Sweep {
        /// Number of contacts.
        #[arg(long, default_value_t = 100_000)]
        contacts: usize,
        /// Intervals (the first is the contacts' start).
        #[arg(long, default_value_t = 4)]
        steps: usize,
        /// Length of an interval [s].
        #[arg(long, default_value_t = 1.0)]
        dt: f64,
    },
    /// Work-precision diagram of the 7-DOF pair integrators (copper and E14B titanium).
    Pair {
        /// Output directory for work_precision.csv and the PNG diagrams.
        #[arg(long, default_value = "out/bench-pair")]
        out: PathBuf,
    },
}

/// A bundled file (`cases/…`) found from anywhere: under the working directory, beside the
/// binary (`target/release/sinterdem` → the repository two levels up; an installed
/// `bin/sinterdem` → `share/sinterdem/`), or in the source tree this binary was built from.
fn bundled(rel: &str) -> Result<PathBuf, Error> {
    let mut roots = vec![PathBuf::from(".")];
    if let Some(dir) = std::env::current_exe().ok().and_then(|e| e.canonicalize().ok()).and_then(|e| e.parent().map(Path::to_path_buf)) {
        roots.extend([dir.join("../.."), dir.join("../share/sinterdem"), dir.clone()]);
    }
    roots.push(PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    roots.iter().map(|r| r.join(rel)).find(|p| p.is_file()).ok_or_else(|| {
        crate::ConfigError::invalid(format!(
            "{rel} not found under the working directory, beside the binary or in {}: run `sinterdem study PATH/{}` with the file of a sinterdem checkout",
            env!("CARGO_MANIFEST_DIR"),
            Path::new(rel).file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default()
        ))
        .into()
    })
}

/// A study's log line on the console: `warning: …` lines as warnings (shown with `-q`), the rest
/// as info.
fn study_log(m: &str) {
    match m.strip_prefix("warning: ") {
        Some(w) => tracing::warn!("{w}"),
        None => tracing::info!("{m}"),
    }
}

/// The folder of a case file (relative paths in it start there); "." for a bare file name.
fn base_dir(case: &Path) -> PathBuf {
    case.parent().filter(|p| !p.as_os_str().is_empty()).map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."))
}

/// `run` and `generate`: the run API with the case's folder as base and log lines on stderr.
fn run_case(case: &CaseArgs, value: toml::Value, out: Option<PathBuf>, quiet: bool, force: bool, extra: Vec<String>) -> Result<(), Error> {
    let stem = case.case.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "case".into());
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(stem));
    let mut sets = case.set.clone();
    sets.extend(extra);
    let params = crate::kinds::RunParams { base_dir: base_dir(&case.case), progress: !quiet, echo_log: true, plots: true, wall_limit: None, force };
    crate::kinds::run(&crate::kinds::title_from_file(value, &case.case), &sets, &out, &params)?;
    Ok(())
}

/// Runs `f` and adds to a configuration error the file:line:column of the key it names in the
/// case file (or the `--set` that set it).
fn located(case: &CaseArgs, f: impl FnOnce() -> Result<(), Error>) -> Result<(), Error> {
    f().map_err(|e| crate::config::messages::locate(e, &case.case, &case.set))
}

/// Runs the command line `args` (the first is the program name, as in `std::env::args_os`) and
/// returns the exit code: 0 on success, 2 for a usage error (clap), else the error class's code
/// ([`Error::exit_code`]); `--help` and `--version` print and return 0.
pub fn main<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return e.exit_code();
        }
    };
    crate::logging::init(crate::logging::Verbosity::from_flags(cli.quiet, cli.verbose));
    match real_main(cli) {
        // a heat or compact run stopped by SIGINT/SIGTERM has written its outputs
        // (completed = false): the exit code says which signal stopped it
        Ok(()) if crate::interrupt::signal().is_some() && crate::interrupt::observed() => {
            let sig = crate::interrupt::signal().unwrap_or(2);
            eprintln!("interrupted by signal {sig}: the outputs are written (summary.json: completed = false, stop_reason = \"interrupted\")");
            128 + sig
        }
        Ok(()) if crate::interrupt::signal().is_some() => {
            let sig = crate::interrupt::signal().unwrap_or(2);
            eprintln!("signal {sig} arrived after the work was done: the outputs are complete");
            0
        }
        Ok(()) => 0,
        // a command that ends with an error because a signal stopped it (a calibration) exits
        // with the signal's code as well
        Err(e) if crate::interrupt::signal().is_some() => {
            eprintln!("error: {e}");
            128 + crate::interrupt::signal().unwrap_or(2)
        }
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

/// `println!` to stdout that returns an i/o error (exit 5) when stdout is a closed pipe or a full
/// device, instead of panicking (issue 38).
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let mut o = std::io::stdout().lock();
        writeln!(o, $($t)*).and_then(|_| o.flush()).map_err(|e| crate::error::IoError::new(std::path::Path::new("<standard output>"), e))?;
    }};
}

/// [`say!`] without the line break (`print!`).
macro_rules! say_raw {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let mut o = std::io::stdout().lock();
        write!(o, $($t)*).and_then(|_| o.flush()).map_err(|e| crate::error::IoError::new(std::path::Path::new("<standard output>"), e))?;
    }};
}

/// The largest `--threads` (and study `threads`/`jobs`) accepted: four per available core (at
/// least 16) — more only adds threads that wait, and an absurd count spawns its OS threads first.
pub fn max_threads() -> usize {
    (4 * std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)).max(16)
}

/// Checks a thread or job count `n` given as `key`: in [1, [`max_threads`]].
pub fn check_threads(key: &str, n: usize) -> Result<usize, crate::ConfigError> {
    let max = max_threads();
    if n == 0 || n > max {
        return Err(crate::ConfigError::OutOfRange {
            key: key.into(),
            value: n as f64,
            range: format!("[1, {max}] (4 per available core, at least 16)"),
            unit: "1".into(),
        });
    }
    Ok(n)
}

fn real_main(cli: Cli) -> Result<(), Error> {
    let quiet = cli.quiet;
    match cli.command {
        Command::Generate { case, out, force } => located(&case, || {
            let value = crate::config::load_case(&case.case, &[])?;
            if crate::kinds::Kind::of(&value)? != crate::kinds::Kind::Generate {
                return Err(crate::ConfigError::invalid(format!("{}: kind must be \"generate\"", case.case.display())).into());
            }
            run_case(&case, value, out.clone(), quiet, force, vec![])
        }),
        Command::Run { case, out, checkpoint_every, threads, force } => located(&case, || {
            let value = crate::config::load_case(&case.case, &[])?;
            let extra = checkpoint_every.map(|n| format!("output.checkpoint_every={n}")).into_iter().collect();
            match threads {
                Some(n) => {
                    let n = check_threads("--threads", n)?;
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(n)
                        .build()
                        .map_err(|e| Error::from(crate::ConfigError::invalid(format!("--threads {n}: {e}"))))?;
                    pool.install(|| run_case(&case, value, out.clone(), quiet, force, extra))
                }
                None => run_case(&case, value, out.clone(), quiet, force, extra),
            }
        }),
        Command::Rve { case, out, force } => located(&case, || {
            let value = crate::config::load_case(&case.case, &[])?;
            let stem = case.case.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "case".into());
            let out = out.clone().unwrap_or_else(|| PathBuf::from("out").join(stem));
            let params = crate::kinds::RunParams { base_dir: base_dir(&case.case), progress: !quiet, echo_log: true, plots: true, wall_limit: None, force };
            crate::kinds::rve::run(&value, &case.set, &out, &params)?;
            Ok(())
        }),
        Command::Resume { dir } => {
            let params = crate::kinds::RunParams { progress: !quiet, echo_log: true, ..Default::default() };
            crate::kinds::resume(&dir, &params)?;
            Ok(())
        }
        Command::Check { case } => located(&case, || {
            let value = crate::config::load_case(&case.case, &[])?;
            let what = crate::calibrate::check_file(&value, &case.set, &base_dir(&case.case))?;
            say!("{}: ok ({what})", case.case.display());
            Ok(())
        }),
        Command::Titanium { out, full, diameter, force } => {
            let study = bundled("cases/studies/titanium-28.toml")?;
            let mut set = vec![];
            if full {
                set.push("temperature.start_temperature=313".to_string());
            }
            if let Some(d) = diameter {
                set.push(format!("pair.radius={:e}", d / 2.0));
            }
            let opts = crate::study::StudyOptions { out: Some(out), overrides: set, progress: !quiet, force, ..Default::default() };
            crate::study::run_study(&study, &opts, &mut study_log)?;
            Ok(())
        }
        Command::Study { study, engine, jobs, out, wait, retry_failed, force, set, partition, time, account, cpus_per_task, chunk, sbatch } => {
            let engine = match engine {
                EngineArg::Local => crate::study::Engine::Local,
                EngineArg::Slurm => crate::study::Engine::Slurm,
            };
            if let Some(j) = jobs.filter(|&j| j > 0) {
                check_threads("--jobs", j)?;
            }
            let slurm = crate::study::slurm::SlurmOverrides { partition, time, account, cpus_per_task, chunk, extra: sbatch };
            let opts = crate::study::StudyOptions { engine, jobs, out, wait, retry_failed, overrides: set, progress: !quiet, slurm, plots: true, force };
            let info = crate::study::run_study(&study, &opts, &mut study_log)?;
            if info.gathered && info.counts.failed > 0 {
                tracing::warn!("{} of {} runs failed (see status and error in {})", info.counts.failed, info.counts.runs, info.dir.join("study.csv").display());
            }
            Ok(())
        }
        Command::StudyTask { dir, batch, task, threads } => {
            let n = crate::study::slurm::run_task(&dir, batch, task, threads)?;
            tracing::info!("study task {batch}/{task}: {n} runs executed");
            Ok(())
        }
        Command::Neck { r1, r2, overlap, kappa, kappa2, conductance, factor, contact_conductance } => {
            let v = neck_report(&NeckArgs { r1, r2, overlap, kappa, kappa2, conductance, factor, contact_conductance })?;
            say!("{}", serde_json::to_string_pretty(&v).unwrap());
            Ok(())
        }
        Command::Conductivity { case } => located(&case, || {
            let value = crate::config::load_case(&case.case, &case.set)?;
            let v = crate::kinds::conductivity::run_case(value, &base_dir(&case.case))?;
            say!("{}", serde_json::to_string_pretty(&v).unwrap());
            Ok(())
        }),
        Command::Calibrate { case, out, generate_synthetic, validate_compact, force } => {
            located(&case, || crate::calibrate::run_file_forced(&case.case, &case.set, &out, quiet, generate_synthetic, validate_compact, force))
        }
        Command::Keys { study } => {
            say_raw!("{}", if study { crate::study::spec::markdown() } else { crate::config::ranges::markdown(&crate::calibrate::every_table()) });
            Ok(())
        }
        Command::Materials { markdown } => {
            use crate::models::diffusion7::library;
            if markdown {
                say_raw!("{}", library::markdown());
            } else {
                for e in library::entries() {
                    say!("{}: {}", e.name, e.description);
                }
            }
            Ok(())
        }
        Command::Bench { which } => run_bench(which),
    }
}

/// The arguments of `sinterdem neck` (SI units; `sinterdem neck --help`).
#[derive(Debug, Clone)]
pub struct NeckArgs {
    pub r1: f64,
    pub r2: f64,
    pub overlap: f64,
    pub kappa: f64,
    pub kappa2: Option<f64>,
    pub conductance: String,
    pub factor: f64,
    pub contact_conductance: Option<f64>,
}

/// `sinterdem neck`: the neck geometry of two spheres at an overlap and the pipe conductance of
/// the pair, as the JSON object the command prints (the Python package's `sinterdem.neck`).
pub fn neck_report(a: &NeckArgs) -> Result<serde_json::Value, Error> {
    let law = match a.conductance.as_str() {
        "linear" => crate::heat::ConductanceLaw::Linear,
        "fe_fit" => crate::heat::ConductanceLaw::FeFit,
        other => return Err(crate::ConfigError::invalid(format!("--conductance {other}: expected linear or fe_fit")).into()),
    };
    let optional = [("--kappa2", a.kappa2), ("--contact-conductance", a.contact_conductance)];
    for (k, v) in [("--r1", a.r1), ("--r2", a.r2), ("--kappa", a.kappa), ("--factor", a.factor)]
        .into_iter()
        .chain(optional.into_iter().filter_map(|(k, v)| Some((k, v?))))
    {
        if !(v > 0.0 && v.is_finite()) {
            return Err(crate::ConfigError::OutOfRange {
                key: k.into(),
                value: v,
                range: "(0, inf)".into(),
                unit: match k {
                    "--r1" | "--r2" => "m",
                    "--kappa" | "--kappa2" => "W/(m K)",
                    "--factor" => "1",
                    _ => "W/K",
                }
                .into(),
            }
            .into());
        }
    }
    let n = crate::neck::solve(a.r1, a.r2, a.overlap)?;
    // one pair: every neck alone on its particle, crowding 1 (docs/heat-model.md (H8a))
    let c = crate::heat::Conductance { law, factor: a.factor, contact: a.contact_conductance, ..Default::default() };
    let p = c.pipe(a.kappa, a.kappa2.unwrap_or(a.kappa), a.r1, a.r2, n.a);
    Ok(serde_json::json!({
        "a": n.a, "a_coble": n.a_coble, "h_ci": n.h_ci, "h_cj": n.h_cj, "h_n": n.h_n,
        "newton_iterations": n.iterations,
        "K_half_i": p.half_i, "K_half_j": p.half_j, "K_pair": p.pair,
        "conductance": a.conductance,
    }))
}

/// `sinterdem bench …`: runs one benchmark of [`crate::bench`] and prints its table.
fn run_bench(which: Bench) -> Result<(), Error> {
    match which {
        Bench::Study { runs, jobs, out } => {
            say!("{}", crate::bench::study::bench_study(runs, jobs, &out)?);
            Ok(())
        }
        Bench::Heat { particles, repeat } => crate::bench::heat::bench_heat(&particles, repeat.max(1)),
        Bench::HeatStep { out, cells, end } => crate::bench::heat::bench_heat_step(&out, [cells[0], cells[1], cells[2]], end).map(|_| ()),
        Bench::Mechanics { particles, cholesky_max, solver: None } => {
            say!("{}", crate::bench::mechanics::bench_mechanics_with(&particles, cholesky_max)?);
            Ok(())
        }
        Bench::Mechanics { particles, solver: Some(s), .. } => {
            let solver = match s.as_str() {
                "cholesky" => crate::mechanics::LinearSolver::Cholesky,
                "cg" => crate::mechanics::LinearSolver::Pcg,
                "amg" => crate::mechanics::LinearSolver::Amg,
                "hypre" => crate::mechanics::LinearSolver::Hypre,
                o => return Err(crate::error::ConfigError::invalid(format!("bench mechanics --solver {o}: expected cholesky, cg, amg or hypre")).into()),
            };
            say!("{}", crate::bench::mechanics::bench_solver(&particles, solver)?);
            Ok(())
        }
        Bench::Coupled { case, particles, packing, steps, set } => {
            let c = (case != "none").then(|| PathBuf::from(&case));
            say!("{}", crate::bench::bench_coupled(c.as_deref(), &particles, &packing, steps, &set)?);
            Ok(())
        }
        Bench::Precision { copper, e14b, corner_edge, out } => {
            let path = |c: &str| (c != "none").then(|| PathBuf::from(c));
            let (c, e) = (path(&copper), path(&e14b));
            let report = crate::bench::precision::bench_precision(c.as_deref(), e.as_deref(), corner_edge, &out, &mut |m| eprintln!("bench precision: {m}"))?;
            say!("{report}");
            Ok(())
        }
        Bench::Generate { particles, out, periodic } => {
            crate::io::ensure_dir(&out)?;
            say!("{}", crate::bench::generate::bench_generate(&out, &particles, periodic)?);
            Ok(())
        }
        Bench::Sweep { contacts, steps, dt } => {
            say!("{}", crate::bench::diffusion7::bench_sweep(contacts, steps, dt)?);
            Ok(())
        }
        Bench::Pair { out } => {
            crate::io::ensure_dir(&out)?;
            let table = crate::bench::diffusion7::bench_pair(&out)?;
            say!("{table}");
            Ok(())
        }
    }
}

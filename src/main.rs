//! The `sinterdem` command line. Run `sinterdem --help`.

use clap::{Args, Parser, Subcommand};
use sinterdem::error::Error;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "sinterdem", version, about = "Coupled thermo-mechanical simulator of powder sintering")]
struct Cli {
    #[command(subcommand)]
    command: Command,
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
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
        /// Compact runs: write DIR/checkpoint.json every N steps (same as --set output.checkpoint_every=N).
        #[arg(long, value_name = "N")]
        checkpoint_every: Option<u64>,
    },
    /// Generate a green packing (kind = "generate"): packing.csv, packing.vtu, summary.json, laminae.
    Generate {
        #[command(flatten)]
        case: CaseArgs,
        /// Output directory (default: out/<case name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Continue an interrupted compact run from DIR/checkpoint.json.
    Resume {
        /// The run's output directory.
        dir: PathBuf,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Validate a case file only (parse, ranges, scene construction).
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
        /// Conductance law: linear (1.064 κ π a) or fe_fit.
        #[arg(long, default_value = "linear")]
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
    /// Run the 28 titanium heating schedules (cases/titanium) as pairs; writes titanium.csv.
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
    },
    /// Print every numeric case-file key with its allowed range and unit (Markdown).
    Keys,
    /// Benchmarks (print figures; not tests).
    Bench {
        #[command(subcommand)]
        which: Bench,
    },
}

#[derive(Subcommand)]
enum Bench {
    /// Assembly, factorisation and solve times of one implicit heat step on random packings.
    Heat {
        /// Particle counts (repeatable).
        #[arg(long = "particles", default_values_t = vec![1000usize, 10000, 100000])]
        particles: Vec<usize>,
        /// Repetitions per size (median reported).
        #[arg(long, default_value_t = 3)]
        repeat: usize,
    },
    /// Packing generation time for given particle counts.
    Generate {
        /// Particle counts (repeatable).
        #[arg(long = "particles", default_values_t = vec![805usize, 3619])]
        particles: Vec<usize>,
        /// Output directory.
        #[arg(long, default_value = "out/bench-generate")]
        out: PathBuf,
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
        /// Steps timed per size.
        #[arg(long, default_value_t = 3)]
        steps: u64,
    },
    /// The bonded 6-DOF solve: assembly, symbolic, factorisation, solve and PCG on bonded packings.
    Mechanics {
        /// Particle counts (repeatable).
        #[arg(long = "particles", default_values_t = vec![1000usize, 10000])]
        particles: Vec<usize>,
        /// Skip the Cholesky columns above this many particles (its factor needs ≈ 14 GB at 10⁵).
        #[arg(long = "cholesky-max", default_value_t = usize::MAX)]
        cholesky_max: usize,
    },
    /// Work-precision diagram of the 7-DOF pair integrators (copper and E14B titanium).
    Pair {
        /// Output directory for work_precision.csv and the PNG diagrams.
        #[arg(long, default_value = "out/bench-pair")]
        out: PathBuf,
    },
}

fn log_to(path: Option<&Path>) -> impl FnMut(&str) + use<> {
    let mut file = path.and_then(|p| std::fs::File::create(p).ok());
    move |msg: &str| {
        eprintln!("{msg}");
        if let Some(f) = file.as_mut() {
            use std::io::Write;
            let _ = writeln!(f, "{msg}");
        }
    }
}

fn case_kind(v: &toml::Value) -> String {
    v.get("kind").and_then(|k| k.as_str()).unwrap_or("heat").to_string()
}

fn base_dir(case: &Path) -> PathBuf {
    case.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."))
}

fn unknown_kind(kind: &str) -> Error {
    sinterdem::ConfigError::invalid(format!("kind = \"{kind}\": expected heat, compact, pair, generate or explicit_sinter")).into()
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match real_main(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn real_main(cli: Cli) -> Result<(), Error> {
    match cli.command {
        Command::Generate { case, out, quiet } => {
            let value = sinterdem::config::load_case(&case.case, &case.set)?;
            if case_kind(&value) != "generate" {
                return Err(sinterdem::ConfigError::invalid(format!("{}: kind must be \"generate\"", case.case.display())).into());
            }
            let stem = case.case.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "case".into());
            let out = out.unwrap_or_else(|| PathBuf::from("out").join(stem));
            sinterdem::io::ensure_dir(&out)?;
            let s = sinterdem::packing::generate_case(&value, &out, !quiet)?;
            eprintln!("{s:?}");
            Ok(())
        }
        Command::Run { case, out, quiet, checkpoint_every } => {
            let mut sets = case.set.clone();
            if let Some(n) = checkpoint_every {
                sets.push(format!("output.checkpoint_every={n}"));
            }
            let value = sinterdem::config::load_case(&case.case, &sets)?;
            let stem = case.case.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "case".into());
            let out = out.unwrap_or_else(|| PathBuf::from("out").join(stem));
            sinterdem::io::ensure_dir(&out)?;
            let mut log = log_to(Some(&out.join("log.txt")));
            log(&format!("sinterdem {}: {} → {}", env!("CARGO_PKG_VERSION"), case.case.display(), out.display()));
            match case_kind(&value).as_str() {
                "heat" => {
                    let prep = sinterdem::heat::run::prepare(value, &base_dir(&case.case))?;
                    sinterdem::heat::run::run(prep, &out, !quiet, &mut log)?;
                }
                "generate" => {
                    let s = sinterdem::packing::generate_case(&value, &out, !quiet)?;
                    log(&format!("done: {s:?}"));
                }
                "compact" => {
                    let sim = sinterdem::scheduler::prepare(value, &base_dir(&case.case), &mut log)?;
                    sinterdem::scheduler::run(sim, &out, !quiet, &mut log)?;
                }
                "pair" => {
                    let s = sinterdem::models::diffusion7::pair::run_pair_case(&value, &out, !quiet)?;
                    log(&format!("done: {s:?}"));
                }
                "explicit_sinter" => {
                    let s = sinterdem::explicit::protocol::run_explicit_case(&value, &out, !quiet)?;
                    log(&format!("done: {s}"));
                }
                k => return Err(unknown_kind(k)),
            }
            Ok(())
        }
        Command::Resume { dir, quiet } => {
            let mut log = log_to(None);
            let mut file_log = {
                let path = dir.join("log.txt");
                let mut f = std::fs::OpenOptions::new().append(true).create(true).open(&path).ok();
                move |msg: &str| {
                    log(msg);
                    if let Some(f) = f.as_mut() {
                        use std::io::Write;
                        let _ = writeln!(f, "{msg}");
                    }
                }
            };
            sinterdem::scheduler::resume(&dir, !quiet, &mut file_log)?;
            Ok(())
        }
        Command::Check { case } => {
            let value = sinterdem::config::load_case(&case.case, &case.set)?;
            match case_kind(&value).as_str() {
                "heat" => {
                    let prep = sinterdem::heat::run::prepare(value, &base_dir(&case.case))?;
                    println!(
                        "{}: ok (heat case, {} particles, {} contacts)",
                        case.case.display(),
                        prep.scene.particles.len(),
                        prep.pipes.pairs.len()
                    );
                }
                "compact" => {
                    let sim = sinterdem::scheduler::prepare(value, &base_dir(&case.case), &mut |_| {})?;
                    println!("{}: ok (compact case, {} particles, {} contacts)", case.case.display(), sim.prep.scene.particles.len(), sim.contacts.len());
                }
                "generate" => {
                    sinterdem::packing::check_generate_case(&value)?;
                    println!("{}: ok (packing generation case)", case.case.display());
                }
                "pair" => {
                    sinterdem::models::diffusion7::pair::check_pair_case(&value)?;
                    println!("{}: ok (pair case)", case.case.display());
                }
                "explicit_sinter" => {
                    sinterdem::explicit::protocol::check_explicit_case(&value)?;
                    println!("{}: ok (explicit_sinter case)", case.case.display());
                }
                k => return Err(unknown_kind(k)),
            }
            Ok(())
        }
        Command::Titanium { out, full, diameter } => {
            use sinterdem::models::diffusion7::titanium;
            sinterdem::io::ensure_dir(&out)?;
            let start = if full { titanium::FULL_START } else { titanium::TRUNCATED_START };
            let results = titanium::run_all_titanium(&out, start, diameter)?;
            eprintln!("{} titanium cases written to {}", results.len(), out.join("titanium.csv").display());
            Ok(())
        }
        Command::Neck { r1, r2, overlap, kappa, kappa2, conductance, factor, contact_conductance } => {
            let law = match conductance.as_str() {
                "linear" => sinterdem::heat::ConductanceLaw::Linear,
                "fe_fit" => sinterdem::heat::ConductanceLaw::FeFit,
                other => return Err(sinterdem::ConfigError::invalid(format!("--conductance {other}: expected linear or fe_fit")).into()),
            };
            let optional = [("--kappa2", kappa2), ("--contact-conductance", contact_conductance)];
            for (k, v) in [("--r1", r1), ("--r2", r2), ("--kappa", kappa), ("--factor", factor)].into_iter().chain(optional.into_iter().filter_map(|(k, v)| Some((k, v?)))) {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(sinterdem::ConfigError::OutOfRange { key: k.into(), value: v, range: "(0, inf)".into(), unit: match k { "--r1" | "--r2" => "m", "--kappa" | "--kappa2" => "W/(m K)", "--factor" => "1", _ => "W/K" }.into() }.into());
                }
            }
            let n = sinterdem::neck::solve(r1, r2, overlap)?;
            let c = sinterdem::heat::Conductance { law, factor, contact: contact_conductance };
            let p = c.pipe(kappa, kappa2.unwrap_or(kappa), r1, r2, n.a);
            let v = serde_json::json!({
                "a": n.a, "a_coble": n.a_coble, "h_ci": n.h_ci, "h_cj": n.h_cj, "h_n": n.h_n,
                "newton_iterations": n.iterations,
                "K_half_i": p.half_i, "K_half_j": p.half_j, "K_pair": p.pair,
                "conductance": conductance,
            });
            println!("{}", serde_json::to_string_pretty(&v).unwrap());
            Ok(())
        }
        Command::Conductivity { case } => {
            let value = sinterdem::config::load_case(&case.case, &case.set)?;
            let v = sinterdem::heat::conductivity::run_case(value, &base_dir(&case.case))?;
            println!("{}", serde_json::to_string_pretty(&v).unwrap());
            Ok(())
        }
        Command::Keys => {
            print!("{}", sinterdem::config::ranges::markdown());
            Ok(())
        }
        Command::Bench { which } => match which {
            Bench::Heat { particles, repeat } => sinterdem::heat::bench::bench_heat(&particles, repeat.max(1)),
            Bench::Mechanics { particles, cholesky_max } => {
                println!("{}", sinterdem::mechanics::bench::bench_mechanics_with(&particles, cholesky_max)?);
                Ok(())
            }
            Bench::Coupled { case, particles, steps } => {
                let c = (case != "none").then(|| PathBuf::from(&case));
                println!("{}", sinterdem::scheduler::bench_coupled(c.as_deref(), &particles, steps)?);
                Ok(())
            }
            Bench::Generate { particles, out } => {
                sinterdem::io::ensure_dir(&out)?;
                println!("{}", sinterdem::packing::bench_generate(&out, &particles)?);
                Ok(())
            }
            Bench::Pair { out } => {
                sinterdem::io::ensure_dir(&out)?;
                let table = sinterdem::models::diffusion7::bench::bench_pair(&out)?;
                println!("{table}");
                Ok(())
            }
        },
    }
}

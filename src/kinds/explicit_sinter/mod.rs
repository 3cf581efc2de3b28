//! Luding's sample history and compression test for the explicit sintering laws (case kind
//! `explicit_sinter`; docs/luding.md "Protocol", Luding et al. 2005 §4).
//!
//! History of one sample, in 3-D, in a box of six walls (x⁻, y⁻, z⁻ fixed through the origin;
//! x⁺, y⁺, z⁺ under stress control `m_w s̈ = p·A − F_w − γ_w ṡ`, eq. 1, A the current face area):
//! 1. **prepare** (0 ≤ t < t_prepare): a loose random packing is compressed by the isotropic wall
//!    pressure p at `temperature_cold` with frictionless particles (`prepare_friction`, paper: 0) and
//!    relaxes;
//! 2. **heat** (t_prepare ≤ t < t_prepare + t_heat): the law's friction switches on and T rises
//!    linearly to `temperature_hot`;
//! 3. **sinter** for t_s at `temperature_hot` with the shortened relaxation time `t0_sinter`
//!    (Luding: Table 1's 0.1 s against 10³ s);
//! 4. **cool** linearly over t_cool back to `temperature_cold`, then **relax** for t_relax;
//! 5. **compression test**: the top wall (z⁺) moves in at the constant strain rate ε̇
//!    (`ε_zz = 1 − z/z_0`), the side walls keep the stress p, until `max_strain`.
//!
//! Several sintering times and pressures run in one case: per pressure the sample is prepared and
//! heated once, and sintered once; at each t_s in increasing order a copy branches off to cool,
//! relax and be compressed, so that all branches share an identical preparation (as the paper).
//!
//! Temperature: `coupling.mode = "profile"` (default) puts every particle on the protocol's T(t);
//! `"network"` fixes the particles touching a wall at the start of heating to T(t) and solves the
//! heat network ([`crate::heat::network`]) for the others every `heat_every` steps with the
//! conductances of the volume-conserving neck of the current overlaps (docs/design.md, "Explicit
//! loop"), warning when Δt_heat > 0.1·min C_i/ΣK_ij. Luding's radii follow T by eq. 9 at constant
//! mass.
//!
//! Output: per branch a time series (`history_*.csv`: T, density ν = ΣV_i/V_box, coordination
//! number, wall stresses, force extremes, mean k1(T,t)/k1 or δ_p), the compression series
//! (`compression_*.csv`), the normal forces of all contacts after sintering and after
//! cool-down/relax (`forces_*.csv`), PNG plots of all of them, and `summary.json`.

mod case;
mod checkpoint;
pub mod laws;
mod machine;
mod output;
mod sample;
mod stepping;

pub use crate::explicit::sinter::SinterLaw;
pub use case::{
    CompressionSpec, CouplingMode, CouplingSpec, ExplicitSinterCase, OutputSpec, ProtocolSpec, SampleSpec, SteppingSpec, WallSpec, parse_explicit_case,
};
pub use checkpoint::CheckpointSink;
pub use machine::{Stage, StepClock};
pub use output::{Branch, ExplicitSinterRun, Row, Stopped, columns, summary_json, write_outputs};
pub use sample::Sample;
pub use stepping::ExplicitRun;

use crate::config::ranges::{Range, c, p};
use crate::error::{ConfigError, Error, IoError};
use serde::Deserialize;
use std::path::Path;

/// Checks a key of this kind (its own [`RANGES`], the laws' tables, then the shared keys).
fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    let tables: Vec<&'static [Range]> = std::iter::once(RANGES).chain(laws::LAWS.iter().map(|l| l.ranges)).collect();
    let own = crate::config::ranges::lookup_in(&tables, key);
    match own {
        Some(r) => r.check(key, v),
        None => crate::config::check(key, v),
    }
}

/// Range table of the `explicit_sinter` case keys (listed in `crate::kinds::keys::tables`).
pub static RANGES: &[Range] = &[
    c("sample.particles", 2.0, 1e6, "1", "number of spheres N"),
    p("sample.mean_radius", 0.0, 1.0, "m", "mean radius r_0"),
    c("sample.radius_spread", 0.0, 0.9, "1", "relative half-width w of the uniform radii r_0(1 +- w)"),
    p("sample.density", 0.0, 1e5, "kg/m^3", "particle material density rho"),
    c("sample.seed", 0.0, 1e15, "1", "seed of the random loose start"),
    c("sample.initial_fraction", 0.01, 0.4, "1", "solid fraction of the loose random start"),
    c("sample.initial_speed", 0.0, 1e3, "m/s", "rms speed of the random initial velocities"),
    p("walls.pressures", 0.0, 1e12, "Pa", "isotropic confining pressure p_3D (one run per value)"),
    p("walls.mass", 0.0, 1e6, "kg", "mass m_w of a stress-controlled wall (eq. 1)"),
    c("walls.damping", 0.0, 1e9, "kg/s", "viscous damping gamma_w of a stress-controlled wall (eq. 1)"),
    c("walls.friction", 0.0, 10.0, "1", "particle-wall friction mu_w"),
    p("protocol.t_prepare", 0.0, 1e9, "s", "compression and relaxation at temperature_cold (t_heat)"),
    p("protocol.t_heat", 0.0, 1e9, "s", "heating ramp duration (t_sinter - t_heat)"),
    c("protocol.t_sinter", 0.0, 1e9, "s", "sintering times t_s (one branch per value)"),
    p("protocol.t_cool", 0.0, 1e9, "s", "cooling ramp duration (t_relax - t_cool)"),
    c("protocol.t_relax", 0.0, 1e9, "s", "relaxation at temperature_cold after cooling (t_f - t_relax)"),
    p("protocol.t0_sinter", 0.0, 1e15, "s", "Luding's relaxation time t_0 while sintering"),
    p("protocol.temperature_cold", 1.0, 1e4, "K", "preparation and final temperature"),
    p("protocol.temperature_hot", 1.0, 1e4, "K", "sintering temperature"),
    c("protocol.prepare_friction", 0.0, 10.0, "1", "particle friction during preparation"),
    p("protocol.output_interval", 0.0, 1e9, "s", "interval of the history rows (averaged wall stress)"),
    p("compression.strain_rate", 0.0, 1e6, "1/s", "constant vertical strain rate of the top wall"),
    p("compression.max_strain", 0.0, 0.9, "1", "vertical strain at which the test stops"),
    p("compression.output_strain", 0.0, 0.5, "1", "strain interval of the compression rows"),
    c("coupling.heat_every", 1.0, 1e9, "1", "explicit steps per heat-network solve"),
    p("coupling.conductivity", 0.0, 1e4, "W/(m K)", "particle thermal conductivity (network mode)"),
    p("coupling.specific_heat", 0.0, 1e6, "J/(kg K)", "particle specific heat (network mode)"),
    p("stepping.dt_fraction", 0.0, 1.0, "1", "time step as a fraction of the shortest contact half-period t_c (eq. 6)"),
    p("stepping.skin", 0.0, 10.0, "1", "Verlet skin relative to r_0"),
    c("stepping.parallel_threshold", 0.0, 1e12, "1", "contact count above which the force sweep runs in parallel"),
];

/// `sinterdem check` for `kind = "explicit_sinter"`.
pub fn check_explicit_case(case: &toml::Value) -> Result<(), Error> {
    let c = parse_explicit_case(case)?;
    case::check_plan(&c)
}

/// Format tag of `explicit_sinter` checkpoints.
pub const EXPLICIT_CHECKPOINT_FORMAT: &str = "sinterdem-explicit-checkpoint-1";

/// Runs a parsed case (no files written); with `progress` the stage lines go to stderr. The loop
/// of [`ExplicitRun`].
pub fn run_explicit(case: &ExplicitSinterCase, progress: bool) -> Result<ExplicitSinterRun, Error> {
    let mut log = |m: &str| {
        if progress {
            tracing::info!("{m}");
        }
    };
    let mut r = ExplicitRun::new(case.clone(), None, None, None, &mut log)?;
    while r.step(&mut log)? {}
    let (run, _, _) = r.into_run(&mut log)?.expect("no stop without a checkpoint sink");
    Ok(run)
}

/// Runs an `explicit_sinter` case and writes its outputs into `out_dir` (module docs); returns the
/// summary (also `summary.json`). With `progress` the stage lines are logged (`tracing`).
pub fn run_explicit_case(case: &toml::Value, out_dir: &Path, progress: bool) -> Result<serde_json::Value, Error> {
    let mut log = |m: &str| {
        if progress {
            tracing::info!("{m}");
        }
    };
    run_explicit_from(case, out_dir, &mut log, None)
}

/// Runs `case` into `out_dir` (the loop of [`ExplicitRun`]), writing `out_dir/checkpoint.json`
/// every `output.checkpoint_every` steps; `stop_after` ends the run right after the checkpoint at
/// or after that step (as if killed there; for tests) with `Ok(Value::Null)`.
pub fn run_explicit_from(case: &toml::Value, out_dir: &Path, log: &mut dyn FnMut(&str), stop_after: Option<u64>) -> Result<serde_json::Value, Error> {
    let mut r = ExplicitRun::start_stopping(case, out_dir, stop_after, log)?;
    while r.step(log)? {}
    r.finish(log)
}

/// `sinterdem resume DIR` for an `explicit_sinter` run: rebuilds the case from the checkpoint's
/// text, restores the protocol's stage, samples and finished branches after checking them against
/// the case, and continues bit for bit.
pub fn resume(dir: &Path, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    #[derive(Deserialize)]
    struct Head {
        format: String,
        case_toml: String,
        model: String,
    }
    let path = dir.join("checkpoint.json");
    let text = crate::io::read_checkpoint_json(&path)?;
    let head: Head = serde_json::from_str(&text).map_err(|e| IoError::new(&path, e))?;
    if head.format != EXPLICIT_CHECKPOINT_FORMAT {
        return Err(ConfigError::invalid(format!("{}: format \"{}\" is not {EXPLICIT_CHECKPOINT_FORMAT}", path.display(), head.format)).into());
    }
    let value =
        toml::Value::Table(head.case_toml.parse::<toml::Table>().map_err(|e| ConfigError::invalid(format!("{}: case: {}", path.display(), e.message())))?);
    let c = parse_explicit_case(&value).map_err(|e| ConfigError::invalid(format!("{}: case: {e}", path.display())))?;
    if head.model != c.law.name() {
        return Err(ConfigError::invalid(format!("{}: model \"{}\" does not match the case's model \"{}\"", path.display(), head.model, c.law.name())).into());
    }
    let sink = (c.output.checkpoint_every > 0.0).then(|| CheckpointSink { dir: dir.to_path_buf(), case_toml: head.case_toml, stop_after: None });
    let mut r = ExplicitRun::new(c, sink, Some((&text, &path)), Some(dir.to_path_buf()), log)?;
    while r.step(log)? {}
    r.finish(log)
}

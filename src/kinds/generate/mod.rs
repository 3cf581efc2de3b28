//! The generate run (`kind = "generate"`): seeded generation of green bodies (random sphere
//! packings). Follows Ivannikov et al. 2022 §3.2 (after Nosewicz et al.): a loose cloud in a box,
//! settled under gravity, then compressed triaxially by the walls to a target solid fraction;
//! then the load is removed and the packing relaxed to a stress-free state. See `docs/packing.md`.
//!
//! **Scaled units.** Only the final geometry matters, so the generator runs the explicit driver in
//! units where the mean radius r̄, the normal stiffness k_n and the mass of a sphere of radius r̄ are 1
//! (density 3/(4π)). The physics that sets the geometry is dimensionless: overlaps relative to r̄
//! (compaction pressure `p (2r̄)²/k_n`), friction, restitution, and the wall speed relative to the
//! elastic time `√(m/k_n)`. Positions are multiplied by r̄ [m] on output.
//!
//! Protocol (`generate`):
//! 1. **Cloud**: radii drawn from the size distribution; particles on a jittered cubic lattice
//!    (spacing > the largest diameter, so no overlap) in random order, in a box whose footprint is
//!    the target footprint and whose height gives `cloud_solid_fraction`. In memory the particles
//!    are ordered along a Morton curve of their lattice cells (neighbours near in memory); the
//!    outputs list them in the order their diameters were drawn.
//! 2. **Settle** under gravity (−z) until the kinetic energy falls below 1 % of `m̄ g r̄` per
//!    particle; gravity is chosen so that the impact speed is ≈ 0.2 √(k_n/m̄) r̄.
//! 3. **Triaxial compaction**: gravity off, top wall lowered onto the highest particle; the three
//!    upper walls move so that the box approaches the target box (the requested shape scaled to the
//!    volume `Σ V_i / φ_target`) along a straight path in (L_x, L_y, L_z). A servo slows the walls
//!    as the mean wall pressure approaches `p_c = compaction_overlap·k_n/(4r̄)`; while it stays
//!    above p_c the friction coefficient is lowered step by step (Yade's "decrease friction until the
//!    target porosity" recipe), so the packing rearranges instead of building up stress.
//! 4. **Unload and relax**: walls held at the target box; if the largest overlap stays above
//!    `max_overlap_rel·r̄`, the walls back off slowly (a fixed strain rate) until the pressure is ≈ 0;
//!    then relax until the kinetic energy per particle falls below `kinetic_energy_rel·k_n r̄²` and
//!    the largest overlap below `max_overlap_rel·r̄`. Once the walls are final and the overlaps
//!    below the threshold, a background viscous damping drains the kinetic energy.

mod case;
mod output;
mod periodic;
mod protocol;

pub use case::{Compaction, GenerateCase, Protocol, parse_generate_case, requested_mean_diameter};
pub use output::{contact_pairs, coordination, coordination_in, write_outputs};
pub use protocol::generate;

use crate::config::ranges::Range;
use crate::error::{Error, SolveError};
use nalgebra::Vector3;
use output::summarise;
use std::path::Path;

type V3 = Vector3<f64>;

const fn rg(key: &'static str, lo: f64, hi: f64, lo_open: bool, unit: &'static str, meaning: &'static str) -> Range {
    Range { key, lo, hi, lo_open, hi_open: false, unit, meaning }
}

/// Range table of the `kind = "generate"` case keys (listed in `crate::kinds::keys::tables`).
pub static RANGES: &[Range] = &[
    rg("packing.particles", 2.0, 1e8, false, "1", "number of particles"),
    rg("packing.seed", 0.0, 9.223_372_036_854_776e18, false, "1", "random seed (a TOML integer: 0 to 2^63 - 1)"),
    rg(
        "packing.target_solid_fraction",
        0.05,
        0.72,
        false,
        "1",
        "solid fraction the walls compress to (eq. 49 with the wall box); periodic: exactly sum(V_i)/(Lx Ly Lz) (docs/packing.md (G6))",
    ),
    rg("packing.box.*", 0.0, 10.0, true, "m", "box edge; only the shape is kept, scaled to the volume of the target"),
    rg(
        "packing.lamina_width",
        1e-9,
        1.0,
        false,
        "m",
        "lamina width q_s of the density report (eq. 48); default the mean radius; at least 1/100 of the mean radius",
    ),
    rg("packing.size.mean_diameter", 2e-9, 1.0, false, "m", "mean particle diameter"),
    rg("packing.size.spread", 0.0, 0.9, false, "1", "uniform: relative half-width, d = mean (1 ± spread)"),
    rg("packing.size.std_diameter", 0.0, 1.0, false, "m", "normal: standard deviation of the diameter"),
    rg("packing.size.truncate", 0.1, 10.0, false, "1", "normal: truncation at mean ± truncate·std"),
    rg("packing.size.diameters.*", 2e-9, 1.0, false, "m", "tabulated: diameters, increasing"),
    rg("packing.size.cumulative.*", 0.0, 1.0, false, "1", "tabulated: cumulative number fraction at each diameter"),
    rg("packing.protocol.friction", 0.0, 2.0, false, "1", "particle friction coefficient during settling and compaction (lowered if the packing jams)"),
    rg("packing.protocol.wall_friction", 0.0, 2.0, false, "1", "particle-wall friction coefficient"),
    rg("packing.protocol.restitution", 0.01, 1.0, false, "1", "normal restitution coefficient of the generator's contacts"),
    rg("packing.protocol.local_damping", 0.0, 0.9, false, "1", "Cundall local damping of the generator"),
    rg("packing.protocol.cloud_solid_fraction", 0.01, 0.45, false, "1", "solid fraction of the initial cloud"),
    rg("packing.protocol.compaction_overlap", 1e-6, 0.05, false, "1", "compaction pressure as a relative overlap, p (2r)^2/k_n"),
    rg("packing.protocol.max_overlap_rel", 1e-7, 0.5, false, "1", "final largest overlap / mean radius"),
    rg("packing.protocol.kinetic_energy_rel", 1e-16, 1e-2, false, "1", "final kinetic energy per particle / (k_n r^2)"),
    rg("packing.protocol.contact_gap_rel", 0.0, 0.5, false, "1", "gap / mean radius below which a pair counts as a contact in the report"),
    rg("packing.protocol.dt_fraction", 1e-3, 0.2, false, "1", "time step / collision time"),
    rg("packing.protocol.max_steps", 100.0, 1e9, false, "1", "step budget of the whole protocol"),
    rg(
        "packing.protocol.strain_rate",
        1e-7,
        1e-2,
        false,
        "1",
        "boundary = \"periodic\": box compaction strain rate -dL/(L dt) per scaled time unit sqrt(m/k_n) (docs/packing.md (G5))",
    ),
];

/// `sinterdem check` for a generate case: parse and validate only.
/// Besides the keys, it draws the sizes (seeded, as the run does) and checks the target box they
/// give ([`protocol::target_box`]): the refusals that `generate` makes before it starts are made
/// here, by the same code (issue 26, class 8).
pub fn check_generate_case(case: &toml::Value) -> Result<(), Error> {
    let c = parse_generate_case(case)?;
    let (_, _, r_max, vp) = protocol::draw_radii(&c, &mut crate::packing::Rng::new(c.seed));
    protocol::target_box(&c, vp, r_max)?;
    Ok(())
}

/// What `generate` reports (also written as `summary.json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GenerateSummary {
    pub particles: usize,
    pub seed: u64,
    /// Σ V_i / V_box with the final wall box (eq. 49).
    pub solid_fraction: f64,
    pub target_solid_fraction: f64,
    /// Mean number of contacts per particle (pairs with gap < contact_gap_rel·r̄).
    pub coordination_mean: f64,
    /// Mean number of strictly overlapping neighbours per particle.
    pub coordination_overlapping: f64,
    /// Particles with no contact.
    pub rattlers: usize,
    /// Largest overlap / mean radius (particle pairs and walls).
    pub max_overlap_rel: f64,
    /// Final kinetic energy per particle / (k_n r̄²) (scaled units).
    pub kinetic_energy_rel: f64,
    /// Final box edges [m] (origin at 0).
    pub box_size: [f64; 3],
    /// Mean radius [m] achieved and requested.
    pub mean_radius: f64,
    pub mean_radius_requested: f64,
    /// Kolmogorov–Smirnov distance between achieved and requested diameter distributions.
    pub size_ks_distance: f64,
    /// Lamina width used [m].
    pub lamina_width: f64,
    /// Per axis x, y, z: largest |ρ_s − mean| over interior laminae (≥ one mean diameter from the walls).
    pub laminae_max_deviation: [f64; 3],
    /// Per axis: mean of the interior laminae densities.
    pub laminae_mean: [f64; 3],
    /// Friction coefficient at the end of compaction.
    pub final_friction: f64,
    pub steps: u64,
    /// Steps per stage: settle, compaction, unload + relax.
    pub stage_steps: [u64; 3],
    /// Time step / collision time and wall-clock time [s].
    pub dt_fraction: f64,
    pub wall_time: f64,
    pub thresholds_met: bool,
    /// `"periodic"` for a periodic packing; absent for the walled box (whose summary is unchanged).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub boundary: Option<String>,
    /// Periodic packings: the box [L_x, L_y, L_z] [m] from the origin, the `particles.periodic_box`
    /// of a case reading `packing.csv` (equal to `box_size`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub box_size_m: Option<[f64; 3]>,
    /// Periodic packings: homogeneity and compaction figures (docs/packing.md (G5)–(G8)).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub periodic: Option<PeriodicReport>,
    /// false when a stop request ([`crate::interrupt`]) ended the protocol early: the packing is
    /// written as it was (absent: the protocol ran to its end).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub completed: Option<bool>,
    /// Why it stopped early ("interrupted").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
}

/// `summary` marked as stopped early when a stop request ended the protocol.
fn interrupted(mut summary: GenerateSummary) -> GenerateSummary {
    if crate::interrupt::requested() {
        summary.completed = Some(false);
        summary.stop_reason = Some("interrupted".into());
    }
    summary
}

/// What a periodic packing reports beside the walled summary (docs/packing.md, "Periodic packings").
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct PeriodicReport {
    /// Solid fractions of the eight octants (x fastest), grid estimate (G8).
    pub octant_solid_fraction: [f64; 8],
    /// Contacts (gap < contact_gap_rel·r̄) across the faces normal to x, y, z.
    pub contacts_across_faces: [usize; 3],
    /// Per axis: mean density of the laminae within one mean diameter of a face, and of the others (G7).
    pub face_laminae_mean: [f64; 3],
    pub interior_laminae_mean: [f64; 3],
    /// Largest kinetic energy per particle during the box compaction / (k_n r̄²) (scaled units).
    pub compaction_kinetic_energy_max_rel: f64,
    /// Virial pressure (G4) at the end of the compaction as an overlap, p (2r̄)²/k_n (the servo holds
    /// it below `compaction_overlap`).
    pub compaction_pressure_end_rel: f64,
    /// Solid fraction at which the compaction first stalled at the compaction pressure (jammed),
    /// or the target if it never did.
    pub first_jam_solid_fraction: f64,
    /// Final mean unbalanced force ratio (Yade's `unbalancedForce`): mean |F_i| over the particles /
    /// mean normal force over the contacts (0 without contacts).
    pub unbalanced_force_ratio: f64,
    /// `compaction = "die"` (G9): the taps the compaction gave (absent for the isotropic path).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub taps: Option<u32>,
}

/// The packing itself: positions [m], radii [m], and the box [m].
#[derive(Debug, Clone)]
pub struct Packing {
    pub positions: Vec<V3>,
    pub radii: Vec<f64>,
    pub box_size: [f64; 3],
}

/// Library entry point of `sinterdem generate CASE.toml --out DIR`: validates the case (overrides
/// already applied), generates, writes the outputs, and returns the summary. If the relaxation did
/// not meet its thresholds within `max_steps`, the outputs are still written and a SolveError says so.
pub fn generate_case(case: &toml::Value, out_dir: &Path, progress: bool) -> Result<GenerateSummary, Error> {
    let c = parse_generate_case(case)?;
    let (packing, summary) = if c.periodic { periodic::generate_periodic(&c, progress)? } else { generate(&c, progress)? };
    // a non-finite figure is a model error, not a summary with null in it
    let s = &summary;
    let figures = [
        ("solid_fraction", s.solid_fraction),
        ("coordination_mean", s.coordination_mean),
        ("max_overlap_rel", s.max_overlap_rel),
        ("kinetic_energy_rel", s.kinetic_energy_rel),
        ("mean_radius", s.mean_radius),
        ("size_ks_distance", s.size_ks_distance),
    ];
    let more = s.box_size.iter().chain(&s.laminae_max_deviation).chain(&s.laminae_mean).map(|&v| ("box_size/laminae", v));
    if let Some((k, v)) = figures.into_iter().chain(more).find(|(_, v)| !v.is_finite()) {
        return Err(crate::error::ModelError::new(format!("packing generation produced a non-finite {k} ({v})"))
            .with_context(format!("{} particles, {} steps", s.particles, s.steps))
            .into());
    }
    crate::finite::ensure_finite_groups("packing generation", summary.steps, 0.0, "particle", "position", packing.positions.iter().map(|x| x.as_ref()))?;
    write_outputs(&c, &packing, &summary, out_dir)?;
    if !summary.thresholds_met && summary.completed.is_none() {
        return Err(SolveError::new(
            "packing relaxation",
            format!(
                "thresholds not met within packing.protocol.max_steps = {}: largest overlap {:.3e} r (limit {:.1e}), kinetic energy {:.3e} (limit {:.1e}); outputs written to {}",
                c.protocol.max_steps,
                summary.max_overlap_rel,
                c.protocol.max_overlap_rel,
                summary.kinetic_energy_rel,
                c.protocol.kinetic_energy_rel,
                out_dir.display()
            ),
        )
        .into());
    }
    Ok(summary)
}

/// Largest shortfall of a walled packing's solid fraction below `packing.target_solid_fraction`
/// that counts as reaching it: the wall layers of a small box cost about 0.01 (docs/packing.md,
/// "Why the copper box lands at ≈ 0.59").
pub const TARGET_TOLERANCE: f64 = 0.01;

/// The warning of a packing whose solid fraction `got` stays more than [`TARGET_TOLERANCE`] below
/// its `target` (None: reached). Periodic packings are built to their target exactly (G6) and
/// refuse one they cannot reach.
pub fn target_shortfall(got: f64, target: f64, periodic: bool) -> Option<String> {
    (!periodic && got < target - TARGET_TOLERANCE).then(|| {
        format!(
            "solid fraction {got:.4} is short of packing.target_solid_fraction = {target:.4} (by more than {TARGET_TOLERANCE}): the packing jammed there (random close packing and the wall layers of the box, docs/packing.md); the packing is written as it is (summary.json: target_reached = false); lower the target or use a larger box"
        )
    })
}

#[cfg(test)]
mod target_tests {
    use super::*;

    #[test]
    fn a_packing_short_of_its_target_warns_within_the_wall_tolerance_it_does_not() {
        // the case: 0.62 asked, 0.5908 reached
        let w = target_shortfall(0.5908, 0.62, false).unwrap();
        assert!(w.contains("0.5908") && w.contains("0.6200"), "{w}");
        // the bundled copper box: 0.593 for 0.60, within the wall layers' 0.01
        assert!(target_shortfall(0.5926, 0.60, false).is_none());
        assert!(target_shortfall(0.58, 0.62, true).is_none());
    }
}

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

use crate::config::ranges::Range;
use crate::error::{ConfigError, Error, IoError, SolveError};
use crate::explicit::law::{Damping, LinearSpringDashpot};
use crate::explicit::{Explicit, Settings, Wall, WallControl, time_step};
use crate::packing::{Rng, SizeDistribution, report};
use crate::particles::Particles;
use nalgebra::Vector3;
use serde::Deserialize;
use std::path::Path;
use std::time::Instant;

type V3 = Vector3<f64>;

const fn rg(key: &'static str, lo: f64, hi: f64, lo_open: bool, unit: &'static str, meaning: &'static str) -> Range {
    Range { key, lo, hi, lo_open, hi_open: false, unit, meaning }
}

/// Range table of the `kind = "generate"` case keys (registered in `config::ranges::TABLES`).
pub static RANGES: &[Range] = &[
    rg("packing.particles", 2.0, 1e8, false, "1", "number of particles"),
    rg("packing.seed", 0.0, 1.8e19, false, "1", "random seed (integer)"),
    rg("packing.target_solid_fraction", 0.05, 0.72, false, "1", "solid fraction the walls compress to (eq. 49 with the wall box)"),
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
];

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseFile {
    kind: String,
    #[serde(default)]
    #[allow(dead_code)]
    title: Option<String>,
    packing: toml::Value,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct PackingFile {
    particles: i64,
    #[serde(default = "one")]
    seed: i64,
    #[serde(default = "sixty")]
    target_solid_fraction: f64,
    #[serde(rename = "box")]
    box_: Vec<f64>,
    lamina_width: Option<f64>,
    size: SizeFile,
    #[serde(default)]
    protocol: ProtocolFile,
}
fn one() -> i64 {
    1
}
fn sixty() -> f64 {
    0.60
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SizeFile {
    distribution: String,
    mean_diameter: Option<f64>,
    spread: Option<f64>,
    std_diameter: Option<f64>,
    truncate: Option<f64>,
    diameters: Option<Vec<f64>>,
    cumulative: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ProtocolFile {
    friction: Option<f64>,
    wall_friction: Option<f64>,
    restitution: Option<f64>,
    local_damping: Option<f64>,
    cloud_solid_fraction: Option<f64>,
    compaction_overlap: Option<f64>,
    max_overlap_rel: Option<f64>,
    kinetic_energy_rel: Option<f64>,
    contact_gap_rel: Option<f64>,
    dt_fraction: Option<f64>,
    max_steps: Option<f64>,
}

/// Protocol parameters (dimensionless; see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Protocol {
    pub friction: f64,
    pub wall_friction: f64,
    pub restitution: f64,
    pub local_damping: f64,
    pub cloud_solid_fraction: f64,
    pub compaction_overlap: f64,
    pub max_overlap_rel: f64,
    pub kinetic_energy_rel: f64,
    pub contact_gap_rel: f64,
    pub dt_fraction: f64,
    pub max_steps: u64,
}

impl Default for Protocol {
    fn default() -> Self {
        Protocol {
            friction: 0.1,
            wall_friction: 0.0,
            restitution: 0.3,
            local_damping: 0.3,
            cloud_solid_fraction: 0.3,
            compaction_overlap: 5e-3,
            max_overlap_rel: 1e-3,
            kinetic_energy_rel: 1e-10,
            contact_gap_rel: 1e-3,
            dt_fraction: 0.08,
            max_steps: 5_000_000,
        }
    }
}

/// A validated `kind = "generate"` case.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateCase {
    pub particles: usize,
    pub seed: u64,
    pub target_solid_fraction: f64,
    /// Requested box [m]; its shape is kept, its size scaled to the target volume.
    pub box_size: [f64; 3],
    /// Lamina width q_s [m] (eq. 48); None: the mean radius.
    pub lamina_width: Option<f64>,
    pub size: SizeDistribution,
    pub protocol: Protocol,
}

fn chk(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(RANGES, key, v)
}

/// Parses and validates a `kind = "generate"` case (for `sinterdem check`).
pub fn parse_generate_case(case: &toml::Value) -> Result<GenerateCase, Error> {
    let cf: CaseFile = crate::config::from_value(case.clone(), "")?;
    if cf.kind != "generate" {
        return Err(ConfigError::inconsistent("kind", format!("\"{}\": a packing case needs kind = \"generate\"", cf.kind)).into());
    }
    let pf: PackingFile = crate::config::from_value(cf.packing, "packing")?;
    let particles = chk("packing.particles", pf.particles as f64)? as usize;
    let seed = chk("packing.seed", pf.seed as f64).map(|_| pf.seed as u64)?;
    let target = chk("packing.target_solid_fraction", pf.target_solid_fraction)?;
    if pf.box_.len() != 3 {
        return Err(ConfigError::inconsistent("packing.box", format!("needs 3 edges [x, y, z] (m), got {}", pf.box_.len())).into());
    }
    for (a, &l) in pf.box_.iter().enumerate() {
        chk(&format!("packing.box.{a}"), l)?;
    }
    let lamina_width = pf.lamina_width.map(|w| chk("packing.lamina_width", w)).transpose()?;
    let s = pf.size;
    let need = |v: Option<f64>, k: &str| -> Result<f64, ConfigError> {
        let v = v.ok_or_else(|| ConfigError::inconsistent(format!("packing.size.{k}"), format!("required by distribution = \"{}\"", s.distribution)))?;
        chk(&format!("packing.size.{k}"), v)
    };
    let unused = |names: &[(&str, bool)]| -> Result<(), ConfigError> {
        for (k, present) in names {
            if *present {
                return Err(ConfigError::inconsistent(format!("packing.size.{k}"), format!("not used by distribution = \"{}\"", s.distribution)));
            }
        }
        Ok(())
    };
    let size = match s.distribution.as_str() {
        "uniform" => {
            unused(&[
                ("std_diameter", s.std_diameter.is_some()),
                ("truncate", s.truncate.is_some()),
                ("diameters", s.diameters.is_some()),
                ("cumulative", s.cumulative.is_some()),
            ])?;
            SizeDistribution::Uniform { mean: need(s.mean_diameter, "mean_diameter")?, spread: need(s.spread.or(Some(0.0)), "spread")? }
        }
        "normal" => {
            unused(&[("spread", s.spread.is_some()), ("diameters", s.diameters.is_some()), ("cumulative", s.cumulative.is_some())])?;
            SizeDistribution::Normal {
                mean: need(s.mean_diameter, "mean_diameter")?,
                std: need(s.std_diameter, "std_diameter")?,
                truncate: need(s.truncate.or(Some(3.0)), "truncate")?,
            }
        }
        "tabulated" => {
            unused(&[
                ("mean_diameter", s.mean_diameter.is_some()),
                ("spread", s.spread.is_some()),
                ("std_diameter", s.std_diameter.is_some()),
                ("truncate", s.truncate.is_some()),
            ])?;
            let d = s.diameters.clone().ok_or_else(|| ConfigError::inconsistent("packing.size.diameters", "required by distribution = \"tabulated\""))?;
            let c = s.cumulative.clone().ok_or_else(|| ConfigError::inconsistent("packing.size.cumulative", "required by distribution = \"tabulated\""))?;
            for (k, v) in d.iter().enumerate() {
                chk(&format!("packing.size.diameters.{k}"), *v)?;
            }
            for (k, v) in c.iter().enumerate() {
                chk(&format!("packing.size.cumulative.{k}"), *v)?;
            }
            SizeDistribution::Tabulated { diameters: d, cumulative: c }
        }
        other => {
            return Err(ConfigError::inconsistent("packing.size.distribution", format!("\"{other}\": expected uniform, normal or tabulated")).into());
        }
    };
    size.validate()?;
    if let Some(w) = lamina_width {
        // eq. 48's laminae are cut at width w along each edge: a width far below a radius asks
        // for an absurd number of laminae (1e-12 m: 1e8 per axis) and says nothing more
        let r = 0.5 * requested_mean_diameter(&size);
        if w < 0.01 * r {
            return Err(ConfigError::inconsistent(
                "packing.lamina_width",
                format!("{} m is below 1/100 of the mean radius ({} m)", crate::error::fmt_value(w), crate::error::fmt_value(r)),
            )
            .into());
        }
    }
    crate::config::plausible::check_memory("packing.particles", particles as f64, crate::config::plausible::BYTES_PER_PARTICLE_GENERATE)?;
    let d = Protocol::default();
    let pr = pf.protocol;
    let get = |v: Option<f64>, k: &str, def: f64| -> Result<f64, ConfigError> { chk(&format!("packing.protocol.{k}"), v.unwrap_or(def)) };
    let protocol = Protocol {
        friction: get(pr.friction, "friction", d.friction)?,
        wall_friction: get(pr.wall_friction, "wall_friction", d.wall_friction)?,
        restitution: get(pr.restitution, "restitution", d.restitution)?,
        local_damping: get(pr.local_damping, "local_damping", d.local_damping)?,
        cloud_solid_fraction: get(pr.cloud_solid_fraction, "cloud_solid_fraction", d.cloud_solid_fraction)?,
        compaction_overlap: get(pr.compaction_overlap, "compaction_overlap", d.compaction_overlap)?,
        max_overlap_rel: get(pr.max_overlap_rel, "max_overlap_rel", d.max_overlap_rel)?,
        kinetic_energy_rel: get(pr.kinetic_energy_rel, "kinetic_energy_rel", d.kinetic_energy_rel)?,
        contact_gap_rel: get(pr.contact_gap_rel, "contact_gap_rel", d.contact_gap_rel)?,
        dt_fraction: get(pr.dt_fraction, "dt_fraction", d.dt_fraction)?,
        max_steps: get(pr.max_steps, "max_steps", d.max_steps as f64)? as u64,
    };
    if target >= 0.66 {
        // frictionless random close packing is ≈ 0.64; a few % above is reachable only with overlap
        return Err(ConfigError::inconsistent(
            "packing.target_solid_fraction",
            format!("{target} is above random close packing (≈ 0.64) and cannot be reached stress-free"),
        )
        .into());
    }
    Ok(GenerateCase { particles, seed, target_solid_fraction: target, box_size: [pf.box_[0], pf.box_[1], pf.box_[2]], lamina_width, size, protocol })
}

/// `sinterdem check` for a generate case: parse and validate only.
pub fn check_generate_case(case: &toml::Value) -> Result<(), Error> {
    parse_generate_case(case).map(|_| ())
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
}

/// The packing itself: positions [m], radii [m], and the box [m].
#[derive(Debug, Clone)]
pub struct Packing {
    pub positions: Vec<V3>,
    pub radii: Vec<f64>,
    pub box_size: [f64; 3],
}

struct Progress {
    on: bool,
    t0: Instant,
}
impl Progress {
    fn say(&self, msg: impl AsRef<str>) {
        if self.on {
            tracing::info!("[generate {:7.2} s] {}", self.t0.elapsed().as_secs_f64(), msg.as_ref());
        }
    }
}

fn box_walls(l: [f64; 3]) -> Vec<Wall> {
    let mut w = Vec::new();
    for a in 0..3 {
        let mut e = V3::zeros();
        e[a] = 1.0;
        w.push(Wall::new(e, V3::zeros()));
        let mut p = V3::zeros();
        p[a] = l[a];
        w.push(Wall::new(-e, p));
    }
    w
}

/// Box edges from the walls (lower walls 2a, upper 2a+1).
fn box_of(walls: &[Wall]) -> [f64; 3] {
    [0, 1, 2].map(|a| -walls[2 * a + 1].offset - walls[2 * a].offset)
}

fn set_areas(walls: &mut [Wall]) {
    let l = box_of(walls);
    for a in 0..3 {
        let area = l[(a + 1) % 3] * l[(a + 2) % 3];
        walls[2 * a].area = area;
        walls[2 * a + 1].area = area;
    }
}

fn max_overlap(p: &Particles, walls: &[Wall], pairs: &[(u32, u32)]) -> f64 {
    let mut m: f64 = 0.0;
    for &(i, j) in pairs {
        let (i, j) = (i as usize, j as usize);
        m = m.max(p.radius[i] + p.radius[j] - (p.position[i] - p.position[j]).norm());
    }
    for w in walls {
        for a in 0..p.len() {
            m = m.max(-(w.normal.dot(&p.position[a]) - w.offset - p.radius[a]));
        }
    }
    m
}

/// Strain rate [1 per scaled time unit] at which the walls back off to unload the packing
/// (the copper box, 15 r̄ high, backs off at 2·10⁻⁴ r̄ per time unit).
const BACKOFF_STRAIN_RATE: f64 = 1.3e-5;
/// Background viscous damping rate [1 per scaled time unit] of the final relaxation: the kinetic
/// energy falls by e^{-0.1} per time unit (≈ 6 steps), a damping ratio of ≈ 0.01 of the contacts.
const DRAIN_DAMPING: f64 = 0.05;

/// Morton (Z-order) key of a lattice cell: the bits of the three indices interleaved.
fn morton(ix: usize, iy: usize, iz: usize) -> u64 {
    fn spread(v: usize) -> u64 {
        let mut x = (v as u64) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f00000000ffff;
        x = (x | x << 16) & 0x1f0000ff0000ff;
        x = (x | x << 8) & 0x100f00f00f00f00f;
        x = (x | x << 4) & 0x10c30c30c30c30c3;
        (x | x << 2) & 0x1249249249249249
    }
    spread(ix) | spread(iy) << 1 | spread(iz) << 2
}

/// Generates the packing of a validated case in scaled units (module docs) and returns it in SI.
pub fn generate(case: &GenerateCase, progress: bool) -> Result<(Packing, GenerateSummary), Error> {
    let pr = Progress { on: progress, t0: Instant::now() };
    let t0 = Instant::now();
    let n = case.particles;
    let proto = &case.protocol;
    let mut rng = Rng::new(case.seed);
    let diam: Vec<f64> = (0..n).map(|_| case.size.sample(&mut rng)).collect();
    let r_unit = diam.iter().sum::<f64>() / (2.0 * n as f64); // length unit: mean radius [m]
    let radii: Vec<f64> = diam.iter().map(|d| 0.5 * d / r_unit).collect();
    let r_max = radii.iter().copied().fold(0.0, f64::max);
    let vp: f64 = radii.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    // target box (scaled)
    let shape = case.box_size;
    // compaction aims slightly above the target: unloading from the compaction pressure expands
    // the box by about the elastic strain; 2·compaction_overlap is the measured relative loss
    let v_target = vp / (case.target_solid_fraction * (1.0 + 2.0 * proto.compaction_overlap));
    let scale = (v_target / (shape[0] * shape[1] * shape[2])).cbrt();
    let target = shape.map(|s| s * scale);
    if target.iter().any(|&l| l < 4.0 * r_max) {
        return Err(ConfigError::inconsistent(
            "packing.box",
            format!("the target box {:?} mean radii is narrower than two largest diameters ({:.3}); add particles or change the shape", target, 4.0 * r_max),
        )
        .into());
    }
    // 1. cloud on a jittered lattice
    let foot = [target[0] * 1.02, target[1] * 1.02];
    let a = 2.0 * r_max * 1.02;
    let nx = (foot[0] / a).floor() as usize;
    let ny = (foot[1] / a).floor() as usize;
    let nz_min = n.div_ceil(nx * ny);
    let h_cloud = (vp / (proto.cloud_solid_fraction * foot[0] * foot[1])).max(nz_min as f64 * a);
    let nz = ((h_cloud / a).floor() as usize).max(nz_min);
    let (ax, ay, az) = (foot[0] / nx as f64, foot[1] / ny as f64, h_cloud / nz as f64);
    let mut cells: Vec<usize> = (0..nx * ny * nz).collect();
    rng.shuffle(&mut cells);
    let mut cloud = Vec::with_capacity(n);
    for k in 0..n {
        let c = cells[k];
        let (ix, iy, iz) = (c % nx, (c / nx) % ny, c / (nx * ny));
        let r = radii[k];
        let jit = |rng: &mut Rng, s: f64| (2.0 * rng.uniform() - 1.0) * (0.5 * s - r).max(0.0) * 0.9;
        let x = V3::new((ix as f64 + 0.5) * ax + jit(&mut rng, ax), (iy as f64 + 0.5) * ay + jit(&mut rng, ay), (iz as f64 + 0.5) * az + jit(&mut rng, az));
        let v = V3::new(rng.normal(), rng.normal(), rng.normal()) * 0.01;
        cloud.push((x, v, morton(ix, iy, iz)));
    }
    // memory order: along a Morton (Z-order) curve of the lattice cells, so that neighbours are
    // near in memory (large packings were dominated by cache misses); `order[m]` is the draw
    // index of the particle stored at m, and the output restores the draw order
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&k| cloud[k].2);
    let mut p = Particles::default();
    let density = 3.0 / (4.0 * std::f64::consts::PI);
    for (m, &k) in order.iter().enumerate() {
        p.push(cloud[k].0, radii[k], 0, density, 1.0, 300.0);
        p.velocity[m] = cloud[k].1;
    }
    let law = LinearSpringDashpot { stiffness: 1.0, damping: Damping::restitution_ratio(proto.restitution) };
    let (dt, tc) = time_step(&law, &p, proto.dt_fraction, 0.0, true)?;
    pr.say(format!(
        "{n} particles, mean radius {r_unit:.4e} m, target box {:.3?} r, cloud height {h_cloud:.2} r, dt = {dt:.4} (t_c = {tc:.4}, scaled units)",
        target
    ));
    let mut settings = Settings::new(dt, 1.0);
    settings.friction = proto.friction;
    settings.wall_friction = proto.wall_friction;
    settings.local_damping = proto.local_damping;
    settings.tangential_damping_ratio = 0.0;
    settings.skin = 0.3;
    let v_imp = 0.2;
    let g = v_imp * v_imp / (2.0 * h_cloud);
    settings.gravity = V3::new(0.0, 0.0, -g);
    let mut walls = box_walls([foot[0], foot[1], h_cloud + 2.0 * r_max]);
    set_areas(&mut walls);
    let mut sim = Explicit::new(settings, law, walls)?;
    sim.parallel_threshold = 30_000;
    let budget = proto.max_steps;
    let out_of_steps = |stage: &str, steps: u64| -> Error {
        SolveError::new("packing generation", format!("{stage}: step budget packing.protocol.max_steps = {budget} exhausted after {steps} steps")).into()
    };
    // 2. settle
    let fall_steps = ((2.0 * h_cloud / g).sqrt() / dt) as u64;
    let ke_settle = 0.01 * g * n as f64;
    let mut steps_settle = 0u64;
    loop {
        sim.run(&mut p, 100)?;
        steps_settle += 100;
        if steps_settle > fall_steps && sim.energy.kinetic < ke_settle {
            break;
        }
        if sim.counters.steps > budget {
            return Err(out_of_steps("settling", sim.counters.steps));
        }
    }
    let zmax = p.position.iter().zip(&p.radius).map(|(x, r)| x[2] + r).fold(0.0, f64::max);
    pr.say(format!(
        "settled after {steps_settle} steps ({} neighbour-list builds so far), top at {zmax:.2} r (target height {:.2} r)",
        sim.counters.rebuilds, target[2]
    ));
    // 3. triaxial compaction
    sim.settings.gravity = V3::zeros();
    sim.walls[5].offset = -zmax;
    sim.invalidate();
    let l0 = box_of(&sim.walls);
    let p_c = proto.compaction_overlap / 4.0;
    let v_max = 0.03; // fastest wall speed, scaled units (r̄ per √(m̄/k_n))
    let path_len = (0..3).map(|a| (target[a] - l0[a]).abs()).fold(0.0, f64::max).max(1e-12);
    let mut lambda = 0.0f64;
    let mut mu = proto.friction;
    let mut steps_compact = 0u64;
    let mut jammed_steps = 0u64;
    let mut phi_at_check = 0.0;
    // tapping (see below): strength, jammed steps before a tap, taps per stall check
    let (tap, quiet_steps, stall_taps) = (0.05, 150u64, 40u32);
    let mut taps = 0u32;
    let mut target = target;
    for a in 0..3 {
        sim.walls[2 * a + 1].control = WallControl::Velocity;
    }
    while lambda < 1.0 {
        let pm = (0..3).map(|a| sim.walls[2 * a + 1].pressure()).sum::<f64>() / 3.0;
        let servo = (1.0 - pm / p_c).clamp(0.0, 1.0);
        let dl = (servo * v_max * dt / path_len).min(1.0 - lambda);
        lambda += dl;
        for a in 0..3 {
            let speed = dl * (target[a] - l0[a]) / dt; // dL/dt
            sim.walls[2 * a + 1].velocity = -speed; // upper wall's normal points down: inward = −dL
        }
        if lambda >= 1.0 {
            // land exactly on the target
            for a in 0..3 {
                let want = -target[a];
                let w = &mut sim.walls[2 * a + 1];
                w.velocity = -((w.offset - want) / dt);
            }
        }
        if servo < 0.05 {
            jammed_steps += 1;
            if jammed_steps >= 300 && mu > 0.0 {
                mu = if mu < 0.005 { 0.0 } else { mu * 0.6 };
                sim.settings.friction = mu;
                if mu == 0.0 {
                    // without friction spin has no effect on the geometry and is never damped
                    p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
                }
                jammed_steps = 0;
                pr.say(format!("jammed at solid fraction {:.4}: friction lowered to {mu:.4}", vp / box_of(&sim.walls).iter().product::<f64>()));
            }
        } else {
            jammed_steps = 0;
        }
        if mu == 0.0 && jammed_steps >= quiet_steps {
            // frictionless and jammed below the target box (the flat walls leave looser layers):
            // tap, i.e. random velocities of `tap`·√(k_n/m̄) r̄, so that the packing explores denser
            // configurations under the same pressure; accept the box once `stall_taps` taps
            // gained < 1e-3 in solid fraction
            jammed_steps = 0;
            taps += 1;
            let phi = vp / box_of(&sim.walls).iter().product::<f64>();
            if taps.is_multiple_of(stall_taps) {
                if phi - phi_at_check < 1e-3 {
                    pr.say(format!("jammed at solid fraction {phi:.4} after {taps} taps: accepting it"));
                    target = box_of(&sim.walls);
                    lambda = 1.0;
                    continue;
                }
                phi_at_check = phi;
            }
            for v in p.velocity.iter_mut() {
                *v += V3::new(rng.normal(), rng.normal(), rng.normal()) * tap;
            }
        }
        sim.step(&mut p)?;
        set_areas(&mut sim.walls);
        steps_compact += 1;
        if steps_compact.is_multiple_of(2000) {
            pr.say(format!(
                "compaction: solid fraction {:.4}, pressure/p_c {:.3}, kinetic energy/particle {:.2e}, contacts/particle {:.2}",
                vp / box_of(&sim.walls).iter().product::<f64>(),
                pm / p_c,
                sim.energy.kinetic / n as f64,
                2.0 * sim.contacts().len() as f64 / n as f64
            ));
        }
        if sim.counters.steps > budget {
            return Err(out_of_steps("compaction", sim.counters.steps));
        }
    }
    for a in 0..3 {
        sim.walls[2 * a + 1].control = WallControl::Fixed;
        sim.walls[2 * a + 1].velocity = 0.0;
        sim.walls[2 * a + 1].offset = -target[a];
    }
    set_areas(&mut sim.walls);
    pr.say(format!(
        "compacted to the target box ({taps} taps) after {steps_compact} steps ({} neighbour-list builds so far), friction {mu:.4}, wall pressure {:.3e} (p_c = {p_c:.3e})",
        sim.counters.rebuilds,
        (0..3).map(|a| sim.walls[2 * a + 1].pressure()).sum::<f64>() / 3.0
    ));
    // 4. unload and relax
    if mu == 0.0 {
        p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
    }
    let ke_tol = proto.kinetic_energy_rel * n as f64;
    let ov_tol = proto.max_overlap_rel;
    let mut steps_relax = 0u64;
    let mut backing_off = false;
    let mut quiet = 0u64;
    let met = loop {
        sim.run(&mut p, 50)?;
        steps_relax += 50;
        if mu > 0.0 {
            // a rattler (no contact: zero force, gravity is off) keeps any spin forever, and its
            // rotational energy would hold the kinetic energy above the threshold; the spin of a
            // contact-free sphere does not affect the geometry, so stop it
            for (w, f) in p.angular_velocity.iter_mut().zip(sim.forces()) {
                if *f == V3::zeros() {
                    *w = V3::zeros();
                }
            }
        }
        let ke = sim.energy.kinetic;
        let ov = max_overlap(&p, &sim.walls, sim.neighbour_pairs());
        if ke < ke_tol && ov < ov_tol && !backing_off {
            break true;
        }
        let pm = (0..3).map(|a| sim.walls[2 * a + 1].pressure()).sum::<f64>() / 3.0;
        // kinetic energy settled but overlaps too large: the packing carries load; back the walls off
        if ov >= ov_tol && ke < 100.0 * ke_tol {
            quiet += 1;
        }
        if !backing_off && quiet >= 4 {
            backing_off = true;
            pr.say(format!("relaxed with largest overlap {ov:.2e} r: backing the walls off (pressure {pm:.3e})"));
        }
        if backing_off {
            let p_end = 0.02 * p_c * proto.max_overlap_rel / proto.compaction_overlap.max(proto.max_overlap_rel);
            if pm <= p_end.max(1e-14) || ov < 0.5 * ov_tol {
                backing_off = false;
                quiet = 0;
                for a in 0..3 {
                    sim.walls[2 * a + 1].control = WallControl::Fixed;
                }
            } else {
                for a in 0..3 {
                    // a strain rate: the walls' travel to unload grows with the box
                    let w = &mut sim.walls[2 * a + 1];
                    w.control = WallControl::Velocity;
                    w.velocity = -BACKOFF_STRAIN_RATE * target[a];
                }
            }
            set_areas(&mut sim.walls);
        }
        if !backing_off && ov < ov_tol && sim.settings.viscous_damping == 0.0 {
            // the box is final and the overlaps are within the threshold: only kinetic energy is
            // left, in a nearly stress-free packing whose particles drift with almost no force
            // (the local damping, proportional to the force, hardly slows them; the kinetic energy
            // of a 10^4-particle packing took ~2·10^4 steps to fall by 100): drain it with a
            // background viscous damping
            sim.settings.viscous_damping = DRAIN_DAMPING;
            pr.say(format!("overlaps below {ov_tol:.1e} r: draining the kinetic energy ({:.2e} per particle) with viscous damping", ke / n as f64));
        }
        if steps_relax.is_multiple_of(2000) {
            pr.say(format!(
                "relax: kinetic energy/particle {:.2e}, largest overlap {ov:.2e} r, pressure/p_c {:.3e}, backing off {backing_off}",
                ke / n as f64,
                pm / p_c
            ));
        }
        if sim.counters.steps > budget {
            break false;
        }
    };
    let steps_total = sim.counters.steps;
    pr.say(format!(
        "relaxed after {steps_relax} steps (kinetic energy {:.3e}, thresholds met: {met}; {} neighbour-list builds in all)",
        sim.energy.kinetic / n as f64,
        sim.counters.rebuilds
    ));
    // report (scaled → SI)
    let lbox = box_of(&sim.walls);
    let lo = V3::new(sim.walls[0].offset, sim.walls[2].offset, sim.walls[4].offset);
    let mut pos_si = vec![V3::zeros(); n];
    let mut rad_si = vec![0.0; n];
    for (m, &k) in order.iter().enumerate() {
        pos_si[k] = (p.position[m] - lo) * r_unit;
        rad_si[k] = p.radius[m] * r_unit;
    }
    let box_si = lbox.map(|l| l * r_unit);
    let summary = summarise(
        case,
        &pos_si,
        &rad_si,
        box_si,
        r_unit,
        sim.energy.kinetic / n as f64,
        mu,
        [steps_settle, steps_compact, steps_relax],
        steps_total,
        t0.elapsed().as_secs_f64(),
        met,
    );
    Ok((Packing { positions: pos_si, radii: rad_si, box_size: box_si }, summary))
}

/// Coordination of every particle: neighbours with gap < `gap` [m].
pub fn coordination(pos: &[V3], rad: &[f64], gap: f64) -> (Vec<u32>, usize) {
    let pairs = crate::contacts::detect::touching_pairs(pos, rad, gap);
    let mut z = vec![0u32; pos.len()];
    let mut overl = 0;
    for &(i, j) in &pairs {
        z[i as usize] += 1;
        z[j as usize] += 1;
        if (pos[i as usize] - pos[j as usize]).norm() < rad[i as usize] + rad[j as usize] {
            overl += 1;
        }
    }
    (z, overl)
}

fn summarise(
    case: &GenerateCase,
    pos: &[V3],
    rad: &[f64],
    box_si: [f64; 3],
    r_unit: f64,
    ke: f64,
    mu: f64,
    stage: [u64; 3],
    steps: u64,
    wall: f64,
    met: bool,
) -> GenerateSummary {
    let n = pos.len();
    let vp: f64 = rad.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let vbox = box_si.iter().product::<f64>();
    let (z, overl) = coordination(pos, rad, case.protocol.contact_gap_rel * r_unit);
    let mut ov: f64 = 0.0;
    for &(i, j) in &crate::contacts::detect::touching_pairs(pos, rad, 0.0) {
        ov = ov.max(rad[i as usize] + rad[j as usize] - (pos[i as usize] - pos[j as usize]).norm());
    }
    for (x, &r) in pos.iter().zip(rad) {
        for a in 0..3 {
            ov = ov.max(r - x[a]).max(r - (box_si[a] - x[a]));
        }
    }
    let width = case.lamina_width.unwrap_or(r_unit);
    let lo = V3::zeros();
    let hi = V3::new(box_si[0], box_si[1], box_si[2]);
    let mut dev = [0.0; 3];
    let mut mean = [0.0; 3];
    for a in 0..3 {
        let l = report::laminae(pos, rad, &lo, &hi, a, width, 2.0 * r_unit);
        let inner: Vec<f64> = l.density.iter().zip(&l.interior).filter(|(_, i)| **i).map(|(d, _)| *d).collect();
        if !inner.is_empty() {
            mean[a] = inner.iter().sum::<f64>() / inner.len() as f64;
            dev[a] = inner.iter().map(|d| (d - mean[a]).abs()).fold(0.0, f64::max);
        }
    }
    let mut d: Vec<f64> = rad.iter().map(|r| 2.0 * r).collect();
    d.sort_by(f64::total_cmp);
    let ks = d.iter().enumerate().map(|(k, &x)| (case.size.cdf(x) - (k as f64 + 0.5) / n as f64).abs()).fold(0.0, f64::max);
    let mean_req = 0.5 * requested_mean_diameter(&case.size);
    GenerateSummary {
        particles: n,
        seed: case.seed,
        solid_fraction: vp / vbox,
        target_solid_fraction: case.target_solid_fraction,
        coordination_mean: z.iter().map(|&c| c as f64).sum::<f64>() / n as f64,
        coordination_overlapping: 2.0 * overl as f64 / n as f64,
        rattlers: z.iter().filter(|&&c| c == 0).count(),
        max_overlap_rel: ov.max(0.0) / r_unit,
        kinetic_energy_rel: ke,
        box_size: box_si,
        mean_radius: r_unit,
        mean_radius_requested: mean_req,
        size_ks_distance: ks,
        lamina_width: width,
        laminae_max_deviation: dev,
        laminae_mean: mean,
        final_friction: mu,
        steps,
        stage_steps: stage,
        dt_fraction: case.protocol.dt_fraction,
        wall_time: wall,
        thresholds_met: met,
    }
}

/// Mean of the requested diameter distribution [m] (tabulated: by the trapezoid rule on the CDF).
pub fn requested_mean_diameter(s: &SizeDistribution) -> f64 {
    match s {
        SizeDistribution::Uniform { mean, .. } | SizeDistribution::Normal { mean, .. } => *mean,
        SizeDistribution::Tabulated { diameters, cumulative } => {
            (1..diameters.len()).map(|k| 0.5 * (diameters[k] + diameters[k - 1]) * (cumulative[k] - cumulative[k - 1])).sum()
        }
    }
}

/// Writes `packing.csv`, `packing.vtu`, `laminae.csv`, `laminae.png`, `size_distribution.csv`
/// and `summary.json` into `out_dir`.
pub fn write_outputs(case: &GenerateCase, packing: &Packing, summary: &GenerateSummary, out_dir: &Path) -> Result<(), Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let mut csv = String::from("x_m,y_m,z_m,radius_m\n");
    for (x, r) in packing.positions.iter().zip(&packing.radii) {
        csv.push_str(&format!("{:.10e},{:.10e},{:.10e},{:.10e}\n", x[0], x[1], x[2], r));
    }
    report::write_text(&out_dir.join("packing.csv"), &csv)?;
    let gap = case.protocol.contact_gap_rel * summary.mean_radius;
    let (z, _) = coordination(&packing.positions, &packing.radii, gap);
    let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&packing.positions, &packing.radii, gap).into_iter().map(|(i, j)| [i, j]).collect();
    // the generator is athermal: the VTU carries no temperature
    report::write_vtu(out_dir, "packing", &packing.positions, &packing.radii, &[], &z, &pairs)?;
    // laminae (eq. 48)
    let hi = V3::new(packing.box_size[0], packing.box_size[1], packing.box_size[2]);
    // relative density of laminae (Ivannikov et al. 2022 eq. 48); position_m = lamina centre
    let mut lam = String::from("axis,position_m,relative_density,interior\n");
    let mut series = Vec::new();
    for a in 0..3 {
        let l = report::laminae(&packing.positions, &packing.radii, &V3::zeros(), &hi, a, summary.lamina_width, 2.0 * summary.mean_radius);
        for k in 0..l.centres.len() {
            lam.push_str(&format!("{},{:.6e},{:.6},{}\n", ["x", "y", "z"][a], l.centres[k], l.density[k], l.interior[k]));
        }
        // normalised position s/L so the three axes share the plot
        series.push((["x", "y", "z"][a], l.centres.iter().zip(&l.density).map(|(c, d)| (c / packing.box_size[a], *d)).collect::<Vec<_>>()));
    }
    report::write_text(&out_dir.join("laminae.csv"), &lam)?;
    let title = format!("Laminae (eq. 48), {} particles", packing.radii.len());
    // the band: ± 0.05 around the mean of the interior laminae (the acceptance criterion)
    let interior_mean = summary.laminae_mean.iter().sum::<f64>() / 3.0;
    report::write_laminae_plot(&out_dir.join("laminae.png"), &title, &series, interior_mean, 0.05)?;
    // size distribution achieved vs asked
    let mut d: Vec<f64> = packing.radii.iter().map(|r| 2.0 * r).collect();
    d.sort_by(f64::total_cmp);
    // number-weighted cumulative distribution of diameters: achieved (sample) vs requested
    let mut sd = String::from("diameter_m,cdf_achieved,cdf_requested\n");
    let (lo, hi) = case.size.support();
    for k in 0..=50 {
        let x = lo + (hi - lo) * k as f64 / 50.0;
        let ach = d.partition_point(|&v| v <= x) as f64 / d.len() as f64;
        sd.push_str(&format!("{x:.6e},{ach:.6},{:.6}\n", case.size.cdf(x)));
    }
    report::write_text(&out_dir.join("size_distribution.csv"), &sd)?;
    let json = serde_json::to_string_pretty(summary).map_err(|e| IoError::new(out_dir.join("summary.json"), e))?;
    report::write_text(&out_dir.join("summary.json"), &(json + "\n"))?;
    Ok(())
}

/// Library entry point of `sinterdem generate CASE.toml --out DIR`: validates the case (overrides
/// already applied), generates, writes the outputs, and returns the summary. If the relaxation did
/// not meet its thresholds within `max_steps`, the outputs are still written and a SolveError says so.
pub fn generate_case(case: &toml::Value, out_dir: &Path, progress: bool) -> Result<GenerateSummary, Error> {
    let c = parse_generate_case(case)?;
    let (packing, summary) = generate(&c, progress)?;
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
    if !summary.thresholds_met {
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

/// The benchmark case for `n` particles: copper-like (mean diameter 50 µm, uniform ±10 %), box
/// shape 1:1:0.8, target 0.60, seed 1.
pub fn bench_case(n: usize) -> toml::Value {
    let text = format!(
        "kind = \"generate\"\n[packing]\nparticles = {n}\nseed = 1\ntarget_solid_fraction = 0.60\nbox = [0.5e-3, 0.5e-3, 0.4e-3]\n[packing.size]\ndistribution = \"uniform\"\nmean_diameter = 50e-6\nspread = 0.1\n"
    );
    toml::Value::Table(text.parse::<toml::Table>().expect("static bench case"))
}

/// Library entry point of `sinterdem bench generate`: generates the benchmark case for each size,
/// writing into `out_dir/bench-N`, and returns a table of wall-clock times and results.
pub fn bench_generate(out_dir: &Path, sizes: &[usize]) -> Result<String, Error> {
    let mut s = format!(
        "# sinterdem bench generate ({} rayon threads)\n{:>9} {:>10} {:>9} {:>8} {:>9} {:>10} {:>10}\n",
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
        let summary = generate_case(&bench_case(n), &out_dir.join(format!("bench-{n}")), false)?;
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

//! Case → scene preparation for the kinds that heat a packing (heat, compact, conductivity):
//! parse and validate the case, build the scene, the heat sources, furnace, conductance law, gap
//! model and the initial pipes; the heat network and its step control from a case.

use crate::config::{self, from_value};
use crate::error::{ConfigError, Error};
use crate::heat::{Conductance, Furnace, HeatNetwork, HeatSources, Pipes};
use crate::profile::Profile;
use crate::scene::case::{Case, FurnaceSpec};
use crate::scene::{self, Scene};
use std::path::Path;

/// A validated, built heat case.
pub struct Prepared {
    pub case: Case,
    pub scene: Scene,
    pub pipes: Pipes,
    pub sources: HeatSources,
    /// `Some(profile)` for `thermal.mode = "isothermal"`.
    pub isothermal: Option<Profile>,
    pub conductance: Conductance,
    /// The gap model (`[thermal.gap]`, docs/heat-model.md (H18)–(H23)) with its neighbour search;
    /// `None`: off.
    pub gap: Option<crate::heat::gap::GapNetwork>,
    /// The case as run (overrides applied) and its folder, for checkpoints; set by the run API.
    pub source: Option<(String, std::path::PathBuf)>,
}

fn furnace(spec: &FurnaceSpec) -> Result<Furnace, ConfigError> {
    let gas = Profile::from_spec(&spec.profile, "thermal.furnace.profile")?;
    let wall = match &spec.wall_profile {
        Some(w) => Profile::from_spec(w, "thermal.furnace.wall_profile")?,
        None => gas.clone(),
    };
    Ok(Furnace {
        gas,
        wall,
        convection: config::check("thermal.furnace.convection_coefficient", spec.convection_coefficient)?,
        emissivity: config::check("thermal.furnace.emissivity", spec.emissivity)?,
    })
}

/// The conductance model of a case.
pub fn conductance_of(case: &Case) -> Result<Conductance, ConfigError> {
    Ok(Conductance {
        law: case.thermal.conductance,
        factor: config::check("thermal.conductance_factor", case.thermal.conductance_factor)?,
        contact: config::check_opt("thermal.contact_conductance", case.thermal.contact_conductance)?,
        boundary_resistance: config::check("thermal.boundary_resistance", case.thermal.boundary_resistance)?,
        multi_neck: case.thermal.multi_neck,
    })
}

/// Parse → validate → build a heat case (no time stepping). `base` is the case file's directory.
pub fn prepare(value: toml::Value, base: &Path) -> Result<Prepared, Error> {
    let prep = prepare_scene(value, base)?;
    let c = &prep.case;
    if let Some(k) = c.kind.as_deref().filter(|k| *k != "heat") {
        return Err(ConfigError::invalid(format!("kind = \"{k}\" is not a heat case")).into());
    }
    for (present, key) in [
        (c.contacts.is_some(), "contacts"),
        (c.model.is_some(), "model"),
        (c.solver.is_some(), "solver"),
        (c.mechanics.is_some(), "mechanics"),
        (c.load.is_some(), "load"),
    ] {
        if present {
            return Err(ConfigError::inconsistent(key, "this section belongs to kind = \"compact\" cases; a heat case has a static packing").into());
        }
    }
    // keys that only a compact run reads: refuse them rather than ignore them
    let t = &c.time;
    let o = &c.output;
    let compact_only = [
        (t.strategy.is_some(), "time.strategy"),
        (t.dt_max.is_some() && t.heat_tolerance.is_none(), "time.dt_max"),
        (t.dt_min.is_some() && t.heat_tolerance.is_none(), "time.dt_min"),
        (t.alpha.is_some(), "time.alpha"),
        (t.grow_below.is_some(), "time.grow_below"),
        (t.shrink_above.is_some(), "time.shrink_above"),
        (t.substeps_allowed.is_some(), "time.substeps_allowed"),
        (t.stop_relative_density.is_some(), "time.stop_relative_density"),
        (!o.conductivity_at.is_empty(), "output.conductivity_at"),
        (!o.correction_histogram_at.is_empty(), "output.correction_histogram_at"),
    ];
    if let Some((_, key)) = compact_only.iter().find(|(present, _)| *present) {
        return Err(ConfigError::inconsistent(
            *key,
            "this key is read by kind = \"compact\" runs only, and by heat runs with time.heat_tolerance (a heat run has no sintering analyses)",
        )
        .into());
    }
    Ok(prep)
}

/// A periodic compact's cell holds two largest reaches along every edge, 2·(2 r_max + g·r̄) with
/// g the larger of `contacts.gap_tolerance` and `contacts.new_contact_gap`: the bound of the cell's
/// contact search (`coupled::cell::PeriodicCell::touching`, minimum image). The range check of
/// `particles.periodic_box` asks 4 r_max only, so a box in between passed `check` and failed at
/// t = 0 with a model error (issue 38); now it is the range error of the key that set it.
fn check_cell_reach(scene: &Scene, case: &Case) -> Result<(), ConfigError> {
    let Some(b) = scene.periodic_box else { return Ok(()) };
    let p = &scene.particles;
    let c = case.contacts.clone().unwrap_or_default();
    let g = c.gap_tolerance.max(c.new_contact_gap.unwrap_or(0.0));
    let r_max = p.radius.iter().copied().fold(0.0, f64::max);
    let need = 2.0 * (2.0 * r_max + g * p.mean_radius());
    match (0..3).map(|a| b[a]).find(|&l| !(l > need)) {
        None => Ok(()),
        Some(l) => Err(ConfigError::OutOfRange {
            key: if case.particles.periodic_box.is_some() { "particles.periodic_box".into() } else { "particles.cells".into() },
            value: l,
            range: format!(
                "({need:.4e}, 1000]: a periodic cell edge above two largest reaches 2·(2 r_max + g·r_mean), g = {g} the contact gap (contacts.gap_tolerance, contacts.new_contact_gap)"
            ),
            unit: "m".into(),
        }),
    }
}

/// Parse → validate → build the parts shared by heat and compact cases: scene, materials,
/// heat sources and the initial contact pipes.
pub fn prepare_scene(value: toml::Value, base: &Path) -> Result<Prepared, Error> {
    let case: Case = from_value(value, "")?;
    let compact = case.kind.as_deref() == Some("compact");
    crate::scene::case::check_time(&case.time, compact)?;
    config::check("output.snapshots", case.output.snapshots)?;
    config::check("output.series_every", case.output.series_every)?;
    config::check("thermal.radiation_tolerance", case.thermal.radiation_tolerance)?;
    config::check_opt("time.heat_tolerance", case.time.heat_tolerance)?;
    if case.output.snapshots.fract() != 0.0 || case.output.series_every.fract() != 0.0 {
        return Err(ConfigError::invalid("output.snapshots and output.series_every must be whole numbers").into());
    }
    let conductance = conductance_of(&case)?;
    let periodic = case.mechanics.as_ref().is_some_and(|m| m.boundary == "periodic");
    if compact && case.particles.periodic_box.is_some() && !periodic {
        return Err(ConfigError::inconsistent(
            "particles.periodic_box",
            "a walled compact run has no periodic cell: set mechanics.boundary = \"periodic\" to run the packing as a periodic cell (docs/mechanics.md \"Periodic cell\"), or drop the box",
        )
        .into());
    }
    // keys that this case's mode does not read are range-checked all the same
    if let Some(f) = &case.thermal.furnace {
        config::check("thermal.furnace.convection_coefficient", f.convection_coefficient)?;
        config::check("thermal.furnace.emissivity", f.emissivity)?;
        config::check("thermal.furnace.exposure", f.exposure)?;
    }
    config::check("conductivity.temperature_difference", case.conductivity.temperature_difference)?;
    config::check_opt("conductivity.layer_fraction", case.conductivity.layer_fraction)?;
    let per_particle = if compact { config::plausible::BYTES_PER_PARTICLE_COMPACT } else { config::plausible::BYTES_PER_PARTICLE_HEAT };
    if let Some(count) = scene::particle_count(&case.particles) {
        config::plausible::check_memory("particles.cells", count, per_particle)?;
    }
    let materials = crate::material::from_case(&case.materials)?;
    let scene = scene::build(&case.particles, materials, base)?;
    if compact && periodic {
        check_cell_reach(&scene, &case)?;
    }
    let n = scene.particles.len();
    config::plausible::check_memory("particles.file", n as f64, per_particle)?;
    let th = &case.thermal;
    let isothermal = match th.mode.as_str() {
        "network" => None,
        "isothermal" => {
            let f = th.furnace.as_ref().ok_or_else(|| ConfigError::inconsistent("thermal.mode", "\"isothermal\" needs [thermal.furnace] with its profile"))?;
            if !th.fixed.is_empty() || !th.volumetric.is_empty() || f.convection_coefficient > 0.0 || f.emissivity > 0.0 {
                return Err(ConfigError::inconsistent(
                    "thermal.mode",
                    "\"isothermal\" scenes are uniform in space: remove thermal.fixed, thermal.volumetric, and furnace convection/emissivity",
                )
                .into());
            }
            Some(Profile::from_spec(&f.profile, "thermal.furnace.profile")?)
        }
        other => return Err(ConfigError::invalid(format!("thermal.mode = \"{other}\": expected network or isothermal")).into()),
    };
    let gap = match &th.gap {
        Some(spec) => {
            let model = crate::heat::gap::GapModel::from_spec(spec)?;
            if isothermal.is_some() {
                return Err(ConfigError::inconsistent(
                    "thermal.gap",
                    "an isothermal scene has no heat solve: remove [thermal.gap] or use thermal.mode = \"network\"",
                )
                .into());
            }
            model.map(crate::heat::gap::GapNetwork::new)
        }
        None => None,
    };
    if !matches!(th.contact_temperature.as_str(), "arithmetic" | "harmonic") {
        return Err(ConfigError::invalid(format!("thermal.contact_temperature = \"{}\": expected arithmetic or harmonic", th.contact_temperature)).into());
    }
    let mut sources = HeatSources { fixed: vec![None; n], exposed_area: vec![0.0; n], power: vec![0.0; n], ..Default::default() };
    for (k, f) in th.fixed.iter().enumerate() {
        let key = format!("thermal.fixed[{k}]");
        let prof = Profile::from_spec(&f.profile, &format!("{key}.profile"))?;
        sources.profiles.push(prof);
        for i in scene::select(&f.region, &scene.particles, &format!("{key}.region"))? {
            if let Some(prev) = sources.fixed[i as usize] {
                return Err(ConfigError::inconsistent(&key, format!("particle {i} is already held by thermal.fixed[{prev}]")).into());
            }
            sources.fixed[i as usize] = Some(k as u32);
        }
    }
    for (k, v) in th.volumetric.iter().enumerate() {
        let key = format!("thermal.volumetric.{k}.power_density");
        let q = config::check(&key, v.power_density)?;
        for i in scene::select(&v.region, &scene.particles, &format!("thermal.volumetric[{k}].region"))? {
            sources.power[i as usize] += q * crate::units::sphere_volume(scene.particles.radius[i as usize]);
        }
    }
    if let (Some(f), None) = (&th.furnace, &isothermal) {
        let fur = furnace(f)?;
        let exposure = config::check("thermal.furnace.exposure", f.exposure)?;
        let exposed: Vec<u32> = match &f.exposed {
            Some(r) => scene::select(r, &scene.particles, "thermal.furnace.exposed")?,
            None => {
                let mut all = Vec::new();
                for face in ["x-", "x+", "y-", "y+", "z-", "z+"] {
                    let r = crate::scene::case::RegionSpec { face: Some(face.into()), ..Default::default() };
                    all.extend(scene::select(&r, &scene.particles, "thermal.furnace.exposed")?);
                }
                all.sort_unstable();
                all.dedup();
                all
            }
        };
        for i in exposed {
            let r = scene.particles.radius[i as usize];
            sources.exposed_area[i as usize] = exposure * 4.0 * std::f64::consts::PI * r * r;
        }
        sources.furnace = Some(fur);
    }
    let pipes = crate::heat::pipes(&scene.particles, &scene.materials, &conductance)?;
    Ok(Prepared { case, scene, pipes, sources, isothermal, conductance, gap, source: None })
}

/// The heat network of a case: capacities, sources, scheme and, when a material has c(T) or κ(T)
/// tables, the temperature-dependent properties (heat-model.md eqs. P1–P4). Shared by heat runs and
/// the coupled loop.
pub fn network_for(
    case: &Case,
    sources: &HeatSources,
    p: &crate::particles::Particles,
    materials: &[crate::material::Material],
    conductance: &Conductance,
) -> HeatNetwork {
    let mut net = HeatNetwork::new(p.capacity.clone(), sources.clone(), case.time.scheme, case.thermal.radiation_tolerance);
    net.set_properties(crate::heat::properties::ThermalProperties::of(&p.mass, &p.material, materials, conductance.contact));
    net
}

/// The step control of a case (heat-model.md eq. E3): `None` without `time.heat_tolerance`.
/// Defaults: dt_min = 1e-9 · end, dt_max = end.
pub fn step_control(case: &Case) -> Result<Option<crate::heat::adaptive::StepControl>, ConfigError> {
    let t = &case.time;
    let Some(tol) = config::check_opt("time.heat_tolerance", t.heat_tolerance)? else { return Ok(None) };
    let dt_min = config::check_opt("time.dt_min", t.dt_min)?.unwrap_or(1e-9 * t.end);
    let dt_max = config::check_opt("time.dt_max", t.dt_max)?.unwrap_or(t.end);
    Ok(Some(crate::heat::adaptive::StepControl { tolerance: tol, dt_min, dt_max }))
}

//! Building a scene from a case: particles (lattices, a pair, a packing file), regions, and the
//! contact pipes of the heat network with their volume-conserving necks.

pub mod case;
mod prepare;

pub use prepare::{Prepared, conductance_of, network_for, prepare, prepare_scene, step_control};

use crate::config::{self};
use crate::error::{ConfigError, Error};
use crate::material::Material;
use crate::particles::Particles;
use crate::scene::case::{ParticlesSpec, RegionSpec};
use nalgebra::Vector3;
use std::path::Path;

/// Bravais lattices for test scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lattice {
    SimpleCubic,
    BodyCentred,
    FaceCentred,
}

impl Lattice {
    pub fn parse(s: &str) -> Result<Self, ConfigError> {
        match s {
            "sc" => Ok(Lattice::SimpleCubic),
            "bcc" => Ok(Lattice::BodyCentred),
            "fcc" => Ok(Lattice::FaceCentred),
            _ => Err(ConfigError::invalid(format!("particles.lattice = \"{s}\": expected sc, bcc or fcc"))),
        }
    }

    /// Cubic cell edge for nearest-neighbour distance `d` [m].
    pub fn cell_edge(self, d: f64) -> f64 {
        match self {
            Lattice::SimpleCubic => d,
            Lattice::BodyCentred => 2.0 * d / 3f64.sqrt(),
            Lattice::FaceCentred => 2f64.sqrt() * d,
        }
    }

    /// Basis positions in units of the cell edge.
    pub fn basis(self) -> &'static [[f64; 3]] {
        match self {
            Lattice::SimpleCubic => &[[0.0, 0.0, 0.0]],
            Lattice::BodyCentred => &[[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]],
            Lattice::FaceCentred => &[[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]],
        }
    }

    /// Largest overlap h/r for which second neighbours do not touch (docs/heat-model.md, "Effective conductivity").
    pub fn max_overlap_for_nearest_neighbours(self) -> f64 {
        match self {
            Lattice::BodyCentred => 2.0 - 3f64.sqrt(),
            _ => 2.0 - 2f64.sqrt(),
        }
    }
}

/// Particles plus what the scene knows about its geometry.
#[derive(Debug, Clone)]
pub struct Scene {
    pub particles: Particles,
    pub materials: Vec<Material>,
    /// The periodic box of a lattice scene (cells × cell edge) or of a file packing
    /// (`particles.periodic_box`) [m], with its origin at 0.
    pub periodic_box: Option<Vector3<f64>>,
    /// Lattice type and nearest-neighbour distance D [m] for lattice scenes.
    pub lattice: Option<(Lattice, f64)>,
}

fn material_index(materials: &[Material], name: Option<&str>, key: &str) -> Result<u16, ConfigError> {
    match name {
        None => Ok(0),
        Some(n) => materials
            .iter()
            .position(|m| m.name == n)
            .map(|i| i as u16)
            .ok_or_else(|| ConfigError::invalid(format!("{key} = \"{n}\": no such material in [[materials]]"))),
    }
}

/// The number of particles a lattice or pair scene will have (None for a packing file), known
/// before anything is built (for the memory estimate of `check`).
pub fn particle_count(spec: &ParticlesSpec) -> Option<f64> {
    match spec.source.as_str() {
        "lattice" => {
            let basis = spec.lattice.as_deref().and_then(|l| Lattice::parse(l).ok()).map_or(1, |l| l.basis().len());
            spec.cells.map(|c| c.iter().map(|&n| n as f64).product::<f64>() * basis as f64)
        }
        "pair" => Some(2.0),
        _ => None,
    }
}

/// Builds the particles of `spec`; `base` is the case file's directory (for `file`).
pub fn build(spec: &ParticlesSpec, materials: Vec<Material>, base: &Path) -> Result<Scene, Error> {
    let t0 = config::check("particles.initial_temperature", spec.initial_temperature.unwrap_or(293.15))?;
    // every key present is range-checked, also where this source does not read it
    config::check_opt("particles.radius", spec.radius)?;
    config::check_opt("particles.radius_2", spec.radius_2)?;
    let mat = material_index(&materials, spec.material.as_deref(), "particles.material")?;
    let mut p = Particles::default();
    let push = |p: &mut Particles, x: Vector3<f64>, r: f64, m: u16, t: f64| {
        let mm = &materials[m as usize];
        p.push(x, r, m, mm.density, mm.heat_capacity, t);
    };
    let overlap = config::check("particles.overlap", spec.overlap)?;
    let mut periodic_box = None;
    let mut lattice = None;
    if spec.periodic_box.is_some() && spec.source != "file" {
        return Err(ConfigError::inconsistent("particles.periodic_box", format!("is read with source = \"file\" only (source = \"{}\")", spec.source)).into());
    }
    match spec.source.as_str() {
        "lattice" => {
            let kind = Lattice::parse(spec.lattice.as_deref().ok_or_else(|| ConfigError::invalid("particles.lattice is required for source = \"lattice\""))?)?;
            let r = config::check("particles.radius", spec.radius.ok_or_else(|| ConfigError::invalid("particles.radius is required"))?)?;
            let cells = spec.cells.ok_or_else(|| ConfigError::invalid("particles.cells = [nx, ny, nz] is required for a lattice"))?;
            if cells.iter().any(|&c| c == 0 || c > 200) {
                return Err(ConfigError::OutOfRange {
                    key: "particles.cells".into(),
                    value: *cells.iter().max().unwrap() as f64,
                    range: "[1, 200] per axis".into(),
                    unit: "1".into(),
                }
                .into());
            }
            if overlap >= kind.max_overlap_for_nearest_neighbours() {
                return Err(ConfigError::inconsistent(
                    "particles.overlap",
                    format!("{overlap} makes second neighbours of this lattice touch (must be < {:.4})", kind.max_overlap_for_nearest_neighbours()),
                )
                .into());
            }
            let d = (2.0 - overlap) * r;
            let e = kind.cell_edge(d);
            for k in 0..cells[2] {
                for j in 0..cells[1] {
                    for i in 0..cells[0] {
                        for b in kind.basis() {
                            let x = Vector3::new((i as f64 + b[0]) * e, (j as f64 + b[1]) * e, (k as f64 + b[2]) * e);
                            push(&mut p, x, r, mat, t0);
                        }
                    }
                }
            }
            periodic_box = Some(Vector3::new(cells[0] as f64 * e, cells[1] as f64 * e, cells[2] as f64 * e));
            lattice = Some((kind, d));
        }
        "pair" => {
            let r1 = config::check("particles.radius", spec.radius.ok_or_else(|| ConfigError::invalid("particles.radius is required"))?)?;
            let r2 = config::check("particles.radius_2", spec.radius_2.unwrap_or(r1))?;
            let h = overlap * r1.min(r2);
            let hmax = crate::neck::max_overlap(r1, r2);
            if h > hmax {
                return Err(ConfigError::inconsistent("particles.overlap", format!("h = {h:.4e} m exceeds the neck model's limit {hmax:.4e} m")).into());
            }
            push(&mut p, Vector3::zeros(), r1, mat, t0);
            push(&mut p, Vector3::new(r1 + r2 - h, 0.0, 0.0), r2, mat, t0);
        }
        "file" => {
            use crate::packing::import::{ImportFormat, import};
            let f = spec.file.as_ref().ok_or_else(|| ConfigError::invalid("particles.file is required for source = \"file\""))?;
            let path = base.join(f);
            let format: ImportFormat = match spec.format.as_deref() {
                Some(s) => s.parse()?,
                None => match path.extension().and_then(|e| e.to_str()) {
                    Some("csv") => ImportFormat::Csv,
                    Some("dump") | Some("liggghts") | Some("lammps") => ImportFormat::Liggghts,
                    _ => ImportFormat::Yade,
                },
            };
            let pk = import(&path, format)?;
            for k in 0..pk.radii.len() {
                let m = match &pk.materials {
                    Some(ids) => {
                        let id = ids[k];
                        if id as usize >= materials.len() {
                            return Err(ConfigError::invalid(format!(
                                "{}: particle {k} has material id {id}, but [[materials]] has {} entries (ids are 0-based)",
                                path.display(),
                                materials.len()
                            ))
                            .into());
                        }
                        id
                    }
                    None => mat,
                };
                let t = match &pk.temperatures {
                    Some(ts) => config::check("particles.initial_temperature", ts[k])?,
                    None => t0,
                };
                config::check("particles.radius", pk.radii[k])?;
                push(&mut p, pk.positions[k], pk.radii[k], m, t);
            }
            if let Some(b) = spec.periodic_box {
                periodic_box = Some(check_periodic_box(b, &p)?);
            }
        }
        other => {
            return Err(ConfigError::invalid(format!("particles.source = \"{other}\": expected lattice, pair or file")).into());
        }
    }
    if p.is_empty() {
        return Err(ConfigError::invalid("particles: the scene has no particles").into());
    }
    Ok(Scene { particles: p, materials, periodic_box, lattice })
}

/// `particles.periodic_box` of a file packing: every length positive and at least two largest
/// particle diameters, so that a pair touches through one periodic image only (minimum image).
fn check_periodic_box(b: [f64; 3], p: &Particles) -> Result<Vector3<f64>, ConfigError> {
    for &l in &b {
        config::check("particles.periodic_box", l)?;
    }
    let d_max = 2.0 * p.radius.iter().copied().fold(0.0, f64::max);
    if let Some(&l) = b.iter().find(|&&l| l < 2.0 * d_max) {
        return Err(ConfigError::OutOfRange {
            key: "particles.periodic_box".into(),
            value: l,
            range: format!("[2 largest particle diameters = {}, 1000]", crate::error::fmt_value(2.0 * d_max)),
            unit: "m".into(),
        });
    }
    Ok(Vector3::from(b))
}

/// The particles of a region, sorted. `key` names the region in errors.
pub fn select(region: &RegionSpec, p: &Particles, key: &str) -> Result<Vec<u32>, ConfigError> {
    let given = region.face.is_some() as u8
        + region.bbox.is_some() as u8
        + region.layer.is_some() as u8
        + region.particles.is_some() as u8
        + region.all.is_some() as u8;
    if given != 1 {
        return Err(ConfigError::inconsistent(key, "give exactly one of face, box, layer, particles, all"));
    }
    let n = p.len();
    let axis = |s: &str| -> Result<usize, ConfigError> {
        match s {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            _ => Err(ConfigError::invalid(format!("{key}: axis \"{s}\" (x, y or z)"))),
        }
    };
    let out: Vec<u32> = if let Some(face) = &region.face {
        if face.len() != 2 || !(face.ends_with('-') || face.ends_with('+')) {
            return Err(ConfigError::invalid(format!("{key}.face = \"{face}\": expected x-, x+, y-, y+, z- or z+")));
        }
        let a = axis(&face[..1])?;
        let depth = region.depth.unwrap_or_else(|| p.mean_radius());
        if !(depth > 0.0 && depth.is_finite()) {
            return Err(ConfigError::OutOfRange { key: format!("{key}.depth"), value: depth, range: "(0, inf)".into(), unit: "m".into() });
        }
        let (lo, hi) = p.bounding_box();
        (0..n as u32)
            .filter(|&i| {
                let (x, r) = (p.position[i as usize][a], p.radius[i as usize]);
                if face.ends_with('-') { x - r <= lo[a] + depth } else { x + r >= hi[a] - depth }
            })
            .collect()
    } else if let Some(b) = &region.bbox {
        (0..n as u32).filter(|&i| (0..3).all(|a| p.position[i as usize][a] >= b[0][a] && p.position[i as usize][a] <= b[1][a])).collect()
    } else if let Some(l) = &region.layer {
        let a = axis(&l.axis)?;
        (0..n as u32).filter(|&i| p.position[i as usize][a] >= l.from && p.position[i as usize][a] <= l.to).collect()
    } else if let Some(list) = &region.particles {
        if let Some(&bad) = list.iter().find(|&&i| i as usize >= n) {
            return Err(ConfigError::invalid(format!("{key}.particles: index {bad} out of range (the scene has {n} particles)")));
        }
        let mut v = list.clone();
        v.sort_unstable();
        v.dedup();
        v
    } else {
        (0..n as u32).collect()
    };
    if out.is_empty() {
        return Err(ConfigError::invalid(format!("{key}: the region contains no particles")));
    }
    Ok(out)
}

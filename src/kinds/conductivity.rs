//! The conductivity run (`sinterdem conductivity CASE`): the steady effective conductivity tensor
//! of a packing by the faces method or periodic homogenisation ([`crate::heat::conductivity`]).

use crate::config;
use crate::error::{ConfigError, Error};
use crate::heat::conductivity::{cut_face_warning, faces, periodic, periodic_pipes};
use nalgebra::Matrix3;

/// `sinterdem conductivity CASE`: the tensor [W/(m·K)] and κ_eff/κ as JSON.
pub fn run_case(value: toml::Value, base: &std::path::Path) -> Result<serde_json::Value, Error> {
    let prep = crate::scene::prepare(value, base)?;
    let spec = &prep.case.conductivity;
    let dt = config::check("conductivity.temperature_difference", spec.temperature_difference)?;
    let p = &prep.scene.particles;
    let kappa_mat = prep.scene.materials[0].conductivity;
    let axes: Vec<usize> = spec
        .axes
        .iter()
        .map(|a| match a.as_str() {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            o => Err(ConfigError::invalid(format!("conductivity.axes: \"{o}\" (x, y or z)"))),
        })
        .collect::<Result<_, _>>()?;
    let mut out = serde_json::Map::new();
    let tensor = match spec.boundary.as_str() {
        "faces" => {
            let depth = match config::check_opt("conductivity.layer_fraction", spec.layer_fraction)? {
                Some(f) => {
                    let (lo, hi) = p.bounding_box();
                    axes.iter().map(|&a| f * (hi[a] - lo[a])).collect::<Vec<_>>()
                }
                None => vec![0.5 * p.mean_radius(); axes.len()],
            };
            let mut t = Matrix3::zeros();
            let mut results = Vec::new();
            for (k, &a) in axes.iter().enumerate() {
                let r = faces(p, &prep.pipes, a, depth[k], dt)?;
                t[(a, a)] = r.kappa;
                results.push(r);
            }
            if let Some(w) = cut_face_warning(&results) {
                tracing::warn!(target: "sinterdem::kinds", "{w}");
                out.insert("warnings".into(), serde_json::json!([w]));
            }
            out.insert("axes".into(), serde_json::to_value(results).unwrap());
            t
        }
        "periodic" => {
            let bbox = prep.scene.periodic_box.ok_or_else(|| {
                ConfigError::inconsistent(
                    "conductivity.boundary",
                    "\"periodic\" needs a periodic box: particles.source = \"lattice\", or a file packing with particles.periodic_box = [Lx, Ly, Lz] (m)",
                )
            })?;
            let (pipes, branch) = periodic_pipes(p, bbox, &prep.scene.materials, &prep.conductance)?;
            out.insert("periodic_contacts".into(), pipes.pairs.len().into());
            // the contacts of the run are the periodic ones (the walled count misses those across
            // the box faces); `walled_contacts` keeps the count without periodic images
            out.insert("contacts".into(), pipes.pairs.len().into());
            out.insert("walled_contacts".into(), prep.pipes.pairs.len().into());
            periodic(p, &pipes, &branch, bbox)?
        }
        o => return Err(ConfigError::invalid(format!("conductivity.boundary = \"{o}\": expected faces or periodic")).into()),
    };
    let rows: Vec<Vec<f64>> = (0..3).map(|i| (0..3).map(|j| tensor[(i, j)]).collect()).collect();
    let ratio: Vec<Vec<f64>> = rows.iter().map(|r| r.iter().map(|v| v / kappa_mat).collect()).collect();
    out.insert("boundary".into(), spec.boundary.clone().into());
    out.insert("kappa_eff_W_per_mK".into(), serde_json::to_value(rows).unwrap());
    out.insert("kappa_eff_over_kappa".into(), serde_json::to_value(ratio).unwrap());
    out.insert("kappa_material_W_per_mK".into(), kappa_mat.into());
    out.insert("particles".into(), p.len().into());
    out.entry("contacts").or_insert(prep.pipes.pairs.len().into());
    if let Some((lat, d)) = prep.scene.lattice {
        // closed forms of docs/heat-model.md for the pipe conductance of the lattice's nearest neighbours
        let r = p.radius[0];
        let neck = crate::neck::solve(r, r, 2.0 * r - d)?;
        // the crowding of every neck of the lattice (heat-model.md (H8c)): nᵀMn/(2a) = 1 (SC),
        // (2 + 6/9)/2 = 4/3 (BCC), (2 + 8/4)/2 = 2 (FCC)
        let (f, phi) = match lat {
            crate::scene::Lattice::SimpleCubic => (1.0, 1.0),
            crate::scene::Lattice::BodyCentred => (3f64.sqrt(), 4.0 / 3.0),
            crate::scene::Lattice::FaceCentred => (2.0 * 2f64.sqrt(), 2.0),
        };
        let kp = prep.conductance.pipe_crowded(kappa_mat, kappa_mat, r, r, neck.a, [phi, phi]).pair;
        out.insert("lattice_closed_form_W_per_mK".into(), (f * kp / d).into());
    }
    Ok(serde_json::Value::Object(out))
}

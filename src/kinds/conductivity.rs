//! The conductivity run (`sinterdem conductivity CASE`): the steady effective conductivity tensor
//! of a packing by the faces method or periodic homogenisation ([`crate::heat::conductivity`]).

use crate::config;
use crate::error::{ConfigError, Error};
use crate::heat::conductivity::{cut_face_warning, faces, periodic, periodic_pipes};
use nalgebra::Matrix3;

/// International Annealed Copper Standard: 100 %IACS = 58.0 MS/m, annealed copper at 1.72e-8 Ω·m
/// at 20 °C (docs/references.md [WP-RES]; copper.org's 1.71 µΩ·cm = 101 %IACS agrees) [S/m].
pub const IACS_S_PER_M: f64 = 58.0e6;

/// `sinterdem conductivity CASE`: the tensor [W/(m·K)] and κ_eff/κ as JSON; with
/// `conductivity.quantity = "electrical"` the electrical conductivity tensor [S/m] of the same
/// network with σ_e = 1/ρ_e(T) for κ (docs/heat-model.md "Electrical conductivity").
pub fn run_case(value: toml::Value, base: &std::path::Path) -> Result<serde_json::Value, Error> {
    let mut prep = crate::scene::prepare(value, base)?;
    let spec = prep.case.conductivity.clone();
    let dt = config::check("conductivity.temperature_difference", spec.temperature_difference)?;
    let electrical = match spec.quantity.as_str() {
        "thermal" => false,
        "electrical" => true,
        o => return Err(ConfigError::invalid(format!("conductivity.quantity = \"{o}\": expected thermal or electrical")).into()),
    };
    let mut notes: Vec<String> = Vec::new();
    let mut temperature = None;
    if electrical {
        // the same network with σ_e for κ (thermal–electrical analogy): κ → 1/ρ_e at the particles' mean temperature, no thermal interface terms
        let ps = &prep.scene.particles;
        let t = ps.temperature.iter().sum::<f64>() / ps.temperature.len().max(1) as f64;
        for (m, s) in prep.scene.materials.iter_mut().zip(&prep.case.materials) {
            m.conductivity = 1.0 / s.electrical_resistivity_at(t)?;
        }
        if prep.conductance.contact.is_some() || prep.conductance.boundary_resistance > 0.0 {
            notes.push("thermal.contact_conductance and thermal.boundary_resistance are thermal interface terms: not applied to the electrical network".into());
            prep.conductance.contact = None;
            prep.conductance.boundary_resistance = 0.0;
        }
        prep.pipes = crate::heat::pipes(&prep.scene.particles, &prep.scene.materials, &prep.conductance)?;
        temperature = Some(t);
    }
    let prep = prep;
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
    let mut hr_periodic = None;
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
            hr_periodic = Some(mean_overlap_ratio(&pipes, p));
            out.insert("periodic_contacts".into(), pipes.pairs.len().into());
            // the run's contacts are the periodic ones (`walled_contacts`: the count without periodic images)
            out.insert("contacts".into(), pipes.pairs.len().into());
            out.insert("walled_contacts".into(), prep.pipes.pairs.len().into());
            let mut t = periodic(p, &pipes, &branch, bbox)?;
            // a network that does not wind around the cell along an axis conducts nothing along
            // it: its entries are round-off of either sign (κ_xx = -1.8e-17 W/(m K), issue 38)
            let span = spanned_axes(&p.position, &pipes.pairs, &branch, bbox);
            if let Some(w) = non_spanning(&mut t, span) {
                tracing::warn!(target: "sinterdem::kinds", "{w}");
                notes.push(w);
            }
            out.insert("spans".into(), serde_json::json!(span));
            t
        }
        o => return Err(ConfigError::invalid(format!("conductivity.boundary = \"{o}\": expected faces or periodic")).into()),
    };
    let rows: Vec<Vec<f64>> = (0..3).map(|i| (0..3).map(|j| tensor[(i, j)]).collect()).collect();
    let ratio: Vec<Vec<f64>> = rows.iter().map(|r| r.iter().map(|v| v / kappa_mat).collect()).collect();
    out.insert("boundary".into(), spec.boundary.clone().into());
    out.insert("quantity".into(), spec.quantity.clone().into());
    if let Some(t) = temperature {
        out.insert("sigma_eff_S_per_m".into(), serde_json::to_value(&rows).unwrap());
        out.insert("sigma_eff_over_sigma".into(), serde_json::to_value(&ratio).unwrap());
        out.insert("sigma_material_S_per_m".into(), kappa_mat.into());
        out.insert("resistivity_material_ohm_m".into(), (1.0 / kappa_mat).into());
        out.insert("temperature_K".into(), t.into());
        // %IACS for copper: every material from a copper preset (`copper`, `copper-ivannikov2022`)
        let copper = |s: &crate::material::MaterialSpec| s.preset.as_deref().is_some_and(|p| p.to_ascii_lowercase().starts_with("copper"));
        if prep.case.materials.iter().all(copper) {
            let iacs: Vec<f64> = (0..3).map(|a| 100.0 * tensor[(a, a)] / IACS_S_PER_M).collect();
            out.insert("iacs_percent".into(), serde_json::to_value(iacs).unwrap());
        }
    } else {
        out.insert("kappa_eff_W_per_mK".into(), serde_json::to_value(&rows).unwrap());
        out.insert("kappa_eff_over_kappa".into(), serde_json::to_value(&ratio).unwrap());
        out.insert("kappa_material_W_per_mK".into(), kappa_mat.into());
    }
    out.insert("particles".into(), p.len().into());
    out.entry("contacts").or_insert(prep.pipes.pairs.len().into());
    // the validated range of the law (docs/validation-conductance.md): mean h/r of the contacts
    let hr = hr_periodic.unwrap_or_else(|| mean_overlap_ratio(&prep.pipes, p));
    let extrapolated = crate::heat::conductance::beyond_validated(hr);
    out.insert("mean_overlap_over_radius".into(), hr.into());
    out.insert("extrapolated".into(), extrapolated.into());
    if extrapolated {
        let w = extrapolated_warning(hr);
        tracing::warn!(target: "sinterdem::kinds", "{w}");
        notes.push(w);
    }
    if let Some(bbox) = prep.scene.periodic_box {
        let phi = crate::heat::pipes::solid_fraction(&p.radius, bbox.x * bbox.y * bbox.z);
        out.insert("solid_fraction".into(), phi.into());
        out.insert("hashin_shtrikman_upper".into(), hashin_shtrikman_upper(phi).into());
    }
    if !notes.is_empty() {
        let mut w: Vec<serde_json::Value> = out.get("warnings").and_then(|w| w.as_array()).cloned().unwrap_or_default();
        w.extend(notes.into_iter().map(serde_json::Value::from));
        out.insert("warnings".into(), w.into());
    }
    if let Some(k) = lattice_closed_form(&prep, kappa_mat)? {
        let key = if electrical { "lattice_closed_form_S_per_m" } else { "lattice_closed_form_W_per_mK" };
        out.insert(key.into(), k.into());
    }
    Ok(serde_json::Value::Object(out))
}

/// The closed form of docs/heat-model.md for a lattice case: the conductivity [W/(m·K)] (or
/// [S/m] with σ for κ) of the pipes of the lattice's nearest neighbours with their crowding and
/// the bound (H8d), `f·K/d`; None for a packing that is not a lattice. `kappa_mat`: the material's
/// κ (or σ).
fn lattice_closed_form(prep: &crate::scene::Prepared, kappa_mat: f64) -> Result<Option<f64>, Error> {
    let Some((lat, d)) = prep.scene.lattice else { return Ok(None) };
    let p = &prep.scene.particles;
    // closed forms of docs/heat-model.md for the pipe conductance of the lattice's nearest neighbours
    let r = p.radius[0];
    let neck = crate::neck::solve(r, r, 2.0 * r - d)?;
    // the crowding of every neck (heat-model.md (H8c)): nᵀMn/(2a) = 1 (SC), (2 + 6/9)/2 = 4/3 (BCC), (2 + 8/4)/2 = 2 (FCC)
    let (f, phi) = match lat {
        crate::scene::Lattice::SimpleCubic => (1.0, 1.0),
        crate::scene::Lattice::BodyCentred => (3f64.sqrt(), 4.0 / 3.0),
        crate::scene::Lattice::FaceCentred => (2.0 * 2f64.sqrt(), 2.0),
    };
    // the volume of one particle's cell
    let cell = match lat {
        crate::scene::Lattice::SimpleCubic => d * d * d,
        crate::scene::Lattice::BodyCentred => 4.0 * d * d * d / (3.0 * 3f64.sqrt()),
        crate::scene::Lattice::FaceCentred => d * d * d / 2f64.sqrt(),
    };
    let pc = prep.conductance.pipe_crowded(kappa_mat, kappa_mat, r, r, neck.a, [phi, phi]);
    // the bound (H8d): the Voigt flux of a Bravais lattice is its κ_eff, f K/d, isotropic; the
    // cell's scale holds it at min(φ_c, HS(φ_c)) κ = HS(φ_c) κ
    let solid = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3) / cell;
    let s = lattice_bound(kappa_mat, solid, f * pc.pair / d);
    let kp = if s < 1.0 { prep.conductance.series(pc.half_i * s, pc.half_j * s, neck.a).pair } else { pc.pair };
    Ok(Some(f * kp / d))
}

/// The axes along which the periodic contact network spans the cell `bbox` [m]: some loop of
/// contacts winds around the cell along that axis. Contact k joins `pairs[k]` = (i, j) through the
/// image of j at `x_i + branch[k]` (minimum image, [m]); walking the network from each
/// particle, every particle gets the cell offset of its unwrapped copy, and a contact that
/// reaches an already placed particle with another offset closes a loop winding by the
/// difference. The effective tensor's range is spanned by these windings, so an axis that none
/// has a component along conducts nothing (docs/heat-model.md, "Periodic homogenisation").
pub fn spanned_axes(position: &[nalgebra::Vector3<f64>], pairs: &[[u32; 2]], branch: &[nalgebra::Vector3<f64>], bbox: nalgebra::Vector3<f64>) -> [bool; 3] {
    let n = position.len();
    let mut adj: Vec<Vec<(usize, [i64; 3])>> = vec![Vec::new(); n];
    for (k, &[i, j]) in pairs.iter().enumerate() {
        let (i, j) = (i as usize, j as usize);
        let d = position[i] + branch[k] - position[j];
        let s = [0, 1, 2].map(|a| (d[a] / bbox[a]).round() as i64);
        adj[i].push((j, s));
        adj[j].push((i, s.map(|v| -v)));
    }
    let mut offset: Vec<Option<[i64; 3]>> = vec![None; n];
    let mut span = [false; 3];
    for root in 0..n {
        if offset[root].is_some() {
            continue;
        }
        offset[root] = Some([0; 3]);
        let mut stack = vec![root];
        while let Some(i) = stack.pop() {
            let oi = offset[i].unwrap_or([0; 3]);
            for &(j, s) in &adj[i] {
                let want = [oi[0] + s[0], oi[1] + s[1], oi[2] + s[2]];
                match offset[j] {
                    None => {
                        offset[j] = Some(want);
                        stack.push(j);
                    }
                    Some(oj) => (0..3).filter(|&a| oj[a] != want[a]).for_each(|a| span[a] = true),
                }
            }
        }
    }
    span
}

/// Sets the rows and columns of the axes the network does not span ([`spanned_axes`]) to exactly
/// zero in the tensor `t` (they hold round-off of either sign) and returns the warning naming them.
pub fn non_spanning(t: &mut Matrix3<f64>, span: [bool; 3]) -> Option<String> {
    let axes: Vec<usize> = (0..3).filter(|&a| !span[a]).collect();
    if axes.is_empty() {
        return None;
    }
    let names: Vec<&str> = axes.iter().map(|&a| ["x", "y", "z"][a]).collect();
    let was: Vec<String> = axes.iter().map(|&a| format!("κ_{0}{0} = {1:.2e}", ["x", "y", "z"][a], t[(a, a)])).collect();
    for &a in &axes {
        for b in 0..3 {
            t[(a, b)] = 0.0;
            t[(b, a)] = 0.0;
        }
    }
    Some(format!(
        "conductivity: the contact network does not span the periodic cell along {} (no path of contacts winds around the cell along {}): the effective conductivity is 0 there (the solve left round-off: {}); is the packing dense enough, or the box too large for it?",
        names.join(", "),
        if names.len() == 1 { "that axis" } else { "those axes" },
        was.join(", ")
    ))
}

/// The Hashin–Shtrikman upper bound of a porous solid of solid fraction φ (voids non-conducting)
/// over the solid's conductivity, 2φ/(3 − φ) (docs/heat-model.md (H8d); φ capped at 1) [1].
pub fn hashin_shtrikman_upper(phi: f64) -> f64 {
    let f = phi.clamp(0.0, 1.0);
    2.0 * f / (3.0 - f)
}

/// The scale (H8d) of a cubic lattice's halves: solid fraction `solid` [1], the network's
/// (isotropic, Voigt-exact) conductivity `network` = f K/d [W/(m·K)], the solid's κ [W/(m·K)]:
/// `min(1, φ_c κ / network, HS(φ_c) κ / network)`, as the cell's scale of the periodic network.
fn lattice_bound(kappa: f64, solid: f64, network: f64) -> f64 {
    let phi_c = solid.min(1.0);
    (phi_c * kappa / network).min(hashin_shtrikman_upper(solid) * kappa / network).min(1.0)
}

/// Mean over the contacts of h/min(r_i, r_j) (h the overlap) [1]; 0 without contacts.
pub fn mean_overlap_ratio(pipes: &crate::heat::Pipes, p: &crate::particles::Particles) -> f64 {
    let n = pipes.pairs.len();
    if n == 0 {
        return 0.0;
    }
    pipes.pairs.iter().zip(&pipes.overlap).map(|(&[i, j], h)| h / p.radius[i as usize].min(p.radius[j as usize])).sum::<f64>() / n as f64
}

/// The message of a result beyond the FE-validated range of the law.
pub fn extrapolated_warning(mean_ratio: f64) -> String {
    format!(
        "conductivity: mean overlap h/r = {mean_ratio:.3} of the contacts is beyond the range the conductance law was validated against 3-D FE (mean h/r <= {}, docs/validation-conductance.md): the result is extrapolated (held below the Hashin-Shtrikman bound by (H8d))",
        crate::heat::conductance::VALIDATED_MEAN_OVERLAP_RATIO
    )
}

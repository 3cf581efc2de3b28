//! The periodic cell of a compact run (`[mechanics] boundary = "periodic"`, docs/mechanics.md
//! "Periodic cell"): its settings (`[mechanics.cell]`, a control per strain component), its
//! state (cell vectors, accumulated mean stress, load distribution) and the minimum-image
//! geometry every stage differences positions with.

use crate::config::ranges::{Range, c};
use crate::error::{ConfigError, ModelError};
use crate::mechanics::periodic::{COMPONENTS, CellControl, minimum_image};
use crate::scene::case::{CellSpec, ComponentSpec};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// The keys of `[mechanics.cell]` (docs/case-file.md).
pub static RANGES: &[Range] = &[
    c("mechanics.cell.*.stress", -1e9, 1e9, "Pa", "periodic compact: constant mean stress of a cell component, tension positive (0: free sintering)"),
    c("mechanics.cell.*.stress_table.time", 0.0, 1e9, "s", "periodic compact: times of a component's [[time s, stress Pa], ...] rows, strictly increasing"),
    c("mechanics.cell.*.stress_table.stress", -1e9, 1e9, "Pa", "periodic compact: stresses of a component's stress_table rows, tension positive"),
    c("mechanics.cell.*.strain_rate", -1.0, 1.0, "1/s", "periodic compact: prescribed strain rate of a cell component (0: constrained sintering)"),
    c(
        "mechanics.cell.contact_stress_limit",
        0.0,
        1e11,
        "Pa",
        "periodic compact: largest mean normal stress F_n/(pi a^2) a contact passes to its diffusion model under a cell stress (docs/pressure.md (P5))",
    ),
];

fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(RANGES, key, v)
}

/// A component's control over time.
#[derive(Debug, Clone, PartialEq)]
pub enum Control {
    /// Piecewise-linear mean stress `[time s, stress Pa]` rows (one row: constant).
    Stress(Vec<[f64; 2]>),
    /// Strain rate [1/s].
    StrainRate(f64),
}

impl Control {
    /// The stress at time `t` [Pa] (None for a strain-rate control): linear between rows, the
    /// first value before the first row and the last after the last.
    pub fn stress_at(&self, t: f64) -> Option<f64> {
        let Control::Stress(rows) = self else { return None };
        let k = rows.partition_point(|r| r[0] <= t);
        Some(match k {
            0 => rows[0][1],
            k if k == rows.len() => rows[k - 1][1],
            k => {
                let (a, b) = (rows[k - 1], rows[k]);
                a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0])
            }
        })
    }
}

/// The validated `[mechanics.cell]`.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSettings {
    /// One control per solved component (3 or 6), in the order xx, yy, zz, yz, xz, xy.
    pub controls: Vec<Control>,
    /// (P5) [Pa]; ∞ without a limit.
    pub contact_stress_limit: f64,
}

impl CellSettings {
    /// From `[mechanics] boundary` and `[mechanics.cell]`: None for walls; errors name the key,
    /// the value and what is allowed.
    pub fn from_spec(boundary: &str, spec: Option<&CellSpec>) -> Result<Option<CellSettings>, ConfigError> {
        match boundary {
            "walls" => {
                if spec.is_some() {
                    return Err(ConfigError::inconsistent("mechanics.cell", "is read with mechanics.boundary = \"periodic\" only (boundary = \"walls\")"));
                }
                return Ok(None);
            }
            "periodic" => {}
            o => return Err(ConfigError::invalid(format!("mechanics.boundary = \"{o}\": expected \"walls\" (default) or \"periodic\""))),
        }
        let spec = spec.cloned().unwrap_or_default();
        let nc = match spec.components.as_deref().unwrap_or("normal") {
            "normal" => 3,
            "all" => 6,
            o => {
                return Err(ConfigError::invalid(format!(
                    "mechanics.cell.components = \"{o}\": expected \"normal\" (xx, yy, zz) or \"all\" (also yz, xz, xy)"
                )));
            }
        };
        let given = [&spec.xx, &spec.yy, &spec.zz, &spec.yz, &spec.xz, &spec.xy];
        let mut controls = Vec::with_capacity(nc);
        for (k, g) in given.iter().enumerate() {
            let name = COMPONENTS[k];
            if k >= nc {
                if g.is_some() {
                    return Err(ConfigError::inconsistent(
                        format!("mechanics.cell.{name}"),
                        "a shear control needs mechanics.cell.components = \"all\" (components = \"normal\" holds the shears at zero)",
                    ));
                }
                continue;
            }
            controls.push(Self::control(name, g.as_ref())?);
        }
        let contact_stress_limit = match spec.contact_stress_limit {
            Some(v) => check("mechanics.cell.contact_stress_limit", v)?,
            None => f64::INFINITY,
        };
        Ok(Some(CellSettings { controls, contact_stress_limit }))
    }

    fn control(name: &str, g: Option<&ComponentSpec>) -> Result<Control, ConfigError> {
        let Some(g) = g else { return Ok(Control::Stress(vec![[0.0, 0.0]])) };
        let key = |s: &str| format!("mechanics.cell.{name}.{s}");
        match (g.stress, &g.stress_table, g.strain_rate) {
            (Some(v), None, None) => Ok(Control::Stress(vec![[0.0, check(&key("stress"), v)?]])),
            (None, Some(rows), None) => {
                if rows.is_empty() {
                    return Err(ConfigError::invalid(format!("{}: needs at least one [time s, stress Pa] row", key("stress_table"))));
                }
                for (k, r) in rows.iter().enumerate() {
                    check("mechanics.cell.*.stress_table.time", r[0]).map_err(|e| renamed(e, format!("{}[{k}] time", key("stress_table"))))?;
                    check("mechanics.cell.*.stress_table.stress", r[1]).map_err(|e| renamed(e, format!("{}[{k}] stress", key("stress_table"))))?;
                    if k > 0 && r[0] <= rows[k - 1][0] {
                        return Err(ConfigError::invalid(format!(
                            "{}[{k}]: time {} s is not after the previous row's {} s",
                            key("stress_table"),
                            r[0],
                            rows[k - 1][0]
                        )));
                    }
                }
                Ok(Control::Stress(rows.clone()))
            }
            (None, None, Some(v)) => Ok(Control::StrainRate(check(&key("strain_rate"), v)?)),
            (None, None, None) => Err(ConfigError::invalid(format!(
                "mechanics.cell.{name}: give one of stress (Pa), stress_table ([[time s, stress Pa], …]) or strain_rate (1/s)"
            ))),
            _ => Err(ConfigError::inconsistent(
                format!("mechanics.cell.{name}"),
                "a component is controlled by its stress or by its strain rate, not both: give exactly one of stress, stress_table and strain_rate",
            )),
        }
    }

    /// The controls of the step `[t0, t1]` [s]: stress increments Σ(t1) − `applied` for stress
    /// components, `rate·Δt` for strain-rate components.
    pub fn step_controls(&self, t1: f64, dt: f64, applied: &[f64; 6]) -> Vec<CellControl> {
        self.controls
            .iter()
            .enumerate()
            .map(|(k, c)| match c {
                Control::Stress(_) => CellControl::Stress(c.stress_at(t1).unwrap_or(0.0) - applied[k]),
                Control::StrainRate(r) => CellControl::Strain(r * dt),
            })
            .collect()
    }

    /// The prescribed stresses at `t` [Pa] (strain-rate components 0).
    pub fn stress_at(&self, t: f64) -> [f64; 6] {
        let mut s = [0.0; 6];
        for (k, c) in self.controls.iter().enumerate() {
            s[k] = c.stress_at(t).unwrap_or(0.0);
        }
        s
    }
}

fn renamed(e: ConfigError, key: String) -> ConfigError {
    match e {
        ConfigError::OutOfRange { value, range, unit, .. } => ConfigError::OutOfRange { key, value, range, unit },
        o => o,
    }
}

/// The state of the periodic cell of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellState {
    /// Cell vectors as columns [m] (column-major 3×3), now and at the start.
    pub cell: [f64; 9],
    pub cell0: [f64; 9],
    /// Mean (virial) stress of the cell (B20), accumulated over the steps [Pa]
    /// `[xx, yy, zz, yz, xz, xy]`, tension positive.
    pub stress: [f64; 6],
    /// The prescribed stresses reached so far [Pa] (the next step's increments start here).
    pub applied: [f64; 6],
    /// Largest gauge reaction relative to the largest bond load of a step so far [1].
    pub gauge_reaction: f64,
    /// The load distribution under the cell stress alone (docs/pressure.md (P3)): axial force per
    /// contact [N] at the stress `ref_stress`, for `ref_contacts` contacts, solved at `ref_step`.
    pub normal: Vec<f64>,
    pub ref_stress: [f64; 6],
    pub ref_contacts: usize,
    pub ref_step: u64,
    /// Distribution solves so far [1].
    pub solves: u64,
}

impl CellState {
    /// The cell of the box `[Lx, Ly, Lz]` [m] at the start.
    pub fn new(b: Vector3<f64>) -> Self {
        let m = Matrix3::from_diagonal(&b);
        let a: [f64; 9] = m.as_slice().try_into().unwrap_or([0.0; 9]);
        CellState {
            cell: a,
            cell0: a,
            stress: [0.0; 6],
            applied: [0.0; 6],
            gauge_reaction: 0.0,
            normal: vec![],
            ref_stress: [0.0; 6],
            ref_contacts: 0,
            ref_step: 0,
            solves: 0,
        }
    }

    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::from_column_slice(&self.cell)
    }

    pub fn matrix0(&self) -> Matrix3<f64> {
        Matrix3::from_column_slice(&self.cell0)
    }

    /// (B21) `L ← (I + ΔE)·L`.
    pub fn deform(&mut self, de: &Matrix3<f64>) {
        let m = (Matrix3::identity() + de) * self.matrix();
        self.cell.copy_from_slice(m.as_slice());
    }

    /// Lengths of the cell vectors [m] (the box edges of an orthorhombic cell).
    pub fn lengths(&self) -> Vector3<f64> {
        let m = self.matrix();
        Vector3::from_fn(|a, _| m.column(a).norm())
    }

    /// The cell's part of `summary.json` (docs/outputs.md "Periodic cell").
    pub fn summary(&self) -> serde_json::Value {
        let l = self.lengths();
        let l0 = Matrix3::from_column_slice(&self.cell0);
        let s = &self.stress;
        serde_json::json!({
            "cell_m": self.cell,
            "cell0_m": self.cell0,
            "lengths_m": [l.x, l.y, l.z],
            "volume_m3": self.volume(),
            "volume_strain": self.volume() / l0.determinant() - 1.0,
            "mean_stress_Pa": s,
            "mean_normal_stress_Pa": (s[0] + s[1] + s[2]) / 3.0,
            "gauge_reaction": self.gauge_reaction,
            "distribution_solves": self.solves,
        })
    }

    /// Volume det(L) [m³].
    pub fn volume(&self) -> f64 {
        self.matrix().determinant()
    }

    /// The minimum-image branch vector `x_j − x_i` (B14) [m].
    pub fn branch(&self, xi: &Vector3<f64>, xj: &Vector3<f64>) -> Vector3<f64> {
        let m = self.matrix();
        match m.try_inverse() {
            Some(inv) => minimum_image(&(xj - xi), &m, &inv),
            None => xj - xi,
        }
    }

    /// Pairs whose minimum-image surface gap is below `margin` [m], `i < j`, each once: the
    /// periodic cell search on the orthorhombic cell of the cell's diagonal, widened by the
    /// shear offsets of a sheared cell and filtered by the exact minimum-image distance.
    pub fn touching(&self, position: &[Vector3<f64>], radius: &[f64], margin: f64) -> Result<Vec<(u32, u32)>, ModelError> {
        let m = self.matrix();
        let inv = crate::mechanics::periodic::cell_inverse(&m)?;
        let diag = Vector3::new(m[(0, 0)], m[(1, 1)], m[(2, 2)]);
        let shear: f64 = (0..3).flat_map(|r| (0..3).filter(move |&c| c != r).map(move |c| (r, c))).map(|(r, c)| m[(r, c)].abs()).sum();
        let r_max = radius.iter().copied().fold(0.0, f64::max);
        if (0..3).any(|a| diag[a] <= 2.0 * (2.0 * r_max + margin + shear)) {
            return Err(ModelError::new(format!(
                "periodic cell: the cell {:?} m has become narrower than two largest reaches ({:e} m): minimum image no longer holds",
                diag.as_slice(),
                2.0 * r_max + margin
            )));
        }
        // positions in the unsheared frame (fractional coordinates times the diagonal)
        let frame: Vec<Vector3<f64>> = position.iter().map(|x| (inv * x).component_mul(&diag)).collect();
        let found = crate::contacts::detect::touching_pairs_periodic(&frame, radius, diag, margin + 2.0 * shear);
        let mut out = Vec::with_capacity(found.len());
        for p in found {
            let d = minimum_image(&(position[p.j as usize] - position[p.i as usize]), &m, &inv).norm();
            if d < radius[p.i as usize] + radius[p.j as usize] + margin {
                out.push((p.i, p.j));
            }
        }
        Ok(out)
    }
}

/// The periodic cell of a compact run at its start, or None for walls: the box of the scene
/// (`particles.periodic_box` of a file packing, or a lattice's), and the combinations a
/// periodic cell does not take refused with the key at fault.
pub fn start(settings: &super::Settings, prep: &crate::scene::Prepared, log: &mut dyn FnMut(&str)) -> Result<Option<CellState>, ConfigError> {
    let Some(cs) = &settings.mechanics.cell else { return Ok(None) };
    let Some(b) = prep.scene.periodic_box else {
        return Err(ConfigError::inconsistent(
            "mechanics.boundary",
            "\"periodic\" needs a periodic box: a file packing with particles.periodic_box = [Lx, Ly, Lz] (m), or particles.source = \"lattice\"",
        ));
    };
    let refuse = |key: &str, why: &str| Err(ConfigError::inconsistent(key, format!("{why} (mechanics.boundary = \"periodic\")")));
    if prep.scene.particles.len() < 3 {
        return refuse("mechanics.boundary", "a periodic cell needs the bonded mechanics, i.e. at least three particles; a pair is kind = \"pair\"");
    }
    if settings.load.is_some() {
        return refuse(
            "load",
            "a periodic cell is loaded through its stress controls, [mechanics.cell] xx = { stress = … } (Pa, tension positive), not by [load]",
        );
    }
    if prep.gap.is_some() {
        return refuse("thermal.gap", "the gap model's neighbour search is not periodic");
    }
    if prep.scene.materials.iter().any(|m| m.thermal_expansion.is_some()) {
        return refuse("materials.thermal_expansion", "thermal expansion (docs/coupled.md (X1)–(X12)) is not taken on a periodic cell");
    }
    if prep.sources.exposed_area.iter().any(|&a| a > 0.0) || prep.sources.fixed.iter().any(Option::is_some) {
        return refuse(
            "thermal",
            "a periodic cell has no faces: use thermal.mode = \"isothermal\" (or volumetric sources without furnace exposure or fixed temperatures)",
        );
    }
    log(&format!("periodic cell {:?} m: {}; no walls, no planes (docs/mechanics.md \"Periodic cell\")", b.as_slice(), describe(cs)));
    Ok(Some(CellState::new(b)))
}

/// The controls as read back for the log.
pub fn describe(s: &CellSettings) -> String {
    s.controls
        .iter()
        .enumerate()
        .map(|(k, c)| match c {
            Control::Stress(rows) if rows.len() == 1 => format!("{} stress {:e} Pa", COMPONENTS[k], rows[0][1]),
            Control::Stress(rows) => format!("{} stress table ({} rows)", COMPONENTS[k], rows.len()),
            Control::StrainRate(r) => format!("{} strain rate {r:e} 1/s", COMPONENTS[k]),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

impl super::Simulation {
    /// (P3) on a periodic cell: every contact's normal force from the bonded equilibrium under the
    /// prescribed cell stress at `t0` [s] alone (strain-controlled components held), solved when
    /// contacts appeared, when the stress changed direction and every
    /// [`super::load::REDISTRIBUTE_EVERY`] steps, otherwise scaled with the stress's magnitude
    /// (the problem is linear); clamped to compression and the (P5) limit. Zero stress: every
    /// normal force exactly 0.
    pub(super) fn update_cell_forces(&mut self, t0: f64) -> Result<(), crate::error::Error> {
        let (Some(cell), Some(cs)) = (self.cell.as_ref(), self.settings.mechanics.cell.as_ref()) else { return Ok(()) };
        let target = cs.stress_at(t0);
        let norm = |s: &[f64; 6]| s.iter().map(|v| v * v).sum::<f64>().sqrt();
        let (nt, nr) = (norm(&target), norm(&cell.ref_stress));
        if nt == 0.0 {
            self.contacts.state.iter_mut().for_each(|c| c.normal_force = 0.0);
            return Ok(());
        }
        let m = self.contacts.len();
        let parallel = nr > 0.0 && (0..6).all(|k| (target[k] / nt - cell.ref_stress[k] / nr).abs() <= 1e-12);
        let resolve = !parallel || cell.ref_contacts != m || cell.normal.len() != m || self.step >= cell.ref_step + super::load::REDISTRIBUTE_EVERY;
        if resolve {
            let controls: Vec<CellControl> = cs
                .controls
                .iter()
                .enumerate()
                .map(|(k, c)| match c {
                    Control::Stress(_) => CellControl::Stress(target[k]),
                    Control::StrainRate(_) => CellControl::Strain(0.0),
                })
                .collect();
            let l = cell.matrix();
            let visc = super::stages::sliding_viscosities(self, t0)?;
            self.mechanics.set_sliding(visc.map(|v| (v, self.dt)));
            let normal = self.mechanics.distribute_periodic(&self.prep.scene.particles, &self.contacts, &l, &controls)?;
            crate::finite::ensure_finite("load distribution", self.step + 1, t0, "contact", "normal force", normal.iter().copied())?;
            let Some(cell) = self.cell.as_mut() else { return Ok(()) };
            cell.normal = normal;
            cell.ref_stress = target;
            cell.ref_contacts = m;
            cell.ref_step = self.step;
            cell.solves += 1;
        }
        let Some(cell) = self.cell.as_ref() else { return Ok(()) };
        let scale = nt / norm(&cell.ref_stress);
        let lim = cs.contact_stress_limit;
        let floors = super::stages::tension_floors(self, t0)?;
        for (k, (c, &nf)) in self.contacts.state.iter_mut().zip(&cell.normal).enumerate() {
            let cap = lim * std::f64::consts::PI * c.y[0] * c.y[0];
            let floor = floors.as_ref().map_or(0.0, |f| f[k]);
            c.normal_force = (nf * scale).clamp(floor, cap);
        }
        Ok(())
    }
}

impl super::Simulation {
    /// The sintering stress of the cell (B23) `[xx, yy, zz, yz, xz, xy]` [Pa], tension positive:
    /// the virial `(1/V) Σ_c F_s,c l_c ⊗ l_c/|l_c|` of the forces `F_s = v0/M_c` (M14) that hold
    /// every contact at rest at its current state and temperature — the mean stress under which
    /// the free approach of every contact vanishes (exact for a lattice, the uniform-force
    /// estimate for a random packing). None for a walled run.
    pub fn sintering_stress(&self) -> Result<Option<[f64; 6]>, crate::error::Error> {
        let Some(cell) = &self.cell else { return Ok(None) };
        let mut sum = Matrix3::zeros();
        for (k, (c, &[i, j])) in self.contacts.state.iter().zip(&self.contacts.pairs).enumerate() {
            let (t, cp) = self.pair_params(i, j, self.t);
            let ctx = |e: ModelError| e.with_context(format!("sintering stress: contact {k} ({i}–{j}) at t = {} s", self.t));
            let coeffs = cp.at(t).map_err(ctx)?;
            let (v0, m) = crate::models::diffusion7::load_response(&c.y, &coeffs).map_err(ctx)?;
            let l = self.branch(i, j);
            sum += l * l.transpose() * (v0 / m / l.norm());
        }
        let v = sum / cell.volume();
        Ok(Some([v[(0, 0)], v[(1, 1)], v[(2, 2)], v[(1, 2)], v[(0, 2)], v[(0, 1)]]))
    }
}

impl super::Simulation {
    /// The contact temperature [K] of particles `i`, `j` at time `t` [s] (the furnace profile when
    /// isothermal, else the contact temperature of the two particles, the one the 7-DOF model
    /// uses) and the 7-DOF parameters of their phase pair at it.
    pub(in crate::coupled) fn pair_params(&self, i: u32, j: u32, t: f64) -> (f64, crate::models::diffusion7::ContactParams) {
        let p = &self.prep.scene.particles;
        let (i, j) = (i as usize, j as usize);
        let temp = match &self.prep.isothermal {
            Some(prof) => prof.temperature(t),
            None => super::stages::contact_temperature(self.settings.harmonic, p.temperature[i], p.temperature[j]),
        };
        let pm = crate::models::diffusion7::PairMaterials {
            a: &self.d7_materials[p.material[i] as usize],
            b: &self.d7_materials[p.material[j] as usize],
            factors: self.settings.factors,
        };
        (temp, pm.params_at(temp))
    }

    /// The Bouvard–McMeeking contact-law sintering stress of the cell (B23a) [Pa], the mean of the
    /// normal components of `(1/V) Σ_c F_BM,c l_c ⊗ l_c/|l_c|`, with the sintering force of the
    /// contact law as Yan et al. (2017) Eq. 1 print it, `F_BM = π γ_s [8R*(1 − cos(ψ/2)) +
    /// a·sin(ψ/2)]`, `R* = R_A R_B/(R_A + R_B)`, the dihedral angle from `cos(ψ/2) =
    /// γ_gb/(2γ_s)` and a the contact's neck radius, over the same contacts as (B23) — the
    /// reference the 7-DOF model's own force is held against (docs/rve.md). None for a walled run.
    pub fn contact_law_sintering_stress(&self) -> Result<Option<f64>, crate::error::Error> {
        let Some(cell) = &self.cell else { return Ok(None) };
        let mut trace = 0.0;
        for (k, (c, &[i, j])) in self.contacts.state.iter().zip(&self.contacts.pairs).enumerate() {
            let (_, cp) = self.pair_params(i, j, self.t);
            let gamma_s = 0.5 * (cp.sides[0].gamma_s + cp.sides[1].gamma_s);
            let cos_half = cp.gamma_gb / (2.0 * gamma_s);
            if !(cos_half.is_finite() && (0.0..1.0).contains(&cos_half)) {
                return Err(ModelError::new(format!(
                    "contact-law sintering stress: contact {k} ({i}–{j}): γ_gb/(2γ_s) = {cos_half} is not a dihedral angle's cosine in [0, 1)"
                ))
                .into());
            }
            let r_star = c.r0[0] * c.r0[1] / (c.r0[0] + c.r0[1]);
            let force = std::f64::consts::PI * gamma_s * (8.0 * r_star * (1.0 - cos_half) + c.y[0] * (1.0 - cos_half * cos_half).sqrt());
            // the trace of l ⊗ l/|l| is |l|
            trace += force * self.branch(i, j).norm();
        }
        Ok(Some(trace / (3.0 * cell.volume())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controls_and_errors() {
        let spec: CellSpec = toml::from_str("xx = { stress_table = [[0.0, 0.0], [100.0, -1e6]] }\nzz = { strain_rate = 0.0 }").unwrap();
        let s = CellSettings::from_spec("periodic", Some(&spec)).unwrap().unwrap();
        assert_eq!(s.controls.len(), 3);
        assert_eq!(s.controls[0].stress_at(50.0), Some(-5e5));
        assert_eq!(s.controls[0].stress_at(500.0), Some(-1e6));
        assert_eq!(s.controls[1], Control::Stress(vec![[0.0, 0.0]]));
        assert_eq!(s.step_controls(50.0, 10.0, &[0.0; 6])[2], CellControl::Strain(0.0));
        let both: CellSpec = toml::from_str("yy = { stress = 0.0, strain_rate = 0.0 }").unwrap();
        let e = CellSettings::from_spec("periodic", Some(&both)).unwrap_err().to_string();
        assert!(e.contains("mechanics.cell.yy") && e.contains("not both"), "{e}");
        let shear: CellSpec = toml::from_str("xy = { stress = 0.0 }").unwrap();
        let e = CellSettings::from_spec("periodic", Some(&shear)).unwrap_err().to_string();
        assert!(e.contains("mechanics.cell.xy") && e.contains("components = \"all\""), "{e}");
        let big: CellSpec = toml::from_str("xx = { stress = 2e9 }").unwrap();
        let e = CellSettings::from_spec("periodic", Some(&big)).unwrap_err().to_string();
        assert!(e.contains("mechanics.cell.xx.stress") && e.contains("Pa"), "{e}");
        assert!(CellSettings::from_spec("walls", Some(&big)).is_err());
        assert!(CellSettings::from_spec("wall", None).unwrap_err().to_string().contains("\"periodic\""));
    }

    /// The search of a sheared cell finds exactly the pairs a brute-force minimum-image search
    /// over all pairs finds (B14), each once.
    #[test]
    fn sheared_cell_search_equals_brute_force() {
        let mut seed = 11u64;
        let mut rng = || crate::mechanics::fixtures::rng(&mut seed);
        let (n, r) = (300, 1.0);
        let mut cell = CellState::new(Vector3::new(14.0, 15.0, 16.0));
        let shear = Matrix3::new(0.0, 0.03, -0.02, 0.03, 0.0, 0.025, -0.02, 0.025, 0.0);
        cell.deform(&shear);
        let m = cell.matrix();
        let pos: Vec<Vector3<f64>> = (0..n).map(|_| m * Vector3::new(rng(), rng(), rng()) + Vector3::new(rng() - 0.5, 0.0, 0.0) * 4.0).collect();
        let rad: Vec<f64> = (0..n).map(|_| r * (0.8 + 0.4 * rng())).collect();
        let margin = 0.1;
        let mut got = cell.touching(&pos, &rad, margin).unwrap();
        got.sort_unstable();
        let mut want = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                if cell.branch(&pos[i], &pos[j]).norm() < rad[i] + rad[j] + margin {
                    want.push((i as u32, j as u32));
                }
            }
        }
        assert!(want.len() > 50, "{}", want.len());
        assert_eq!(got, want);
    }
}

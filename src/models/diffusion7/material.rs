//! Material data of the 7-DOF model (docs/diffusion7.md §9) and their resolution into the
//! per-contact, per-phase parameters of §3, then into temperature-dependent transport
//! coefficients (M4), (M9).
//!
//! A [`Material`] has one or more [`Phase`]s; a phase applies from its `from_temperature` up to the
//! next phase's (titanium: α below 1156 K, β at and above). The phase of a contact is chosen at the
//! contact temperature, for both sides together (§3).

use crate::config::from_value;

/// Checks a key of the 7-DOF model's table (then the shared keys).
fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(super::RANGES, key, v)
}
use crate::error::{ConfigError, ModelError};
use crate::units::{BOLTZMANN, arrhenius};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// One phase of a material: interfacial energies, layer thicknesses, mobile fractions and
/// Arrhenius data (M9) of surface, GB and lattice diffusion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Phase {
    pub name: String,
    /// Lowest temperature of this phase [K].
    pub from_temperature: f64,
    /// Atomic volume Ω [m³] ("Vm, atom volume" of the tables, §10).
    pub atomic_volume: f64,
    /// Free-surface energy γ_s [J/m²].
    pub gamma_surface: f64,
    /// Grain-boundary energy γ_gb [J/m²].
    pub gamma_gb: f64,
    /// Surface-layer thickness δ_s [m].
    pub delta_surface: f64,
    /// GB thickness δ_gb [m].
    pub delta_gb: f64,
    /// Fraction of mobile surface atoms n_s [1].
    pub mobile_fraction_surface: f64,
    /// Fraction of mobile GB atoms n_gb [1].
    pub mobile_fraction_gb: f64,
    /// Lattice weight n_b [1] (not in the papers; 1, docs/diffusion7.md (M6)).
    #[serde(default = "one")]
    pub mobile_fraction_lattice: f64,
    /// Surface-diffusion prefactor D0_s [m²/s].
    pub d0_surface: f64,
    /// Surface-diffusion activation energy Q_s [J/mol].
    pub q_surface: f64,
    /// GB-diffusion prefactor D0_gb [m²/s].
    pub d0_gb: f64,
    /// GB-diffusion activation energy Q_gb [J/mol].
    pub q_gb: f64,
    /// Lattice-diffusion prefactor D0_b [m²/s].
    pub d0_lattice: f64,
    /// Lattice-diffusion activation energy Q_b [J/mol].
    pub q_lattice: f64,
}

fn one() -> f64 {
    1.0
}

/// A material of the 7-DOF model (docs/diffusion7.md §9), with the temperature range its diffusion data were
/// calibrated for (§10: a contact leaving it triggers a warning).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    pub name: String,
    /// Where the data come from.
    #[serde(default)]
    pub source: String,
    /// Young's modulus E [Pa] (only for the virtual sintering force (F4)).
    pub young_modulus: f64,
    /// Poisson ratio ν [1].
    pub poisson_ratio: f64,
    /// E(T) `[[T, E], ...]` ([K], [Pa]) of a library entry (docs/materials.md "Elastic
    /// constants"); None: `young_modulus` at every temperature. Not a case key.
    #[serde(skip)]
    pub young_modulus_table: Option<Vec<[f64; 2]>>,
    /// Lower end of the calibrated temperature range [K].
    pub calibrated_min_temperature: f64,
    /// Upper end of the calibrated temperature range [K].
    pub calibrated_max_temperature: f64,
    /// Melting (solidus) temperature [K]: a compact run stops with a ModelError when a particle
    /// reaches it. Optional.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub melting_temperature: Option<f64>,
    /// Phases in increasing `from_temperature`.
    pub phases: Vec<Phase>,
}

/// The bundled materials library (docs/materials.md), as TOML: the 7-DOF data of every entry
/// plus its preset constants, tables and sources ([`super::library`]).
pub const BUILTIN_MATERIALS: &str = super::library::LIBRARY;

impl Material {
    /// Deserialises and validates one `[[materials]]` table.
    pub fn from_value(v: toml::Value) -> Result<Material, ConfigError> {
        let m: Material = from_value(v, "materials")?;
        m.validate()?;
        Ok(m)
    }

    /// A bundled material by name (`"copper"`, `"titanium"`, … : the entries of the materials
    /// library, docs/materials.md).
    pub fn builtin(name: &str) -> Result<Material, ConfigError> {
        match super::library::entry(name) {
            Some(e) => Ok(e.diffusion()),
            None => Err(ConfigError::invalid(format!(
                "material \"{name}\" is neither defined in the case's [[materials]] nor bundled (bundled: {}; docs/materials.md)",
                super::library::names()
            ))),
        }
    }

    /// The seed paper's fitted copper, `copper-ivannikov2022` (docs/diffusion7.md §9, Table 2 of
    /// [IV22]; the compiled set is `builtin("copper")`, docs/materials.md).
    pub fn copper() -> Material {
        Material::builtin("copper-ivannikov2022").expect("bundled copper-ivannikov2022 is valid")
    }

    /// The seed paper's fitted titanium with α and β phases, `titanium-ivannikov2022`
    /// (docs/diffusion7.md §9, Table 4 of [IV22]; the compiled set is `builtin("titanium")`).
    pub fn titanium() -> Material {
        Material::builtin("titanium-ivannikov2022").expect("bundled titanium-ivannikov2022 is valid")
    }

    /// Checks every numeric key against the range table and the phase ordering.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let n = &self.name;
        if n.is_empty() {
            return Err(ConfigError::invalid("materials: a material needs a non-empty name"));
        }
        check(&format!("materials.{n}.young_modulus"), self.young_modulus)?;
        check(&format!("materials.{n}.poisson_ratio"), self.poisson_ratio)?;
        check(&format!("materials.{n}.calibrated_min_temperature"), self.calibrated_min_temperature)?;
        check(&format!("materials.{n}.calibrated_max_temperature"), self.calibrated_max_temperature)?;
        if self.calibrated_min_temperature > self.calibrated_max_temperature {
            return Err(ConfigError::inconsistent(
                format!("materials.{n}.calibrated_min_temperature"),
                format!("{} K is above calibrated_max_temperature {} K", self.calibrated_min_temperature, self.calibrated_max_temperature),
            ));
        }
        if let Some(tm) = self.melting_temperature {
            check(&format!("materials.{n}.melting_temperature"), tm)?;
        }
        if self.phases.is_empty() {
            return Err(ConfigError::inconsistent(format!("materials.{n}.phases"), "at least one phase is needed"));
        }
        for (i, ph) in self.phases.iter().enumerate() {
            let k = |f: &str| format!("materials.{n}.phases.{}.{f}", ph.name);
            check(&k("from_temperature"), ph.from_temperature)?;
            check(&k("atomic_volume"), ph.atomic_volume)?;
            check(&k("gamma_surface"), ph.gamma_surface)?;
            check(&k("gamma_gb"), ph.gamma_gb)?;
            check(&k("delta_surface"), ph.delta_surface)?;
            check(&k("delta_gb"), ph.delta_gb)?;
            check(&k("mobile_fraction_surface"), ph.mobile_fraction_surface)?;
            check(&k("mobile_fraction_gb"), ph.mobile_fraction_gb)?;
            check(&k("mobile_fraction_lattice"), ph.mobile_fraction_lattice)?;
            check(&k("d0_surface"), ph.d0_surface)?;
            check(&k("q_surface"), ph.q_surface)?;
            check(&k("d0_gb"), ph.d0_gb)?;
            check(&k("q_gb"), ph.q_gb)?;
            check(&k("d0_lattice"), ph.d0_lattice)?;
            check(&k("q_lattice"), ph.q_lattice)?;
            if i > 0 && ph.from_temperature <= self.phases[i - 1].from_temperature {
                return Err(ConfigError::inconsistent(
                    k("from_temperature"),
                    format!(
                        "phases must be listed in strictly increasing from_temperature ({} K follows {} K)",
                        ph.from_temperature,
                        self.phases[i - 1].from_temperature
                    ),
                ));
            }
        }
        Ok(())
    }

    /// E at temperature `t` [K]: the E(T) table, piecewise linear in T and held at its end
    /// points, where the material has one; else `young_modulus` (docs/materials.md (L1)).
    pub fn young_modulus_at(&self, t: f64) -> f64 {
        let Some(tab) = self.young_modulus_table.as_deref().filter(|x| !x.is_empty()) else {
            return self.young_modulus;
        };
        let (first, last) = (tab[0], tab[tab.len() - 1]);
        if !(t > first[0]) {
            return first[1];
        }
        if t >= last[0] {
            return last[1];
        }
        let k = tab.iter().position(|p| p[0] > t).unwrap_or(tab.len() - 1);
        let ([t0, e0], [t1, e1]) = (tab[k - 1], tab[k]);
        e0 + (e1 - e0) * (t - t0) / (t1 - t0)
    }

    /// Index of the phase at temperature `t` [K]: the last phase whose `from_temperature ≤ t`
    /// (the first phase below all of them).
    pub fn phase_at(&self, t: f64) -> usize {
        self.phases.iter().rposition(|p| p.from_temperature <= t).unwrap_or(0)
    }

    /// Phase-transition temperatures [K] (every `from_temperature` after the first phase's).
    pub fn transitions(&self) -> impl Iterator<Item = f64> + '_ {
        self.phases.iter().skip(1).map(|p| p.from_temperature)
    }
}

/// Path-length factors and lattice depth of docs/diffusion7.md §3 (M6).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PathFactors {
    /// λ_gb: GB paths I, II have length λ_gb·a [1] (default 1/4).
    pub path_factor_gb: f64,
    /// λ_n: neck paths III, IV have length λ_n·s [1] (default 1/2).
    pub path_factor_neck: f64,
    /// λ_p: cap paths V, VI have length λ_p·s [1] (default 1/2).
    pub path_factor_cap: f64,
    /// f_l: lattice depth l = f_l·s [1] (default 1).
    pub lattice_depth_factor: f64,
}

impl Default for PathFactors {
    fn default() -> Self {
        PathFactors { path_factor_gb: 0.25, path_factor_neck: 0.5, path_factor_cap: 0.5, lattice_depth_factor: 1.0 }
    }
}

impl PathFactors {
    /// Checks the factors against the range table (`model.*` keys).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check("model.path_factor_gb", self.path_factor_gb)?;
        check("model.path_factor_neck", self.path_factor_neck)?;
        check("model.path_factor_cap", self.path_factor_cap)?;
        check("model.lattice_depth_factor", self.lattice_depth_factor)?;
        Ok(())
    }
}

/// Arrhenius data of one mechanism: `D = d0·exp(−q/(R T))` [m²/s].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrhenius {
    /// D0 [m²/s].
    pub d0: f64,
    /// Q [J/mol].
    pub q: f64,
}

impl Arrhenius {
    /// D(T) [m²/s] (M9). Skips the exponential when D0 = 0 or Q = 0.
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        if self.d0 == 0.0 || self.q == 0.0 { self.d0 } else { arrhenius(self.d0, self.q, t) }
    }
}

/// One side's data in a contact (§3: its own surface and lattice data).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideData {
    /// γ_s [J/m²].
    pub gamma_s: f64,
    /// δ_s·n_s [m].
    pub delta_n_s: f64,
    pub surface: Arrhenius,
    /// n_b [1].
    pub n_b: f64,
    pub lattice: Arrhenius,
    /// δ_gb·n_gb [m] (averaged over the sides as a transport coefficient).
    pub delta_n_gb: f64,
    pub gb: Arrhenius,
}

/// Parameters of one contact in one phase (pair): resolved once per material pair and phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactParams {
    /// Ω, mean of the two sides [m³].
    pub omega: f64,
    /// γ_gb, mean of the two sides [J/m²].
    pub gamma_gb: f64,
    pub sides: [SideData; 2],
    pub factors: PathFactors,
}

impl ContactParams {
    /// Resolves the parameters of a contact between phase `pa` of `ma` and phase `pb` of `mb` (§3).
    pub fn new(ma: &Material, pa: usize, mb: &Material, pb: usize, factors: PathFactors) -> ContactParams {
        let side = |ph: &Phase| SideData {
            gamma_s: ph.gamma_surface,
            delta_n_s: ph.delta_surface * ph.mobile_fraction_surface,
            surface: Arrhenius { d0: ph.d0_surface, q: ph.q_surface },
            n_b: ph.mobile_fraction_lattice,
            lattice: Arrhenius { d0: ph.d0_lattice, q: ph.q_lattice },
            delta_n_gb: ph.delta_gb * ph.mobile_fraction_gb,
            gb: Arrhenius { d0: ph.d0_gb, q: ph.q_gb },
        };
        let (a, b) = (&ma.phases[pa], &mb.phases[pb]);
        ContactParams { omega: 0.5 * (a.atomic_volume + b.atomic_volume), gamma_gb: 0.5 * (a.gamma_gb + b.gamma_gb), sides: [side(a), side(b)], factors }
    }

    /// Same material on both sides, one phase.
    pub fn single(m: &Material, phase: usize, factors: PathFactors) -> ContactParams {
        ContactParams::new(m, phase, m, phase, factors)
    }

    /// Whether every transport coefficient (M9), each a sum of terms `D0·exp(−Q/(R T))/(k_B T)`,
    /// rises with the temperature up to `t` [K]: a term does for `T < Q/R` (its logarithm's
    /// derivative is `(Q/R − T)/T²`), so every mechanism with `D0 ≠ 0` needs `Q ≥ R·t` (a term with
    /// `Q = 0` falls as `1/T`). Then the coefficients over a temperature interval below `t` are
    /// at most those at `t` (docs/diffusion7.md (T2)).
    pub fn coefficients_rise_up_to(&self, t: f64) -> bool {
        self.sides.iter().all(|sd| [sd.surface, sd.lattice, sd.gb].iter().all(|m| m.d0 == 0.0 || m.q >= crate::units::GAS_CONSTANT * t))
    }

    /// The transport coefficients at contact temperature `t` [K] (M4), (M9).
    pub fn at(&self, t: f64) -> Result<Coeffs, ModelError> {
        if !(t > 0.0 && t.is_finite()) {
            return Err(ModelError::new(format!("contact temperature {t} K is not positive and finite")));
        }
        let kt = BOLTZMANN * t;
        let f = &self.factors;
        let same = self.sides[0] == self.sides[1];
        let mut c = Coeffs {
            omega: self.omega,
            gamma_s: [self.sides[0].gamma_s, self.sides[1].gamma_s],
            gamma_gb: self.gamma_gb,
            k_gb: 0.0,
            k_lat_gb: [0.0; 2],
            k_s_neck: [0.0; 2],
            k_b_neck: [0.0; 2],
            k_s_cap: [0.0; 2],
            k_b_cap: [0.0; 2],
            normal_force: 0.0,
        };
        let mut gb = [0.0; 2];
        for s in 0..2 {
            if s == 1 && same {
                c.k_lat_gb[1] = c.k_lat_gb[0];
                c.k_s_neck[1] = c.k_s_neck[0];
                c.k_b_neck[1] = c.k_b_neck[0];
                c.k_s_cap[1] = c.k_s_cap[0];
                c.k_b_cap[1] = c.k_b_cap[0];
                gb[1] = gb[0];
                break;
            }
            let sd = &self.sides[s];
            let (ds, db) = (sd.surface.at(t), sd.lattice.at(t));
            gb[s] = sd.delta_n_gb * sd.gb.at(t);
            c.k_lat_gb[s] = 2.0 / 3.0 * PI * db * sd.n_b / (kt * f.path_factor_gb);
            c.k_s_neck[s] = PI * sd.delta_n_s * ds / (kt * f.path_factor_neck);
            c.k_b_neck[s] = PI * f.lattice_depth_factor * db * sd.n_b / (kt * f.path_factor_neck);
            c.k_s_cap[s] = 2.0 * PI * sd.delta_n_s * ds / (kt * f.path_factor_cap);
            c.k_b_cap[s] = 2.0 * PI * f.lattice_depth_factor * db * sd.n_b / (kt * f.path_factor_cap);
        }
        c.k_gb = PI * 0.5 * (gb[0] + gb[1]) / (kt * f.path_factor_gb);
        Ok(c)
    }
}

/// Transport coefficients of a contact at one temperature; the flux of a path is its coefficient
/// times a geometric factor times the potential difference (M4), (M5):
/// `J_I = k_gb·Δμ`, `J_II = k_lat_gb·a·Δμ`, `J_III = k_s_neck·(a+h)/s·Δμ`,
/// `J_IV = k_b_neck·(a+h)·Δμ`, `J_V = k_s_cap·h/s·Δμ`, `J_VI = k_b_cap·h·Δμ` [m³/s].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coeffs {
    /// Ω [m³].
    pub omega: f64,
    /// γ_s per side [J/m²].
    pub gamma_s: [f64; 2],
    /// γ_gb [J/m²].
    pub gamma_gb: f64,
    /// π·δ_gb·n_gb·D_gb/(k_B T λ_gb) [m³/(J s)].
    pub k_gb: f64,
    /// (2/3)π·D_b·n_b/(k_B T λ_gb) [m²/(J s)].
    pub k_lat_gb: [f64; 2],
    /// π·δ_s·n_s·D_s/(k_B T λ_n) [m³/(J s)].
    pub k_s_neck: [f64; 2],
    /// π·f_l·D_b·n_b/(k_B T λ_n) [m²/(J s)].
    pub k_b_neck: [f64; 2],
    /// 2π·δ_s·n_s·D_s/(k_B T λ_p) [m³/(J s)].
    pub k_s_cap: [f64; 2],
    /// 2π·f_l·D_b·n_b/(k_B T λ_p) [m²/(J s)].
    pub k_b_cap: [f64; 2],
    /// Mechanical normal force F_n on the grain boundary [N], compressive positive (an applied
    /// load carried by the contact, docs/pressure.md): shifts the GB potentials μ4, μ7 by
    /// Ω·F_n/(∂V/∂y4), Ω·F_n/(∂V/∂y7) (docs/diffusion7.md (M11)). 0 in [`ContactParams::at`]; the
    /// caller sets it per contact (`Contact7::normal_force`).
    pub normal_force: f64,
}

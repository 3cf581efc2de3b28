//! Temperature-dependent thermal properties of the heat network (heat-model.md
//! "Temperature-dependent properties", eqs. P1–P4).
//!
//! - Enthalpy per particle `H_i(T) = m_i ∫_0^T c(θ) dθ` (eq. P1; c constant below the first table
//!   point), so that the stored heat of a step is `H_i(T^{n+1}) − H_i(T^n)`, not `C ΔT`.
//! - Secant capacity `C_i(T^n, T) = m_i c̄(T^n, T)`, c̄ the mean of c over [T^n, T] (eq. P2): then
//!   `C_i(T^n, T)(T − T^n) = H_i(T) − H_i(T^n)` exactly.
//! - Pipe conductance with κ(T): each half is rescaled by `κ̄(T_i, T_j)/κ_ref`, κ̄ the mean of the
//!   half's κ over [T_i, T_j] (eq. P3; on one linear piece, κ at the contact temperature
//!   (T_i + T_j)/2), then in series as in eq. 8 with the neck's boundary resistance (H7) (eq. P4). For a one-material pipe the flux is
//!   `G (Φ(T_i) − Φ(T_j))` with the Kirchhoff transform `Φ(T) = ∫ κ dT`: exact in steady state
//!   for any piecewise-linear κ.

use crate::heat::PipeConductance;
use crate::material::{Material, Table};

/// Per-material tables and per-particle masses. Materials without a table keep the constant
/// capacity and conductance given to the network.
#[derive(Debug, Clone)]
pub struct ThermalProperties {
    /// m_i [kg] per particle.
    pub mass: Vec<f64>,
    /// Material index per particle.
    pub material: Vec<u16>,
    /// c(T) [J/(kg·K)] per material.
    pub heat_capacity: Vec<Option<Table>>,
    /// κ(T) [W/(m·K)] per material and κ_ref [W/(m·K)], the constant the pipe halves were
    /// computed with.
    pub conductivity: Vec<Option<(Table, f64)>>,
    /// Interface conductance K_c in series [W/K] (eq. 8).
    pub contact: Option<f64>,
}

impl ThermalProperties {
    /// The tables of `materials` for particles of `material` index and `mass` [kg]; `None` when no
    /// material has a table (then the network is the constant-property one, bit for bit).
    pub fn of(mass: &[f64], material: &[u16], materials: &[Material], contact: Option<f64>) -> Option<ThermalProperties> {
        if materials.iter().all(|m| m.heat_capacity_table.is_none() && m.conductivity_table.is_none()) {
            return None;
        }
        Some(ThermalProperties {
            mass: mass.to_vec(),
            material: material.to_vec(),
            heat_capacity: materials.iter().map(|m| m.heat_capacity_table.clone()).collect(),
            conductivity: materials.iter().map(|m| m.conductivity_table.clone().map(|t| (t, m.conductivity))).collect(),
            contact,
        })
    }

    /// Whether any material has κ(T) (then the network needs the pipe halves).
    pub fn has_conductivity(&self) -> bool {
        self.conductivity.iter().any(Option::is_some)
    }

    /// c(T) table of particle `i`, if any.
    pub fn capacity_table(&self, i: usize) -> Option<&Table> {
        self.heat_capacity[self.material[i] as usize].as_ref()
    }

    /// Pipe conductance K_ij [W/K] at temperatures `ti`, `tj` [K] (eqs. P3–P4) from the halves
    /// computed with κ_ref.
    pub fn pipe(&self, pc: &PipeConductance, i: usize, j: usize, ti: f64, tj: f64) -> f64 {
        let scale = |p: usize| match &self.conductivity[self.material[p] as usize] {
            Some((t, kref)) => t.mean(ti, tj) / kref,
            None => 1.0,
        };
        let (hi, hj) = (pc.half_i * scale(i), pc.half_j * scale(j));
        if !(hi > 0.0 && hj > 0.0) {
            return 0.0;
        }
        let mut inv = 1.0 / hi + 1.0 / hj;
        if let Some(kc) = self.contact {
            inv += 1.0 / kc;
        }
        if pc.boundary > 0.0 {
            // the neck's boundary resistance R_b/(π a²) (H7) does not scale with κ(T)
            inv += pc.boundary;
        }
        1.0 / inv
    }
}

//! The energy balance of a heat run or a compact run's heat network.

/// Floor of the energy-balance denominator, relative to the stored heat Σ C_i T_i [1].
pub const ENERGY_BALANCE_FLOOR: f64 = 1e-6;

/// The energy-balance residual |ΔE − Q| / max(Σ|Q_step|, |ΔE|, 1e-6·E) of a run: `stored_change`
/// ΔE and `heat_in` Q [J] over the run, `scale` Σ|Q_step| [J], `stored_total` E = Σ C_i T_i [J].
/// The floor tied to the stored heat keeps the figure meaningful when almost no heat flows (then
/// the residual is round-off of E, and a purely relative figure would read O(1)).
pub fn energy_balance_rel(stored_change: f64, heat_in: f64, scale: f64, stored_total: f64) -> f64 {
    let denom = scale.max(stored_change.abs()).max(ENERGY_BALANCE_FLOOR * stored_total.abs()).max(f64::MIN_POSITIVE);
    (stored_change - heat_in).abs() / denom
}

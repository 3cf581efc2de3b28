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

/// Largest magnitude of an energy account in a checkpoint [J]: sums over 1e12 steps of such
/// values stay finite (an account of 1e308 J validated and turned a resumed run's balance into
/// inf / NaN).
pub const MAX_ENERGY_ACCOUNT_J: f64 = 1e100;

/// An energy account `v` [J] read from a checkpoint under `key`: finite and within
/// ±[`MAX_ENERGY_ACCOUNT_J`].
pub fn energy_account(key: &str, v: f64) -> Result<(), crate::error::ConfigError> {
    if v.is_finite() && v.abs() <= MAX_ENERGY_ACCOUNT_J {
        Ok(())
    } else {
        Err(crate::error::ConfigError::OutOfRange {
            key: key.to_string(),
            value: v,
            range: format!("[-{0}, {0}]", crate::error::fmt_value(MAX_ENERGY_ACCOUNT_J)),
            unit: "J".into(),
        })
    }
}

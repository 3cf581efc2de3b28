//! Physical constants (SI) and small helpers shared by the models.

/// Boltzmann constant k_B [J/K].
pub const BOLTZMANN: f64 = 1.380649e-23;
/// Molar gas constant R [J/(mol·K)].
pub const GAS_CONSTANT: f64 = 8.314462618;
/// Stefan–Boltzmann constant σ [W/(m²·K⁴)].
pub const STEFAN_BOLTZMANN: f64 = 5.670374419e-8;
/// 0 °C in kelvin.
pub const ZERO_CELSIUS: f64 = 273.15;

/// Arrhenius law `D = D0·exp(−Q/(R·T))` (docs/diffusion7.md (M9)): `d0` [m²/s], `q` [J/mol], `t` [K].
#[inline]
pub fn arrhenius(d0: f64, q: f64, t: f64) -> f64 {
    d0 * (-q / (GAS_CONSTANT * t)).exp()
}

/// Volume of a sphere of radius `r` [m] → [m³].
#[inline]
pub fn sphere_volume(r: f64) -> f64 {
    4.0 / 3.0 * std::f64::consts::PI * r * r * r
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn arrhenius_matches_definition() {
        // Copper surface diffusion at 1293 K (docs/diffusion7.md §9): D_s ≈ 7.9e-9 m²/s.
        let d = arrhenius(7.0e6, 370e3, 1293.0);
        assert!((d / 7.9e-9 - 1.0).abs() < 0.02, "{d}");
        assert_eq!(arrhenius(2.0, 0.0, 300.0), 2.0);
    }
}

/// A time [s] as a user reads it in log lines, one format everywhere (issue 25): four significant
/// digits, plain between 1e-3 s and 1e7 s (`4700 s`, `111.4 s`, `0.01234 s`), scientific outside
/// (`2.605e-6 s`).
pub fn fmt_seconds(t: f64) -> String {
    if t == 0.0 || !t.is_finite() {
        return format!("{t} s");
    }
    if (1e-3..1e7).contains(&t.abs()) {
        let digits = (3 - t.abs().log10().floor() as i32).max(0) as usize;
        let s = format!("{t:.digits$}");
        let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
        format!("{s} s")
    } else {
        format!("{t:.3e} s")
    }
}

#[cfg(test)]
mod fmt_tests {
    #[test]
    fn seconds_read_with_four_significant_digits() {
        use super::fmt_seconds;
        assert_eq!(fmt_seconds(4700.0), "4700 s");
        assert_eq!(fmt_seconds(111.397), "111.4 s");
        assert_eq!(fmt_seconds(0.0123456), "0.01235 s");
        assert_eq!(fmt_seconds(2.604938e-6), "2.605e-6 s");
        assert_eq!(fmt_seconds(0.0), "0 s");
        assert_eq!(fmt_seconds(5000.0), "5000 s");
    }
}

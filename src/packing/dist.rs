//! Seeded random numbers and particle size distributions.
//!
//! The generator is a xoshiro256** stream seeded through SplitMix64 (Blackman & Vigna 2018): small,
//! fast, and the same sequence on every platform, so a seed reproduces a packing exactly.

use crate::error::ConfigError;

/// xoshiro256** pseudo-random generator.
#[derive(Debug, Clone)]
pub struct Rng {
    s: [u64; 4],
}

impl Rng {
    pub fn new(seed: u64) -> Self {
        let mut z = seed;
        let mut next = || {
            z = z.wrapping_add(0x9E3779B97F4A7C15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D049BB133111EB);
            x ^ (x >> 31)
        };
        Rng { s: [next(), next(), next(), next()] }
    }
    pub fn next_u64(&mut self) -> u64 {
        let r = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        r
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
    /// Uniform integer in [0, n).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n.saturating_sub(1))
    }
    /// Fisher–Yates shuffle.
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = self.below(i + 1);
            v.swap(i, j);
        }
    }
}

/// A particle diameter distribution (number-weighted), diameters in metres.
#[derive(Debug, Clone, PartialEq)]
pub enum SizeDistribution {
    /// `d = mean·(1 + spread·u)`, u uniform in [−1, 1] (Yade's makeCloud "rRelFuzz").
    Uniform { mean: f64, spread: f64 },
    /// Normal with mean and standard deviation [m], truncated at `mean ± truncate·std`.
    Normal { mean: f64, std: f64, truncate: f64 },
    /// Tabulated cumulative number fraction F(d_k), strictly increasing diameters, F from 0 to 1;
    /// sampled by linear interpolation of the inverse CDF.
    Tabulated { diameters: Vec<f64>, cumulative: Vec<f64> },
}

impl SizeDistribution {
    pub fn validate(&self) -> Result<(), ConfigError> {
        match self {
            SizeDistribution::Uniform { mean, spread } => {
                if !(*mean > 0.0 && (0.0..1.0).contains(spread)) {
                    return Err(ConfigError::inconsistent("packing.size", "uniform needs mean_diameter > 0 and 0 <= spread < 1"));
                }
            }
            SizeDistribution::Normal { mean, std, truncate } => {
                if !(*mean > 0.0 && *std >= 0.0 && *truncate > 0.0) {
                    return Err(ConfigError::inconsistent("packing.size", "normal needs mean_diameter > 0, std_diameter >= 0, truncate > 0"));
                }
                if mean - truncate * std <= 0.0 {
                    return Err(ConfigError::inconsistent(
                        "packing.size.truncate",
                        format!("mean_diameter - truncate*std_diameter = {:e} m must be > 0", mean - truncate * std),
                    ));
                }
            }
            SizeDistribution::Tabulated { diameters, cumulative } => {
                if diameters.len() < 2 || diameters.len() != cumulative.len() {
                    return Err(ConfigError::inconsistent(
                        "packing.size.cumulative",
                        format!("needs as many entries as packing.size.diameters (>= 2); got {} and {}", cumulative.len(), diameters.len()),
                    ));
                }
                for k in 0..diameters.len() {
                    if !(diameters[k] > 0.0 && diameters[k].is_finite()) {
                        return Err(ConfigError::inconsistent(format!("packing.size.diameters.{k}"), format!("{} must be > 0 (m)", diameters[k])));
                    }
                    if !(0.0..=1.0).contains(&cumulative[k]) {
                        return Err(ConfigError::inconsistent(format!("packing.size.cumulative.{k}"), format!("{} must be in [0, 1]", cumulative[k])));
                    }
                    if k > 0 && (diameters[k] <= diameters[k - 1] || cumulative[k] < cumulative[k - 1]) {
                        return Err(ConfigError::inconsistent(
                            format!("packing.size.diameters.{k}"),
                            "diameters must increase strictly and cumulative fractions must not decrease",
                        ));
                    }
                }
                if cumulative[0] != 0.0 || *cumulative.last().unwrap() != 1.0 {
                    return Err(ConfigError::inconsistent("packing.size.cumulative", "must start at 0 and end at 1"));
                }
            }
        }
        Ok(())
    }

    /// Cumulative number fraction F(d) of the requested distribution.
    pub fn cdf(&self, d: f64) -> f64 {
        match self {
            SizeDistribution::Uniform { mean, spread } => {
                if *spread == 0.0 {
                    return if d >= *mean { 1.0 } else { 0.0 };
                }
                ((d / mean - 1.0) / spread * 0.5 + 0.5).clamp(0.0, 1.0)
            }
            SizeDistribution::Normal { mean, std, truncate } => {
                if *std == 0.0 {
                    return if d >= *mean { 1.0 } else { 0.0 };
                }
                let phi = |z: f64| 0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2));
                let z = ((d - mean) / std).clamp(-truncate, *truncate);
                (phi(z) - phi(-truncate)) / (phi(*truncate) - phi(-truncate))
            }
            SizeDistribution::Tabulated { diameters, cumulative } => {
                if d <= diameters[0] {
                    return 0.0;
                }
                for k in 1..diameters.len() {
                    if d <= diameters[k] {
                        let t = (d - diameters[k - 1]) / (diameters[k] - diameters[k - 1]);
                        return cumulative[k - 1] + t * (cumulative[k] - cumulative[k - 1]);
                    }
                }
                1.0
            }
        }
    }

    /// Smallest and largest diameter the distribution can produce [m].
    pub fn support(&self) -> (f64, f64) {
        match self {
            SizeDistribution::Uniform { mean, spread } => (mean * (1.0 - spread), mean * (1.0 + spread)),
            SizeDistribution::Normal { mean, std, truncate } => (mean - truncate * std, mean + truncate * std),
            SizeDistribution::Tabulated { diameters, .. } => (diameters[0], *diameters.last().unwrap()),
        }
    }

    /// Draws one diameter [m].
    pub fn sample(&self, rng: &mut Rng) -> f64 {
        match self {
            SizeDistribution::Uniform { mean, spread } => mean * (1.0 + spread * (2.0 * rng.uniform() - 1.0)),
            SizeDistribution::Normal { mean, std, truncate } => loop {
                let z = rng.normal();
                if z.abs() <= *truncate {
                    return mean + std * z;
                }
            },
            SizeDistribution::Tabulated { diameters, cumulative } => {
                let u = rng.uniform();
                for k in 1..diameters.len() {
                    if u < cumulative[k] || k + 1 == diameters.len() {
                        let df = cumulative[k] - cumulative[k - 1];
                        let t = if df > 0.0 { ((u - cumulative[k - 1]) / df).clamp(0.0, 1.0) } else { 0.0 };
                        return diameters[k - 1] + t * (diameters[k] - diameters[k - 1]);
                    }
                }
                *diameters.last().unwrap()
            }
        }
    }
}

/// Error function (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7).
pub fn erf(x: f64) -> f64 {
    let s = x.signum();
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.3275911 * x);
    let y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t + 0.254829592) * t * (-x * x).exp();
    s * y
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn samples_follow_the_cdf() {
        let dists = [
            SizeDistribution::Uniform { mean: 50e-6, spread: 0.1 },
            SizeDistribution::Normal { mean: 64e-6, std: 6.4e-6, truncate: 2.5 },
            SizeDistribution::Tabulated { diameters: vec![40e-6, 60e-6, 80e-6], cumulative: vec![0.0, 0.3, 1.0] },
        ];
        for d in &dists {
            d.validate().unwrap();
            let mut rng = Rng::new(7);
            let mut xs: Vec<f64> = (0..20000).map(|_| d.sample(&mut rng)).collect();
            xs.sort_by(f64::total_cmp);
            // Kolmogorov–Smirnov distance against the requested CDF
            let ks = xs.iter().enumerate().map(|(k, &x)| (d.cdf(x) - (k as f64 + 0.5) / xs.len() as f64).abs()).fold(0.0, f64::max);
            assert!(ks < 0.015, "{d:?}: KS {ks}");
            let (lo, hi) = d.support();
            assert!(xs[0] >= lo && *xs.last().unwrap() <= hi);
        }
    }
}

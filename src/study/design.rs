//! Designs: how parameter values combine into the points of a study (docs/studies.md "Designs").
//!
//! - grid: the Cartesian product (last parameter fastest);
//! - zip: the i-th value of every parameter together;
//! - lhs: Latin hypercube — each parameter's range cut into n equal strata, one point per stratum,
//!   strata paired by seeded random permutations, the point uniform within its stratum;
//! - sobol: Owen-scrambled Sobol points (`sobol_burley`, scrambling seed = `design.seed`), the
//!   low-discrepancy choice for variance-based sensitivity.
//!
//! With `log = true` a value is uniform in ln x: x = lo·(hi/lo)^u.

use super::spec::{DesignKind, Parameter, Values};
use crate::packing::Rng;

/// One design point: (parameter column name, key, value) in parameter order.
pub type Point = Vec<(String, String, toml::Value)>;

/// Number of values of a list or range (bounds have none of their own).
pub fn count(v: &Values) -> usize {
    match v {
        Values::List(l) => l.len(),
        Values::Range { num, .. } => *num,
        Values::Bounds { .. } => 0,
    }
}

/// Maps u ∈ [0, 1] onto [lo, hi], linearly or in ln x.
pub fn scale(u: f64, lo: f64, hi: f64, log: bool) -> f64 {
    if log { (lo.ln() + u * (hi.ln() - lo.ln())).exp() } else { lo + u * (hi - lo) }
}

fn expand(v: &Values) -> Vec<toml::Value> {
    match v {
        Values::List(l) => l.clone(),
        Values::Range { lo, hi, num, log } => (0..*num)
            .map(|i| {
                let u = if *num == 1 { 0.0 } else { i as f64 / (*num - 1) as f64 };
                // the ends exactly as written
                let x = if i == 0 {
                    *lo
                } else if i + 1 == *num {
                    *hi
                } else {
                    scale(u, *lo, *hi, *log)
                };
                toml::Value::Float(x)
            })
            .collect(),
        Values::Bounds { .. } => vec![],
    }
}

/// Unit-cube samples of a Latin hypercube: `n` points in `d` dimensions.
pub fn latin_hypercube(n: usize, d: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = Rng::new(seed);
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(d);
    for _ in 0..d {
        let mut perm: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = (rng.uniform() * (i + 1) as f64) as usize;
            perm.swap(i, j.min(i));
        }
        cols.push(perm.iter().map(|&k| (k as f64 + rng.uniform()) / n as f64).collect());
    }
    (0..n).map(|i| cols.iter().map(|c| c[i]).collect()).collect()
}

/// Unit-cube samples of an Owen-scrambled Sobol sequence.
pub fn sobol(n: usize, d: usize, seed: u64) -> Vec<Vec<f64>> {
    (0..n).map(|i| (0..d).map(|k| sobol_burley::sample(i as u32, k as u32, seed as u32) as f64).collect()).collect()
}

/// The points of a design.
pub fn points(params: &[Parameter], kind: DesignKind) -> Vec<Point> {
    let named = |i: usize, v: toml::Value| (params[i].name.clone(), params[i].key.clone(), v);
    match kind {
        DesignKind::Grid => {
            let lists: Vec<Vec<toml::Value>> = params.iter().map(|p| expand(&p.values)).collect();
            let mut out: Vec<Point> = vec![vec![]];
            for (i, l) in lists.iter().enumerate() {
                out = out
                    .into_iter()
                    .flat_map(|pt| {
                        l.iter().map(move |v| {
                            let mut q = pt.clone();
                            q.push(named(i, v.clone()));
                            q
                        })
                    })
                    .collect();
            }
            out
        }
        DesignKind::Zip => {
            let lists: Vec<Vec<toml::Value>> = params.iter().map(|p| expand(&p.values)).collect();
            let n = lists.first().map_or(1, Vec::len);
            (0..n).map(|k| lists.iter().enumerate().map(|(i, l)| named(i, l[k].clone())).collect()).collect()
        }
        DesignKind::Lhs { samples, seed } | DesignKind::Sobol { samples, seed } => {
            let u = if matches!(kind, DesignKind::Lhs { .. }) { latin_hypercube(samples, params.len(), seed) } else { sobol(samples, params.len(), seed) };
            u.iter()
                .map(|row| {
                    row.iter()
                        .enumerate()
                        .map(|(i, &x)| match params[i].values {
                            Values::Bounds { lo, hi, log } => named(i, toml::Value::Float(scale(x, lo, hi, log))),
                            _ => unreachable!("sampled designs have bounds (checked at load)"),
                        })
                        .collect()
                })
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(name: &str, values: Values) -> Parameter {
        Parameter { key: name.into(), name: name.into(), values }
    }

    #[test]
    fn grid_is_the_cartesian_product_last_fastest() {
        let ps = [p("a", Values::List(vec![1.into(), 2.into()])), p("b", Values::Range { lo: 10.0, hi: 30.0, num: 3, log: false })];
        let pts = points(&ps, DesignKind::Grid);
        assert_eq!(pts.len(), 6);
        let flat: Vec<(i64, f64)> = pts.iter().map(|q| (q[0].2.as_integer().unwrap(), q[1].2.as_float().unwrap())).collect();
        assert_eq!(flat, vec![(1, 10.0), (1, 20.0), (1, 30.0), (2, 10.0), (2, 20.0), (2, 30.0)]);
    }

    #[test]
    fn log_range_is_geometric_with_exact_ends() {
        let v = expand(&Values::Range { lo: 1e-3, hi: 1e1, num: 5, log: true });
        let x: Vec<f64> = v.iter().map(|v| v.as_float().unwrap()).collect();
        assert_eq!(x[0], 1e-3);
        assert_eq!(x[4], 1e1);
        for k in 1..5 {
            assert!((x[k] / x[k - 1] / 10.0 - 1.0).abs() < 1e-12, "{x:?}");
        }
    }

    #[test]
    fn latin_hypercube_has_one_point_per_stratum_and_is_seeded() {
        let n = 50;
        let s = latin_hypercube(n, 3, 7);
        for d in 0..3 {
            let mut strata: Vec<usize> = s.iter().map(|r| (r[d] * n as f64) as usize).collect();
            strata.sort();
            assert_eq!(strata, (0..n).collect::<Vec<_>>(), "dimension {d}");
        }
        assert_eq!(s, latin_hypercube(n, 3, 7));
        assert_ne!(s, latin_hypercube(n, 3, 8));
    }

    #[test]
    fn sobol_points_are_balanced_in_every_dyadic_interval() {
        // a (0, m, 2) net: 2^m points put exactly 2^(m-k) in each of the 2^k intervals of a dimension
        let n = 256;
        let s = sobol(n, 4, 3);
        for d in 0..4 {
            for k in 1..=8 {
                let bins = 1usize << k;
                let mut c = vec![0usize; bins];
                for r in &s {
                    c[(r[d] * bins as f64) as usize] += 1;
                }
                assert!(c.iter().all(|&x| x == n / bins), "dimension {d}, {bins} bins: {c:?}");
            }
        }
        // the mean of x over the unit cube is 1/2; Sobol's error is far below Monte Carlo's 1/sqrt(12 n)
        let mean: f64 = s.iter().map(|r| r[0]).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.1 / (12.0 * n as f64).sqrt(), "{mean}");
    }

    #[test]
    fn zip_pairs_values() {
        let ps = [p("a", Values::List(vec![1.into(), 2.into()])), p("b", Values::List(vec!["x".into(), "y".into()]))];
        let pts = points(&ps, DesignKind::Zip);
        assert_eq!(pts.len(), 2);
        assert_eq!(pts[1][1].2.as_str(), Some("y"));
    }
}
